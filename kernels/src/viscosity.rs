//! Pass 3: fluid-fluid viscosity (P-Eq. 23, the Morris form, PHYSICS.md §5)
//! and the prediction u* = u + dt (g + a^visc) (PHYSICS.md §2.4, item 4).

use crate::blocks::BLOCK;
use crate::iisph::Vel;
use crate::lanes::{gather, load, sum, F, LANES};
use crate::neighbors::{PairLists, Points};
use rayon::prelude::*;

/// Inputs of the viscosity pass.
pub struct ViscosityInput<'a> {
    /// Fluid-fluid pairs with unscaled gradients grad W_ij.
    pub ff: &'a PairLists,
    pub x: Points<'a>,
    pub u: Vel<'a>,
    /// Rest (mixture) density rho_fm, kg/m^3.
    pub rest_density: &'a [f32],
    /// Mixture viscosity mu_m, Pa s.
    pub mu: &'a [f32],
    /// Particle spacing h, m (regulariser 0.01 h^2).
    pub h: f32,
    pub gravity: [f32; 3],
    pub dt: f32,
}

/// a^visc_i = sum_j (m_j / (rho_i rho_j)) (mu_i + mu_j)
///   ((x_j - x_i).grad W_ij / (|x_ij|^2 + 0.01 h^2)) (u_j - u_i),
/// then u*_i = u_i + dt (g + a^visc_i). The phase pair weight of P-Eq. 23 is
/// 1 for a single phase. Masses are m_j = rho_fm,j h^3 (pass 1), so
/// m_j / (rho_i rho_j) = h^3 / rho_i.
pub fn predict_velocity(inp: &ViscosityInput, ux: &mut [f32], uy: &mut [f32], uz: &mut [f32]) {
    let eps = 0.01 * inp.h * inp.h;
    let (u, x) = (inp.u, inp.x);
    ux.par_chunks_mut(BLOCK)
        .zip(uy.par_chunks_mut(BLOCK))
        .zip(uz.par_chunks_mut(BLOCK))
        .zip(inp.ff.used().par_iter())
        .enumerate()
        .for_each(|(b, (((ox, oy), oz), blk))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let (mut ax, mut ay, mut az) = (F::ZERO, F::ZERO, F::ZERO);
                let (xi, yi, zi) = (F::splat(x.x[i]), F::splat(x.y[i]), F::splat(x.z[i]));
                let (uxi, uyi, uzi) = (F::splat(u.x[i]), F::splat(u.y[i]), F::splat(u.z[i]));
                let (mui, rhoi) = (F::splat(inp.mu[i]), inp.rest_density[i]);
                let r = blk.range(q);
                let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
                let mut k = r.start;
                while k < r.end {
                    let dx = xi - gather(x.x, j, k);
                    let dy = yi - gather(x.y, j, k);
                    let dz = zi - gather(x.z, j, k);
                    let r2 = dx * dx + dy * dy + dz * dz;
                    // (x_j - x_i).grad W_ij = -x_ij.grad W_ij >= 0
                    let xg = -(dx * load(gx, k) + dy * load(gy, k) + dz * load(gz, k));
                    let c = (mui + gather(inp.mu, j, k)) * xg / (r2 + F::splat(eps));
                    ax += c * (gather(u.x, j, k) - uxi);
                    ay += c * (gather(u.y, j, k) - uyi);
                    az += c * (gather(u.z, j, k) - uzi);
                    k += LANES;
                }
                let inv = if rhoi > 0.0 { inp.h * inp.h * inp.h / rhoi } else { 0.0 };
                ox[q] = u.x[i] + inp.dt * (inp.gravity[0] + inv * sum(ax));
                oy[q] = u.y[i] + inp.dt * (inp.gravity[1] + inv * sum(ay));
                oz[q] = u.z[i] + inp.dt * (inp.gravity[2] + inv * sum(az));
            }
        });
}
