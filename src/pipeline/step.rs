//! The step: passes 0-5 and 10-14 of PHYSICS.md §6 for one or more fluid
//! phases sharing each particle (the mixture model of PHYSICS.md §4.1), and
//! static walls, and elastic solids (PHYSICS.md §3, passes 6 and 8). With
//! one phase the mixture passes (10-12 and the correction of 14) are
//! skipped, so the step is the single-fluid step; without solids every
//! solid argument is `None` and the solid passes take no time.

use super::solid::SolidModel;
use super::timing::pass;
use super::{Params, Simulation, StepStats, Workspace};
use crate::backend::gpu::{
    DriftInput, DriftOutput, GpuBackend, PorousDriftInput, SolveInput, SolveOutput, SolveSettings, WallInput,
};
use crate::store::{FluidStore, SolidStore, WallStore};
use bumpalo::Bump;
use glam::Vec3;
use porosph_kernels::blocks::{max_f32, nblocks, sum_f64, BLOCK};
use porosph_kernels::drift::{self, PhaseVelocityInput};
use porosph_kernels::drift_momentum::{drift_momentum, DriftMomentumInput};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph::{self, FluidRows, Jacobi, Rows, SolidPairs, Vel, VelMut, WallRows};
use porosph_kernels::integrate::{integrate, State};
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, PairLists, Points};
use porosph_kernels::phase_transport;
use porosph_kernels::phases::{PhaseConstants, PhaseVel};
use porosph_kernels::viscosity::{predict_velocity, predict_velocity_mixture, ViscosityInput};
use rayon::prelude::*;
use std::fmt;

/// A step that cannot go on: a NaN or an exploding velocity.
#[derive(Clone, Debug, PartialEq)]
pub struct StepError {
    pub step: u64,
    pub time: f64,
    /// Stable id of the first offending particle.
    pub particle: u32,
    pub position: [f32; 3],
    pub velocity: [f32; 3],
    pub reason: String,
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "step {} (t = {:.6} s): {}: particle id {} at {:?} m with velocity {:?} m/s",
            self.step, self.time, self.reason, self.particle, self.position, self.velocity
        )
    }
}

impl std::error::Error for StepError {}

impl Simulation {
    /// Advances by one step of length [`Simulation::dt`], then picks the next dt.
    pub fn step(&mut self) -> Result<&StepStats, StepError> {
        let dt = self.dt;
        // Prescribed velocities of the fixed solid particles for this step.
        for (i, &b) in self.solids.body.iter().enumerate() {
            if self.solids.fixed[i] != 0 {
                let v = self.scene.solids[b as usize].fixed_velocity(self.time);
                (self.solids.vx[i], self.solids.vy[i], self.solids.vz[i]) = (v[0], v[1], v[2]);
            }
        }
        let Simulation { params, fluid, walls, solids, solid_model, work, arena, .. } = self;
        let bodies = Bodies { store: solids, model: solid_model.as_mut() };
        let mut stats = step_passes(params, fluid, walls, bodies, work, arena, dt);
        arena.reset();
        if let Some(reason) = work.gpu_error.take() {
            return Err(StepError { step: self.step, time: self.time, reason, ..self.blowup(0.0) });
        }
        self.time += dt as f64;
        self.step += 1;
        let t = std::time::Instant::now();
        let speed = self.max_speed();
        if !speed.is_finite() || speed > self.blowup_speed() {
            return Err(self.blowup(speed));
        }
        self.dt = self.next_dt(speed, stats.max_drift_speed.max(stats.max_darcy_speed));
        stats.times.ms[pass::TIME_STEP] += t.elapsed().as_secs_f64() * 1e3;
        stats.max_speed = speed;
        stats.dt = dt;
        self.last = stats;
        Ok(&self.last)
    }

    /// Largest fluid or solid speed, m/s (NaN if any velocity is NaN).
    pub fn max_speed(&self) -> f32 {
        let f = &self.fluid;
        let s = &self.solids;
        let fluid = max_f32(f.len(), |i| (f.ux[i] * f.ux[i] + f.uy[i] * f.uy[i] + f.uz[i] * f.uz[i]).sqrt());
        let solid = max_f32(s.len(), |i| (s.vx[i] * s.vx[i] + s.vy[i] * s.vy[i] + s.vz[i] * s.vz[i]).sqrt());
        if fluid.is_nan() || solid.is_nan() {
            f32::NAN
        } else {
            fluid.max(solid)
        }
    }

    /// The time step rule of PHYSICS.md §7:
    /// dt = min(max_dt, lambda h / max|u|, 0.125 h^2 rho_k / mu_k), and with
    /// two or more phases also lambda h / max_k|u_mk| and
    /// 0.1 h^2 / max_k sigma_k; `max_drift` is the largest of the last
    /// step's outer and inner drift speeds and Darcy speeds |u_rk| (the
    /// step passes max(max_drift_speed, max_darcy_speed); PHYSICS.md writes
    /// 0.4 = lambda's default).
    pub fn next_dt(&self, max_speed: f32, max_drift: f32) -> f32 {
        let p = &self.params;
        let mut dt = p.max_dt;
        if max_speed > 0.0 {
            dt = dt.min(p.cfl * p.h / max_speed);
        }
        for (&rho, &mu) in p.phase_density.iter().zip(&p.phase_viscosity) {
            if mu > 0.0 {
                dt = dt.min(0.125 * p.h * p.h * rho / mu);
            }
        }
        if p.mixture() {
            if max_drift > 0.0 {
                dt = dt.min(p.cfl * p.h / max_drift);
            }
            let sigma = p.drift_diffusivity();
            if sigma > 0.0 {
                dt = dt.min(0.1 * p.h * p.h / sigma);
            }
        }
        dt
    }

    /// A speed at which the CFL step would fall below 1e-4 max_dt: the run
    /// has exploded.
    fn blowup_speed(&self) -> f32 {
        self.params.cfl * self.params.h / (1e-4 * self.params.max_dt)
    }

    fn blowup(&self, speed: f32) -> StepError {
        let (f, s) = (&self.fluid, &self.solids);
        let limit = self.blowup_speed();
        let bad = |x: [f32; 3], v: [f32; 3]| {
            let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            !speed.is_finite() || speed > limit || !x.iter().all(|c| c.is_finite())
        };
        let fluid_bad = (0..f.len()).find(|&i| bad([f.x[i], f.y[i], f.z[i]], [f.ux[i], f.uy[i], f.uz[i]]));
        let solid_bad = (0..s.len()).find(|&i| bad([s.x[i], s.y[i], s.z[i]], [s.vx[i], s.vy[i], s.vz[i]]));
        // The offending particle: a fluid one if any, else a solid one.
        let (what, id, position, velocity) = match (fluid_bad, solid_bad) {
            (None, Some(b)) => ("solid velocity", s.id[b], [s.x[b], s.y[b], s.z[b]], [s.vx[b], s.vy[b], s.vz[b]]),
            _ if f.is_empty() => ("velocity", 0, [f32::NAN; 3], [f32::NAN; 3]),
            (b, _) => {
                let b = b.unwrap_or(0);
                ("velocity", f.id.get(b).copied().unwrap_or(0), [f.x[b], f.y[b], f.z[b]], [f.ux[b], f.uy[b], f.uz[b]])
            }
        };
        StepError {
            step: self.step,
            time: self.time,
            particle: id,
            position,
            velocity,
            reason: if speed.is_finite() {
                format!("{what} exploded ({speed:.3e} m/s > {limit:.3e} m/s)")
            } else {
                format!("{what} is NaN or infinite")
            },
        }
    }
}

