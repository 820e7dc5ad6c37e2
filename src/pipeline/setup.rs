//! Building a [`Simulation`] from a [`Scene`]: sampling, the static wall
//! structures, and the initial time step.

use super::granular::{Granular, Mixed};
use super::solid::{Peer2018, SolidModel};
use super::step::explicit_viscosity_bound;
use super::{PairSet, Params, Simulation, StepStats, Workspace};
use crate::backend::Passes;
use crate::scene::{
    sample_fluid, sample_solids, sample_walls, DriftMomentum, KernelChoice, PhasePressure, PhaseTransport,
    PressureWarmStart, Scene, SolidMaterial, ViscositySolver, WallRowsChoice,
};
use crate::store::{FluidStore, SolidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::blocks::BLOCK;
use porosph_kernels::elasticity::Lame;
use porosph_kernels::kernel::{Kernel, KernelShape};
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, PairLists};
use porosph_kernels::soa::Vel;

impl Params {
    /// Parameters of a scene (PHYSICS.md §1: H = 2h, h = particle spacing).
    pub fn from_scene(scene: &Scene) -> Self {
        let s = &scene.simulation;
        let h = s.particle_spacing;
        // The explicit viscosity's stable step: the least over the viscous
        // phases (infinite without one).
        let explicit_bound = scene
            .phases
            .iter()
            .filter(|p| p.viscosity > 0.0)
            .map(|p| explicit_viscosity_bound(h, p.density, p.viscosity))
            .fold(f32::INFINITY, f32::min);
        Self {
            h,
            kernel: Kernel::with_shape(
                match s.kernel {
                    KernelChoice::CubicSpline => KernelShape::CubicSpline,
                    KernelChoice::WendlandC2 => KernelShape::WendlandC2,
                },
                2.0 * h,
            ),
            gravity: s.gravity,
            max_dt: s.max_dt,
            cfl: s.cfl_number,
            max_density_error: s.max_density_error,
            max_row_density_error: s.max_row_density_error.unwrap_or(f32::INFINITY),
            min_iterations: s.min_iterations,
            max_iterations: s.max_iterations,
            omega: s.omega,
            chebyshev_radius: s.chebyshev_radius,
            hydrostatic_warm_start: s.pressure_warm_start == PressureWarmStart::Hydrostatic,
            lattice_wall_rows: s.wall_rows == WallRowsChoice::Lattice,
            phase_density: scene.phases.iter().map(|p| p.density).collect(),
            phase_viscosity: scene.phases.iter().map(|p| p.viscosity).collect(),
            phase_drift_tau: scene.phases.iter().map(|p| p.drift_tau).collect(),
            phase_drift_sigma: scene.phases.iter().map(|p| p.drift_sigma).collect(),
            drift_momentum_sign: match s.drift_momentum {
                DriftMomentum::Physical => -1.0,
                DriftMomentum::Plus => 1.0,
                DriftMomentum::Off => 0.0,
            },
            conservative_transport: s.phase_transport == PhaseTransport::Conservative,
            fraction_pressure: s.phase_pressure == PhasePressure::Fraction,
            solid_granular: scene.solids.iter().map(|b| matches!(b.model, SolidMaterial::Granular(_))).collect(),
            solid_lame: scene.solids.iter().map(|b| Lame { mu: b.shear_modulus, lambda: b.lame_lambda }).collect(),
            implicit_viscosity: match s.viscosity_solver {
                ViscositySolver::Explicit => false,
                ViscositySolver::Implicit => true,
                ViscositySolver::Auto => explicit_bound < s.max_dt,
            },
            implicit_viscosity_above: match s.viscosity_solver {
                ViscositySolver::Auto => explicit_bound,
                _ => 0.0,
            },
            explicit_viscosity_dt: explicit_bound,
            viscosity_tolerance: s.viscosity_tolerance,
            elastic_tolerance: s.elastic_tolerance,
            elastic_prediction_tolerance: s.elastic_prediction_tolerance,
            elastic_max_iterations: s.elastic_max_iterations,
            solid_group: {
                let mut names: Vec<&str> = Vec::new();
                scene
                    .solids
                    .iter()
                    .map(|b| match names.iter().position(|n| *n == b.body) {
                        Some(g) => g as u32,
                        None => {
                            names.push(&b.body);
                            (names.len() - 1) as u32
                        }
                    })
                    .collect()
            },
            solid_rest_mass: scene.solids.iter().map(|b| b.density * h * h * h).collect(),
            porous: scene.solids.iter().map(|b| b.porous.clone()).collect(),
            pore_drift: s.pore_drift,
            inner_drift_tau: s.inner_drift_tau,
            inner_drift_sigma: s.inner_drift_sigma,
        }
    }

