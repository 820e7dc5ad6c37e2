//! Pass 13: symplectic Euler, u^{n+1} = u* + dt a^p, x^{n+1} = x + dt u^{n+1}
//! (PHYSICS.md §6).

use crate::blocks::BLOCK;
use crate::soa::Vel;
use rayon::prelude::*;

/// Positions and velocities to update in place.
pub struct State<'a> {
    pub x: &'a mut [f32],
    pub y: &'a mut [f32],
    pub z: &'a mut [f32],
    pub ux: &'a mut [f32],
    pub uy: &'a mut [f32],
    pub uz: &'a mut [f32],
}

/// u <- u* + dt a^p; x <- x + dt u.
pub fn integrate(s: State, u_star: Vel, ap: Vel, dt: f32) {
    s.x.par_chunks_mut(BLOCK)
        .zip(s.y.par_chunks_mut(BLOCK))
        .zip(s.z.par_chunks_mut(BLOCK))
        .zip(s.ux.par_chunks_mut(BLOCK).zip(s.uy.par_chunks_mut(BLOCK)).zip(s.uz.par_chunks_mut(BLOCK)))
        .enumerate()
        .for_each(|(b, (((x, y), z), ((ux, uy), uz)))| {
            for q in 0..x.len() {
                let i = b * BLOCK + q;
                ux[q] = u_star.x[i] + dt * ap.x[i];
                uy[q] = u_star.y[i] + dt * ap.y[i];
                uz[q] = u_star.z[i] + dt * ap.z[i];
                x[q] += dt * ux[q];
                y[q] += dt * uy[q];
                z[q] += dt * uz[q];
            }
        });
}