fn zeros(arena: &Bump, n: usize) -> &mut [f32] {
    arena.alloc_slice_fill_copy(n, 0.0f32)
}

/// The solid particles and their model.
struct Bodies<'a> {
    store: &'a mut SolidStore,
    model: &'a mut dyn SolidModel,
}

/// Passes 0-13 of one step; scratch comes from `arena`.
fn step_passes(
    p: &Params,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    bodies: Bodies,
    w: &mut Workspace,
    arena: &Bump,
    dt: f32,
) -> StepStats {
    let mut st = StepStats::default();
    let tm = &mut st.times;
    let n = fluid.len();
    let support = p.kernel.support;
    let Bodies { store: solids, model: solid_model } = bodies;
    let ns = solids.len();

    // Pass 0: Morton sort of the fluid, grid, neighbour pairs.
    let mut gpu_ms = 0.0;
    tm.time(pass::NEIGHBORS, || {
        let fp = Points { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        // The keys and sort on the GPU (bitwise the CPU's order), or here;
        // a GPU failure is reported after the step, which completes on the CPU.
        let gpu = w.gpu.as_deref_mut().filter(|g| g.passes.neighbors);
        let sorted = match gpu.map(|g| g.sort_permutation(fp, 1.0 / support, &mut w.sort, &mut w.perm)) {
            Some(Ok(ms)) => {
                gpu_ms = ms.unwrap_or(0.0);
                true
            }
            Some(Err(e)) => {
                w.gpu_error = Some(format!("GPU neighbour sort failed: {e}"));
                false
            }
            None => false,
        };
        if !sorted {
            w.keys.resize(n, 0);
            compute_keys(&fluid.x, &fluid.y, &fluid.z, 1.0 / support, &mut w.keys);
            sort_permutation(&w.keys, &mut w.sort, &mut w.perm);
        }
        if w.perm.iter().enumerate().any(|(i, &j)| i as u32 != j) {
            fluid.reorder(&w.perm, &mut w.reorder);
        }
        w.keys.clear();
        w.keys.extend(w.sort.iter().map(|&(k, _)| k));
        w.fluid_grid.build(&w.keys, support);
        let fp = Points { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        let wp = Points { x: &walls.x, y: &walls.y, z: &walls.z };
        build_pairs(&mut w.ff, fp, fp, &w.fluid_grid, None, &p.kernel);
        build_pairs(&mut w.fb, fp, wp, &w.wall_grid, Some(&w.wall_near), &p.kernel);
        // Active walls: those with at least one fluid neighbour (PHYSICS.md
        // §2.4), in wall order: the targets of the fluid-wall pairs.
        w.wall_flag.resize(walls.len(), 0);
        for &b in &w.active {
            w.wall_flag[b as usize] = 0;
        }
        for blk in w.fb.used() {
            for (&b, &wt) in blk.j.iter().zip(&blk.w) {
                if wt > 0.0 {
                    w.wall_flag[b as usize] = 1;
                }
            }
        }
        w.active.clear();
        w.active.extend((0..walls.len() as u32).filter(|&b| w.wall_flag[b as usize] != 0));
    });
    let na = w.active.len();
    let ax = arena.alloc_slice_fill_iter(w.active.iter().map(|&b| walls.x[b as usize]));
    let ay = arena.alloc_slice_fill_iter(w.active.iter().map(|&b| walls.y[b as usize]));
    let az = arena.alloc_slice_fill_iter(w.active.iter().map(|&b| walls.z[b as usize]));
    tm.time(pass::NEIGHBORS, || {
        let fp = Points { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        build_pairs(&mut w.bf, Points { x: ax, y: ay, z: az }, fp, &w.fluid_grid, None, &p.kernel);
        if ns > 0 {
            solid_neighbors(p, fluid, solids, walls, w);
        }
        // With the neighbour search on the GPU, also the cell-range tables
        // the GPU passes of this step read (with the walls' rows for the
        // pressure solve), built on the device; else the first pass that
        // needs them builds them.
        let solve_on_gpu = |g: &GpuBackend| g.passes.pressure_solve && ns == 0;
        let tables = |g: &GpuBackend| g.passes.neighbors && (solve_on_gpu(g) || (g.passes.drift && p.mixture()));
        if let Some(g) = w.gpu.as_deref_mut().filter(|g| n > 0 && tables(g)) {
            let wp = Points { x: &walls.x, y: &walls.y, z: &walls.z };
            let with_walls = solve_on_gpu(g).then_some(WallInput { grid: &w.wall_grid, walls: wp, active: &w.active });
            match g.cell_ranges(&w.fluid_grid, with_walls) {
                Ok(ms) => gpu_ms += ms,
                Err(e) => w.gpu_error = Some(format!("GPU cell-range tables failed: {e}")),
            }
        }
    });
    let fs_pairs = (ns > 0).then_some(&w.fs);
    tm.gpu_ms[pass::NEIGHBORS] = gpu_ms;

    // Porous coupling, part 1: N_f and the fallback of P Alg. 4.
    let porous = p.porous() && ns > 0 && n > 0;
    let (n_f, porous_mask) = if porous {
        tm.time(pass::POROUS, || super::porous::partition(p, fluid, solids, w, arena))
    } else {
        (&[][..], &[][..])
    };

    // Pass 1: phase bookkeeping: rest density rho_fm = sum_k alpha_k rho_k,
    // mu_m = sum_k alpha_k mu_k, alpha_f = sum_k alpha_k; m = rho_fm h^3 and
    // V0 = alpha_f h^3 (P §6.1).
    let rest_density = zeros(arena, n);
    let mu = zeros(arena, n);
    let alpha_f = zeros(arena, n);
    let mass = zeros(arena, n);
    let v0 = zeros(arena, n);
    tm.time(pass::PHASES, || {
        let cell = p.cell_volume();
        rest_density
            .par_chunks_mut(BLOCK)
            .zip(mu.par_chunks_mut(BLOCK))
            .zip(alpha_f.par_chunks_mut(BLOCK))
            .zip(mass.par_chunks_mut(BLOCK).zip(v0.par_chunks_mut(BLOCK)))
            .enumerate()
            .for_each(|(b, (((rho, mu), af), (m, v0)))| {
                for q in 0..rho.len() {
                    let i = b * BLOCK + q;
                    let (mut r, mut v, mut a) = (0.0, 0.0, 0.0);
                    for (k, al) in fluid.alpha.iter().enumerate() {
                        r += al[i] * p.phase_density[k];
                        v += al[i] * p.phase_viscosity[k];
                        a += al[i];
                    }
                    // Inner fractions count in the mass and viscosity (P-Eq. 10).
                    if porous {
                        for (k, be) in fluid.beta.iter().enumerate() {
                            r += be[i] * p.phase_density[k];
                            v += be[i] * p.phase_viscosity[k];
                        }
                    }
                    rho[q] = r;
                    mu[q] = v;
                    af[q] = a;
                    m[q] = r * cell;
                    // The outer volume fades out of the solve with the
                    // row weight (iisph::row_weight): 0 below alpha_f = 0.5.
                    v0[q] = iisph::row_weight(a) * a * cell;
                }
            });
    });

    // Pass 2 (4a-b): volumes V = V0 / sum_j V0_j W_ij, densities m / V.
    let sigma = zeros(arena, n);
    let vol = zeros(arena, n);
    let vm = zeros(arena, n);
    let sigma_b = zeros(arena, na);
    let vol_b = zeros(arena, na);
    let vol_b_full = zeros(arena, walls.len());
    // Solid rows, in the sorted order of the workspace: body, rest volumes,
    // sigma_s = sum V0 W over the own body (current) and fluid, volumes.
    let body_s =
        arena.alloc_slice_fill_iter(w.solid_perm.iter().map(|&i| p.solid_group[solids.body[i as usize] as usize]));
    let v0_s = arena.alloc_slice_fill_iter(w.solid_perm.iter().map(|&i| solids.ppe_volume[i as usize]));
    let sigma_s = zeros(arena, ns);
    let vol_s = zeros(arena, ns);
    tm.time(pass::DENSITIES, || {
        let fs = fs_pairs.map(|pairs| SolidPairs { pairs, values: v0_s });
        iisph::fluid_volumes(&w.ff, &w.fb, fs, v0, &walls.rest_volume, sigma, vol);
        if ns > 0 {
            let sigma_ss = zeros(arena, ns);
            iisph::kernel_sums_within(&w.ss, v0_s, body_s, sigma_ss);
            iisph::wall_volumes(&w.sf, &w.solid_rows, sigma_ss, v0_s, v0, sigma_s, vol_s);
        }
        iisph::wall_volumes(&w.bf, &w.active, &walls.sigma_static, &walls.rest_volume, v0, sigma_b, vol_b);
        // Output density of every wall: its fluid-free value, then the
        // active walls' (no dependence on the last step's active set, which
        // a resumed run does not have).
        let rho_ref = p.wall_reference_density();
        walls.density.par_iter_mut().zip(walls.sigma_static.par_iter()).for_each(|(d, s)| *d = rho_ref * s);
        for (k, &b) in w.active.iter().enumerate() {
            vol_b_full[b as usize] = vol_b[k];
            walls.density[b as usize] = rho_ref * sigma_b[k];
        }
        fluid.density.par_iter_mut().zip(vm.par_iter_mut()).enumerate().for_each(|(i, (d, vm))| {
            *d = if vol[i] > 0.0 { mass[i] / vol[i] } else { rest_density[i] };
            *vm = if mass[i] > 0.0 { vol[i] / mass[i] } else { 0.0 };
        });
    });

    // Pass 3: viscosity (P-Eq. 23) and u* = u + dt (g + a^visc); with
    // several phases, with the phase pair weights, keeping a^visc for the
    // drift velocities.
    let mixture = p.mixture() && n > 0;
    let np = fluid.alpha.len();
    let nm = if mixture { n } else { 0 };
    let usx = zeros(arena, n);
    let usy = zeros(arena, n);
    let usz = zeros(arena, n);
    let avx = zeros(arena, nm);
    let avy = zeros(arena, nm);
    let avz = zeros(arena, nm);
    tm.time(pass::VISCOSITY, || {
        let inp = ViscosityInput {
            ff: &w.ff,
            x: Points { x: &fluid.x, y: &fluid.y, z: &fluid.z },
            u: Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz },
            rest_density,
            mu,
            h: p.h,
            gravity: p.gravity,
            dt,
        };
        if mixture {
            let alpha = arena.alloc_slice_fill_iter(fluid.alpha.iter().map(|a| a.as_slice()));
            let u_star = VelMut { x: &mut *usx, y: &mut *usy, z: &mut *usz };
            let a_visc = VelMut { x: &mut *avx, y: &mut *avy, z: &mut *avz };
            predict_velocity_mixture(&inp, alpha, u_star, a_visc);
        } else {
            predict_velocity(&inp, usx, usy, usz);
        }
    });
    let a_visc = Vel { x: avx, y: avy, z: avz };

    // Porous coupling, part 2 (passes 6-7, 9): before the pressure solve
    // scales the fluid-solid pair gradients by pair volumes. With several
    // phases, also the fluid pairs of the inner transport (h^3 grad W).
    let terms = porous.then(|| {
        tm.time(pass::POROUS, || {
            if mixture {
                w.ffb.clone_from(&w.ff);
                let cell = p.cell_volume();
                w.ffb.used_mut().par_iter_mut().for_each(|blk| {
                    for g in [&mut blk.gx, &mut blk.gy, &mut blk.gz] {
                        g.iter_mut().for_each(|x| *x *= cell);
                    }
                });
            }
            super::porous::pore_state(p, fluid, solids, w, arena, n_f, porous_mask)
        })
    });
    if let Some(t) = &terms {
        st.max_darcy_speed = t.max_darcy_speed;
    }
    let u_star = Vel { x: usx, y: usy, z: usz };

    // Pass 4c: pair volumes, sources (P-Eqs. 26, 29) and diagonals.
    let src = zeros(arena, n);
    let diag = zeros(arena, n);
    let src_b = zeros(arena, na);
    let diag_b = zeros(arena, na);
    let p_b = zeros(arena, na);
    // Solid rows: u*_s = v + dt g for free particles (their elastic and
    // pressure forces come after the solve), the prescribed v for fixed ones.
    let (usx, usy, usz) = (zeros(arena, ns), zeros(arena, ns), zeros(arena, ns));
    for (k, &i) in w.solid_perm.iter().enumerate() {
        let i = i as usize;
        let free = if solids.fixed[i] != 0 { 0.0 } else { dt };
        usx[k] = solids.vx[i] + free * p.gravity[0];
        usy[k] = solids.vy[i] + free * p.gravity[1];
        usz[k] = solids.vz[i] + free * p.gravity[2];
    }
    let u_solid = Vel { x: usx, y: usy, z: usz };
    // Within the pressure solve every solid body moves rigidly: a^p_s =
    // sum_body F_s / M (strong coupling of the rigid motion, which carries
    // the fluid's added mass; a body lighter than the fluid is unstable with
    // per-particle masses, whose surface layer alone would face the fluid).
    // A body with fixed particles does not move within the solve. The
    // elastic solve then takes the per-particle forces F_s.
    let nbodies = p.bodies();
    let body_inv_mass = arena.alloc_slice_fill_copy(nbodies, 0.0f32);
    {
        let mass = arena.alloc_slice_fill_copy(nbodies, 0.0f64);
        let anchored = arena.alloc_slice_fill_copy(nbodies, false);
        for i in 0..ns {
            let b = p.solid_group[solids.body[i] as usize] as usize;
            mass[b] += f64::from(solids.mass[i]);
            anchored[b] |= solids.fixed[i] != 0;
        }
        for b in 0..nbodies {
            body_inv_mass[b] = if anchored[b] || mass[b] <= 0.0 { 0.0 } else { (1.0 / mass[b]) as f32 };
        }
    }
    let inv_mass_s = arena.alloc_slice_fill_iter(body_s.iter().map(|&b| body_inv_mass[b as usize]));
    let body_force = arena.alloc_slice_fill_copy(3 * nbodies, 0.0f64);
    let (asx, asy, asz) = (zeros(arena, ns), zeros(arena, ns), zeros(arena, ns));
    let src_s = zeros(arena, ns);
    let diag_s = zeros(arena, ns);
    let p_s = arena.alloc_slice_fill_iter(w.solid_perm.iter().map(|&i| 0.5 * solids.pressure[i as usize]));
    tm.time(pass::PPE_SETUP, || {
        let rows = FluidRows {
            u_star,
            vol,
            vm,
            alpha_f,
            sigma,
            vol_wall: vol_b_full,
            vol_solid: vol_s,
            u_solid,
            inv_mass_solid: inv_mass_s,
        };
        let fs = if ns > 0 { Some(&mut w.fs) } else { None };
        iisph::fluid_setup(&mut w.ff, &mut w.fb, fs, rows, dt, src, diag);
        let rows = WallRows {
            vol: vol_b,
            sigma: sigma_b,
            u_star,
            vm_fluid: vm,
            vol_fluid: vol,
            u_own: None,
            inv_mass_own: None,
        };
        iisph::wall_setup(&mut w.bf, rows, dt, src_b, diag_b);
        if ns > 0 {
            let rows = WallRows {
                vol: vol_s,
                sigma: sigma_s,
                u_star,
                vm_fluid: vm,
                vol_fluid: vol,
                u_own: Some(u_solid),
                inv_mass_own: Some(inv_mass_s),
            };
            iisph::wall_setup(&mut w.sf, rows, dt, src_s, diag_s);
        }
        // Warm start from half the last pressure (PHYSICS.md §2.2).
        fluid.pressure.par_iter_mut().for_each(|x| *x *= 0.5);
        for (k, &b) in w.active.iter().enumerate() {
            p_b[k] = 0.5 * walls.pressure[b as usize];
        }
        walls.pressure.iter_mut().for_each(|x| *x = 0.0);
        for (k, &b) in w.active.iter().enumerate() {
            walls.pressure[b as usize] = p_b[k];
        }
    });

    // Pass 5: relaxed Jacobi (P-Eqs. 27-28) until the mean predicted
    // density error is at most eta.
    let apx = zeros(arena, n);
    let apy = zeros(arena, n);
    let apz = zeros(arena, n);
    let err = zeros(arena, n);
    let parts = arena.alloc_slice_fill_copy(nblocks(n), 0.0f64);
    let rows_active = sum_f64(n, parts, |i| (diag[i] != 0.0) as u32 as f64).max(1.0);
    let fs_pairs = (ns > 0).then_some(&w.fs);
    let mut gpu_ms = 0.0;
    tm.time(pass::PRESSURE_SOLVE, || {
        // The GPU solve has fluid and wall rows only: with solids the solve
        // stays on the CPU.
        if let Some(gpu) = w.gpu.as_deref_mut().filter(|g| g.passes.pressure_solve && ns == 0) {
            // The same loop on the GPU (shaders/iisph.wgsl), data resident.
            let settings = SolveSettings {
                dt,
                omega: p.omega,
                min_iterations: p.min_iterations,
                max_iterations: p.max_iterations,
                max_density_error: p.max_density_error,
                rows_active: rows_active as f32,
            };
            let inp = SolveInput {
                support,
                fluid_grid: &w.fluid_grid,
                wall_grid: &w.wall_grid,
                fluid: Points { x: &fluid.x, y: &fluid.y, z: &fluid.z },
                walls: Points { x: &walls.x, y: &walls.y, z: &walls.z },
                vol,
                vm,
                rows: Rows { source: src, diag },
                vol_wall: vol_b_full,
                active: &w.active,
                wall_rows: Rows { source: src_b, diag: diag_b },
                settings,
            };
            let ap = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
            let out = SolveOutput { p: &mut fluid.pressure, p_wall: &mut walls.pressure, ap };
            match gpu.pressure_solve(&inp, out) {
                Ok(r) => {
                    st.iterations = r.iterations;
                    st.density_error = r.density_error;
                    gpu_ms = r.gpu_ms.unwrap_or(0.0);
                    return;
                }
                // Reported after the step, which completes on the CPU.
                Err(e) => w.gpu_error = Some(format!("GPU pressure solve failed: {e}")),
            }
        }
        // The warm start, kept for a restart with a smaller omega
        // (iisph::Divergence).
        let start = [arena.alloc_slice_copy(&fluid.pressure), arena.alloc_slice_copy(p_b), arena.alloc_slice_copy(p_s)];
        let mut omega = p.omega;
        let mut guard = iisph::Divergence::default();
        let mut it = 0;
        loop {
            let out = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
            let fs = fs_pairs.map(|pairs| SolidPairs { pairs, values: &*p_s });
            iisph::pressure_acceleration(&w.ff, &w.fb, fs, vm, &fluid.pressure, &walls.pressure, out);
            if ns > 0 {
                let out = VelMut { x: &mut *asx, y: &mut *asy, z: &mut *asz };
                let bodies = BodyMotion { body: body_s, inv_mass: body_inv_mass, sums: &mut *body_force };
                rigid_pressure_acceleration(&w.sf, p_s, &fluid.pressure, vol, bodies, out);
            }
            let ap = Vel { x: apx, y: apy, z: apz };
            let a_s = Vel { x: asx, y: asy, z: asz };
            let jac = Jacobi { dt, omega };
            let rows = Rows { source: src, diag };
            let fs = fs_pairs.map(|pairs| (pairs, a_s));
            iisph::fluid_jacobi(&w.ff, &w.fb, fs, ap, rows, jac, &mut fluid.pressure, err);
            iisph::wall_jacobi(&w.bf, ap, None, Rows { source: src_b, diag: diag_b }, jac, p_b);
            if ns > 0 {
                iisph::wall_jacobi(&w.sf, ap, Some(a_s), Rows { source: src_s, diag: diag_s }, jac, p_s);
            }
            it += 1;
            let e = (sum_f64(n, parts, |i| err[i] as f64) / rows_active) as f32;
            st.density_error = e;
            let restart = guard.diverging(e) && e > p.max_density_error && st.solve_restarts < iisph::MAX_BACKOFFS;
            if restart {
                fluid.pressure.copy_from_slice(start[0]);
                p_b.copy_from_slice(start[1]);
                p_s.copy_from_slice(start[2]);
                omega *= iisph::RELAXATION_BACKOFF;
                guard = iisph::Divergence::default();
                st.solve_restarts += 1;
            }
            for (k, &b) in w.active.iter().enumerate() {
                walls.pressure[b as usize] = p_b[k];
            }
            if (!restart && it >= p.min_iterations && e <= p.max_density_error) || it >= p.max_iterations {
                break;
            }
        }
        st.iterations = it;
        let out = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
        let fs = fs_pairs.map(|pairs| SolidPairs { pairs, values: &*p_s });
        iisph::pressure_acceleration(&w.ff, &w.fb, fs, vm, &fluid.pressure, &walls.pressure, out);
    });
    tm.gpu_ms[pass::PRESSURE_SOLVE] = gpu_ms;

    // Pass 8: the solids, with the fluid's pressure force (the reaction of
    // the solid terms of a^p) and gravity as external acceleration.
    if ns > 0 {
        tm.time(pass::ELASTICITY, || {
            let (fx, fy, fz) = (zeros(arena, ns), zeros(arena, ns), zeros(arena, ns));
            iisph::solid_pressure_force(&w.sf, p_s, &fluid.pressure, vol, VelMut { x: fx, y: fy, z: fz });
            let g = Vec3::from(p.gravity);
            let a_ext = arena.alloc_slice_fill_copy(ns, g);
            for (k, &i) in w.solid_perm.iter().enumerate() {
                let i = i as usize;
                solids.pressure[i] = p_s[k];
                a_ext[i] = g + Vec3::new(fx[k], fy[k], fz[k]) / solids.mass[i];
            }
            let pore = terms.as_ref().and_then(|t| t.pore_stress);
            let cg = solid_model.advance(solids, a_ext, pore, dt);
            st.cg_iterations = cg.iterations;
            st.cg_residual = cg.residual;
            wall_contact(p, solids, walls, w);
        });
    }

    // Porous coupling, part 3: a^cap and a^pore (P-Eqs. 10, 14), added to
    // a^p, so the drift's a = -(a^visc + a^p + a^pore + a^cap).
    if let Some(t) = &terms {
        tm.time(pass::POROUS, || {
            super::porous::accelerations(p, fluid, t, rest_density, u_star, dt, [&mut *apx, &mut *apy, &mut *apz]);
        });
    }

    // Passes 10-12: drift velocities, drift momentum, volume-fraction
    // transport (several phases only; the pair lists now hold
    // Vbar_ij grad W_ij). apx.. then hold a^p (+ a^pore + a^cap) + a^Dm.
    let nt = if mixture || porous { n } else { 0 };
    let alpha_next = zeros(arena, np * nt);
    let beta_next = zeros(arena, if porous { np * n } else { 0 });
    if mixture {
        let inner = terms.as_ref().map(|t| PorousDrift {
            grad_pore: t.grad_pore,
            q: t.q,
            ffb: &w.ffb,
            pore_drift: p.pore_drift,
            inner_tau: p.inner_drift_tau,
            inner_sigma: p.inner_drift_sigma,
            beta_next: &mut *beta_next,
        });
        let ms = mixture_passes(
            p,
            fluid,
            &w.ff,
            arena,
            dt,
            a_visc,
            [&mut *apx, &mut *apy, &mut *apz],
            alpha_f,
            rest_density,
            alpha_next,
            Buffers { pair_limit: &mut w.pair_limit, pair_flux: &mut w.pair_flux },
            inner,
            w.gpu.as_deref_mut().filter(|g| g.passes.drift).map(|backend| GpuDrift {
                backend,
                grid: &w.fluid_grid,
                vol,
                support,
                error: &mut w.gpu_error,
            }),
            tm,
        );
        st.max_drift_speed = ms;
    } else if porous {
        // One phase: nothing drifts; the fractions change only by absorption.
        alpha_next.copy_from_slice(&fluid.alpha[0]);
        beta_next.copy_from_slice(&fluid.beta[0]);
    }
    // The absorption exchange of pass 12 (P-Eqs. 6-7, 22), within each
    // particle, after the transport.
    if let Some(t) = &terms {
        tm.time(pass::PHASE_TRANSPORT, || {
            for (k, (a, b)) in alpha_next.chunks_mut(n).zip(beta_next.chunks_mut(n)).enumerate() {
                porosph_kernels::porous::exchange(&t.gamma[k * n..(k + 1) * n], dt, a, b);
            }
        });
    }

    // Absorbed liquid does not pass through walls (porous::wall_guard).
    if porous {
        tm.time(pass::POROUS, || {
            super::porous::wall_guard(p, fluid, walls, &w.fb, u_star, dt, [&mut *apx, &mut *apy, &mut *apz]);
        });
    }

    // Pass 13: symplectic Euler.
    tm.time(pass::INTEGRATE, || {
        let s = State {
            x: &mut fluid.x,
            y: &mut fluid.y,
            z: &mut fluid.z,
            ux: &mut fluid.ux,
            uy: &mut fluid.uy,
            uz: &mut fluid.uz,
        };
        integrate(s, u_star, Vel { x: apx, y: apy, z: apz }, dt);
        // Solids: x += dt v^{n+1} (symplectic Euler, PHYSICS.md §3.3).
        let sv = solids.vx.iter().zip(&solids.vy).zip(&solids.vz);
        let sx = solids.x.iter_mut().zip(solids.y.iter_mut()).zip(solids.z.iter_mut());
        for (((x, y), z), ((vx, vy), vz)) in sx.zip(sv) {
            *x += dt * vx;
            *y += dt * vy;
            *z += dt * vz;
        }
    });

    // Pass 14: correction of the volume fractions (several phases only),
    // with porous solids of alpha and beta together (P Alg. 4): negative
    // fractions to 0, then alpha and beta scaled by one common factor so
    // that sum_k (alpha_k + beta_k) = 1, keeping the alpha/beta split.
    if porous {
        tm.time(pass::PHASE_CORRECTION, || {
            let next = arena.alloc_slice_fill_iter((0..2 * np).map(|k| {
                if k < np {
                    &alpha_next[k * n..(k + 1) * n]
                } else {
                    &beta_next[(k - np) * n..(k - np + 1) * n]
                }
            }));
            let total = zeros(arena, n);
            let largest = arena.alloc_slice_fill_copy(n, 0u32);
            phase_transport::correction_sums(next, total, largest);
            for (k, a) in fluid.alpha.iter_mut().chain(fluid.beta.iter_mut()).enumerate() {
                phase_transport::correct(next[k], total, largest, k, a);
            }
        });
    } else if mixture {
        tm.time(pass::PHASE_CORRECTION, || {
            let next = arena.alloc_slice_fill_iter(alpha_next.chunks(n));
            let total = zeros(arena, n);
            let largest = arena.alloc_slice_fill_copy(n, 0u32);
            phase_transport::correction_sums(next, total, largest);
            for (k, a) in fluid.alpha.iter_mut().enumerate() {
                phase_transport::correct(next[k], total, largest, k, a);
            }
        });
    }
    st
}

/// Pass 10 on the GPU (`--gpu-passes drift`): the backend, the fluid grid
/// of the sort, the current volumes the pair lists were scaled by, the
/// support, and where a failure is reported (the pass then runs on the CPU).
struct GpuDrift<'a> {
    backend: &'a mut GpuBackend,
    grid: &'a CellGrid,
    vol: &'a [f32],
    support: f32,
    error: &'a mut Option<String>,
}

/// Passes 10-12 (PHYSICS.md §6) of a step with two or more phases: drift
/// velocities (P-Eq. 11; with porous solids its porous term and the inner
/// drift of P-Eq. 12, which transports beta), the drift momentum term
/// (added to `ap`, which holds a^p on entry), and the transport of the
/// fractions into `alpha_next` (phase k at `[k n, (k + 1) n)`). Returns
/// the largest drift speed, m/s.
#[allow(clippy::too_many_arguments)]
fn mixture_passes(
    p: &Params,
    fluid: &FluidStore,
    ff: &porosph_kernels::neighbors::PairLists,
    arena: &Bump,
    dt: f32,
    a_visc: Vel,
    ap: [&mut [f32]; 3],
    alpha_f: &[f32],
    rest_density: &[f32],
    alpha_next: &mut [f32],
    buffers: Buffers,
    porous: Option<PorousDrift>,
    gpu: Option<GpuDrift>,
    tm: &mut super::PassTimes,
) -> f32 {
    let n = fluid.len();
    let np = fluid.alpha.len();
    let [apx, apy, apz] = ap;
    let alpha: &[&[f32]] = arena.alloc_slice_fill_iter(fluid.alpha.iter().map(|a| a.as_slice()));
    // Pass 10: v_k and w_k per phase, then s and m, then u_mk (over v_k)
    // and the phase fluxes F_k (over w_k).
    let ux = zeros(arena, np * n);
    let uy = zeros(arena, np * n);
    let uz = zeros(arena, np * n);
    let fx = zeros(arena, np * n);
    let fy = zeros(arena, np * n);
    let fz = zeros(arena, np * n);
    // P-Eq. 12's inner fractions, drift velocities and fluxes (porous only).
    let (ni, beta, beta_f): (usize, &[&[f32]], &[f32]) = if porous.is_some() {
        let beta = arena.alloc_slice_fill_iter(fluid.beta.iter().map(|b| b.as_slice()));
        (np * n, beta, arena.alloc_slice_fill_iter((0..n).map(|i| beta.iter().map(|b| b[i]).sum::<f32>())))
    } else {
        (0, &[], &[])
    };
    let [bx, by, bz] = [zeros(arena, ni), zeros(arena, ni), zeros(arena, ni)];
    let [gx, gy, gz] = [zeros(arena, ni), zeros(arena, ni), zeros(arena, ni)];
    let mut inner_done = false;
    let mut gpu_ms = 0.0;
    let max_drift = tm.time(pass::DRIFT, || {
        let pf = zeros(arena, if p.fraction_pressure { n } else { 0 });
        if p.fraction_pressure {
            drift::pressure_per_fraction(&fluid.pressure, alpha_f, pf);
        }
        let p_per_fraction = if p.fraction_pressure { Some(&*pf) } else { None };
        if let Some(g) = gpu {
            // The same three gathers on the GPU (shaders/drift.wgsl), with
            // porous solids twice: outer and inner (P-Eqs. 11-12).
            let phases = arena.alloc_slice_fill_iter((0..np).map(|k| PhaseConstants {
                density: p.phase_density[k],
                tau: p.phase_drift_tau[k],
                sigma: p.phase_drift_sigma[k],
            }));
            let inp = DriftInput {
                support: g.support,
                fluid_grid: g.grid,
                fluid: Points { x: &fluid.x, y: &fluid.y, z: &fluid.z },
                vol: g.vol,
                alpha,
                alpha_f,
                p_per_fraction,
                a_visc,
                a_p: Vel { x: apx, y: apy, z: apz },
                phases,
                conservative: p.conservative_transport,
                porous: porous.as_ref().map(|pd| PorousDriftInput {
                    grad_pore: pd.grad_pore,
                    pore_drift: pd.pore_drift,
                    beta,
                    beta_f,
                    q: pd.q,
                    inner_tau: pd.inner_tau,
                    inner_sigma: pd.inner_sigma,
                    cell_volume: p.cell_volume(),
                }),
            };
            let out =
                DriftOutput { ux: &mut *ux, uy: &mut *uy, uz: &mut *uz, fx: &mut *fx, fy: &mut *fy, fz: &mut *fz };
            let inner = porous.is_some().then_some(DriftOutput {
                ux: &mut *bx,
                uy: &mut *by,
                uz: &mut *bz,
                fx: &mut *gx,
                fy: &mut *gy,
                fz: &mut *gz,
            });
            match g.backend.drift(&inp, out, inner) {
                Ok(ms) => {
                    gpu_ms = ms.unwrap_or(0.0);
                    inner_done = porous.is_some();
                    let outer = drift::max_drift_speed(phase_vel(arena, ux, uy, uz, n), n);
                    return outer.max(if inner_done {
                        drift::max_drift_speed(phase_vel(arena, bx, by, bz, n), n)
                    } else {
                        0.0
                    });
                }
                // Reported after the step; the pass runs on the CPU.
                Err(e) => *g.error = Some(format!("GPU drift pass failed: {e}")),
            }
        }
        let inp = PhaseVelocityInput { ff, alpha_f, p_per_fraction, a_visc, a_p: Vel { x: apx, y: apy, z: apz } };
        let v = ux.chunks_mut(n).zip(uy.chunks_mut(n)).zip(uz.chunks_mut(n));
        let w = fx.chunks_mut(n).zip(fy.chunks_mut(n)).zip(fz.chunks_mut(n));
        for (k, (((x, y), z), ((wx, wy), wz))) in v.zip(w).enumerate() {
            let phase = PhaseConstants {
                density: p.phase_density[k],
                tau: p.phase_drift_tau[k],
                sigma: p.phase_drift_sigma[k],
            };
            let (mut v, mut w) = (VelMut { x, y, z }, VelMut { x: wx, y: wy, z: wz });
            drift::phase_velocity(&inp, alpha[k], phase, v.reborrow(), w.reborrow());
            // P-Eq. 11's porous term, -phi (grad p^pore_fk - sum c grad p^pore_fk').
            if let Some(pd) = &porous {
                let r = k * n..(k + 1) * n;
                let [gx, gy, gz] = pd.grad_pore;
                let e = Vel { x: &gx[r.clone()], y: &gy[r.clone()], z: &gz[r] };
                porosph_kernels::porous::add_phase_term(alpha[k], alpha_f, e, -pd.pore_drift, v, w);
            }
        }
        let ctx = MixtureSums { arena, n, density: &p.phase_density, conservative: p.conservative_transport };
        ctx.drift_velocities(alpha, alpha_f, [&mut *ux, &mut *uy, &mut *uz], [&mut *fx, &mut *fy, &mut *fz]);
        drift::max_drift_speed(phase_vel(arena, ux, uy, uz, n), n)
    });
    tm.gpu_ms[pass::DRIFT] = gpu_ms;
    let u_drift = phase_vel(arena, ux, uy, uz, n);

    // P-Eq. 12: the inner drift velocities and fluxes, over the pairs with
    // h^3 grad W (inner particles have no pressure-solve volume).
    let mut max_drift = max_drift;
    let mut beta_next = None;
    if let Some(pd) = porous {
        let PorousDrift { q, ffb, inner_tau, inner_sigma, beta_next: out, .. } = pd;
        if !inner_done {
            let speed = tm.time(pass::DRIFT, || {
                let inp = PhaseVelocityInput {
                    ff: ffb,
                    alpha_f: beta_f,
                    p_per_fraction: None,
                    a_visc,
                    a_p: Vel { x: apx, y: apy, z: apz },
                };
                for (k, &beta_k) in beta.iter().enumerate() {
                    let r = k * n..(k + 1) * n;
                    let phase =
                        PhaseConstants { density: p.phase_density[k], tau: p.phase_drift_tau[k], sigma: inner_sigma };
                    let v = VelMut { x: &mut bx[r.clone()], y: &mut by[r.clone()], z: &mut bz[r.clone()] };
                    let w = VelMut { x: &mut gx[r.clone()], y: &mut gy[r.clone()], z: &mut gz[r.clone()] };
                    drift::phase_velocity(&inp, beta_k, phase, v, w);
                    let v = VelMut { x: &mut bx[r.clone()], y: &mut by[r.clone()], z: &mut bz[r.clone()] };
                    let w = VelMut { x: &mut gx[r.clone()], y: &mut gy[r.clone()], z: &mut gz[r.clone()] };
                    let e = Vel { x: &q[0][r.clone()], y: &q[1][r.clone()], z: &q[2][r] };
                    porosph_kernels::porous::add_phase_term(beta_k, beta_f, e, -inner_tau, v, w);
                }
                let ctx = MixtureSums { arena, n, density: &p.phase_density, conservative: p.conservative_transport };
                ctx.drift_velocities(beta, beta_f, [&mut *bx, &mut *by, &mut *bz], [&mut *gx, &mut *gy, &mut *gz]);
                drift::max_drift_speed(phase_vel(arena, bx, by, bz, n), n)
            });
            max_drift = max_drift.max(speed);
        }
        beta_next = Some((ffb, beta, [&*gx, &*gy, &*gz], out));
    }

    // Pass 11: a^Dm (PHYSICS.md §4.1, sign per §8.15), added to a^p.
    if p.drift_momentum_sign != 0.0 {
        tm.time(pass::DRIFT_MOMENTUM, || {
            let (dx, dy, dz) = (zeros(arena, n), zeros(arena, n), zeros(arena, n));
            let inp = DriftMomentumInput {
                ff,
                alpha,
                u_drift,
                density: &p.phase_density,
                rest_density,
                sign: p.drift_momentum_sign,
            };
            drift_momentum(&inp, VelMut { x: &mut *dx, y: &mut *dy, z: &mut *dz });
            for (a, d) in [(&mut *apx, &*dx), (&mut *apy, &*dy), (&mut *apz, &*dz)] {
                a.par_iter_mut().zip(d.par_iter()).for_each(|(a, d)| *a += d);
            }
        });
    }

    // Pass 12: transport of every phase at the old positions (P-Eq. 2),
    // outer fractions over the pressure solve's pairs, inner ones (P-Eq. 7)
    // over the h^3 pairs.
    tm.time(pass::PHASE_TRANSPORT, || {
        let u = Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz };
        let Buffers { pair_limit, pair_flux } = buffers;
        let mut tr = Transport { p, arena, n, dt, u, pair_limit, pair_flux };
        tr.run(ff, alpha, phase_vel(arena, fx, fy, fz, n), alpha_next);
        if let Some((ffb, beta, [gx, gy, gz], out)) = beta_next {
            tr.run(ffb, beta, phase_vel(arena, gx, gy, gz, n), out);
        }
    });
    max_drift
}