    /// Whether any solid is porous (the porous passes run).
    pub fn porous(&self) -> bool {
        self.porous.iter().any(Option::is_some)
    }

    /// Whether a pass reads the solid-solid pairs: the porous terms (pore
    /// pressure and its gradient among a solid's particles), the granular
    /// stress, and the solid rows, which take only pairs of two bodies
    /// (`solid_rows::solid_pair`). With one non-porous, non-granular body
    /// nothing does, and the neighbour pass builds none.
    pub fn solid_pairs_read(&self) -> bool {
        self.porous() || self.solid_granular.iter().any(|&g| g) || self.bodies() > 1
    }

    /// Number of elastic bodies (distinct `body` names).
    pub fn bodies(&self) -> usize {
        self.solid_group.iter().map(|&g| g as usize + 1).max().unwrap_or(0)
    }

    /// The rest mass m_s0 of each solid particle, kg.
    pub fn particle_rest_mass(&self, solids: &SolidStore) -> Vec<f32> {
        solids.body.iter().map(|&b| self.solid_rest_mass[b as usize]).collect()
    }

    /// The elastic body of each solid particle.
    pub fn particle_groups(&self, solids: &SolidStore) -> Vec<u32> {
        solids.body.iter().map(|&b| self.solid_group[b as usize]).collect()
    }

    /// The solid model of `solids` of `scene` (PHYSICS.md §3: Peer et al.
    /// 2018; with granular bodies, [`Mixed`] with the Drucker-Prager
    /// continuum, `granular.rs`).
    pub fn solid_model(&self, scene: &Scene, solids: &SolidStore) -> Box<dyn SolidModel> {
        let granular = Granular::new(scene, solids);
        let mut groups = self.particle_groups(solids);
        if let Some(g) = &granular {
            // Granular particles have no rest neighbours: a group each.
            let first = self.bodies() as u32;
            for (i, grp) in groups.iter_mut().enumerate() {
                if g.is_granular(i) {
                    *grp = first + i as u32;
                }
            }
        }
        let elastic = Peer2018::new(
            solids,
            &groups,
            &self.particle_rest_mass(solids),
            &self.solid_lame,
            &self.kernel,
            self.elastic_prediction_tolerance,
            self.elastic_max_iterations,
        );
        match granular {
            Some(g) => Box::new(Mixed::new(elastic, g)),
            None => Box::new(elastic),
        }
    }

    /// Number of phases K.
    pub fn phases(&self) -> usize {
        self.phase_density.len()
    }

    /// Whether the mixture passes run: with two or more phases. With one
    /// phase the drift, drift momentum, transport and correction passes are
    /// skipped, so a one-phase step is the single-fluid IISPH step.
    pub fn mixture(&self) -> bool {
        self.phases() >= 2
    }

    /// The diffusivity of the drift for the time step rule, the largest
    /// sigma_k and, with porous solids, sigma' of P-Eq. 12, m^2/s
    /// (PHYSICS.md §7).
    pub fn drift_diffusivity(&self) -> f32 {
        let outer = self.phase_drift_sigma.iter().copied().fold(0.0, f32::max);
        if self.porous() {
            outer.max(self.inner_drift_sigma)
        } else {
            outer
        }
    }

    /// A bound on the drift speed before the first step, m/s: the
    /// buoyancy part of P-Eq. 11 at rest, max_k tau_k (rho_max - rho_min) |g|.
    pub fn drift_speed_estimate(&self) -> f32 {
        if !self.mixture() {
            return 0.0;
        }
        let lo = self.phase_density.iter().copied().fold(f32::INFINITY, f32::min);
        let hi = self.phase_density.iter().copied().fold(0.0, f32::max);
        let g = self.gravity.iter().map(|c| c * c).sum::<f32>().sqrt();
        let tau = self.phase_drift_tau.iter().copied().fold(0.0, f32::max);
        tau * (hi - lo) * g
    }

