//! Volume fractions of the mixture (PHYSICS.md §4.1): pass 12, the transport
//! of P-Eq. 2 in the symmetric form, and pass 14, the correction that
//! restores sum_k alpha_k = 1 (P §6.4).
//!
//! The transport reads the fractions of the step's start and writes new ones
//! to a second buffer (double-buffered), at the old positions; the
//! correction then writes the corrected fractions back.
//!
//! Two forms of the transport ([inferred]; the scene key
//! `simulation.phase_transport` picks one):
//! - [`transport_reference`]: P-Eq. 2 exactly as [RG], [AC] and
//!   PHYSICS.md §4.1 write it, with the fluxes alpha_k u_mk and the term
//!   (alpha_k,i + alpha_k,j)/2 (u_m,j - u_m,i) for alpha_k div u_m. Each
//!   phase's volume sum_i h^3 alpha_k,i drifts: the fluxes alpha_k u_mk of
//!   all phases do not add up to 0, the centred pair flux (F_i + F_j)/2 can
//!   empty a particle below 0, and the symmetric divergence term exchanges
//!   fractions between particles wherever the velocity field expands; the
//!   correction's clamp and renormalisation then add or remove volume
//!   (1.2 % of a phase's volume in the 600 steps, 1.2 s, of the coarse
//!   mixing scene in `tests/mixture.rs`).
//! - [`transport`], the default, "conservative": (1) the fluxes are
//!   F_k = alpha_k (u_mk - j), the phase velocity relative to the
//!   volume-averaged velocity (see `drift`), which add up to 0 in every
//!   particle and every pair; (2) the alpha_k div u_m term is left out: it
//!   belongs to a particle whose volume changes, but IISPH holds every
//!   particle's volume at alpha_f h^3 (div u_m = 0 up to the solver
//!   tolerance), and with sum_k F_k = 0 the correction's renormalisation
//!   would remove it again anyway; (3) a positivity limiter
//!   ([`outflow_limit`], [`pair_limit`]) scales each pair flux, by the same
//!   factor for all phases, so that no particle loses more of a phase than
//!   it holds. Each pair flux is then antisymmetric and adds up to 0 over
//!   the phases, so every phase's volume is conserved and sum_k alpha_k
//!   stays 1 to rounding (each phase's volume changes by 2e-11 in the same
//!   600 steps: the rounding of each particle's f32 sum of pair fluxes,
//!   with the new fraction computed in f64 from the stored fraction and
//!   its low part, `phases::join`; 2e-8 when the fractions were f32
//!   alone); the limiter acts only where a phase runs out (a settling
//!   front), not in a uniform bulk.

use crate::blocks::BLOCK;
use crate::iisph::Vel;
use crate::lanes::{gather, load, store, sum, F, LANES};
use crate::neighbors::PairLists;
use crate::phases::{join, split};
use rayon::prelude::*;
use wide::Select;

/// Pass 12, conservative transport, step 1 for phase k: the pair fluxes
/// phi_k,ij = (F_k,i + F_k,j) . Vbar_ij grad W_ij, stored per pair in
/// `pair_flux` (`pair_flux[b]` for block b of `ff`, in its pair order), and
/// the outflow limit lambda_k,i = min(1, alpha_k,i / (dt O_k,i)), where
/// O_k,i = sum_j max(phi_k,ij, 0) is the rate at which phase k leaves
/// particle i (1 where nothing leaves). `flux` is F_k.
pub fn outflow_limit(ff: &PairLists, alpha_k: &[f32], flux: Vel, dt: f32, out: &mut [f32], pair_flux: &mut [Vec<f32>]) {
    out.par_chunks_mut(BLOCK).zip(ff.used().par_iter().zip(pair_flux.par_iter_mut())).enumerate().for_each(
        |(b, (o, (blk, phi_out)))| {
            phi_out.clear();
            phi_out.resize(blk.len(), 0.0);
            for (q, o) in o.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                let (fxi, fyi, fzi) = (F::splat(flux.x[i]), F::splat(flux.y[i]), F::splat(flux.z[i]));
                let mut acc = F::ZERO;
                let r = blk.range(q);
                let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
                let mut p = r.start;
                while p < r.end {
                    let phi = (gather(flux.x, j, p) + fxi) * load(gx, p)
                        + (gather(flux.y, j, p) + fyi) * load(gy, p)
                        + (gather(flux.z, j, p) + fzi) * load(gz, p);
                    store(phi_out, p, phi);
                    acc += phi.max(F::ZERO);
                    p += LANES;
                }
                let leaving = dt * sum(acc);
                *o = if leaving > alpha_k[i] { alpha_k[i].max(0.0) / leaving } else { 1.0 };
            }
        },
    );
}

