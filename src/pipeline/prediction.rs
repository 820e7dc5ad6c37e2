//! Pass 3, the non-pressure prediction (PHYSICS.md §2.4 item 4, §5):
//! the viscosity of P-Eq. 23 and u* = u + dt (g + a^visc); with several
//! phases with the phase pair weights, keeping a^visc for the drift
//! velocities (P-Eq. 11's a).

use super::phases::PhaseState;
use super::timing::{pass, PassTimes};
use super::Params;
use crate::store::FluidStore;
use bumpalo::Bump;
use porosph_kernels::iisph::{Vel, VelMut};
use porosph_kernels::neighbors::{PairLists, Points};
use porosph_kernels::viscosity::{predict_velocity, predict_velocity_mixture, ViscosityInput};

/// What pass 3 gives the later passes.
pub(super) struct Prediction<'a> {
    /// u*, m/s.
    pub u_star: Vel<'a>,
    /// a^visc, m/s^2 (empty with one phase: only the drift reads it).
    pub a_visc: Vel<'a>,
}

/// Pass 3 over the fluid pairs `ff` (plain kernel gradients).
pub(super) fn predict<'a>(
    p: &Params,
    fluid: &FluidStore,
    ff: &PairLists,
    ph: &PhaseState,
    dt: f32,
    arena: &'a Bump,
    tm: &mut PassTimes,
) -> Prediction<'a> {
    let n = fluid.len();
    let mixture = p.mixture() && n > 0;
    let nm = if mixture { n } else { 0 };
    let zeros = |n: usize| arena.alloc_slice_fill_copy(n, 0.0f32);
    let (usx, usy, usz) = (zeros(n), zeros(n), zeros(n));
    let (avx, avy, avz) = (zeros(nm), zeros(nm), zeros(nm));
    tm.time(pass::VISCOSITY, || {
        let inp = ViscosityInput {
            ff,
            x: Points { x: &fluid.x, y: &fluid.y, z: &fluid.z },
            u: Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz },
            rest_density: ph.rest_density,
            mu: ph.mu,
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
    Prediction { u_star: Vel { x: usx, y: usy, z: usz }, a_visc: Vel { x: avx, y: avy, z: avz } }
}
