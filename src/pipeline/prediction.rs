//! Pass 3, the non-pressure prediction (PHYSICS.md §2.4 item 4, §5):
//! the viscosity of P-Eq. 23 and u* = u + dt (g + a^visc); with several
//! phases with the phase pair weights, keeping a^visc for the drift
//! velocities (P-Eq. 11's a). a^visc is explicit (the velocities at the
//! step's start) or implicit (of u*, a linear solve: `Params::implicit_viscosity`).

use super::phases::PhaseState;
use super::step::StepCtx;
use super::timing::Pass;
use crate::store::FluidStore;
use bumpalo::Bump;
use porosph_kernels::blocks::{nblocks, BLOCK};
use porosph_kernels::drift::{pack_fractions, PACKED_PHASES};
use porosph_kernels::lanes::Packed;
use porosph_kernels::neighbors::PairLists;
use porosph_kernels::soa::{zeros, zeros3, Vel, VelMut};
use porosph_kernels::viscosity::{
    predict_velocity, predict_velocity_implicit, predict_velocity_mixture, ImplicitScratch, ViscosityInput,
};
use rayon::prelude::*;

/// What pass 3 gives the later passes.
pub(super) struct Prediction<'a> {
    /// u*, m/s.
    pub u_star: Vel<'a>,
    /// a^visc, m/s^2 (empty with one phase: only the drift reads it).
    pub a_visc: Vel<'a>,
    /// Conjugate-gradient iterations of the implicit viscosity (0 if explicit).
    pub iterations: u32,
}

/// Pass 3 over the fluid pairs `ff` (plain kernel gradients).
pub(super) fn predict<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &FluidStore,
    ff: &PairLists,
    visc_coef: &mut Vec<Vec<f32>>,
    ph: &PhaseState,
) -> Prediction<'a> {
    let (p, dt, arena) = (cx.p, cx.dt, cx.arena);
    let tm = &mut cx.tm;
    let n = fluid.len();
    let mixture = p.mixture() && n > 0;
    let nm = if mixture { n } else { 0 };
    let VelMut { x: usx, y: usy, z: usz } = zeros3(arena, n);
    let VelMut { x: avx, y: avy, z: avz } = zeros3(arena, nm);
    let mut iterations = 0;
    let scratch = cx.scratch.fresh();
    tm.time(Pass::Viscosity, || {
        let x = Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        let u = Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz };
        let alpha = &*arena.alloc_slice_fill_iter(fluid.alpha.iter().map(|a| a.as_slice()));
        let phases = if mixture && alpha.len() <= PACKED_PHASES {
            pack_fractions(alpha, Some(ph.mu), scratch.alloc_slice_fill_copy(n, [0.0f32; 4]))
        } else {
            None
        };
        let inp = ViscosityInput {
            ff,
            x,
            u,
            packed: Some([pack(scratch, x), pack(scratch, u)]),
            rest_density: ph.rest_density,
            mu: ph.mu,
            mu_uniform: ph.mu.par_iter().all(|&m| m == ph.mu[0]),
            phases,
            h: p.h,
            gravity: p.gravity,
            dt,
        };
        if p.implicit_viscosity && dt > p.implicit_viscosity_above && n > 0 {
            let alpha = mixture.then_some(alpha);
            let z3 = || [zeros(arena, n), zeros(arena, n), zeros(arena, n)];
            let scratch = ImplicitScratch {
                diag: zeros(arena, n),
                r: z3(),
                z: z3(),
                p: z3(),
                ap: z3(),
                parts: arena.alloc_slice_fill_copy(nblocks(n), 0.0f64),
            };
            let u_star = VelMut { x: &mut *usx, y: &mut *usy, z: &mut *usz };
            let tol = p.viscosity_tolerance;
            iterations =
                predict_velocity_implicit(&inp, alpha, visc_coef, scratch, tol, MAX_ITERATIONS, u_star).iterations;
            if mixture {
                // a^visc = (u* - u) / dt - g, for the drift velocities.
                let (u, g) = ([&fluid.ux, &fluid.uy, &fluid.uz], p.gravity);
                for (c, (a, us)) in [&mut *avx, &mut *avy, &mut *avz].into_iter().zip([&*usx, &*usy, &*usz]).enumerate()
                {
                    a.par_iter_mut().enumerate().for_each(|(i, a)| *a = (us[i] - u[c][i]) / dt - g[c]);
                }
            }
        } else if mixture {
            let u_star = VelMut { x: &mut *usx, y: &mut *usy, z: &mut *usz };
            let a_visc = VelMut { x: &mut *avx, y: &mut *avy, z: &mut *avz };
            predict_velocity_mixture(&inp, alpha, u_star, a_visc);
        } else {
            predict_velocity(&inp, usx, usy, usz);
        }
    });
    Prediction { u_star: Vel { x: usx, y: usy, z: usz }, a_visc: Vel { x: avx, y: avy, z: avz }, iterations }
}

/// `v` packed ([`Packed`]) in `scratch`.
fn pack<'s>(scratch: &'s Bump, v: Vel) -> &'s [Packed] {
    let out = scratch.alloc_slice_fill_copy(v.x.len(), [0.0f32; 4]);
    out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
        for (q, o) in o.iter_mut().enumerate() {
            let i = b * BLOCK + q;
            *o = [v.x[i], v.y[i], v.z[i], 0.0];
        }
    });
    out
}

/// Largest number of conjugate-gradient iterations of the implicit viscosity.
const MAX_ITERATIONS: u32 = 500;
