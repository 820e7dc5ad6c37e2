//! The step: passes 0-5 and 10-14 of PHYSICS.md §6 for one or more fluid
//! phases sharing each particle (the mixture model of PHYSICS.md §4.1), and
//! static walls. With one phase the mixture passes (10-12 and the
//! correction of 14) are skipped, so the step is the single-fluid step.

use super::timing::pass;
use super::{Params, Simulation, StepStats, Workspace};
use crate::backend::gpu::{SolveInput, SolveOutput, SolveSettings};
use crate::store::{FluidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::blocks::{max_f32, nblocks, sum_f64, BLOCK};
use porosph_kernels::drift::{self, PhaseVelocityInput};
use porosph_kernels::drift_momentum::{drift_momentum, DriftMomentumInput};
use porosph_kernels::iisph::{self, FluidRows, Jacobi, Rows, Vel, VelMut, WallRows, MIN_ALPHA_F};
use porosph_kernels::integrate::{integrate, State};
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, Points};
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
        let Simulation { params, fluid, walls, work, arena, .. } = self;
        let mut stats = step_passes(params, fluid, walls, work, arena, dt);
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
        self.dt = self.next_dt(speed, stats.max_drift_speed);
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

    /// The time step rule of PHYSICS.md §7 without porous terms:
    /// dt = min(max_dt, lambda h / max|u|, 0.125 h^2 rho_k / mu_k), and with
    /// two or more phases also lambda h / max_k|u_mk| (`max_drift`, the
    /// drift speed of the last step; PHYSICS.md writes 0.4 = lambda's
    /// default) and 0.1 h^2 / max_k sigma_k.
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
    });
    tm.gpu_ms[pass::NEIGHBORS] = gpu_ms;

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
    let u_star = Vel { x: usx, y: usy, z: usz };
    let a_visc = Vel { x: avx, y: avy, z: avz };

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
    let mut gpu_ms = 0.0;
    tm.time(pass::PRESSURE_SOLVE, || {
        if let Some(gpu) = w.gpu.as_deref_mut().filter(|g| g.passes.pressure_solve) {
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
    tm.gpu_ms[pass::PRESSURE_SOLVE] = gpu_ms;

    // Passes 10-12: drift velocities, drift momentum, volume-fraction
    // transport (several phases only; the pair lists now hold
    // Vbar_ij grad W_ij). apx.. then hold a^p + a^Dm.
    let alpha_next = zeros(arena, np * nm);
    if mixture {
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
            tm,
        );
        st.max_drift_speed = ms;
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
    });

    // Pass 14: correction of the volume fractions (several phases only).
    if mixture {
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

/// Passes 10-12 (PHYSICS.md §6) of a step with two or more phases: drift
/// velocities (P-Eq. 11 without its porous term), the drift momentum term
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
    let max_drift = tm.time(pass::DRIFT, || {
        let pf = zeros(arena, if p.fraction_pressure { n } else { 0 });
        if p.fraction_pressure {
            drift::pressure_per_fraction(&fluid.pressure, alpha_f, pf);
        }
        let p_per_fraction = if p.fraction_pressure { Some(&*pf) } else { None };
        let inp = PhaseVelocityInput { ff, alpha_f, p_per_fraction, a_visc, a_p: Vel { x: apx, y: apy, z: apz } };
        let v = ux.chunks_mut(n).zip(uy.chunks_mut(n)).zip(uz.chunks_mut(n));
        let w = fx.chunks_mut(n).zip(fy.chunks_mut(n)).zip(fz.chunks_mut(n));
        for (k, (((x, y), z), ((wx, wy), wz))) in v.zip(w).enumerate() {
            let phase = PhaseConstants {
                density: p.phase_density[k],
                tau: p.phase_drift_tau[k],
                sigma: p.phase_drift_sigma[k],
            };
            drift::phase_velocity(&inp, alpha[k], phase, VelMut { x, y, z }, VelMut { x: wx, y: wy, z: wz });
        }
        let (sx, sy, sz) = (zeros(arena, n), zeros(arena, n), zeros(arena, n));
        let (mx, my, mz) = (zeros(arena, n), zeros(arena, n), zeros(arena, n));
        {
            let w = phase_vel(arena, fx, fy, fz, n);
            let s = VelMut { x: &mut *sx, y: &mut *sy, z: &mut *sz };
            let m = VelMut { x: &mut *mx, y: &mut *my, z: &mut *mz };
            drift::mixture_velocity(alpha, alpha_f, &p.phase_density, w, s, m);
        }
        let (s, m) = (Vel { x: sx, y: sy, z: sz }, Vel { x: mx, y: my, z: mz });
        let m = if p.conservative_transport { Some(m) } else { None };
        let u = ux.chunks_mut(n).zip(uy.chunks_mut(n)).zip(uz.chunks_mut(n));
        let f = fx.chunks_mut(n).zip(fy.chunks_mut(n)).zip(fz.chunks_mut(n));
        for (k, (((x, y), z), ((gx, gy), gz))) in u.zip(f).enumerate() {
            drift::drift_velocity(alpha[k], s, m, VelMut { x, y, z }, VelMut { x: gx, y: gy, z: gz });
        }
        drift::max_drift_speed(phase_vel(arena, ux, uy, uz, n), n)
    });
    let u_drift = phase_vel(arena, ux, uy, uz, n);

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

    // Pass 12: transport of every phase at the old positions (P-Eq. 2).
    tm.time(pass::PHASE_TRANSPORT, || {
        let u = Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz };
        let flux = phase_vel(arena, fx, fy, fz, n);
        if p.conservative_transport {
            let nb = ff.used().len();
            let Buffers { pair_limit, pair_flux } = buffers;
            pair_flux.resize_with(np, Vec::new);
            for f in pair_flux.iter_mut() {
                f.resize_with(nb.max(f.len()), Vec::new);
            }
            if pair_limit.len() < nb {
                pair_limit.resize_with(nb, Vec::new);
            }
            let limit = zeros(arena, np * n);
            for (k, (l, phi)) in limit.chunks_mut(n).zip(pair_flux.iter_mut()).enumerate() {
                phase_transport::outflow_limit(ff, alpha[k], flux.phase(k), dt, l, &mut phi[..nb]);
            }
            let limit = arena.alloc_slice_fill_iter(limit.chunks(n));
            let phi = arena.alloc_slice_fill_iter(pair_flux.iter().map(|f| &f[..nb]));
            phase_transport::pair_limit(ff, phi, limit, &mut pair_limit[..nb]);
            for (k, out) in alpha_next.chunks_mut(n).enumerate() {
                phase_transport::transport(ff, alpha[k], phi[k], &pair_limit[..nb], dt, out);
            }
        } else {
            for (k, out) in alpha_next.chunks_mut(n).enumerate() {
                phase_transport::transport_reference(ff, u, alpha[k], flux.phase(k), dt, out);
            }
        }
    });
    max_drift
}

/// Pair buffers of the conservative transport, kept across steps.
struct Buffers<'a> {
    pair_limit: &'a mut Vec<Vec<f32>>,
    pair_flux: &'a mut Vec<Vec<Vec<f32>>>,
}

/// Per-phase views of three flat arrays holding phase k at `[k n, (k + 1) n)`.
fn phase_vel<'a>(arena: &'a Bump, x: &'a [f32], y: &'a [f32], z: &'a [f32], n: usize) -> PhaseVel<'a> {
    PhaseVel {
        x: arena.alloc_slice_fill_iter(x.chunks(n.max(1))),
        y: arena.alloc_slice_fill_iter(y.chunks(n.max(1))),
        z: arena.alloc_slice_fill_iter(z.chunks(n.max(1))),
    }
}
