//! IISPH (Ihmsen et al. 2014) in the volume form of the paper (P-Eqs. 25-29)
//! with pressure boundaries (Band et al. 2018a): static wall particles are
//! rows of the pressure system. PHYSICS.md §2.2-2.4, passes 4 and 5 of §6.
//!
//! Notation: fluid particle i, wall (boundary) particle b. `FF`, `FB` are the
//! fluid and wall neighbours of fluid particles; `BF` the fluid neighbours of
//! the active wall particles (those with at least one fluid neighbour).
//! After [`scale_by_pair_volume`], the stored pair gradient is
//! g_ij = Vbar_ij grad W_ij with Vbar_ij = 2 V_i V_j / (V_i + V_j).

use crate::blocks::BLOCK;
use crate::lanes::{gather, load, sum, F, LANES};
use crate::neighbors::PairLists;
use rayon::prelude::*;

/// Harmonic pair volume Vbar_ij = 2 V_i V_j / (V_i + V_j), 0 if either is 0
/// (PHYSICS.md §0, with the factor 2 the paper drops, §8.2).
#[inline(always)]
pub fn harmonic_volume(vi: f32, vj: f32) -> f32 {
    let s = vi + vj;
    if vi * vj > 0.0 {
        2.0 * vi * vj / s
    } else {
        0.0
    }
}

/// Pass 2/4b, fluid rows: sigma_i = sum_j V0_j W_ij over fluid (incl. self)
/// and wall neighbours, and the current volume V_i = V0_i / sigma_i
/// (PHYSICS.md §2.3). `sigma` is the smoothed outer-fluid fraction V0/V.
pub fn fluid_volumes(ff: &PairLists, fb: &PairLists, v0_f: &[f32], v0_b: &[f32], sigma: &mut [f32], vol: &mut [f32]) {
    sigma
        .par_chunks_mut(BLOCK)
        .zip(vol.par_chunks_mut(BLOCK))
        .zip(ff.used().par_iter().zip(fb.used().par_iter()))
        .enumerate()
        .for_each(|(b, ((sig, v), (bf, bb)))| {
            for q in 0..sig.len() {
                let i = b * BLOCK + q;
                let s = weighted_sum(&bf.j, &bf.w, bf.range(q), v0_f) + weighted_sum(&bb.j, &bb.w, bb.range(q), v0_b);
                sig[q] = s;
                v[q] = if s > 0.0 { v0_f[i] / s } else { 0.0 };
            }
        });
}

/// Pass 2/4b, wall rows: sigma_b = (static wall part) + sum_f V0_f W_bf,
/// V_b = V0_b / sigma_b, for the active wall particles `active`.
pub fn wall_volumes(
    bf: &PairLists,
    active: &[u32],
    sigma_static: &[f32],
    v0_b: &[f32],
    v0_f: &[f32],
    sigma: &mut [f32],
    vol: &mut [f32],
) {
    sigma.par_chunks_mut(BLOCK).zip(vol.par_chunks_mut(BLOCK)).zip(bf.used().par_iter()).enumerate().for_each(
        |(b, ((sig, v), blk))| {
            for q in 0..sig.len() {
                let w = active[b * BLOCK + q] as usize;
                let s = sigma_static[w] + weighted_sum(&blk.j, &blk.w, blk.range(q), v0_f);
                sig[q] = s;
                v[q] = if s > 0.0 { v0_b[w] / s } else { 0.0 };
            }
        },
    );
}

#[inline(always)]
fn weighted_sum(j: &[u32], w: &[f32], r: std::ops::Range<usize>, val: &[f32]) -> f32 {
    let (j, w) = (&j[..r.end], &w[..r.end]);
    let mut acc = F::ZERO;
    let mut k = r.start;
    while k < r.end {
        acc += gather(val, j, k) * load(w, k);
        k += LANES;
    }
    sum(acc)
}

