//! Pass 11 (PHYSICS.md §6): the drift momentum term of the mixture,
//! a^Dm_i = -(1/rho_i) div( sum_k alpha_k rho_k u_mk (x) u_mk ) (Manninen et
//! al. 1996; PHYSICS.md §4.1), in the symmetric SPH form
//!
//! a^Dm_i = -(1/rho_i) sum_j Vbar_ij sum_k rho_k [ alpha_k,i u_mk,i (u_mk,i . grad W_ij)
//!                                              + alpha_k,j u_mk,j (u_mk,j . grad W_ij) ],
//!
//! over fluid neighbours, with rho_i the rest mixture density rho_fm,i. As
//! m_i / rho_fm,i = h^3 for every particle and the bracket is symmetric in
//! i and j, the pair forces cancel: the term conserves momentum.
//!
//! Sign (PHYSICS.md §8.15): the mixture momentum equation has the minus
//! sign above; the reference codes [RG] and [AC] add the term with a plus
//! sign. `sign` is -1 for the physical form, +1 for the codes' form.

use crate::blocks::BLOCK;
use crate::lanes::{pair_vectors, sum, Packed, F};
use crate::neighbors::PairLists;
use crate::phases::PhaseVel;
use crate::soa::VelMut;
use rayon::prelude::*;

/// Inputs of [`drift_momentum`].
pub struct DriftMomentumInput<'a> {
    /// Fluid-fluid pairs holding Vbar_ij grad W_ij (after
    /// `iisph::scale_by_pair_volume`).
    pub ff: &'a PairLists,
    /// Volume fraction alpha_k per phase.
    pub alpha: &'a [&'a [f32]],
    /// Drift velocity u_mk per phase, m/s.
    pub u_drift: PhaseVel<'a>,
    /// Rest density rho_k per phase, kg/m^3.
    pub density: &'a [f32],
    /// Rest mixture density rho_fm per particle, kg/m^3.
    pub rest_density: &'a [f32],
    /// -1: the physical sign; +1: the sign of [RG] and [AC].
    pub sign: f32,
}

/// a^Dm per particle, m/s^2 (module doc). The phases enter through the
/// symmetric tensor T_i = sum_k rho_k alpha_k,i u_mk,i (x) u_mk,i of each
/// particle, so that a pair reads T_j whatever the number of phases: the
/// bracket of the module doc summed over k is (T_i + T_j) . grad W_ij.
/// `t` is scratch for T, packed ([`Packed`]; each the particle count):
/// the diagonal (xx, yy, zz) and the rest (xy, xz, yz), two 16-byte loads
/// a pair instead of six gathers.
pub fn drift_momentum(inp: &DriftMomentumInput, out: VelMut, t: [&mut [Packed]; 2]) {
    let np = inp.alpha.len();
    let u = inp.u_drift;
    let [diag, off] = t;
    diag.par_chunks_mut(BLOCK).zip(off.par_chunks_mut(BLOCK)).enumerate().for_each(|(b, (dg, of))| {
        for q in 0..dg.len() {
            let i = b * BLOCK + q;
            let mut m = [0.0f32; 6];
            for k in 0..np {
                let c = inp.density[k] * inp.alpha[k][i];
                let (ux, uy, uz) = (u.x[k][i], u.y[k][i], u.z[k][i]);
                let (cx, cy, cz) = (c * ux, c * uy, c * uz);
                m[0] += cx * ux;
                m[1] += cy * uy;
                m[2] += cz * uz;
                m[3] += cx * uy;
                m[4] += cx * uz;
                m[5] += cy * uz;
            }
            dg[q] = [m[0], m[1], m[2], 0.0];
            of[q] = [m[3], m[4], m[5], 0.0];
        }
    });
    let (diag, off) = (&*diag, &*off);
    out.x
        .par_chunks_mut(BLOCK)
        .zip(out.y.par_chunks_mut(BLOCK))
        .zip(out.z.par_chunks_mut(BLOCK))
        .zip(inp.ff.used().par_iter())
        .enumerate()
        .for_each(|(b, (((ox, oy), oz), blk))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let (mut ax, mut ay, mut az) = (F::ZERO, F::ZERO, F::ZERO);
                let (mut sx, mut sy, mut sz) = (F::ZERO, F::ZERO, F::ZERO);
                for v in pair_vectors(&blk.j, blk.range(q)) {
                    let (x, y, z) = (v.load(&blk.gx), v.load(&blk.gy), v.load(&blk.gz));
                    sx += x;
                    sy += y;
                    sz += z;
                    let [xx, yy, zz] = v.gather3(diag);
                    let [xy, xz, yz] = v.gather3(off);
                    ax += xx * x + xy * y + xz * z;
                    ay += xy * x + yy * y + yz * z;
                    az += xz * x + yz * y + zz * z;
                }
                // The particle's own terms: T_i . sum_j g_ij.
                let (sx, sy, sz) = (sum(sx), sum(sy), sum(sz));
                let ([txx, tyy, tzz, _], [txy, txz, tyz, _]) = (diag[i], off[i]);
                let a = [
                    sum(ax) + txx * sx + txy * sy + txz * sz,
                    sum(ay) + txy * sx + tyy * sy + tyz * sz,
                    sum(az) + txz * sx + tyz * sy + tzz * sz,
                ];
                let rho = inp.rest_density[i];
                let c = if rho > 0.0 { inp.sign / rho } else { 0.0 };
                (ox[q], oy[q], oz[q]) = (c * a[0], c * a[1], c * a[2]);
            }
        });
}
