//! The solid rows of the pressure solve, and the solids in the wall rows:
//! the pressure boundaries of elastic bodies (Band et al. 2018a, PHYSICS.md
//! §2.3; P-Eqs. 26-28), which also carry the contact of a body with the
//! walls and with other bodies.
//!
//! Notation as in [`crate::iisph`]: solid particle s (sorted order of the
//! pair lists), fluid f, wall b, another body's particle s'. A solid row's
//! pairs are SF, SB and SS; the pairs of SS within the row's own body take
//! no part (the body's own density is the elastic model's business, not the
//! pressure solve's: a soft body compressed by 10-20 % under its own weight
//! would otherwise read as a density error the fluid cannot relieve).
//!
//! - Volume: sigma_s = omega_s + sum_f V0_f W_sf + sum_b V0_b W_sb +
//!   sum_s' V0_s' W_ss', V_s = V0_s / sigma_s, with omega_s the body's own
//!   share of the row's neighbourhood: constant, from the rest lattice
//!   (`pipeline::volumes::rest_rows`).
//! - Pressure force on s (the reaction of the fluid's P-Eq. 27 for fluid
//!   pairs; a symmetric coefficient for pairs of two bodies, so that linear
//!   momentum is conserved pairwise):
//!   F_s = -sum_f V_f (p_s + p_f) g_sf - sum_b V_s (p_s + p_b) g_sb -
//!   sum_s' (V_s + V_s')/2 (p_s + p_s') g_ss', with g_ij = Vbar_ij grad W_ij
//!   after [`solid_setup`].
//! - The solid particles move within the solve with a^p_s = C F_s, C the
//!   compliance of the elastic body ((M + dt^2 K)^-1 of its implicit step),
//!   so the rows see the bodies give way as they will; `mobility` c_s is an
//!   estimate of C's diagonal for the Jacobi diagonals.
//! - Rows: S_s = 1 + dt div*_s - sigma_s with
//!   div*_s = -sum_j Vbar_sj (u*_s - u*_j).grad W_sj over SF, SB (u*_b = 0)
//!   and SS, and (Ap)_s = dt^2 sum_j g_sj.(a_s - a_j) (walls: a_b = 0).

use crate::blocks::BLOCK;
use crate::iisph::{add_relative_accel, scale_pairs, weighted_sum, Jacobi, Rows};
use crate::lanes::{pair_vectors, sum, Field3, F};
use crate::neighbors::{PairBlock, PairLists};
use crate::soa::{Vel, VelMut};
use rayon::prelude::*;

/// The neighbours of the solid rows (queries in the sorted solid order).
#[derive(Clone, Copy)]
pub struct SolidNeighbours<'a> {
    /// Solid-fluid, solid-wall (wall targets in wall order) and solid-solid
    /// (targets in the sorted solid order) pairs.
    pub sf: &'a PairLists,
    pub sb: &'a PairLists,
    pub ss: &'a PairLists,
    /// Elastic body of each solid particle (sorted order).
    pub body: &'a [u32],
    /// 1 for the solid particles that do not move (sorted order).
    pub fixed: &'a [u32],
    /// 1 for the solid particles without wall pairs in the solve (sorted
    /// order): the fixed ones, and granular ones, whose contact with walls
    /// is their own stress (`granular.rs`).
    pub no_walls: &'a [u32],
}

/// The same, to scale in place.
pub struct SolidNeighboursMut<'a> {
    pub sf: &'a mut PairLists,
    pub sb: &'a mut PairLists,
    pub ss: &'a mut PairLists,
    pub body: &'a [u32],
    pub fixed: &'a [u32],
    pub no_walls: &'a [u32],
}

/// Whether the SS pair (i, j) takes part in the solve: two bodies, not both fixed.
#[inline]
fn solid_pair(body: &[u32], fixed: &[u32], i: usize, j: usize) -> bool {
    body[i] != body[j] && (fixed[i] == 0 || fixed[j] == 0)
}

