//! Passes 4c and 5: the IISPH pressure solve with pressure boundaries
//! (PHYSICS.md §2.2-2.4; P §6.1). [`setup`] builds the rows: the pair
//! volumes V̄_ij in the pair lists, the sources of the fluid rows ([AC]'s
//! alpha_f (1 + dt div - V0/V), README "Porous solids") and of the wall and
//! solid rows (P-Eq. 26), and the diagonals; and warm-starts the
//! pressures. [`solve`] hands the system to the backend's Jacobi loop
//! (P-Eqs. 27-28) and returns the pressure accelerations.

use super::phases::PhaseState;
use super::prediction::Prediction;
use super::timing::{pass, PassTimes};
use super::volumes::Volumes;
use super::{Params, StepStats, Workspace};
use crate::backend::passes::{PressureSystem, SolidSystem, SolveSettings, Unknowns, WallInput};
use crate::store::{FluidStore, SolidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::blocks::{nblocks, sum_f64};
use porosph_kernels::iisph::{self, FluidRows, Rows, Vel, VelMut, WallRows};
use porosph_kernels::neighbors::Points;
use rayon::prelude::*;

/// The rows of the system and the warm-started boundary pressures.
pub(super) struct PressureRows<'a> {
    /// Fluid rows (S, a_ii).
    pub fluid: Rows<'a>,
    /// Active wall rows.
    pub walls: Rows<'a>,
    /// Solid rows (sorted solid order).
    pub solids: Rows<'a>,
    /// 1/M of each body within the solve (0 for a body with fixed particles).
    pub body_inv_mass: &'a [f32],
    /// Pressures of the active walls and of the solids, warm-started, Pa.
    pub p_active: &'a mut [f32],
    pub p_solid: &'a mut [f32],
}