/// Scales every stored pair gradient by the harmonic pair volume:
/// g_ij <- Vbar_ij grad W_ij, with V_i from `vol_q` (query side, indexed
/// like the lists) and V_j from `vol_t` (target side).
pub fn scale_by_pair_volume(lists: &mut PairLists, vol_q: &[f32], vol_t: &[f32]) {
    lists.used_mut().par_iter_mut().enumerate().for_each(|(b, blk)| {
        let nq = blk.start.len().saturating_sub(1);
        for q in 0..nq {
            let vi = vol_q[b * BLOCK + q];
            for p in blk.range(q) {
                let s = harmonic_volume(vi, vol_t[blk.j[p] as usize]);
                blk.gx[p] *= s;
                blk.gy[p] *= s;
                blk.gz[p] *= s;
            }
        }
    });
}

/// Velocities as three slices.
#[derive(Clone, Copy)]
pub struct Vel<'a> {
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub z: &'a [f32],
}

/// Inputs of the fluid rows of the system.
pub struct FluidRows<'a> {
    pub ff: &'a PairLists,
    pub fb: &'a PairLists,
    /// Predicted velocity u* (after non-pressure forces), m/s.
    pub u_star: Vel<'a>,
    /// Current volume V, m^3.
    pub vol: &'a [f32],
    /// V / m, m^3/kg (0 for rows outside the solve).
    pub vm: &'a [f32],
    /// Outer fluid fraction alpha_f (1 for a single phase).
    pub alpha_f: &'a [f32],
    /// sigma = V0 / V.
    pub sigma: &'a [f32],
}

/// Rows below this outer fraction take no part in the solve (PHYSICS.md §2.4).
pub const MIN_ALPHA_F: f32 = 0.01;

/// Pass 4c, fluid rows (after [`scale_by_pair_volume`]):
/// source S_f = alpha_f (1 + dt div*_f) - V0_f/V_f (P-Eq. 29) with
/// div*_f = -sum_j Vbar (u*_f - u*_j).grad W (P-Eq. 25; walls have u* = 0),
/// and diagonal a_ff = -dt^2 [ (V_f/m_f) |sum_j Vbar grad W|^2
/// + sum_{j fluid} (V_j/m_j) Vbar^2 |grad W|^2 ] (PHYSICS.md §2.2).
pub fn fluid_source_diagonal(rows: &FluidRows, dt: f32, source: &mut [f32], diag: &mut [f32]) {
    let dt2 = dt * dt;
    source
        .par_chunks_mut(BLOCK)
        .zip(diag.par_chunks_mut(BLOCK))
        .zip(rows.ff.used().par_iter().zip(rows.fb.used().par_iter()))
        .enumerate()
        .for_each(|(b, ((src, dg), (bf, bb)))| {
            for q in 0..src.len() {
                let i = b * BLOCK + q;
                if rows.alpha_f[i] < MIN_ALPHA_F || rows.vol[i] <= 0.0 {
                    src[q] = 0.0;
                    dg[q] = 0.0;
                    continue;
                }
                let u = rows.u_star;
                let (uxi, uyi, uzi) = (F::splat(u.x[i]), F::splat(u.y[i]), F::splat(u.z[i]));
                let mut div = F::ZERO;
                let (mut sx, mut sy, mut sz) = (F::ZERO, F::ZERO, F::ZERO);
                let mut s2 = F::ZERO;
                let r = bf.range(q);
                let (j, gx, gy, gz) = (&bf.j[..r.end], &bf.gx[..r.end], &bf.gy[..r.end], &bf.gz[..r.end]);
                let mut k = r.start;
                while k < r.end {
                    let (x, y, z) = (load(gx, k), load(gy, k), load(gz, k));
                    let dux = uxi - gather(u.x, j, k);
                    let duy = uyi - gather(u.y, j, k);
                    let duz = uzi - gather(u.z, j, k);
                    div -= dux * x + duy * y + duz * z;
                    sx += x;
                    sy += y;
                    sz += z;
                    s2 += gather(rows.vm, j, k) * (x * x + y * y + z * z);
                    k += LANES;
                }
                let r = bb.range(q);
                let (gx, gy, gz) = (&bb.gx[..r.end], &bb.gy[..r.end], &bb.gz[..r.end]);
                let mut k = r.start;
                while k < r.end {
                    let (x, y, z) = (load(gx, k), load(gy, k), load(gz, k));
                    div -= uxi * x + uyi * y + uzi * z;
                    sx += x;
                    sy += y;
                    sz += z;
                    k += LANES;
                }
                let (sx, sy, sz) = (sum(sx), sum(sy), sum(sz));
                let vm_i = rows.vm[i];
                src[q] = rows.alpha_f[i] * (1.0 + dt * sum(div)) - rows.sigma[i];
                dg[q] = -dt2 * (vm_i * (sx * sx + sy * sy + sz * sz) + sum(s2));
            }
        });
}