/// sum_j val_j W_ij over the SS pairs of query `i` (block query `q`) that
/// take part in the solve.
#[inline]
fn solid_pair_sum(blk: &PairBlock, q: usize, i: usize, val: &[f32], body: &[u32], fixed: &[u32]) -> f32 {
    blk.range(q)
        .filter(|&k| solid_pair(body, fixed, i, blk.j[k] as usize))
        .map(|k| val[blk.j[k] as usize] * blk.w[k])
        .sum()
}

/// Pass 4b, solid rows: sigma_s and V_s (module doc). `own` is omega_s,
/// `v0_f`, `v0_b` (every wall) and `v0_s` the rest volumes of the solve.
pub fn solid_volumes(
    nb: SolidNeighbours,
    own: &[f32],
    v0_f: &[f32],
    v0_b: &[f32],
    v0_s: &[f32],
    sigma: &mut [f32],
    vol: &mut [f32],
) {
    sigma
        .par_chunks_mut(BLOCK)
        .zip(vol.par_chunks_mut(BLOCK))
        .zip(nb.sf.used().par_iter().zip(nb.sb.used().par_iter()).zip(nb.ss.used().par_iter()))
        .enumerate()
        .for_each(|(b, ((sig, v), ((bf, bb), bs)))| {
            for q in 0..sig.len() {
                let i = b * BLOCK + q;
                let walls = if nb.no_walls[i] != 0 { 0.0 } else { weighted_sum(&bb.j, &bb.w, bb.range(q), v0_b) };
                let s = own[i]
                    + weighted_sum(&bf.j, &bf.w, bf.range(q), v0_f)
                    + walls
                    + solid_pair_sum(bs, q, i, v0_s, nb.body, nb.fixed);
                sig[q] = s;
                v[q] = if s > 0.0 { v0_s[i] / s } else { 0.0 };
            }
        });
}

/// Pass 4b, the solids' share of the wall rows: sigma_b += sum_s V0_s W_bs
/// over `bs` (active walls' solid neighbours that are not fixed), then
/// V_b = V0_b / sigma_b (`v0_b` of every wall, `active` the rows' walls).
/// `v0_free` is V0_s of each solid particle, 0 for fixed ones.
pub fn wall_solid_volumes(
    bs: &PairLists,
    active: &[u32],
    v0_b: &[f32],
    v0_free: &[f32],
    sigma: &mut [f32],
    vol: &mut [f32],
) {
    sigma.par_chunks_mut(BLOCK).zip(vol.par_chunks_mut(BLOCK)).zip(bs.used().par_iter()).enumerate().for_each(
        |(b, ((sig, v), blk))| {
            for q in 0..sig.len() {
                let w = active[b * BLOCK + q] as usize;
                let s = sig[q] + weighted_sum(&blk.j, &blk.w, blk.range(q), v0_free);
                sig[q] = s;
                v[q] = if s > 0.0 { v0_b[w] / s } else { 0.0 };
            }
        },
    );
}

/// Per-particle inputs of the solid rows.
#[derive(Clone, Copy)]
pub struct SolidRows<'a> {
    /// V_s and sigma_s of each solid (sorted order).
    pub vol: &'a [f32],
    pub sigma: &'a [f32],
    /// u*_s: the velocity each solid particle has before the pressure, m/s.
    pub u: Vel<'a>,
    /// c_s, the estimate of the compliance's diagonal, 1/kg (0 if fixed).
    pub mobility: &'a [f32],
    /// Fluid V, V/m and u*.
    pub vol_fluid: &'a [f32],
    pub vm_fluid: &'a [f32],
    pub u_fluid: Vel<'a>,
    /// V_b of every wall (0 for inactive walls), m^3.
    pub vol_wall: &'a [f32],
}

