//! The CPU backend of the pass interface: pass 0's sort, pass 5's Jacobi
//! loop and pass 10's drift velocities with the `porosph-kernels` passes
//! (cache blocks under rayon, SIMD neighbour loops, reductions in block
//! order: bitwise the same for any thread count).

use super::passes::{
    Compliance, DriftOutput, DriftProblem, DriftReport, Passes, PressureSystem, SolidUnknowns, SolveReport, StepShape,
    Unknowns, WallInput,
};
use super::BackendKind;
use bumpalo::Bump;
use porosph_kernels::blocks::{nblocks, sum_f64};
use porosph_kernels::chebyshev;
use porosph_kernels::drift::{self, DriftSums, PhaseVelocityInput};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph::{self, Jacobi, SolidPairs};
use porosph_kernels::neighbors::{compute_keys, sort_permutation_into};
use porosph_kernels::phases::PhaseConstants;
use porosph_kernels::soa::{zeros, Vel, VelMut};
use porosph_kernels::solid_rows;
use rayon::prelude::*;

/// Every pass on the CPU.
#[derive(Clone, Copy, Debug, Default)]
pub struct Cpu;

impl Passes for Cpu {
    fn kind(&self) -> BackendKind {
        BackendKind::Cpu
    }

    fn sort(&mut self, fluid: Vel, inv_cell: f32, keys: &mut [u64], sort: &mut [(u64, u32)], perm: &mut [u32]) -> f64 {
        compute_keys(fluid.x, fluid.y, fluid.z, inv_cell, keys);
        sort_permutation_into(keys, sort, perm);
        0.0
    }

    fn prepare(&mut self, _fluid_grid: &CellGrid, _walls: WallInput, _step: StepShape) -> f64 {
        0.0
    }

    fn pressure_solve(&mut self, sys: &PressureSystem, x: Unknowns, arena: &Bump) -> SolveReport {
        jacobi_loop(sys, x, arena)
    }

    fn drift(
        &mut self,
        prob: &DriftProblem,
        out: DriftOutput,
        inner: Option<DriftOutput>,
        arena: &Bump,
    ) -> DriftReport {
        let inp = &prob.input;
        let n = inp.alpha_f.len();
        let density = arena.alloc_slice_fill_iter(inp.phases.iter().map(|c| c.density));
        // P-Eq. 11: the outer drift over the pressure solve's pairs, with
        // its porous term -phi (grad p^pore_fk - sum c grad p^pore_fk').
        let sums = DriftSums {
            density,
            porous: inp.porous.as_ref().map(|pd| (pd.grad_pore, -pd.pore_drift)),
            conservative: inp.conservative,
        };
        // The fractions packed, for the outer drift and then the inner one.
        let packed = arena.alloc_slice_fill_copy(n, [0.0f32; 4]);
        let pv = PhaseVelocityInput {
            ff: prob.ff,
            alpha_f: inp.alpha_f,
            p_per_fraction: inp.p_per_fraction,
            a_visc: inp.a_visc,
            a_p: inp.a_p,
            packed: drift::pack_fractions(inp.alpha, inp.p_per_fraction, &mut *packed),
        };
        let mut max_speed = drift::drift_velocities(&pv, inp.alpha, inp.phases, &sums, out.u, out.f);
        // P-Eq. 12: the inner drift over the pairs with h^3 grad W (inner
        // particles have no pressure-solve volume), its porous term
        // -tau' q_k.
        if let (Some(pd), Some(ffb), Some(out)) = (&inp.porous, prob.ffb, inner) {
            let pv = PhaseVelocityInput {
                ff: ffb,
                alpha_f: pd.beta_f,
                p_per_fraction: None,
                a_visc: inp.a_visc,
                a_p: inp.a_p,
                packed: drift::pack_fractions(pd.beta, None, packed),
            };
            let inner_phases =
                arena.alloc_slice_fill_iter(inp.phases.iter().map(|&c| PhaseConstants { sigma: pd.inner_sigma, ..c }));
            let sums = DriftSums { porous: Some((pd.q, -pd.inner_tau)), ..sums };
            max_speed = max_speed.max(drift::drift_velocities(&pv, pd.beta, inner_phases, &sums, out.u, out.f));
        }
        DriftReport { max_speed, gpu_ms: 0.0 }
    }

