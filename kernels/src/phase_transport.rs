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
//!   would remove it again anyway; (3) a positivity limiter (the outflow
//!   and pair limits of [`transport`]) scales each pair flux, by the same
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
use crate::lanes::{pair_vectors, sum, Packed, F, LANES};
use crate::neighbors::{PairBlock, PairLists};
use crate::phases::{join, split, PhaseVel};
use crate::soa::Vel;
use rayon::prelude::*;
use wide::Select;

/// Phases handled together in one pass over the pairs; more are done in
/// groups of this many.
const GROUP: usize = 8;

/// Per-step scratch of [`transport`] (from the step's arena), `np` the
/// number of phases, `n` of particles.
pub struct TransportScratch<'a> {
    /// Outflow limits lambda_k,i, particle-major (`i np + k`).
    pub limit: &'a mut [f32],
    /// Unlimited net outflow sum_j phi_k,ij, particle-major.
    pub net: &'a mut [f32],
    /// min_k lambda_k,i, per particle.
    pub least: &'a mut [f32],
    /// The fluxes F_k packed (`[x, y, z, 0]`), phase k at `[k n, (k + 1)
    /// n)`: the pair loops read a neighbour's flux with one 16-byte load
    /// instead of three gathers.
    pub flux: &'a mut [Packed],
    /// Per particle: limited or next to a limited particle.
    pub near: &'a mut [bool],
}

/// Pass 12, the conservative transport of every phase (the default; see
/// the module doc), in one pass over the pairs for all phases:
///
/// dalpha_k,i/dt = -sum_j Lambda_ij phi_k,ij,  phi_k,ij = (F_k,i + F_k,j) . Vbar_ij grad W_ij,
///
/// then alpha_k^{n+1} = alpha_k + dt dalpha_k/dt in f64 from the stored
/// fraction `alpha[k]` + `lo[k]` (`phases::join`), into `out` (phase k at
/// `[k n, (k + 1) n)`). F_k = alpha_k (u_mk - j) is the volume-weighted
/// phase flux of `drift::drift_velocity`.
///
/// The positivity limiter: lambda_k,i = min(1, alpha_k,i / (dt O_k,i)),
/// O_k,i = sum_j max(phi_k,ij, 0) the rate at which phase k leaves i (1
/// where nothing leaves); the pair limit Lambda_ij = min over phases k of
/// the outflow limit of the particle that phase k leaves in that pair
/// (lambda_k,i if phi_k,ij > 0, lambda_k,j if phi_k,ij < 0). It is the same
/// for all phases and for (i, j) and (j, i), so the limited pair fluxes
/// stay antisymmetric and add up to 0 over the phases, and no particle
/// loses more of a phase than it holds (a particle without phase k still
/// receives it: there k leaves the other particle).
///
/// Where neither i nor any neighbour is limited (every lambda 1), every
/// Lambda_ij is 1 and the sum is the unlimited net outflow of the first
/// pass; only particles next to a limited one go over their pairs again
/// with the pair limits. The pair fluxes are not stored: the arithmetic is
/// that of storing them (same expressions, same order), so the result is
/// bit for bit that of the three-pass form (fluxes, pair limits, sums) that
/// `kernels/tests/mixture.rs` keeps as its reference.
pub fn transport(
    ff: &PairLists,
    alpha: &[&[f32]],
    lo: &[&[f32]],
    flux: PhaseVel,
    dt: f32,
    scratch: TransportScratch,
    out: &mut [f64],
) {
    let np = alpha.len();
    let n = out.len() / np.max(1);
    if np == 0 || n == 0 {
        return;
    }
    let TransportScratch { limit, net, least, flux: packed, near } = scratch;
    pack_fluxes(flux, n, packed);
    let flux = Fluxes { packed, n };
    outflow(ff, alpha, flux, dt, limit, net, least);
    let near = near_limited(ff, least, near);
    // The limited sums replace the unlimited ones in `net` (a particle's
    // own entries: no other particle reads them); both are f32 sums.
    let limit: &[f32] = limit;
    net.par_chunks_mut(BLOCK * np).zip(ff.used().par_iter()).enumerate().for_each(|(b, (s, blk))| {
        for q in 0..s.len() / np {
            let i = b * BLOCK + q;
            if near[i] {
                limited_sums(blk, q, i, flux, limit, np, &mut s[q * np..(q + 1) * np]);
            }
        }
    });
    for (k, out) in out.chunks_mut(n).enumerate() {
        let (a, lo, net) = (alpha[k], lo[k], &*net);
        out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
            for (q, o) in o.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                *o = join(a[i], lo[i]) - f64::from(dt) * f64::from(net[i * np + k]);
            }
        });
    }
}