/// Steps 2-3 of P-Eq. 11 (or 12) for all phases: the mass- and
/// volume-weighted mean phase velocities, then the drift velocities over
/// the phase velocities v and the transport fluxes over w.
struct MixtureSums<'a> {
    arena: &'a Bump,
    n: usize,
    density: &'a [f32],
    conservative: bool,
}

impl<'a> MixtureSums<'a> {
    fn drift_velocities(&self, frac: &[&[f32]], frac_f: &[f32], v: [&mut [f32]; 3], w: [&mut [f32]; 3]) {
        let (arena, n) = (self.arena, self.n);
        let [ux, uy, uz] = v;
        let [fx, fy, fz] = w;
        let (sx, sy, sz) = (zeros(arena, n), zeros(arena, n), zeros(arena, n));
        let (mx, my, mz) = (zeros(arena, n), zeros(arena, n), zeros(arena, n));
        {
            let w = phase_vel(arena, fx, fy, fz, n);
            let s = VelMut { x: &mut *sx, y: &mut *sy, z: &mut *sz };
            let m = VelMut { x: &mut *mx, y: &mut *my, z: &mut *mz };
            drift::mixture_velocity(frac, frac_f, self.density, w, s, m);
        }
        let (s, m) = (Vel { x: sx, y: sy, z: sz }, Vel { x: mx, y: my, z: mz });
        let m = if self.conservative { Some(m) } else { None };
        let u = ux.chunks_mut(n).zip(uy.chunks_mut(n)).zip(uz.chunks_mut(n));
        let f = fx.chunks_mut(n).zip(fy.chunks_mut(n)).zip(fz.chunks_mut(n));
        for (k, (((x, y), z), ((gx, gy), gz))) in u.zip(f).enumerate() {
            drift::drift_velocity(frac[k], s, m, VelMut { x, y, z }, VelMut { x: gx, y: gy, z: gz });
        }
    }
}