    fn take_error(&mut self) -> Option<String> {
        None
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}

impl Default for Box<dyn Passes> {
    /// The CPU backend.
    fn default() -> Self {
        Box::new(Cpu)
    }
}

/// Pass 5 on the CPU: relaxed Jacobi (P-Eqs. 27-28) until the mean
/// predicted density error of the fluid rows, and of the solid rows, is at
/// most the settings' bound. Each sweep: the fluid's a^p, the solids'
/// pressure forces and the bodies' response to them (a few iterations of
/// their compliance solve, warm-started from the last sweep), then the
/// updates of every row. A solve whose error grows starts over from the
/// warm start with a smaller omega (`iisph::Divergence`).
fn jacobi_loop(sys: &PressureSystem, x: Unknowns, arena: &Bump) -> SolveReport {
    let Unknowns { p, p_wall, p_active, ap, solids } = x;
    let VelMut { x: apx, y: apy, z: apz } = ap;
    let (p_s, mut accel, mut response): (&mut [f32], VelMut, Option<&mut dyn Compliance>) = match solids {
        Some(SolidUnknowns { p, accel, response }) => (p, accel, Some(response)),
        None => (&mut [], VelMut { x: &mut [], y: &mut [], z: &mut [] }, None),
    };
    let s = &sys.settings;
    let n = p.len();
    let ns = p_s.len();
    let err = zeros(arena, n);
    let err_s = zeros(arena, ns);
    let parts = arena.alloc_slice_fill_copy(nblocks(n.max(ns)), 0.0f64);
    let (fx, fy, fz) = (zeros(arena, ns), zeros(arena, ns), zeros(arena, ns));
    // a^p packed for the sweeps' reads at the pairs' targets.
    let packed = arena.alloc_slice_fill_copy(n, [0.0f32; 4]);
    let solid_rows_active = match &sys.solids {
        Some(sol) => sum_f64(ns, parts, |i| (sol.rows.diag[i] != 0.0) as u32 as f64).max(1.0),
        None => 1.0,
    };
    let fs_pairs = sys.solids.as_ref().map(|s| s.fs);
    // The warm start, kept for a restart with a smaller omega.
    let start = [arena.alloc_slice_copy(p), arena.alloc_slice_copy(p_active), arena.alloc_slice_copy(p_s)];
    let mut omega = s.omega;
    let mut cheb =
        (s.chebyshev_radius > 0.0).then(|| Chebyshev::new(arena, s.chebyshev_radius, [n, p_active.len(), ns]));
    let mut guard = iisph::Divergence::default();
    let mut local = iisph::Divergence::local();
    let mut report = SolveReport::default();
    let mut it = 0;
    loop {
        if let Some(c) = cheb.as_mut() {
            c.keep([&*p, &*p_active, &*p_s]);
        }
        let out = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
        let fs = fs_pairs.map(|pairs| SolidPairs { pairs, values: &*p_s });
        iisph::pressure_acceleration(sys.ff, sys.fb, fs, sys.vm, p, p_wall, out, Some(&mut *packed));
        if let (Some(sol), Some(r)) = (&sys.solids, response.as_mut()) {
            let f = VelMut { x: &mut *fx, y: &mut *fy, z: &mut *fz };
            solid_rows::solid_force(sol.solid, p_s, p, p_wall, sys.vol, sol.vol, f);
            r.respond(Vel { x: fx, y: fy, z: fz }, accel.reborrow(), false);
        }
        let ap = &*packed;
        let jac = Jacobi { dt: s.dt, omega };
        let a_s = Vel { x: &*accel.x, y: &*accel.y, z: &*accel.z };
        let fs = fs_pairs.map(|pairs| (pairs, a_s));
        iisph::fluid_jacobi(sys.ff, sys.fb, fs, ap, sys.rows, jac, p, err);
        let bs = sys.solids.as_ref().map(|s| (s.bs, a_s));
        iisph::wall_jacobi(sys.bf, ap, bs, sys.wall_rows, jac, p_active);
        if let Some(sol) = &sys.solids {
            solid_rows::solid_jacobi(sol.solid, a_s, ap, sol.rows, jac, p_s, err_s);
        }
        it += 1;
        let e = (sum_f64(n, parts, |i| err[i] as f64) / f64::from(s.rows_active)) as f32;
        let e_s = (sum_f64(ns, parts, |i| err_s[i] as f64) / solid_rows_active) as f32;
        report.density_error = e;
        report.solid_error = e_s;
        let worst = e.max(e_s);
        // The largest row error: a local mode the mean hides
        // (`iisph::Divergence::local`, and `max_row_density_error`).
        let largest = err.par_iter().chain(err_s.par_iter()).copied().reduce(|| 0.0, f32::max);
        report.largest_error = largest;
        let met = worst <= s.max_density_error && largest <= s.max_row_density_error;
        let done = it >= s.min_iterations && met || it >= s.max_iterations;
        if let (Some(c), false) = (cheb.as_mut(), done) {
            c.extrapolate([&mut *p, &mut *p_active, &mut *p_s]);
        }
        let diverging = guard.diverging(worst) | local.diverging(largest);
        let restart = diverging && worst > s.max_density_error && report.restarts < iisph::MAX_BACKOFFS;
        if restart {
            p.copy_from_slice(start[0]);
            p_active.copy_from_slice(start[1]);
            p_s.copy_from_slice(start[2]);
            omega *= iisph::RELAXATION_BACKOFF;
            guard = iisph::Divergence::default();
            local = iisph::Divergence::local();
            report.restarts += 1;
            cheb = None;
        }
        for (k, &b) in sys.walls.active.iter().enumerate() {
            p_wall[b as usize] = p_active[k];
        }
        if (!restart && it >= s.min_iterations && met) || it >= s.max_iterations {
            break;
        }
    }
    report.iterations = it;
    let out = VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz };
    let fs = fs_pairs.map(|pairs| SolidPairs { pairs, values: &*p_s });
    iisph::pressure_acceleration(sys.ff, sys.fb, fs, sys.vm, p, p_wall, out, None);
    if let (Some(sol), Some(r)) = (&sys.solids, response.as_mut()) {
        let f = VelMut { x: &mut *fx, y: &mut *fy, z: &mut *fz };
        solid_rows::solid_force(sol.solid, p_s, p, p_wall, sys.vol, sol.vol, f);
        r.respond(Vel { x: fx, y: fy, z: fz }, accel.reborrow(), true);
    }
    report
}