/// Every phase's flux F_k packed, phase k at `[k n, (k + 1) n)`.
#[derive(Clone, Copy)]
struct Fluxes<'a> {
    packed: &'a [Packed],
    n: usize,
}

impl<'a> Fluxes<'a> {
    /// Phase k's fluxes.
    #[inline(always)]
    fn phase(self, k: usize) -> &'a [Packed] {
        &self.packed[k * self.n..(k + 1) * self.n]
    }
}

/// The fluxes `flux` packed into `out` (phase k at `[k n, (k + 1) n)`).
fn pack_fluxes(flux: PhaseVel, n: usize, out: &mut [Packed]) {
    for (k, out) in out.chunks_mut(n).enumerate() {
        let (x, y, z) = (flux.x[k], flux.y[k], flux.z[k]);
        out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
            for (q, o) in o.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                *o = [x[i], y[i], z[i], 0.0];
            }
        });
    }
}

/// The particles that go over their pairs again in [`transport`]: those
/// with a limit below 1 and their neighbours, marked from the limited
/// particles' own pairs (few, where a phase runs out) into `near`. The
/// lists are symmetric (j is i's neighbour if i is j's: the same distance
/// test, negated differences), and an inner list `ffb` holds every
/// neighbour of a particle that has any (`copy_scaled_where`), which a
/// limited particle has: only a nonzero pair flux limits. Marking a
/// particle without a limited neighbour would be harmless: with every
/// Lambda_ij = 1, [`limited_sums`] repeats the unlimited sum.
fn near_limited<'a>(ff: &PairLists, least: &[f32], near: &'a mut [bool]) -> &'a [bool] {
    near.fill(false);
    if !least.par_iter().any(|&l| l < 1.0) {
        return near;
    }
    let blocks = ff.used();
    for (i, _) in least.iter().enumerate().filter(|(_, &l)| l < 1.0) {
        near[i] = true;
        let blk = &blocks[i / BLOCK];
        for &j in &blk.j[blk.range(i % BLOCK)] {
            near[j as usize] = true;
        }
    }
    near
}

/// The first pass of [`transport`]: per particle and phase, the outflow
/// limit lambda_k,i and the unlimited net outflow sum_j phi_k,ij; and the
/// least limit of each particle.
fn outflow(
    ff: &PairLists,
    alpha: &[&[f32]],
    flux: Fluxes,
    dt: f32,
    limit: &mut [f32],
    net: &mut [f32],
    least: &mut [f32],
) {
    let np = alpha.len();
    limit
        .par_chunks_mut(BLOCK * np)
        .zip(net.par_chunks_mut(BLOCK * np))
        .zip(least.par_chunks_mut(BLOCK))
        .zip(ff.used().par_iter())
        .enumerate()
        .for_each(|(b, (((l, s), m), blk))| {
            for (q, m) in m.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                let r = blk.range(q);
                let (j, gx, gy, gz) = (&blk.j[..r.end], &blk.gx[..r.end], &blk.gy[..r.end], &blk.gz[..r.end]);
                let pairs = Pairs { r, j, gx, gy, gz };
                for k0 in (0..np).step_by(GROUP) {
                    let g = (np - k0).min(GROUP);
                    let (l, s) = (&mut l[q * np + k0..q * np + k0 + g], &mut s[q * np + k0..q * np + k0 + g]);
                    let a = &alpha[k0..k0 + g];
                    match g {
                        1 => outflow_group::<1>(&pairs, i, k0, a, flux, dt, l, s),
                        2 => outflow_group::<2>(&pairs, i, k0, a, flux, dt, l, s),
                        3 => outflow_group::<3>(&pairs, i, k0, a, flux, dt, l, s),
                        4 => outflow_group::<4>(&pairs, i, k0, a, flux, dt, l, s),
                        5 => outflow_group::<5>(&pairs, i, k0, a, flux, dt, l, s),
                        6 => outflow_group::<6>(&pairs, i, k0, a, flux, dt, l, s),
                        7 => outflow_group::<7>(&pairs, i, k0, a, flux, dt, l, s),
                        _ => outflow_group::<GROUP>(&pairs, i, k0, a, flux, dt, l, s),
                    }
                }
                *m = l[q * np..(q + 1) * np].iter().fold(1.0f32, |m, &x| m.min(x));
            }
        });
}

