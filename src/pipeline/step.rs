//! The step: passes 0-5, 13 and 14 of PHYSICS.md §6 for one or more fluid
//! phases sharing each particle, and static walls.

use super::timing::pass;
use super::{Params, Simulation, StepStats, Workspace};
use crate::store::{FluidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::blocks::{max_f32, nblocks, sum_f64, BLOCK};
use porosph_kernels::iisph::{self, FluidRows, Jacobi, Rows, Vel, VelMut, WallRows, MIN_ALPHA_F};
use porosph_kernels::integrate::{integrate, State};
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, Points};
use porosph_kernels::viscosity::{predict_velocity, ViscosityInput};
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
        let Simulation { params, fluid, walls, work, arena, .. } = self;
        let mut stats = step_passes(params, fluid, walls, work, arena, dt);
        arena.reset();
        self.time += dt as f64;
        self.step += 1;
        let t = std::time::Instant::now();
        let speed = self.max_speed();
        if !speed.is_finite() || speed > self.blowup_speed() {
            return Err(self.blowup(speed));
        }
        self.dt = self.next_dt(speed);
        stats.times.ms[pass::TIME_STEP] += t.elapsed().as_secs_f64() * 1e3;
        stats.max_speed = speed;
        stats.dt = dt;
        self.last = stats;
        Ok(&self.last)
    }

    /// Largest fluid speed, m/s (NaN if any velocity is NaN).
    pub fn max_speed(&self) -> f32 {
        let f = &self.fluid;
        max_f32(f.len(), |i| (f.ux[i] * f.ux[i] + f.uy[i] * f.uy[i] + f.uz[i] * f.uz[i]).sqrt())
    }

    /// The time step rule of PHYSICS.md §7 for one or more phases without
    /// drift: dt = min(max_dt, lambda h / max|u|, 0.125 h^2 rho / mu_max).
    pub fn next_dt(&self, max_speed: f32) -> f32 {
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
        dt
    }

    /// A speed at which the CFL step would fall below 1e-4 max_dt: the run
    /// has exploded.
    fn blowup_speed(&self) -> f32 {
        self.params.cfl * self.params.h / (1e-4 * self.params.max_dt)
    }

    fn blowup(&self, speed: f32) -> StepError {
        let f = &self.fluid;
        let limit = self.blowup_speed();
        let bad = (0..f.len())
            .find(|&i| {
                let s = (f.ux[i] * f.ux[i] + f.uy[i] * f.uy[i] + f.uz[i] * f.uz[i]).sqrt();
                !s.is_finite() || s > limit || !(f.x[i].is_finite() && f.y[i].is_finite() && f.z[i].is_finite())
            })
            .unwrap_or(0);
        StepError {
            step: self.step,
            time: self.time,
            particle: f.id.get(bad).copied().unwrap_or(0),
            position: [f.x[bad], f.y[bad], f.z[bad]],
            velocity: [f.ux[bad], f.uy[bad], f.uz[bad]],
            reason: if speed.is_finite() {
                format!("velocity exploded ({speed:.3e} m/s > {limit:.3e} m/s)")
            } else {
                "velocity is NaN or infinite".to_string()
            },
        }
    }
}

fn zeros(arena: &Bump, n: usize) -> &mut [f32] {
    arena.alloc_slice_fill_copy(n, 0.0f32)
}

/// Passes 0-13 of one step; scratch comes from `arena`.
fn step_passes(
    p: &Params,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    w: &mut Workspace,
    arena: &Bump,
    dt: f32,
) -> StepStats {
    let mut st = StepStats::default();
    let tm = &mut st.times;
    let n = fluid.len();
    let support = p.kernel.support;

    // Pass 0: Morton sort of the fluid, grid, neighbour pairs.
    tm.time(pass::NEIGHBORS, || {
        w.keys.resize(n, 0);
        compute_keys(&fluid.x, &fluid.y, &fluid.z, 1.0 / support, &mut w.keys);
        sort_permutation(&w.keys, &mut w.sort, &mut w.perm);
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
    });

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
                    rho[q] = r;
                    mu[q] = v;
                    af[q] = a;
                    m[q] = r * cell;
                    v0[q] = if a >= MIN_ALPHA_F { a * cell } else { 0.0 };
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
    tm.time(pass::DENSITIES, || {
        iisph::fluid_volumes(&w.ff, &w.fb, v0, &walls.rest_volume, sigma, vol);
        iisph::wall_volumes(&w.bf, &w.active, &walls.sigma_static, &walls.rest_volume, v0, sigma_b, vol_b);
        let rho_ref = p.phase_density.first().copied().unwrap_or(0.0);
        for (k, &b) in w.active.iter().enumerate() {
            vol_b_full[b as usize] = vol_b[k];
            walls.density[b as usize] = rho_ref * sigma_b[k];
        }
        fluid.density.par_iter_mut().zip(vm.par_iter_mut()).enumerate().for_each(|(i, (d, vm))| {
            *d = if vol[i] > 0.0 { mass[i] / vol[i] } else { rest_density[i] };
            *vm = if mass[i] > 0.0 { vol[i] / mass[i] } else { 0.0 };
        });
    });

    // Pass 3: viscosity (P-Eq. 23) and u* = u + dt (g + a^visc).
    let usx = zeros(arena, n);
    let usy = zeros(arena, n);
    let usz = zeros(arena, n);
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
        predict_velocity(&inp, usx, usy, usz);
    });
    let u_star = Vel { x: usx, y: usy, z: usz };

    // Pass 4c: pair volumes, sources (P-Eqs. 26, 29) and diagonals.
    let src = zeros(arena, n);
    let diag = zeros(arena, n);
    let src_b = zeros(arena, na);
    let diag_b = zeros(arena, na);
    let p_b = zeros(arena, na);
    tm.time(pass::PPE_SETUP, || {
        let rows = FluidRows { u_star, vol, vm, alpha_f, sigma, vol_wall: vol_b_full };
        iisph::fluid_setup(&mut w.ff, &mut w.fb, rows, dt, src, diag);
        let rows = WallRows { vol: vol_b, sigma: sigma_b, u_star, vm_fluid: vm, vol_fluid: vol };
        iisph::wall_setup(&mut w.bf, rows, dt, src_b, diag_b);
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
    tm.time(pass::PRESSURE_SOLVE, || {
        let mut it = 0;
        loop {
            let out = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
            iisph::pressure_acceleration(&w.ff, &w.fb, vm, &fluid.pressure, &walls.pressure, out);
            let ap = Vel { x: apx, y: apy, z: apz };
            let jac = Jacobi { dt, omega: p.omega };
            iisph::fluid_jacobi(&w.ff, &w.fb, ap, Rows { source: src, diag }, jac, &mut fluid.pressure, err);
            iisph::wall_jacobi(&w.bf, ap, Rows { source: src_b, diag: diag_b }, jac, p_b);
            for (k, &b) in w.active.iter().enumerate() {
                walls.pressure[b as usize] = p_b[k];
            }
            it += 1;
            let e = (sum_f64(n, parts, |i| err[i] as f64) / rows_active) as f32;
            st.density_error = e;
            if (it >= p.min_iterations && e <= p.max_density_error) || it >= p.max_iterations {
                break;
            }
        }
        st.iterations = it;
        let out = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
        iisph::pressure_acceleration(&w.ff, &w.fb, vm, &fluid.pressure, &walls.pressure, out);
    });

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
    });
    st
}
