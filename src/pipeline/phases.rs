//! Pass 1, phase bookkeeping (PHYSICS.md §0, §6): each fluid particle's
//! rest density, viscosity, outer fraction, mass and pressure-solve rest
//! volume from its fractions (P-Eq. 10, P §6.1).

use super::step::StepCtx;
use super::timing::Pass;
use crate::store::FluidStore;
use porosph_kernels::blocks::BLOCK;
use porosph_kernels::iisph;
use rayon::prelude::*;

/// What pass 1 derives per fluid particle.
pub(super) struct PhaseState<'a> {
    /// rho_fm = sum_k (alpha_k + beta_k) rho_k, kg/m^3.
    pub rest_density: &'a [f32],
    /// mu_m = sum_k (alpha_k + beta_k) mu_k, Pa s.
    pub mu: &'a [f32],
    /// alpha_f = sum_k alpha_k.
    pub alpha_f: &'a [f32],
    /// m = rho_fm h^3, kg.
    pub mass: &'a [f32],
    /// V0 = w(alpha_f) alpha_f h^3 (P §6.1, faded out of the solve below
    /// alpha_f = 1 by `iisph::row_weight`), m^3.
    pub v0: &'a [f32],
}

/// The rest volumes V0 of [`PhaseState`] alone, into `v0` (for the
/// neighbour pass, which sums V0_j W_ij as it finds the pairs; the same
/// values as [`bookkeeping`]'s, bit for bit, where the fractions have not
/// changed in between).
pub(super) fn rest_volumes(cell: f32, fluid: &FluidStore, v0: &mut [f32]) {
    v0.par_chunks_mut(BLOCK).enumerate().for_each(|(b, v0)| {
        for (q, v) in v0.iter_mut().enumerate() {
            let i = b * BLOCK + q;
            let mut a = 0.0;
            for al in &fluid.alpha {
                a += al[i];
            }
            *v = iisph::row_weight(a) * a * cell;
        }
    });
}

/// Pass 1. With porous solids the inner fractions count in the mass and
/// the viscosity (P-Eq. 10). `v0`: the rest volumes, which the neighbour
/// pass computed ([`rest_volumes`]).
pub(super) fn bookkeeping<'a>(cx: &mut StepCtx<'a>, fluid: &FluidStore, porous: bool, v0: &'a [f32]) -> PhaseState<'a> {
    let (p, arena) = (cx.p, cx.arena);
    let tm = &mut cx.tm;
    let n = fluid.len();
    let rest_density = arena.alloc_slice_fill_copy(n, 0.0f32);
    let mu = arena.alloc_slice_fill_copy(n, 0.0f32);
    let alpha_f = arena.alloc_slice_fill_copy(n, 0.0f32);
    let mass = arena.alloc_slice_fill_copy(n, 0.0f32);
    tm.time(Pass::Phases, || {
        let cell = p.cell_volume();
        rest_density
            .par_chunks_mut(BLOCK)
            .zip(mu.par_chunks_mut(BLOCK))
            .zip(alpha_f.par_chunks_mut(BLOCK))
            .zip(mass.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(b, (((rho, mu), af), m))| {
                for q in 0..rho.len() {
                    let i = b * BLOCK + q;
                    let (mut r, mut v, mut a) = (0.0, 0.0, 0.0);
                    for (k, al) in fluid.alpha.iter().enumerate() {
                        r += al[i] * p.phase_density[k];
                        v += al[i] * p.phase_viscosity[k];
                        a += al[i];
                    }
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
                }
            });
    });
    PhaseState { rest_density, mu, alpha_f, mass, v0 }
}