/// Pass 12, conservative transport, step 2: the limit of every pair,
/// Lambda_ij = min over phases k of the outflow limit of the particle that
/// phase k leaves in that pair (lambda_k,i if phi_k,ij > 0, lambda_k,j if
/// phi_k,ij < 0). It is the same for all phases and for (i, j) and (j, i),
/// so the limited pair fluxes stay antisymmetric and add up to 0 over the
/// phases, and no particle loses more of a phase than it holds (a particle
/// without phase k still receives it: there k leaves the other particle).
/// `pair_flux[k]` and `limit[k]` are the phi_k and lambda_k of
/// [`outflow_limit`]; `out[b]` gets the limits of block b's pairs.
pub fn pair_limit(ff: &PairLists, pair_flux: &[&[Vec<f32>]], limit: &[&[f32]], out: &mut [Vec<f32>]) {
    out.par_iter_mut().zip(ff.used().par_iter()).enumerate().for_each(|(b, (o, blk))| {
        o.clear();
        o.resize(blk.len(), 1.0);
        let nq = blk.start.len().saturating_sub(1);
        for q in 0..nq {
            let i = b * BLOCK + q;
            let r = blk.range(q);
            let j = &blk.j[..r.end];
            let mut p = r.start;
            while p < r.end {
                let mut lam = F::splat(1.0);
                for (phi, l) in pair_flux.iter().zip(limit) {
                    let phi = load(&phi[b], p);
                    // phi > 0: phase k leaves i; phi < 0: it leaves j; 0: no limit.
                    let from_j = Select::select(phi.simd_lt(F::ZERO), gather(l, j, p), F::splat(1.0));
                    lam = lam.min(Select::select(phi.simd_gt(F::ZERO), F::splat(l[i]), from_j));
                }
                store(o, p, lam);
                p += LANES;
            }
        }
    });
}

/// Pass 12, conservative transport, step 3 for phase k (the default; see the
/// module doc): the drift part of P-Eq. 2 in the symmetric form,
///
/// dalpha_k,i/dt = -sum_j Lambda_ij (F_k,i + F_k,j) . Vbar_ij grad W_ij,
///
/// over fluid neighbours, then alpha_k^{n+1} = alpha_k + dt dalpha_k/dt,
/// in f64 from the stored fraction `alpha_k` + `alpha_lo`
/// (`phases::join`). F_k = alpha_k (u_mk - j) is the volume-weighted phase
/// flux of `drift::drift_velocity`; `pair_flux` holds the pair fluxes
/// phi_k,ij of [`outflow_limit`] and `pair_limit` the Lambda_ij of
/// [`pair_limit`].
pub fn transport(
    ff: &PairLists,
    alpha_k: &[f32],
    alpha_lo: &[f32],
    pair_flux: &[Vec<f32>],
    pair_limit: &[Vec<f32>],
    dt: f32,
    out: &mut [f64],
) {
    out.par_chunks_mut(BLOCK)
        .zip(ff.used().par_iter().zip(pair_flux.par_iter().zip(pair_limit.par_iter())))
        .enumerate()
        .for_each(|(b, (o, (blk, (phi, lim))))| {
            for (q, o) in o.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                let mut acc = F::ZERO;
                let r = blk.range(q);
                let mut p = r.start;
                while p < r.end {
                    acc += load(phi, p) * load(lim, p);
                    p += LANES;
                }
                *o = join(alpha_k[i], alpha_lo[i]) - f64::from(dt) * f64::from(sum(acc));
            }
        });
}