/// Pass 4c. Scales the pair lists of `w` by the pair volumes.
#[allow(clippy::too_many_arguments)]
pub(super) fn setup<'a>(
    p: &Params,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    solids: &SolidStore,
    w: &mut Workspace,
    ph: &PhaseState,
    vols: &Volumes,
    pred: &Prediction,
    dt: f32,
    arena: &'a Bump,
    tm: &mut PassTimes,
) -> PressureRows<'a> {
    let (n, na, ns) = (fluid.len(), w.active.len(), solids.len());
    let zeros = |n: usize| arena.alloc_slice_fill_copy(n, 0.0f32);
    let (src, diag) = (zeros(n), zeros(n));
    let (src_b, diag_b, p_b) = (zeros(na), zeros(na), zeros(na));
    // Solid rows: u*_s = v + dt g for free particles (their elastic and
    // pressure forces come after the solve), the prescribed v for fixed ones.
    let (usx, usy, usz) = (zeros(ns), zeros(ns), zeros(ns));
    for (k, &i) in w.solid_perm.iter().enumerate() {
        let i = i as usize;
        let free = if solids.fixed[i] != 0 { 0.0 } else { dt };
        usx[k] = solids.vx[i] + free * p.gravity[0];
        usy[k] = solids.vy[i] + free * p.gravity[1];
        usz[k] = solids.vz[i] + free * p.gravity[2];
    }
    let u_solid = Vel { x: usx, y: usy, z: usz };
    let body_inv_mass = rigid_inverse_masses(p, solids, arena);
    let inv_mass_s = arena.alloc_slice_fill_iter(vols.body_solid.iter().map(|&b| body_inv_mass[b as usize]));
    let (src_s, diag_s) = (zeros(ns), zeros(ns));
    let p_s = arena.alloc_slice_fill_iter(w.solid_perm.iter().map(|&i| 0.5 * solids.pressure[i as usize]));
    tm.time(pass::PPE_SETUP, || {
        let rows = FluidRows {
            u_star: pred.u_star,
            vol: vols.vol,
            vm: vols.vm,
            alpha_f: ph.alpha_f,
            sigma: vols.sigma,
            vol_wall: vols.vol_wall_full,
            vol_solid: vols.vol_solid,
            u_solid,
            inv_mass_solid: inv_mass_s,
        };
        let fs = if ns > 0 { Some(&mut w.fs) } else { None };
        iisph::fluid_setup(&mut w.ff, &mut w.fb, fs, rows, dt, src, diag);
        let rows = WallRows {
            vol: vols.vol_wall,
            sigma: vols.sigma_wall,
            u_star: pred.u_star,
            vm_fluid: vols.vm,
            vol_fluid: vols.vol,
            u_own: None,
            inv_mass_own: None,
        };
        iisph::wall_setup(&mut w.bf, rows, dt, src_b, diag_b);
        if ns > 0 {
            let rows = WallRows {
                vol: vols.vol_solid,
                sigma: vols.sigma_solid,
                u_star: pred.u_star,
                vm_fluid: vols.vm,
                vol_fluid: vols.vol,
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
    PressureRows {
        fluid: Rows { source: src, diag },
        walls: Rows { source: src_b, diag: diag_b },
        solids: Rows { source: src_s, diag: diag_s },
        body_inv_mass,
        p_active: p_b,
        p_solid: p_s,
    }
}

/// 1/M of every elastic body within the solve, where each moves rigidly
/// under the sum of the pressure forces on it (strong coupling of the rigid
/// motion, which carries the fluid's added mass); 0 for a body with fixed
/// particles, which does not move within the solve.
fn rigid_inverse_masses<'a>(p: &Params, solids: &SolidStore, arena: &'a Bump) -> &'a [f32] {
    let nbodies = p.bodies();
    let body_inv_mass = arena.alloc_slice_fill_copy(nbodies, 0.0f32);
    let mass = arena.alloc_slice_fill_copy(nbodies, 0.0f64);
    let anchored = arena.alloc_slice_fill_copy(nbodies, false);
    for i in 0..solids.len() {
        let b = p.solid_group[solids.body[i] as usize] as usize;
        mass[b] += f64::from(solids.mass[i]);
        anchored[b] |= solids.fixed[i] != 0;
    }
    for b in 0..nbodies {
        body_inv_mass[b] = if anchored[b] || mass[b] <= 0.0 { 0.0 } else { (1.0 / mass[b]) as f32 };
    }
    body_inv_mass
}

/// What pass 5 gives the later passes.
pub(super) struct Solved<'a> {
    /// a^p of the fluid, m/s^2 (the later passes add to it).
    pub ap: [&'a mut [f32]; 3],
    /// Solid pressures (sorted solid order), Pa.
    pub p_solid: &'a [f32],
}

/// Pass 5 on the step's backend: the pressures of every row and the final
/// a^p, until the mean predicted density error is at most eta.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve<'a>(
    p: &Params,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    w: &mut Workspace,
    vols: &Volumes,
    rows: PressureRows<'a>,
    dt: f32,
    arena: &'a Bump,
    st: &mut StepStats,
) -> Solved<'a> {
    let n = fluid.len();
    let zeros = |n: usize| arena.alloc_slice_fill_copy(n, 0.0f32);
    let (apx, apy, apz) = (zeros(n), zeros(n), zeros(n));
    let parts = arena.alloc_slice_fill_copy(nblocks(n), 0.0f64);
    let rows_active = sum_f64(n, parts, |i| (rows.fluid.diag[i] != 0.0) as u32 as f64).max(1.0);
    let PressureRows { fluid: fluid_rows, walls: wall_rows, solids: solid_rows, body_inv_mass, p_active, p_solid } =
        rows;
    let sys = PressureSystem {
        support: p.kernel.support,
        fluid_grid: &w.fluid_grid,
        fluid: Points { x: &fluid.x, y: &fluid.y, z: &fluid.z },
        walls: WallInput {
            grid: &w.wall_grid,
            walls: Points { x: &walls.x, y: &walls.y, z: &walls.z },
            active: &w.active,
        },
        ff: &w.ff,
        fb: &w.fb,
        bf: &w.bf,
        vol: vols.vol,
        vm: vols.vm,
        rows: fluid_rows,
        vol_wall: vols.vol_wall_full,
        wall_rows,
        solids: (!p_solid.is_empty()).then_some(SolidSystem {
            fs: &w.fs,
            sf: &w.sf,
            rows: solid_rows,
            body: vols.body_solid,
            body_inv_mass,
        }),
        settings: SolveSettings {
            dt,
            omega: p.omega,
            min_iterations: p.min_iterations,
            max_iterations: p.max_iterations,
            max_density_error: p.max_density_error,
            rows_active: rows_active as f32,
        },
    };
    let x = Unknowns {
        p: &mut fluid.pressure,
        p_wall: &mut walls.pressure,
        p_active,
        p_solid: &mut *p_solid,
        ap: VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz },
    };
    let report = st.times.time(pass::PRESSURE_SOLVE, || w.backend.pressure_solve(&sys, x, arena));
    st.iterations = report.iterations;
    st.density_error = report.density_error;
    st.solve_restarts = report.restarts;
    st.times.gpu_ms[pass::PRESSURE_SOLVE] = report.gpu_ms.unwrap_or(0.0);
    Solved { ap: [apx, apy, apz], p_solid }
}