/// Pass 4c, solid rows: scales the SF, SB and SS pair gradients in place
/// by the harmonic pair volume (SS pairs within the row's body by 0, and
/// those then dropped from the list), then
/// forms the sources and the diagonals
/// a_ss = -dt^2 [ c_s max(0, (sum_j g_sj).(sum_f V_f g_sf + sum_b V_s g_sb
///                 + sum_s' (V_s + V_s')/2 g_ss'))
///               + sum_f (V_f/m_f) |g_sf|^2 + sum_s' c_s' (V_s + V_s')/2 |g_ss'|^2 ]
/// (the derivative of (Ap)_s by p_s through a_s, the fluid's a^p and the
/// other bodies' a^p; module doc).
pub fn solid_setup(nb: SolidNeighboursMut, rows: SolidRows, dt: f32, source: &mut [f32], diag: &mut [f32]) {
    let dt2 = dt * dt;
    let (body, fixed) = (nb.body, nb.fixed);
    source
        .par_chunks_mut(BLOCK)
        .zip(diag.par_chunks_mut(BLOCK))
        .zip(nb.sf.used_mut().par_iter_mut().zip(nb.sb.used_mut().par_iter_mut()).zip(nb.ss.used_mut().par_iter_mut()))
        .enumerate()
        .for_each(|(b, ((src, dg), ((bf, bb), bs)))| {
            // The SS pairs scaled by their harmonic pair volume, and those
            // scaled to 0 (within one body, both fixed, or a particle
            // without volume) dropped: they add nothing to the solve's sums
            // but were visited in every sweep's force and Jacobi update;
            // with one body, every SS pair (Example 1 at d = 4 mm: 1.06 M,
            // 32 a solid particle).
            bs.scale_retain_nonzero(|q, j| {
                let i = b * BLOCK + q;
                let (vi, vj, takes_part) = (rows.vol[i], rows.vol[j], solid_pair(body, fixed, i, j));
                if takes_part && vi * vj > 0.0 {
                    2.0 * vi * vj / (vi + vj)
                } else {
                    0.0
                }
            });
            for (q, (src, dg)) in src.iter_mut().zip(dg.iter_mut()).enumerate() {
                let i = b * BLOCK + q;
                let vi = rows.vol[i];
                scale_pairs(bf, q, vi, rows.vol_fluid);
                if nb.no_walls[i] != 0 {
                    // A fixed (or granular) particle and a wall: no pair of the solve.
                    scale_pairs(bb, q, 0.0, rows.vol_wall);
                } else {
                    scale_pairs(bb, q, vi, rows.vol_wall);
                }
                let ui = [rows.u.x[i], rows.u.y[i], rows.u.z[i]];
                // Fluid pairs (SIMD).
                let (mut div, mut g_all, mut g_force, mut s2) = {
                    let u = rows.u_fluid;
                    let (uxi, uyi, uzi) = (F::splat(ui[0]), F::splat(ui[1]), F::splat(ui[2]));
                    let (mut d, mut sx, mut sy, mut sz) = (F::ZERO, F::ZERO, F::ZERO, F::ZERO);
                    let (mut fx, mut fy, mut fz, mut q2) = (F::ZERO, F::ZERO, F::ZERO, F::ZERO);
                    for pv in pair_vectors(&bf.j, bf.range(q)) {
                        let (x, y, z) = (pv.load(&bf.gx), pv.load(&bf.gy), pv.load(&bf.gz));
                        d -= (uxi - pv.gather(u.x)) * x + (uyi - pv.gather(u.y)) * y + (uzi - pv.gather(u.z)) * z;
                        let v = pv.gather(rows.vol_fluid);
                        sx += x;
                        sy += y;
                        sz += z;
                        fx += v * x;
                        fy += v * y;
                        fz += v * z;
                        q2 += pv.gather(rows.vm_fluid) * (x * x + y * y + z * z);
                    }
                    (sum(d), [sum(sx), sum(sy), sum(sz)], [sum(fx), sum(fy), sum(fz)], sum(q2))
                };
                // Wall pairs: u*_b = 0, force coefficient V_s.
                for k in bb.range(q) {
                    let g = [bb.gx[k], bb.gy[k], bb.gz[k]];
                    div -= ui[0] * g[0] + ui[1] * g[1] + ui[2] * g[2];
                    for c in 0..3 {
                        g_all[c] += g[c];
                        g_force[c] += vi * g[c];
                    }
                }
                // Other bodies' pairs: force coefficient (V_s + V_s') / 2.
                for k in bs.range(q) {
                    let j = bs.j[k] as usize;
                    let g = [bs.gx[k], bs.gy[k], bs.gz[k]];
                    let uj = [rows.u.x[j], rows.u.y[j], rows.u.z[j]];
                    div -= (ui[0] - uj[0]) * g[0] + (ui[1] - uj[1]) * g[1] + (ui[2] - uj[2]) * g[2];
                    let c = 0.5 * (vi + rows.vol[j]);
                    for a in 0..3 {
                        g_all[a] += g[a];
                        g_force[a] += c * g[a];
                    }
                    s2 += rows.mobility[j] * c * (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
                }
                // The own term is the row's push on itself through its own
                // motion. The pair coefficients of F_s differ (V_f, V_s) so
                // that F_s is the exact reaction of the fluid's force, and
                // where the pairs on opposite sides have different ones
                // (a wall on one side, a partly absorbed particle of small V_f
                // on the other) the product can vanish or turn positive
                // (measured: 4.5e-17 on a solid particle with two fluid and
                // one wall pair, whose relaxed update then sent p_s to
                // 1.7e15 Pa): the term is taken at least 0.
                let own =
                    rows.mobility[i] * (g_all[0] * g_force[0] + g_all[1] * g_force[1] + g_all[2] * g_force[2]).max(0.0);
                *src = 1.0 + dt * div - rows.sigma[i];
                *dg = -dt2 * (own + s2);
            }
        });
}

/// The solids' share of the wall rows (after `iisph::wall_setup`, which
/// set them up from their fluid pairs): scales the wall-solid pair
/// gradients by the harmonic pair volume (0 for fixed solid particles:
/// `vol_solid` holds 0 for them), then adds dt sum_s g_bs.u*_s to the
/// sources and -dt^2 sum_s c_s V_s |g_bs|^2 (d(a_s)/dp_b) to the
/// diagonals. `vol_wall` is V_b of the active walls (the rows' order).
#[allow(clippy::too_many_arguments)]
pub fn wall_solid_setup(
    bs: &mut PairLists,
    vol_wall: &[f32],
    vol_solid: &[f32],
    u_solid: Vel,
    mobility: &[f32],
    dt: f32,
    source: &mut [f32],
    diag: &mut [f32],
) {
    let dt2 = dt * dt;
    source
        .par_chunks_mut(BLOCK)
        .zip(diag.par_chunks_mut(BLOCK))
        .zip(bs.used_mut().par_iter_mut())
        .enumerate()
        .for_each(|(b, ((src, dg), blk))| {
            for (q, (src, dg)) in src.iter_mut().zip(dg.iter_mut()).enumerate() {
                let i = b * BLOCK + q;
                scale_pairs(blk, q, vol_wall[i], vol_solid);
                let (mut div, mut s2) = (0.0f32, 0.0f32);
                for k in blk.range(q) {
                    let j = blk.j[k] as usize;
                    let g = [blk.gx[k], blk.gy[k], blk.gz[k]];
                    div += u_solid.x[j] * g[0] + u_solid.y[j] * g[1] + u_solid.z[j] * g[2];
                    s2 += mobility[j] * vol_solid[j] * (g[0] * g[0] + g[1] * g[1] + g[2] * g[2]);
                }
                *src += dt * div;
                *dg -= dt2 * s2;
            }
        });
}

/// The pressure force F_s on every solid particle (module doc), N.
/// `p_wall` holds every wall's pressure.
pub fn solid_force(
    nb: SolidNeighbours,
    p_s: &[f32],
    p_f: &[f32],
    p_wall: &[f32],
    vol_f: &[f32],
    vol_s: &[f32],
    out: VelMut,
) {
    out.x
        .par_chunks_mut(BLOCK)
        .zip(out.y.par_chunks_mut(BLOCK))
        .zip(out.z.par_chunks_mut(BLOCK))
        .zip(nb.sf.used().par_iter().zip(nb.sb.used().par_iter()).zip(nb.ss.used().par_iter()))
        .enumerate()
        .for_each(|(b, (((ox, oy), oz), ((bf, bb), bs)))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let ps = F::splat(p_s[i]);
                let (mut sx, mut sy, mut sz) = (F::ZERO, F::ZERO, F::ZERO);
                for v in pair_vectors(&bf.j, bf.range(q)) {
                    let c = v.gather(vol_f) * (ps + v.gather(p_f));
                    sx += c * v.load(&bf.gx);
                    sy += c * v.load(&bf.gy);
                    sz += c * v.load(&bf.gz);
                }
                let mut f = [sum(sx), sum(sy), sum(sz)];
                for k in bb.range(q) {
                    let c = vol_s[i] * (p_s[i] + p_wall[bb.j[k] as usize]);
                    f[0] += c * bb.gx[k];
                    f[1] += c * bb.gy[k];
                    f[2] += c * bb.gz[k];
                }
                for k in bs.range(q) {
                    let j = bs.j[k] as usize;
                    let c = 0.5 * (vol_s[i] + vol_s[j]) * (p_s[i] + p_s[j]);
                    f[0] += c * bs.gx[k];
                    f[1] += c * bs.gy[k];
                    f[2] += c * bs.gz[k];
                }
                ox[q] = -f[0];
                oy[q] = -f[1];
                oz[q] = -f[2];
            }
        });
}

