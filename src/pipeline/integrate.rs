//! Passes 13-14 (P Alg. 4): symplectic Euler for the fluid and the solids,
//! then the correction of the volume fractions.

use super::mixture::NextFractions;
use super::step::StepCtx;
use super::timing::Pass;
use crate::store::{FluidStore, SolidStore};
use porosph_kernels::integrate::{integrate, State};
use porosph_kernels::phase_transport;
use porosph_kernels::soa::Vel;
use rayon::prelude::*;

/// Pass 13: u^{n+1} = u* + dt a (a = a^p and what the later passes added),
/// x += dt u^{n+1}; solids: x += dt v^{n+1} (PHYSICS.md §3.3).
pub(super) fn positions(cx: &mut StepCtx, fluid: &mut FluidStore, solids: &mut SolidStore, u_star: Vel, a: Vel) {
    let dt = cx.dt;
    let tm = &mut cx.tm;
    tm.time(Pass::Integrate, || {
        let s = State {
            x: &mut fluid.x,
            y: &mut fluid.y,
            z: &mut fluid.z,
            ux: &mut fluid.ux,
            uy: &mut fluid.uy,
            uz: &mut fluid.uz,
        };
        integrate(s, u_star, a, dt);
        let sv = (&solids.vx[..], &solids.vy[..], &solids.vz[..]).into_par_iter();
        let sx = (&mut solids.x[..], &mut solids.y[..], &mut solids.z[..]).into_par_iter();
        sx.zip(sv).for_each(|((x, y, z), (vx, vy, vz))| {
            *x += dt * vx;
            *y += dt * vy;
            *z += dt * vz;
        });
    });
}

/// Pass 14's correction (P §6.4, P Alg. 4): negative fractions to 0, then
/// every fraction of a particle scaled by one common factor so that
/// sum_k (alpha_k + beta_k) = 1 (with porous solids alpha and beta
/// together, keeping the alpha/beta split), in f64, stored as the fluid's
/// fractions and their low parts. Nothing with one phase and no porous
/// solid.
pub(super) fn correct_fractions(cx: &mut StepCtx, fluid: &mut FluidStore, next: NextFractions) {
    let arena = cx.arena;
    let tm = &mut cx.tm;
    let n = fluid.len();
    if next.alpha.is_empty() {
        return;
    }
    let np = fluid.alpha.len();
    let porous = !next.beta.is_empty();
    tm.time(Pass::PhaseCorrection, || {
        let sets = if porous { 2 * np } else { np };
        let all = arena.alloc_slice_fill_iter((0..sets).map(|k| {
            if k < np {
                &next.alpha[k * n..(k + 1) * n]
            } else {
                &next.beta[(k - np) * n..(k - np + 1) * n]
            }
        }));
        let total = arena.alloc_slice_fill_copy(n, 0.0f64);
        let largest = arena.alloc_slice_fill_copy(n, 0u32);
        phase_transport::correction_sums(all, total, largest);
        let sets = if porous { np } else { 0 };
        let hi = fluid.alpha.iter_mut().chain(fluid.beta.iter_mut().take(sets));
        let lo = fluid.alpha_lo.iter_mut().chain(fluid.beta_lo.iter_mut().take(sets));
        for (k, (a, l)) in hi.zip(lo).enumerate() {
            phase_transport::correct(all[k], total, largest, k, a, l);
        }
    });
}