/// The volume-fraction transport of pass 12 for one set of fractions.
struct Transport<'a, 'b> {
    p: &'a Params,
    arena: &'a Bump,
    n: usize,
    dt: f32,
    u: Vel<'a>,
    pair_limit: &'b mut Vec<Vec<f32>>,
    pair_flux: &'b mut Vec<Vec<Vec<f32>>>,
}

impl Transport<'_, '_> {
    /// Moves the fractions `frac` (per phase) by the fluxes `flux` over the
    /// pairs `ff` into `next` (phase k at `[k n, (k + 1) n)`).
    fn run(&mut self, ff: &PairLists, frac: &[&[f32]], flux: PhaseVel, next: &mut [f32]) {
        let (arena, n, dt, np) = (self.arena, self.n, self.dt, frac.len());
        if self.p.conservative_transport {
            let nb = ff.used().len();
            let (pair_limit, pair_flux) = (&mut *self.pair_limit, &mut *self.pair_flux);
            pair_flux.resize_with(np, Vec::new);
            for f in pair_flux.iter_mut() {
                f.resize_with(nb.max(f.len()), Vec::new);
            }
            if pair_limit.len() < nb {
                pair_limit.resize_with(nb, Vec::new);
            }
            let limit = zeros(arena, np * n);
            for (k, (l, phi)) in limit.chunks_mut(n).zip(pair_flux.iter_mut()).enumerate() {
                phase_transport::outflow_limit(ff, frac[k], flux.phase(k), dt, l, &mut phi[..nb]);
            }
            let limit = arena.alloc_slice_fill_iter(limit.chunks(n));
            let phi = arena.alloc_slice_fill_iter(pair_flux.iter().map(|f| &f[..nb]));
            phase_transport::pair_limit(ff, phi, limit, &mut pair_limit[..nb]);
            for (k, out) in next.chunks_mut(n).enumerate() {
                phase_transport::transport(ff, frac[k], phi[k], &pair_limit[..nb], dt, out);
            }
        } else {
            for (k, out) in next.chunks_mut(n).enumerate() {
                phase_transport::transport_reference(ff, self.u, frac[k], flux.phase(k), dt, out);
            }
        }
    }
}