/// Relaxed Jacobi update of the solid rows (P-Eq. 28): (Ap)_s = dt^2
/// [sum_f g_sf.(a_s - a_f) + sum_b g_sb.a_s + sum_s' g_ss'.(a_s - a_s')],
/// r_s = S_s - (Ap)_s, p_s <- max(0, p_s + omega r_s / a_ss). Writes
/// max(-r_s, 0) (the predicted compression) to `err`.
#[allow(clippy::too_many_arguments)]
pub fn solid_jacobi(
    nb: SolidNeighbours,
    a_s: Vel,
    a_f: impl Field3,
    rows: Rows,
    jac: Jacobi,
    p: &mut [f32],
    err: &mut [f32],
) {
    let dt2 = jac.dt * jac.dt;
    p.par_chunks_mut(BLOCK)
        .zip(err.par_chunks_mut(BLOCK))
        .zip(nb.sf.used().par_iter().zip(nb.sb.used().par_iter()).zip(nb.ss.used().par_iter()))
        .enumerate()
        .for_each(|(b, ((pp, ee), ((bf, bb), bs)))| {
            for (q, (p, e)) in pp.iter_mut().zip(ee.iter_mut()).enumerate() {
                let i = b * BLOCK + q;
                if rows.diag[i].abs() < f32::MIN_POSITIVE {
                    *p = 0.0;
                    *e = 0.0;
                    continue;
                }
                let ai = [a_s.x[i], a_s.y[i], a_s.z[i]];
                let (axi, ayi, azi) = (F::splat(ai[0]), F::splat(ai[1]), F::splat(ai[2]));
                let mut acc = F::ZERO;
                add_relative_accel(&mut acc, bf, bf.range(q), [axi, ayi, azi], a_f);
                let mut acc = sum(acc);
                for k in bb.range(q) {
                    acc += ai[0] * bb.gx[k] + ai[1] * bb.gy[k] + ai[2] * bb.gz[k];
                }
                for k in bs.range(q) {
                    let j = bs.j[k] as usize;
                    acc +=
                        (ai[0] - a_s.x[j]) * bs.gx[k] + (ai[1] - a_s.y[j]) * bs.gy[k] + (ai[2] - a_s.z[j]) * bs.gz[k];
                }
                let res = rows.source[i] - dt2 * acc;
                *p = (*p + jac.omega * res / rows.diag[i]).max(0.0);
                *e = (-res).max(0.0);
            }
        });
}