    /// Reference density of the walls' output `density` (rho_ref V0/V):
    /// the first phase's rest density (a scene has at least one phase).
    pub fn wall_reference_density(&self) -> f32 {
        self.phase_density.first().copied().unwrap_or(0.0)
    }

    /// The lattice volume h^3, m^3: rest volume of a full fluid particle
    /// (P §6.1, V_f0 = alpha_f h^3) and of a wall particle.
    pub fn cell_volume(&self) -> f32 {
        self.h * self.h * self.h
    }
}

impl Simulation {
    /// Samples the scene into particles and prepares the static walls.
    pub fn new(scene: Scene) -> Self {
        let params = Params::from_scene(&scene);
        let sampled_walls = sample_walls(&scene);
        let sampled_fluid = sample_fluid(&scene, &sampled_walls);
        let sampled_solids = sample_solids(&scene, &sampled_walls);
        let nf = sampled_fluid.positions.len();
        let nw = sampled_walls.positions.len();
        let k = scene.phases.len();

        let mut fluid = FluidStore::default();
        for (p, v) in sampled_fluid.positions.iter().zip(&sampled_fluid.velocities) {
            fluid.x.push(p[0]);
            fluid.y.push(p[1]);
            fluid.z.push(p[2]);
            fluid.ux.push(v[0]);
            fluid.uy.push(v[1]);
            fluid.uz.push(v[2]);
        }
        fluid.pressure = vec![0.0; nf];
        fluid.density = vec![0.0; nf];
        fluid.alpha = (0..k).map(|ph| sampled_fluid.fractions.iter().map(|f| f[ph]).collect()).collect();
        fluid.beta = vec![vec![0.0; nf]; k];
        (fluid.alpha_lo, fluid.beta_lo) = (vec![vec![0.0; nf]; k], vec![vec![0.0; nf]; k]);
        fluid.id = (0..nf as u32).collect();

        let mut walls = WallStore::default();
        for p in &sampled_walls.positions {
            walls.x.push(p[0]);
            walls.y.push(p[1]);
            walls.z.push(p[2]);
        }
        // Rest volumes are set below, once the wall neighbours are known.
        walls.rest_volume = vec![0.0; nw];
        walls.pressure = vec![0.0; nw];
        walls.density = vec![0.0; nw];
        walls.sigma_static = vec![0.0; nw];
        walls.id = (nf as u32..(nf + nw) as u32).collect();

        // Solids: mass rho_s d^3.
        let mut solids = SolidStore::default();
        let ns = sampled_solids.positions.len();
        let cell = params.cell_volume();
        for (i, p) in sampled_solids.positions.iter().enumerate() {
            let v = sampled_solids.velocities[i];
            let body = sampled_solids.body[i];
            for (col, val) in [
                (&mut solids.x, p[0]),
                (&mut solids.y, p[1]),
                (&mut solids.z, p[2]),
                (&mut solids.x0, p[0]),
                (&mut solids.y0, p[1]),
                (&mut solids.z0, p[2]),
                (&mut solids.vx, v[0]),
                (&mut solids.vy, v[1]),
                (&mut solids.vz, v[2]),
                (&mut solids.mass, scene.solids[body as usize].density * cell),
                (&mut solids.qx, 0.0),
                (&mut solids.qy, 0.0),
                (&mut solids.qz, 0.0),
                (&mut solids.qw, 1.0),
                (&mut solids.pressure, 0.0),
                (&mut solids.stress, 0.0),
                (&mut solids.strain_trace, 0.0),
                (&mut solids.saturation, 0.0),
                (&mut solids.pore_pressure, 0.0),
                (&mut solids.sxx, 0.0),
                (&mut solids.syy, 0.0),
                (&mut solids.szz, 0.0),
                (&mut solids.sxy, 0.0),
                (&mut solids.sxz, 0.0),
                (&mut solids.syz, 0.0),
                (&mut solids.plastic_strain, 0.0),
            ] {
                col.push(val);
            }
        }
        solids.body = sampled_solids.body;
        solids.fixed = sampled_solids.fixed;
        solids.id = ((nf + nw) as u32..(nf + nw + ns) as u32).collect();
        super::granular::set_initial_stress(&scene, glam::Vec3::from(params.gravity), params.h, &mut solids);
        let solid_model = params.solid_model(&scene, &solids);

        let mut work = wall_workspace(&mut walls, &params);
        (work.solid_own, work.solid_v0) = super::volumes::rest_rows(&params, &solids);
        let mut bb = PairLists::default();
        let pts = Vel { x: &walls.x, y: &walls.y, z: &walls.z };
        build_pairs(&mut bb, pts, pts, &work.wall_grid, None, &params.kernel);
        // Rest volume of a wall particle (PHYSICS.md §2.3, Akinci-style):
        // V0_b = gamma / sum_{b'} W_bb' over the wall (incl. self), with gamma
        // the value of d^3 sum W over a flat wall of two lattice layers. So
        // V0_b = d^3 exactly on a flat wall (where the wall stands for the
        // missing fluid lattice), less in corners, more at convex edges; and
        // sum_b' V0_b' W_bb' ~ gamma < 1 everywhere, so a wall row only
        // resists compression by fluid, never by its own sampling. With
        // `wall_rows = "lattice"` the rows' own part is the lattice's d^3
        // sum_b' W_bb' = gamma d^3 / V0_b instead (`iisph::wall_row_sigma`),
        // so that in a concave corner, too, a row reads 1 beside a fluid
        // lattice at rest.
        let gamma = params.kernel.flat_wall_gamma(params.h);
        let mut sum_w = vec![0.0f32; nw];
        for (b, blk) in bb.used().iter().enumerate() {
            for q in 0..blk.start.len().saturating_sub(1) {
                sum_w[b * BLOCK + q] = blk.range(q).map(|p| blk.w[p]).sum();
            }
        }
        for (v, s) in walls.rest_volume.iter_mut().zip(&sum_w) {
            *v = if *s > 0.0 { gamma / s } else { params.cell_volume() };
        }
        for (b, blk) in bb.used().iter().enumerate() {
            for q in 0..blk.start.len().saturating_sub(1) {
                let i = b * BLOCK + q;
                walls.sigma_static[i] = blk.range(q).map(|p| walls.rest_volume[blk.j[p] as usize] * blk.w[p]).sum();
            }
        }
        let rho_ref = params.wall_reference_density();
        for (d, s) in walls.density.iter_mut().zip(&walls.sigma_static) {
            *d = rho_ref * s;
        }

        let mut sim = Simulation {
            scene,
            params,
            fluid,
            walls,
            solids,
            solid_model,
            backend: Box::<dyn Passes>::default(),
            pairs: PairSet::default(),
            time: 0.0,
            step: 0,
            dt: 0.0,
            last: StepStats::default(),
            work,
            arena: Bump::new(),
            arena_used: 0,
            scratch: Default::default(),
        };
        let v0 = sim.max_speed();
        let (dt, by) = sim.dt_rule(v0, sim.params.drift_speed_estimate());
        (sim.dt, sim.last.next_dt_limit) = (dt, Some(by));
        sim
    }
}

/// A fresh workspace for `walls`: walls never move, so they are sorted along
/// the Morton curve once and their grid is built once, here. Walls that are
/// already sorted (restored from a checkpoint) keep their order: the sort
/// breaks ties by index, so its permutation is the identity.
pub(super) fn wall_workspace(walls: &mut WallStore, params: &Params) -> Workspace {
    let mut work = Workspace::default();
    let inv_cell = 1.0 / params.kernel.support;
    let mut keys = vec![0; walls.len()];
    compute_keys(&walls.x, &walls.y, &walls.z, inv_cell, &mut keys);
    let (mut sort, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut sort, &mut perm);
    walls.reorder(&perm, &mut work.reorder);
    let sorted: Vec<u64> = sort.iter().map(|&(k, _)| k).collect();
    work.wall_grid.build(&sorted, params.kernel.support);
    let near = work.wall_grid.dilated_keys();
    work.wall_near.build(&near, params.kernel.support);
    work
}