/// Pass 4c, wall rows (after [`scale_by_pair_volume`]): S_b = 1 + dt div*_b
/// - V0_b/V_b (P-Eq. 26) with div*_b = -sum_f Vbar (0 - u*_f).grad W_bf, and
/// a_bb = -dt^2 sum_f (V_f/m_f) Vbar^2 |grad W_bf|^2 (static: no own term).
pub fn wall_source_diagonal(
    bf: &PairLists,
    u_star: Vel,
    vm_f: &[f32],
    sigma_b: &[f32],
    dt: f32,
    source: &mut [f32],
    diag: &mut [f32],
) {
    let dt2 = dt * dt;
    source.par_chunks_mut(BLOCK).zip(diag.par_chunks_mut(BLOCK)).zip(bf.used().par_iter()).enumerate().for_each(
        |(b, ((src, dg), blk))| {
            for q in 0..src.len() {
                let r = blk.range(q);
                let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
                let mut div = F::ZERO;
                let mut s2 = F::ZERO;
                let mut k = r.start;
                while k < r.end {
                    let (x, y, z) = (load(gx, k), load(gy, k), load(gz, k));
                    div += gather(u_star.x, j, k) * x + gather(u_star.y, j, k) * y + gather(u_star.z, j, k) * z;
                    s2 += gather(vm_f, j, k) * (x * x + y * y + z * z);
                    k += LANES;
                }
                src[q] = 1.0 + dt * sum(div) - sigma_b[b * BLOCK + q];
                dg[q] = -dt2 * sum(s2);
            }
        },
    );
}

/// Pressure acceleration, P-Eq. 27 with the factor 2 restored:
/// a^p_f = -(V_f/m_f) sum_j Vbar_fj (p_f + p_j) grad W_fj over fluid and wall
/// neighbours (`p_b` is the full wall pressure array).
pub fn pressure_acceleration(
    ff: &PairLists,
    fb: &PairLists,
    vm: &[f32],
    p_f: &[f32],
    p_b: &[f32],
    ax: &mut [f32],
    ay: &mut [f32],
    az: &mut [f32],
) {
    ax.par_chunks_mut(BLOCK)
        .zip(ay.par_chunks_mut(BLOCK))
        .zip(az.par_chunks_mut(BLOCK))
        .zip(ff.used().par_iter().zip(fb.used().par_iter()))
        .enumerate()
        .for_each(|(b, (((ox, oy), oz), (bf, bb)))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let pi = F::splat(p_f[i]);
                let (mut sx, mut sy, mut sz) = (F::ZERO, F::ZERO, F::ZERO);
                for (blk, p) in [(bf, p_f), (bb, p_b)] {
                    let r = blk.range(q);
                    let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
                    let mut k = r.start;
                    while k < r.end {
                        let s = pi + gather(p, j, k);
                        sx += s * load(gx, k);
                        sy += s * load(gy, k);
                        sz += s * load(gz, k);
                        k += LANES;
                    }
                }
                let c = -vm[i];
                ox[q] = c * sum(sx);
                oy[q] = c * sum(sy);
                oz[q] = c * sum(sz);
            }
        });
}