/// Pair buffers of the conservative transport, kept across steps.
struct Buffers<'a> {
    pair_limit: &'a mut Vec<Vec<f32>>,
    pair_flux: &'a mut Vec<Vec<Vec<f32>>>,
}

/// The porous inputs of the drift and transport passes (P-Eqs. 11-12).
struct PorousDrift<'a> {
    /// grad p^pore_fk per phase (flat), Pa/m.
    grad_pore: [&'a [f32]; 3],
    /// q_k,f per phase (flat), m/s.
    q: [&'a [f32]; 3],
    /// Fluid pairs with h^3 grad W.
    ffb: &'a PairLists,
    /// phi of P-Eq. 11, m^2/(Pa s).
    pore_drift: f32,
    /// tau' of P-Eq. 12.
    inner_tau: f32,
    /// sigma' of P-Eq. 12, m^2/s.
    inner_sigma: f32,
    /// Where the transported beta goes (flat per phase).
    beta_next: &'a mut [f32],
}

/// Per-phase views of three flat arrays holding phase k at `[k n, (k + 1) n)`.
fn phase_vel<'a>(arena: &'a Bump, x: &'a [f32], y: &'a [f32], z: &'a [f32], n: usize) -> PhaseVel<'a> {
    PhaseVel {
        x: arena.alloc_slice_fill_iter(x.chunks(n.max(1))),
        y: arena.alloc_slice_fill_iter(y.chunks(n.max(1))),
        z: arena.alloc_slice_fill_iter(z.chunks(n.max(1))),
    }
}

/// The bodies of the solid particles (sorted order) within the solve.
struct BodyMotion<'a> {
    /// Body of each solid particle.
    body: &'a [u32],
    /// 1/M of each body (0 if it has fixed particles).
    inv_mass: &'a [f32],
    /// Scratch: 3 per body.
    sums: &'a mut [f64],
}