/// The semi-iteration's state in the Jacobi loop (`porosph_kernels::chebyshev`):
/// the iterate before the sweep (`cur`, p_k) and the one before that
/// (`prev`, p_{k-1}) of the fluid, active wall and solid rows.
struct Chebyshev<'a> {
    weights: chebyshev::Weights,
    prev: [&'a mut [f32]; 3],
    cur: [&'a mut [f32]; 3],
}

impl<'a> Chebyshev<'a> {
    fn new(arena: &'a Bump, rho: f32, lens: [usize; 3]) -> Self {
        let b = |k: usize| arena.alloc_slice_fill_copy(lens[k], 0.0f32);
        Self {
            weights: chebyshev::Weights::new(rho, chebyshev::PLAIN_SWEEPS),
            prev: [b(0), b(1), b(2)],
            cur: [b(0), b(1), b(2)],
        }
    }

    /// Keeps p_k before the sweep.
    fn keep(&mut self, p: [&[f32]; 3]) {
        for (c, p) in self.cur.iter_mut().zip(p) {
            c.copy_from_slice(p);
        }
    }

    /// After the sweep (`p` = J(p_k)): p_{k+1}.
    fn extrapolate(&mut self, p: [&mut [f32]; 3]) {
        let w = self.weights.after_sweep();
        for ((p, q), c) in p.into_iter().zip(self.prev.iter()).zip(self.cur.iter()) {
            chebyshev::extrapolate(w, p, c, q);
        }
        std::mem::swap(&mut self.prev, &mut self.cur);
    }
}