/// Relaxed Jacobi update of the fluid rows, P-Eq. 28:
/// (Ap)_f = dt^2 sum_j Vbar (a^p_f - a^p_j).grad W (walls: a^p = 0),
/// r_f = S_f - (Ap)_f, p_f <- max(0, p_f + omega r_f / a_ff).
/// Writes max(-r_f, 0) (the predicted compression) to `err`.
#[allow(clippy::too_many_arguments)]
pub fn fluid_jacobi(
    ff: &PairLists,
    fb: &PairLists,
    ap: Vel,
    source: &[f32],
    diag: &[f32],
    dt: f32,
    omega: f32,
    p: &mut [f32],
    err: &mut [f32],
) {
    let dt2 = dt * dt;
    p.par_chunks_mut(BLOCK)
        .zip(err.par_chunks_mut(BLOCK))
        .zip(ff.used().par_iter().zip(fb.used().par_iter()))
        .enumerate()
        .for_each(|(b, ((pp, ee), (bf, bb)))| {
            for q in 0..pp.len() {
                let i = b * BLOCK + q;
                if diag[i].abs() < f32::MIN_POSITIVE {
                    pp[q] = 0.0;
                    ee[q] = 0.0;
                    continue;
                }
                let (axi, ayi, azi) = (F::splat(ap.x[i]), F::splat(ap.y[i]), F::splat(ap.z[i]));
                let mut acc = F::ZERO;
                let r = bf.range(q);
                let (j, gx, gy, gz) = (&bf.j[..r.end], &bf.gx[..r.end], &bf.gy[..r.end], &bf.gz[..r.end]);
                let mut k = r.start;
                while k < r.end {
                    acc += (axi - gather(ap.x, j, k)) * load(gx, k)
                        + (ayi - gather(ap.y, j, k)) * load(gy, k)
                        + (azi - gather(ap.z, j, k)) * load(gz, k);
                    k += LANES;
                }
                let r = bb.range(q);
                let (gx, gy, gz) = (&bb.gx[..r.end], &bb.gy[..r.end], &bb.gz[..r.end]);
                let mut k = r.start;
                while k < r.end {
                    acc += axi * load(gx, k) + ayi * load(gy, k) + azi * load(gz, k);
                    k += LANES;
                }
                let res = source[i] - dt2 * sum(acc);
                pp[q] = (pp[q] + omega * res / diag[i]).max(0.0);
                ee[q] = (-res).max(0.0);
            }
        });
}

/// Relaxed Jacobi update of the active wall rows (compact arrays):
/// (Ap)_b = -dt^2 sum_f Vbar a^p_f.grad W_bf, then as [`fluid_jacobi`].
pub fn wall_jacobi(bf: &PairLists, ap: Vel, source: &[f32], diag: &[f32], dt: f32, omega: f32, p: &mut [f32]) {
    let dt2 = dt * dt;
    p.par_chunks_mut(BLOCK).zip(bf.used().par_iter()).enumerate().for_each(|(b, (pp, blk))| {
        for q in 0..pp.len() {
            let i = b * BLOCK + q;
            if diag[i].abs() < f32::MIN_POSITIVE {
                pp[q] = 0.0;
                continue;
            }
            let r = blk.range(q);
            let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
            let mut acc = F::ZERO;
            let mut k = r.start;
            while k < r.end {
                acc += gather(ap.x, j, k) * load(gx, k)
                    + gather(ap.y, j, k) * load(gy, k)
                    + gather(ap.z, j, k) * load(gz, k);
                k += LANES;
            }
            let res = source[i] + dt2 * sum(acc);
            pp[q] = (pp[q] + omega * res / diag[i]).max(0.0);
        }
    });
}