/// The rigid pressure acceleration of the bodies within the solve:
/// a^p_s = (sum over the body of F_s) / M for every particle s of a body,
/// F_s from [`iisph::solid_pressure_force`] (summed in f64 in particle
/// order: deterministic).
fn rigid_pressure_acceleration(
    sf: &porosph_kernels::neighbors::PairLists,
    p_s: &[f32],
    p_f: &[f32],
    vol_f: &[f32],
    bodies: BodyMotion,
    out: VelMut,
) {
    let VelMut { x, y, z } = out;
    iisph::solid_pressure_force(sf, p_s, p_f, vol_f, VelMut { x: &mut *x, y: &mut *y, z: &mut *z });
    let BodyMotion { body, inv_mass, sums } = bodies;
    sums.iter_mut().for_each(|s| *s = 0.0);
    for (k, &b) in body.iter().enumerate() {
        let b = 3 * b as usize;
        sums[b] += f64::from(x[k]);
        sums[b + 1] += f64::from(y[k]);
        sums[b + 2] += f64::from(z[k]);
    }
    for (k, &b) in body.iter().enumerate() {
        let m = inv_mass[b as usize];
        let b = 3 * b as usize;
        x[k] = (sums[b] * f64::from(m)) as f32;
        y[k] = (sums[b + 1] * f64::from(m)) as f32;
        z[k] = (sums[b + 2] * f64::from(m)) as f32;
    }
}

