//! Pass 3: fluid-fluid viscosity (P-Eq. 23, the Morris form, PHYSICS.md §5)
//! with the phase pair weights of the mixture, and the prediction
//! u* = u + dt (g + a^visc) (PHYSICS.md §2.4, item 4).

use crate::blocks::BLOCK;
use crate::iisph::Vel;
use crate::lanes::{gather, load, sum, F, LANES};
use crate::neighbors::{PairBlock, PairLists, Points};
use crate::phases::VelMut;
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

/// The phase pair weight w_ij of P-Eq. 23 for a vector of pairs.
trait PairWeight: Sync {
    /// `c` times w_ij for particle i and the pairs `j[p..p + LANES]`.
    fn apply(&self, c: F, i: usize, j: &[u32], p: usize) -> F;
}

/// One phase: w_ij = 1, and `c` is returned as it is (no multiply), so
/// the one-phase result is exactly that of the Morris form without weights.
struct Unweighted;

impl PairWeight for Unweighted {
    #[inline(always)]
    fn apply(&self, c: F, _: usize, _: &[u32], _: usize) -> F {
        c
    }
}

/// Several phases: w_ij = sum_k 2 alpha_ik alpha_jk / (alpha_ik + alpha_jk)
/// (PHYSICS.md §5: the harmonic mean, 1 for two particles of the same
/// mixture, 0 for two pure particles of different phases; a phase absent
/// from both particles adds 0).
struct PhaseWeights<'a>(&'a [&'a [f32]]);

impl PairWeight for PhaseWeights<'_> {
    #[inline(always)]
    fn apply(&self, c: F, i: usize, j: &[u32], p: usize) -> F {
        let mut w = F::ZERO;
        for a in self.0 {
            let (ai, aj) = (F::splat(a[i]), gather(a, j, p));
            w += F::splat(2.0) * ai * aj / (ai + aj).max(F::splat(f32::MIN_POSITIVE));
        }
        c * w
    }
}

/// a^visc_i (P-Eq. 23) of particle `i`, the query `q` of block `blk`.
#[inline(always)]
fn viscous_acceleration<W: PairWeight>(inp: &ViscosityInput, blk: &PairBlock, q: usize, i: usize, wt: &W) -> [f32; 3] {
    let eps = 0.01 * inp.h * inp.h;
    let (u, x) = (inp.u, inp.x);
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
        let c = wt.apply((mui + gather(inp.mu, j, k)) * xg / (r2 + F::splat(eps)), i, j, k);
        ax += c * (gather(u.x, j, k) - uxi);
        ay += c * (gather(u.y, j, k) - uyi);
        az += c * (gather(u.z, j, k) - uzi);
        k += LANES;
    }
    let inv = if rhoi > 0.0 { inp.h * inp.h * inp.h / rhoi } else { 0.0 };
    [inv * sum(ax), inv * sum(ay), inv * sum(az)]
}

/// One phase: a^visc_i = sum_j (m_j / (rho_i rho_j)) (mu_i + mu_j)
///   ((x_j - x_i).grad W_ij / (|x_ij|^2 + 0.01 h^2)) (u_j - u_i)
/// (the pair weight of P-Eq. 23 is 1 for a single phase), then
/// u*_i = u_i + dt (g + a^visc_i). Masses are m_j = rho_fm,j h^3 (pass 1),
/// so m_j / (rho_i rho_j) = h^3 / rho_i.
pub fn predict_velocity(inp: &ViscosityInput, ux: &mut [f32], uy: &mut [f32], uz: &mut [f32]) {
    let u = inp.u;
    ux.par_chunks_mut(BLOCK)
        .zip(uy.par_chunks_mut(BLOCK))
        .zip(uz.par_chunks_mut(BLOCK))
        .zip(inp.ff.used().par_iter())
        .enumerate()
        .for_each(|(b, (((ox, oy), oz), blk))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let a = viscous_acceleration(inp, blk, q, i, &Unweighted);
                ox[q] = u.x[i] + inp.dt * (inp.gravity[0] + a[0]);
                oy[q] = u.y[i] + inp.dt * (inp.gravity[1] + a[1]);
                oz[q] = u.z[i] + inp.dt * (inp.gravity[2] + a[2]);
            }
        });
}

/// Several phases: as [`predict_velocity`], with the phase pair weights
/// w_ij of P-Eq. 23 from the fractions `alpha` (one slice per phase), and
/// a^visc also written to `a_visc` (the drift velocities need it). With
/// one phase of fraction 1, w_ij = 1 exactly and the result is bitwise
/// that of [`predict_velocity`].
pub fn predict_velocity_mixture(inp: &ViscosityInput, alpha: &[&[f32]], u_star: VelMut, a_visc: VelMut) {
    let u = inp.u;
    let wt = PhaseWeights(alpha);
    u_star
        .x
        .par_chunks_mut(BLOCK)
        .zip(u_star.y.par_chunks_mut(BLOCK))
        .zip(u_star.z.par_chunks_mut(BLOCK))
        .zip(a_visc.x.par_chunks_mut(BLOCK).zip(a_visc.y.par_chunks_mut(BLOCK)).zip(a_visc.z.par_chunks_mut(BLOCK)))
        .zip(inp.ff.used().par_iter())
        .enumerate()
        .for_each(|(b, ((((ox, oy), oz), ((vx, vy), vz)), blk))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let a = viscous_acceleration(inp, blk, q, i, &wt);
                (vx[q], vy[q], vz[q]) = (a[0], a[1], a[2]);
                ox[q] = u.x[i] + inp.dt * (inp.gravity[0] + a[0]);
                oy[q] = u.y[i] + inp.dt * (inp.gravity[1] + a[1]);
                oz[q] = u.z[i] + inp.dt * (inp.gravity[2] + a[2]);
            }
        });
}