/// One particle's pairs: its range `r` in the block's lists.
struct Pairs<'a> {
    r: std::ops::Range<usize>,
    j: &'a [u32],
    gx: &'a [f32],
    gy: &'a [f32],
    gz: &'a [f32],
}

/// [`outflow`] for the `G` phases `k0..k0 + G` of particle i, whose
/// fractions are `alpha`: the outflow limits into `l`, the net outflows
/// into `s`. `G` a constant, so that the per-phase sums stay in registers.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
fn outflow_group<const G: usize>(
    pairs: &Pairs,
    i: usize,
    k0: usize,
    alpha: &[&[f32]],
    flux: Fluxes,
    dt: f32,
    l: &mut [f32],
    s: &mut [f32],
) {
    let Pairs { r, j, gx, gy, gz } = pairs;
    let fk: [&[Packed]; G] = std::array::from_fn(|k| flux.phase(k0 + k));
    let fi: [[F; 3]; G] = std::array::from_fn(|k| {
        let [x, y, z, _] = fk[k][i];
        [F::splat(x), F::splat(y), F::splat(z)]
    });
    let (mut leave, mut sum_phi) = ([F::ZERO; G], [F::ZERO; G]);
    for v in pair_vectors(j, r.clone()) {
        let (wx, wy, wz) = (v.load(gx), v.load(gy), v.load(gz));
        for k in 0..G {
            let [fx, fy, fz] = v.gather3(fk[k]);
            let phi = (fx + fi[k][0]) * wx + (fy + fi[k][1]) * wy + (fz + fi[k][2]) * wz;
            leave[k] += phi.max(F::ZERO);
            sum_phi[k] += phi;
        }
    }
    for k in 0..G {
        let a = alpha[k][i];
        let leaving = dt * sum(leave[k]);
        l[k] = if leaving > a { a.max(0.0) / leaving } else { 1.0 };
        s[k] = sum(sum_phi[k]);
    }
}

/// sum_j Lambda_ij phi_k,ij of particle i (query q of `blk`) for every
/// phase, into `o`: the fluxes again, with the pair limits.
fn limited_sums(blk: &PairBlock, q: usize, i: usize, flux: Fluxes, limit: &[f32], np: usize, o: &mut [f32]) {
    let r = blk.range(q);
    let (gx, gy, gz) = (&blk.gx, &blk.gy, &blk.gz);
    for k0 in (0..np).step_by(GROUP) {
        let g = (np - k0).min(GROUP);
        let mut acc = [F::ZERO; GROUP];
        for v in pair_vectors(&blk.j, r.clone()) {
            let (wx, wy, wz) = (v.load(gx), v.load(gy), v.load(gz));
            let j = v.indices();
            // Lambda_ij over all phases (not only this group's).
            let mut lam = F::splat(1.0);
            let mut phis = [F::ZERO; GROUP];
            for k in 0..np {
                let fk = flux.phase(k);
                let [fx, fy, fz] = v.gather3(fk);
                let [fxi, fyi, fzi, _] = fk[i];
                let phi = (fx + F::splat(fxi)) * wx + (fy + F::splat(fyi)) * wy + (fz + F::splat(fzi)) * wz;
                let lj = F::from(std::array::from_fn::<f32, LANES, _>(|l| limit[j[l] as usize * np + k]));
                let from_j = Select::select(phi.simd_lt(F::ZERO), lj, F::splat(1.0));
                lam = lam.min(Select::select(phi.simd_gt(F::ZERO), F::splat(limit[i * np + k]), from_j));
                if (k0..k0 + g).contains(&k) {
                    phis[k - k0] = phi;
                }
            }
            for k in 0..g {
                acc[k] += phis[k] * lam;
            }
        }
        for k in 0..g {
            o[k0 + k] = sum(acc[k]);
        }
    }
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
            for v in pair_vectors(&blk.j, blk.range(q)) {
                let c = half * (vai + v.gather(alpha_k));
                let vx = c * (v.gather(u.x) - uxi) + v.gather(flux.x) + fxi;
                let vy = c * (v.gather(u.y) - uyi) + v.gather(flux.y) + fyi;
                let vz = c * (v.gather(u.z) - uzi) + v.gather(flux.z) + fzi;
                acc += vx * v.load(&blk.gx) + vy * v.load(&blk.gy) + vz * v.load(&blk.gz);
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