/// Pass 0 for solids: Morton order of the solid positions (a sorted copy; the
/// store keeps its order), the solid grid, and the fluid-solid, solid-fluid
/// and solid-solid pairs (solids in the sorted order).
fn solid_neighbors(p: &Params, fluid: &FluidStore, solids: &SolidStore, walls: &WallStore, w: &mut Workspace) {
    let ns = solids.len();
    let support = p.kernel.support;
    w.solid_keys.resize(ns, 0);
    compute_keys(&solids.x, &solids.y, &solids.z, 1.0 / support, &mut w.solid_keys);
    sort_permutation(&w.solid_keys, &mut w.solid_sort, &mut w.solid_perm);
    w.solid_keys.clear();
    w.solid_keys.extend(w.solid_sort.iter().map(|&(k, _)| k));
    w.solid_grid.build(&w.solid_keys, support);
    for (dst, src) in w.solid_sorted.iter_mut().zip([&solids.x, &solids.y, &solids.z]) {
        dst.clear();
        dst.extend(w.solid_perm.iter().map(|&i| src[i as usize]));
    }
    if w.solid_rows.len() != ns {
        w.solid_rows.clear();
        w.solid_rows.extend(0..ns as u32);
    }
    let [sx, sy, sz] = &w.solid_sorted;
    let sp = Points { x: sx, y: sy, z: sz };
    let fp = Points { x: &fluid.x, y: &fluid.y, z: &fluid.z };
    build_pairs(&mut w.fs, fp, sp, &w.solid_grid, None, &p.kernel);
    build_pairs(&mut w.sf, sp, fp, &w.fluid_grid, None, &p.kernel);
    build_pairs(&mut w.ss, sp, sp, &w.solid_grid, None, &p.kernel);
    let wp = Points { x: &walls.x, y: &walls.y, z: &walls.z };
    build_pairs(&mut w.sb, sp, wp, &w.wall_grid, Some(&w.wall_near), &p.kernel);
}