/// Pass 12 for one phase k, the reference form: P-Eq. 2 in the symmetric
/// form of [RG] and [AC] exactly as PHYSICS.md §4.1 writes it,
///
/// dalpha_k,i/dt = -sum_j Vbar_ij [ (alpha_k,i + alpha_k,j)/2 (u_m,j - u_m,i)
///                                  + (F_k,j + F_k,i) ] . grad W_ij,
///
/// with F_k = alpha_k u_mk, then alpha_k^{n+1} = alpha_k + dt dalpha_k/dt
/// (in f64 from `alpha_k` + `alpha_lo`, as [`transport`]).
/// `u` is the mixture velocity u_m at the step's start.
pub fn transport_reference(
    ff: &PairLists,
    u: Vel,
    alpha_k: &[f32],
    alpha_lo: &[f32],
    flux: Vel,
    dt: f32,
    out: &mut [f64],
) {
    let half = F::splat(0.5);
    out.par_chunks_mut(BLOCK).zip(ff.used().par_iter()).enumerate().for_each(|(b, (o, blk))| {
        for (q, o) in o.iter_mut().enumerate() {
            let i = b * BLOCK + q;
            let ai = alpha_k[i];
            let (vai, uxi, uyi, uzi) = (F::splat(ai), F::splat(u.x[i]), F::splat(u.y[i]), F::splat(u.z[i]));
            let (fxi, fyi, fzi) = (F::splat(flux.x[i]), F::splat(flux.y[i]), F::splat(flux.z[i]));
            let mut acc = F::ZERO;
            let r = blk.range(q);
            let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
            let mut p = r.start;
            while p < r.end {
                let c = half * (vai + gather(alpha_k, j, p));
                let vx = c * (gather(u.x, j, p) - uxi) + gather(flux.x, j, p) + fxi;
                let vy = c * (gather(u.y, j, p) - uyi) + gather(flux.y, j, p) + fyi;
                let vz = c * (gather(u.z, j, p) - uzi) + gather(flux.z, j, p) + fzi;
                acc += vx * load(gx, p) + vy * load(gy, p) + vz * load(gz, p);
                p += LANES;
            }
            *o = join(ai, alpha_lo[i]) - f64::from(dt) * f64::from(sum(acc));
        }
    });
}

/// Pass 14, first half of the correction (P §6.4, PHYSICS.md §4.1): per
/// particle, the sum of the clamped fractions sum_k max(alpha_k, 0), and
/// the phase with the largest fraction before clamping (the fallback when
/// every fraction is <= 0; the first such phase on ties).
pub fn correction_sums(alpha: &[&[f64]], total: &mut [f64], largest: &mut [u32]) {
    total.par_chunks_mut(BLOCK).zip(largest.par_chunks_mut(BLOCK)).enumerate().for_each(|(b, (t, l))| {
        for q in 0..t.len() {
            let i = b * BLOCK + q;
            let mut s = 0.0f64;
            let mut best = 0usize;
            for (k, a) in alpha.iter().enumerate() {
                s += a[i].max(0.0);
                if a[i] > alpha[best][i] {
                    best = k;
                }
            }
            t[q] = s;
            l[q] = best as u32;
        }
    });
}

/// Pass 14, second half, for phase k: negative fractions become 0, the rest
/// are divided by `total` so that they sum to 1; where every fraction was
/// <= 0, the phase `largest` gets 1 and the others 0. Reads
/// `alpha_next` (the transported fraction of phase k, f64), writes the
/// store's `out` and `out_lo` (`phases::split`).
pub fn correct(alpha_next: &[f64], total: &[f64], largest: &[u32], k: usize, out: &mut [f32], out_lo: &mut [f32]) {
    out.par_chunks_mut(BLOCK).zip(out_lo.par_chunks_mut(BLOCK)).enumerate().for_each(|(b, (o, lo))| {
        for (q, (v, l)) in o.iter_mut().zip(lo.iter_mut()).enumerate() {
            let i = b * BLOCK + q;
            let c = if (total[i] - 1.0).abs() <= 2.0 * f64::EPSILON {
                // Already normalised up to rounding: dividing by a total one
                // ulp off 1 would only add a rounding bias (a drift of each
                // phase's volume over thousands of steps).
                alpha_next[i].max(0.0)
            } else if total[i] > 0.0 {
                alpha_next[i].max(0.0) / total[i]
            } else if largest[i] as usize == k {
                1.0
            } else {
                0.0
            };
            (*v, *l) = split(c);
        }
    });
}