/// Contact of solids with the static walls (walls do not take part in the
/// elastic solve): a solid particle closer than d to a wall particle may
/// not move further towards the wall. Its velocity loses the component
/// along the wall normal n that points into the wall, n the direction of
/// -sum_b grad W_sb over its wall neighbours (frictionless, inelastic
/// contact; a velocity projection after the elastic solve).
fn wall_contact(p: &Params, solids: &mut SolidStore, walls: &WallStore, w: &Workspace) {
    let d2 = p.h * p.h;
    for (b, blk) in w.sb.used().iter().enumerate() {
        for q in 0..blk.start.len().saturating_sub(1) {
            let k = b * porosph_kernels::blocks::BLOCK + q;
            let i = w.solid_perm[k] as usize;
            if solids.fixed[i] != 0 {
                continue;
            }
            let (xs, ys, zs) = (solids.x[i], solids.y[i], solids.z[i]);
            let mut touching = false;
            let mut n = Vec3::ZERO;
            for pr in blk.range(q) {
                if blk.w[pr] <= 0.0 {
                    continue;
                }
                let j = blk.j[pr] as usize;
                let r2 = (xs - walls.x[j]).powi(2) + (ys - walls.y[j]).powi(2) + (zs - walls.z[j]).powi(2);
                touching |= r2 < d2;
                n -= Vec3::new(blk.gx[pr], blk.gy[pr], blk.gz[pr]);
            }
            let len = n.length();
            if !touching || len <= 0.0 {
                continue;
            }
            let n = n / len;
            let v = Vec3::new(solids.vx[i], solids.vy[i], solids.vz[i]);
            let vn = v.dot(n);
            if vn < 0.0 {
                let v = v - vn * n;
                (solids.vx[i], solids.vy[i], solids.vz[i]) = (v.x, v.y, v.z);
            }
        }
    }
}
