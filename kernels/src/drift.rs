//! Pass 10 (PHYSICS.md §6): drift velocities u_mk of the mixture model
//! (Ren et al. 2014; PHYSICS.md §4.1), P-Eq. 11 without its last (porous)
//! term, and the phase fluxes that the transport (pass 12) moves.
//!
//! P-Eq. 11 reads, with mass fractions c_k = alpha_k rho_k / sum_k' alpha_k' rho_k',
//!
//! u_mk = tau (rho_k - sum_k' c_k' rho_k') a - tau (grad p_k - sum_k' c_k' grad p_k')
//!        - sigma (grad alpha_k / alpha_k - sum_k' c_k' grad alpha_k' / alpha_k').
//!
//! It is computed as u_mk = v_k - s, s = sum_k' c_k' v_k', from the phase
//! velocity v_k = tau_k (rho_k a - grad p_k) - sigma_k grad alpha_k / alpha_k:
//! P-Eq. 11 term by term when all phases share tau and sigma, and with
//! sum_k c_k u_mk = 0 kept when a scene gives phases their own tau_k, sigma_k.
//! s is summed from w_k = alpha_k v_k (c_k v_k = rho_k w_k / sum alpha rho),
//! which has no division by alpha_k, so the mixture sums stay exact for a
//! phase that is absent from the particle but not from its neighbours.
//!
//! - a = g - Du_m/Dt, implemented as a = -(a^visc + a^p), minus the
//!   particle's non-gravity accelerations of this step (PHYSICS.md §4.1).
//!   tau is not divided by the viscosity ([AC] does; a Stokes-like
//!   d^2 / (18 mu) belongs in the scene's value), so tau is in
//!   m^2/(Pa s) = m^3 s/kg (PHYSICS.md §7).
//! - Gradients in difference form over fluid neighbours,
//!   grad A_i = sum_j Vbar_ij (A_j - A_i) grad W_ij, with the harmonic pair
//!   volume Vbar_ij of the pressure solve (the pair lists hold
//!   Vbar_ij grad W_ij after `iisph::scale_by_pair_volume`); in the bulk
//!   Vbar_ij = V_j, the volume PHYSICS.md §4.1 writes.
//! - Guards (PHYSICS.md §4.1): the term sigma grad alpha_k / alpha_k of
//!   u_mk itself is dropped where alphahat_k < 0.01; everything is 0 where
//!   alpha_f < 0.01.
//! - Phase pressures p_k [inferred]. The scene's `phase_pressure` picks:
//!   - `"shared"` (default): p_k = p for every phase, so the two pressure
//!     terms cancel and u_mk = tau (rho_k - sum c rho) a - sigma (...), the
//!     buoyancy slip of Manninen's mixture model (where grad p = rho_m a is
//!     what makes the buoyancy).
//!   - `"fraction"`: p_k = alphahat_k p with alphahat_k = alpha_k / alpha_f
//!     and p the solved IISPH pressure, as PHYSICS.md §4.1 writes it after
//!     [AC]. grad p_k = alphahat_k grad p + p grad alphahat_k; the second
//!     part depends on where p is zero (not a physical property) and acts
//!     as a diffusion of fractions with coefficient about 2 tau p alpha c
//!     (up to 0.006 m^2/s at 0.4 m depth of water with tau = 3e-6, six
//!     times the paper's sigma), which is unstable for
//!     dt > 0.1 h^2 / (2 tau p alpha c)
//!     and picks up the IISPH pressure's step-to-step noise. In a column at
//!     rest (grad p = rho_m g, a = g) the first part gives a two-phase drift
//!     u_mh - u_ml = tau g [(rho_h - rho_l) - rho_m (alpha_h - alpha_l)],
//!     which stops settling where the bracket is 0: at alpha_h = 0.69 for
//!     rho_h / rho_l = 1.5, 0.59 for 1.2. A suspension never separates
//!     completely (`tests/mixture.rs` checks both forms).
//!
//! Three gathers, each writing its own arrays (so the GPU twin,
//! `shaders/drift.wgsl`, can use the same function names):
//! 1. [`phase_velocity`], once per phase: v_k and w_k ([`phase_velocities`]
//!    for all phases in one pass over the pairs).
//! 2. [`mixture_velocity`]: s = sum_k c_k v_k and the volume-weighted mean
//!    phase velocity m = sum_k alphahat_k v_k.
//! 3. [`drift_velocity`], once per phase: u_mk = v_k - s (over v_k), and
//!    the phase flux F_k = w_k - alpha_k m = alpha_k (u_mk - j) for the
//!    transport (over w_k), j = sum_k alphahat_k u_mk.
//!
//! The CPU runs all three, with P-Eq. 11's (12's) porous term between 1
//! and 2 and the largest drift speed, in one pass: [`drift_velocities`],
//! bit for bit the sequence (steps 2-3 and the porous term need only the
//! particle's own values, so they follow each particle's pair loop instead
//! of reading and writing every phase's arrays again).
//!
//! Why the (default, conservative) transport moves F_k = alpha_k (u_mk - j)
//! rather than alpha_k u_mk [inferred]: u_mk is the phase velocity relative
//! to the mass-averaged velocity, and sum_k alpha_k u_mk = alpha_f j is in
//! general not 0 (a heavy phase going down and a light one going up carry
//! unequal volumes), so those fluxes would create or destroy volume in a
//! particle whose volume IISPH holds at alpha_f h^3, and the correction
//! would renormalise it away unevenly: each phase's total volume drifts
//! (`phase_transport` gives numbers). u_mk - j is the phase velocity
//! relative to the volume-averaged velocity; these fluxes add up to 0 in
//! every particle. For incompressible phases this is the same continuum
//! model with the particles moving at the volume-averaged velocity, the
//! one that is divergence-free, as IISPH makes the particle velocity. The
//! top of a settling two-phase suspension falls at
//! alpha_l |u_mh - u_ml| = (rho_m / rho_l) |u_mh| either way. The sigma
//! part of F_k is -sigma grad alpha_k + alpha_k sum_k' sigma_k' grad alpha_k'
//! (Fick's law for equal sigma), also between two pure particles, where
//! alpha_k u_mk would be 0.

use crate::band::BandVel;
use crate::blocks::{keep_largest, larger, BLOCK};
use crate::lanes::{pair_vectors, sum, Packed, F};
use crate::neighbors::{PairBlock, PairLists};
use crate::phases::{PhaseConstants, PhaseVel, MIN_ALPHA_F, MIN_PHASE_FRACTION};
use crate::soa::{Vel, VelMut};
use rayon::prelude::*;

/// p / alpha_f per particle (0 where alpha_f < 0.01), so that the phase
/// pressure is p_k = alpha_k (p / alpha_f) = alphahat_k p (PHYSICS.md §4.1).
pub fn pressure_per_fraction(p: &[f32], alpha_f: &[f32], out: &mut [f32]) {
    out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
        for (q, v) in o.iter_mut().enumerate() {
            let i = b * BLOCK + q;
            *v = if alpha_f[i] >= MIN_ALPHA_F { p[i] / alpha_f[i] } else { 0.0 };
        }
    });
}

/// Inputs of [`phase_velocity`].
pub struct PhaseVelocityInput<'a> {
    /// Fluid-fluid pairs holding Vbar_ij grad W_ij (after
    /// `iisph::scale_by_pair_volume`).
    pub ff: &'a PairLists,
    /// Outer fraction alpha_f = sum_k alpha_k.
    pub alpha_f: &'a [f32],
    /// p / alpha_f from [`pressure_per_fraction`], Pa, for the phase
    /// pressures p_k = alphahat_k p; `None` for a pressure shared by all
    /// phases, p_k = p, whose terms in P-Eq. 11 cancel (module doc).
    pub p_per_fraction: Option<&'a [f32]>,
    /// Viscous acceleration a^visc of this step, m/s^2.
    pub a_visc: Vel<'a>,
    /// Pressure acceleration a^p of this step, m/s^2.
    pub a_p: Vel<'a>,
    /// With at most [`PACKED_PHASES`] phases, the fractions and p / alpha_f
    /// packed ([`pack_fractions`]), which [`phase_velocities`] then reads
    /// at the pairs' targets with one load each instead of a gather per
    /// phase and one for the pressure (the same values).
    pub packed: Option<&'a [Packed]>,
}

/// Phases that [`pack_fractions`] packs with the pressure.
pub const PACKED_PHASES: usize = 3;

/// `[alpha_0, alpha_1, alpha_2, p / alpha_f]` per particle (0 past the
/// phases and without `pf`) into `out`, for [`PhaseVelocityInput::packed`]
/// (with mu_m as `pf`, for [`crate::viscosity::ViscosityInput::phases`]);
/// `None` for more than [`PACKED_PHASES`] phases.
pub fn pack_fractions<'o>(alpha: &[&[f32]], pf: Option<&[f32]>, out: &'o mut [Packed]) -> Option<&'o [Packed]> {
    if alpha.len() > PACKED_PHASES {
        return None;
    }
    out.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
        for (q, o) in o.iter_mut().enumerate() {
            let i = b * BLOCK + q;
            *o = [0.0; 4];
            for (k, a) in alpha.iter().enumerate() {
                o[k] = a[i];
            }
            o[3] = pf.map_or(0.0, |pf| pf[i]);
        }
    });
    Some(out)
}

/// Step 1 of P-Eq. 11 for phase k (module doc), with a = -(a^visc + a^p)
/// and p_k = alphahat_k p, both in m/s and 0 where alpha_f < 0.01:
/// - `v`: v_k = tau_k (rho_k a - grad p_k) - sigma_k grad alpha_k / alpha_k,
///   the diffusion part dropped where alphahat_k < 0.01;
/// - `w`: w_k = alpha_k tau_k (rho_k a - grad p_k) - sigma_k grad alpha_k,
///   which is alpha_k v_k without that guard (finite as alpha_k -> 0).
///
/// `alpha_k` is the fraction of phase k.
pub fn phase_velocity(inp: &PhaseVelocityInput, alpha_k: &[f32], phase: PhaseConstants, v: VelMut, w: VelMut) {
    let (tau, sigma, rho) = (phase.tau, phase.sigma, phase.density);
    v.x.par_chunks_mut(BLOCK)
        .zip(v.y.par_chunks_mut(BLOCK))
        .zip(v.z.par_chunks_mut(BLOCK))
        .zip(w.x.par_chunks_mut(BLOCK).zip(w.y.par_chunks_mut(BLOCK)).zip(w.z.par_chunks_mut(BLOCK)))
        .zip(inp.ff.used().par_iter())
        .enumerate()
        .for_each(|(b, ((((vx, vy), vz), ((wx, wy), wz)), blk))| {
            for q in 0..vx.len() {
                let i = b * BLOCK + q;
                let af = inp.alpha_f[i];
                if af < MIN_ALPHA_F {
                    (vx[q], vy[q], vz[q], wx[q], wy[q], wz[q]) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
                    continue;
                }
                let ai = alpha_k[i];
                let r = blk.range(q);
                let (ga, gp) = match inp.p_per_fraction {
                    Some(pf) => gradients::<true>(blk, r, alpha_k, pf, ai, ai * pf[i]),
                    None => gradients::<false>(blk, r, alpha_k, alpha_k, ai, 0.0),
                };
                let (av, ap) = (inp.a_visc, inp.a_p);
                let a = [-(av.x[i] + ap.x[i]), -(av.y[i] + ap.y[i]), -(av.z[i] + ap.z[i])];
                let own = ai >= MIN_PHASE_FRACTION * af;
                let mut out_v = [0.0f32; 3];
                let mut out_w = [0.0f32; 3];
                for c in 0..3 {
                    let t = tau * (rho * a[c] - gp[c]);
                    out_v[c] = if own { t - sigma * ga[c] / ai } else { t };
                    out_w[c] = ai * t - sigma * ga[c];
                }
                (vx[q], vy[q], vz[q]) = (out_v[0], out_v[1], out_v[2]);
                (wx[q], wy[q], wz[q]) = (out_w[0], out_w[1], out_w[2]);
            }
        });
}

/// [`phase_velocity`] for every phase in one pass over the pairs: each
/// pair's j and gradient are read once for all phases instead of once a
/// phase (the pairs are most of what the pass reads). `alpha[k]` and
/// `phases[k]` are phase k's; `v` and `w` hold phase k at `[k n, (k + 1) n)`
/// (n = `inp.alpha_f.len()`). Bit for bit [`phase_velocity`] phase by
/// phase: the same sums in the same order (`kernels/tests/mixture.rs`).
pub fn phase_velocities(inp: &PhaseVelocityInput, alpha: &[&[f32]], phases: &[PhaseConstants], v: VelMut, w: VelMut) {
    one_pass(inp, alpha, phases, None, v, w);
}

/// Phases per pair loop of [`phase_velocities`]: with phase pressures six
/// accumulators a phase stay in registers.
const GROUP: usize = 4;

/// What [`drift_velocities`] does after the phase velocities, per particle.
#[derive(Clone, Copy)]
pub struct DriftSums<'a> {
    /// Rest density rho_k per phase, kg/m^3.
    pub density: &'a [f32],
    /// P-Eq. 11's (12's) porous term, `scale` e_k with e_k per phase on
    /// the fluid-solid band, as [`crate::porous::add_phase_term`] adds it.
    pub porous: Option<(BandVel<'a>, f32)>,
    /// The conservative transport's fluxes F_k = w_k - alpha_k m; else the
    /// reference form's alpha_k u_mk ([`drift_velocity`]).
    pub conservative: bool,
}

/// Steps 1-3 of P-Eq. 11 for every phase in one pass (module doc): per
/// particle [`phase_velocities`], then [`crate::porous::add_phase_term`]
/// (with `sums.porous`), [`mixture_velocity`] and [`drift_velocity`] of
/// each phase, from its own values: `u` gets u_mk, `f` the flux F_k (phase
/// k at `[k n, (k + 1) n)` of each component). Returns
/// [`max_drift_speed`] of u. Bit for bit that sequence of passes
/// (`kernels/tests/mixture.rs`): the same expressions in the same order.
pub fn drift_velocities(
    inp: &PhaseVelocityInput,
    alpha: &[&[f32]],
    phases: &[PhaseConstants],
    sums: &DriftSums,
    u: VelMut,
    f: VelMut,
) -> f32 {
    assert_eq!(
        sums.density.len(),
        alpha.len(),
        "drift pass: {} densities for {} fractions",
        sums.density.len(),
        alpha.len()
    );
    one_pass(inp, alpha, phases, Some(sums), u, f)
}

/// [`phase_velocities`] into `v` and `w`, and with `sums` the rest of
/// [`drift_velocities`] in place (returning its largest speed; 0 without).
fn one_pass(
    inp: &PhaseVelocityInput,
    alpha: &[&[f32]],
    phases: &[PhaseConstants],
    sums: Option<&DriftSums>,
    v: VelMut,
    w: VelMut,
) -> f32 {
    let (n, np) = (inp.alpha_f.len(), alpha.len());
    assert_eq!(phases.len(), np, "drift pass: {} phases' constants for {np} fractions", phases.len());
    let VelMut { x: vx, y: vy, z: vz } = v;
    let VelMut { x: wx, y: wy, z: wz } = w;
    let out = [vx, vy, vz, wx, wy, wz].map(|o| {
        assert_eq!(o.len(), np * n, "drift pass: {} outputs for {np} phases of {n} particles", o.len());
        PhaseOut(o.as_mut_ptr())
    });
    let blocks = &inp.ff.used()[..n.div_ceil(BLOCK)];
    let packed = inp.packed.filter(|_| np <= PACKED_PHASES);
    blocks
        .par_iter()
        .enumerate()
        .map(|(b, blk)| {
            let mut largest = 0.0f32;
            for i in b * BLOCK..((b + 1) * BLOCK).min(n) {
                let q = i - b * BLOCK;
                if inp.alpha_f[i] < MIN_ALPHA_F {
                    for k in 0..np {
                        // SAFETY: i belongs to this block alone, k n + i < np n.
                        out.iter().for_each(|o| unsafe { o.write(k * n + i, 0.0) });
                    }
                } else {
                    for k0 in (0..np).step_by(GROUP) {
                        let (a, c) = (&alpha[k0..(k0 + GROUP).min(np)], &phases[k0..(k0 + GROUP).min(np)]);
                        let at = (i, k0, n);
                        match a.len() {
                            1 => velocity_group::<1>(inp, blk, q, at, (a, packed), c, &out),
                            2 => velocity_group::<2>(inp, blk, q, at, (a, packed), c, &out),
                            3 => velocity_group::<3>(inp, blk, q, at, (a, packed), c, &out),
                            _ => velocity_group::<GROUP>(inp, blk, q, at, (a, None), c, &out),
                        }
                    }
                }
                if let Some(sums) = sums {
                    // SAFETY: particle i's indices, this block's alone.
                    keep_largest(&mut largest, unsafe { finish_particle(i, n, alpha, inp.alpha_f, sums, &out) });
                }
            }
            largest
        })
        .reduce(|| 0.0f32, larger)
}

/// The per-particle rest of [`drift_velocities`] for particle i, over its
/// phase velocities v_k (`out[0..3]`) and w_k (`out[3..6]`) at `k n + i`:
/// the porous term, s and m, u_mk and F_k in place; returns max_k |u_mk|
/// as [`max_drift_speed`] takes it.
///
/// # Safety
/// No other thread reads or writes particle i's indices meanwhile.
#[inline(always)]
unsafe fn finish_particle(
    i: usize,
    n: usize,
    alpha: &[&[f32]],
    alpha_f: &[f32],
    sums: &DriftSums,
    out: &[PhaseOut; 6],
) -> f32 {
    let np = alpha.len();
    let af = alpha_f[i];
    // SAFETY (every read and write below): particle i's index of phase k,
    // the caller's.
    let get = |c: usize, k: usize| unsafe { out[c].read(k * n + i) };
    let set = |c: usize, k: usize, v: f32| unsafe { out[c].write(k * n + i, v) };
    // crate::porous::add_phase_term.
    if let (Some((e, scale)), true) = (sums.porous, af >= MIN_ALPHA_F) {
        for (k, alpha_k) in alpha.iter().enumerate() {
            let t = e.get(k, i).map(|e| scale * e);
            let a = alpha_k[i];
            for (c, t) in t.into_iter().enumerate() {
                set(c, k, get(c, k) + t);
                set(3 + c, k, get(3 + c, k) + a * t);
            }
        }
    }
    // mixture_velocity.
    let mass: f32 = (0..np).map(|k| alpha[k][i] * sums.density[k]).sum();
    let (s, m) = if af < MIN_ALPHA_F || mass <= 0.0 {
        ([0.0f32; 3], [0.0f32; 3])
    } else {
        let (mut ms, mut mv) = ([0.0f32; 3], [0.0f32; 3]);
        for (k, rho) in sums.density.iter().enumerate() {
            for c in 0..3 {
                let wk = get(3 + c, k);
                ms[c] += rho * wk;
                mv[c] += wk;
            }
        }
        (ms.map(|x| x / mass), mv.map(|x| x / af))
    };
    // drift_velocity, and max_drift_speed's per-particle speed.
    let mut speed = 0.0f32;
    for (k, alpha_k) in alpha.iter().enumerate() {
        let a = alpha_k[i];
        let uk: [f32; 3] = std::array::from_fn(|c| get(c, k) - s[c]);
        for c in 0..3 {
            set(c, k, uk[c]);
            let fk = if sums.conservative { get(3 + c, k) - a * m[c] } else { a * uk[c] };
            set(3 + c, k, fk);
        }
        keep_largest(&mut speed, (uk[0] * uk[0] + uk[1] * uk[1] + uk[2] * uk[2]).sqrt());
    }
    speed
}

/// Where the blocks of [`phase_velocities`] write: each particle's values
/// at indices no other particle writes.
#[derive(Clone, Copy)]
struct PhaseOut(*mut f32);

// SAFETY: the parallel loop writes each index from one thread only.
unsafe impl Send for PhaseOut {}
unsafe impl Sync for PhaseOut {}

impl PhaseOut {
    /// # Safety
    /// `i` is within the slice the pointer came from, which outlives the
    /// call, and no other thread reads or writes index `i` meanwhile.
    unsafe fn write(&self, i: usize, v: f32) {
        unsafe { *self.0.add(i) = v }
    }

    /// # Safety
    /// As [`PhaseOut::write`].
    unsafe fn read(&self, i: usize) -> f32 {
        unsafe { *self.0.add(i) }
    }
}

/// [`phase_velocities`] for the `G` phases `alpha` (constants `phases`),
/// phase k0 + k of the `(i, k0, n)` of `at`: particle i, query q of `blk`;
/// the fractions also packed where [`PhaseVelocityInput::packed`] holds
/// them (G <= 3).
#[inline(always)]
fn velocity_group<const G: usize>(
    inp: &PhaseVelocityInput,
    blk: &PairBlock,
    q: usize,
    (i, k0, n): (usize, usize, usize),
    (alpha, packed): (&[&[f32]], Option<&[Packed]>),
    phases: &[PhaseConstants],
    out: &[PhaseOut; 6],
) {
    let r = blk.range(q);
    let ai: [f32; G] = std::array::from_fn(|k| alpha[k][i]);
    let (ga, gp) = match inp.p_per_fraction {
        Some(pf) => gradients_group::<G, true>(blk, r, (alpha, packed), pf, ai, ai.map(|a| a * pf[i])),
        None => gradients_group::<G, false>(blk, r, (alpha, packed), &[], ai, [0.0; G]),
    };
    let (av, ap) = (inp.a_visc, inp.a_p);
    let a = [-(av.x[i] + ap.x[i]), -(av.y[i] + ap.y[i]), -(av.z[i] + ap.z[i])];
    let af = inp.alpha_f[i];
    for k in 0..G {
        let PhaseConstants { tau, sigma, density: rho } = phases[k];
        let own = ai[k] >= MIN_PHASE_FRACTION * af;
        let at = (k0 + k) * n + i;
        for c in 0..3 {
            let t = tau * (rho * a[c] - gp[k][c]);
            let v = if own { t - sigma * ga[k][c] / ai[k] } else { t };
            // SAFETY: particle i's index of phase k0 + k, written by this
            // block alone (`phase_velocities`).
            unsafe {
                out[c].write(at, v);
                out[3 + c].write(at, ai[k] * t - sigma * ga[k][c]);
            }
        }
    }
}

/// [`gradients`] for `G` phases over one pass of the pairs, the
/// neighbours' fractions and p / alpha_f from `packed` where given (G <= 3;
/// [`pack_fractions`]).
#[inline(always)]
fn gradients_group<const G: usize, const PRESSURE: bool>(
    blk: &PairBlock,
    r: std::ops::Range<usize>,
    (alpha, packed): (&[&[f32]], Option<&[Packed]>),
    pf: &[f32],
    ai: [f32; G],
    pki: [f32; G],
) -> ([[f32; 3]; G], [[f32; 3]; G]) {
    assert!(packed.is_none() || G <= PACKED_PHASES, "{G} phases packed");
    let (vai, vpi) = (ai.map(F::splat), pki.map(F::splat));
    let (mut ga, mut gp) = ([[F::ZERO; 3]; G], [[F::ZERO; 3]; G]);
    for v in pair_vectors(&blk.j, r) {
        let (x, y, z) = (v.load(&blk.gx), v.load(&blk.gy), v.load(&blk.gz));
        let g4 = packed.map(|pk| v.gather4(pk));
        let pj = match (PRESSURE, g4) {
            (false, _) => F::ZERO,
            (true, Some(g)) => g[3],
            (true, None) => v.gather(pf),
        };
        for k in 0..G {
            let aj = match g4 {
                Some(g) => g[k],
                None => v.gather(alpha[k]),
            };
            let da = aj - vai[k];
            ga[k][0] += da * x;
            ga[k][1] += da * y;
            ga[k][2] += da * z;
            if PRESSURE {
                let dp = aj * pj - vpi[k];
                gp[k][0] += dp * x;
                gp[k][1] += dp * y;
                gp[k][2] += dp * z;
            }
        }
    }
    (ga.map(|g| g.map(sum)), gp.map(|g| g.map(sum)))
}

/// grad alpha_k and (with `PRESSURE`) grad p_k of one particle in the
/// difference form, over the pairs `r` of `blk`; `pf` is p / alpha_f, `ai`
/// and `pki` the particle's alpha_k and p_k.
#[inline(always)]
fn gradients<const PRESSURE: bool>(
    blk: &PairBlock,
    r: std::ops::Range<usize>,
    alpha_k: &[f32],
    pf: &[f32],
    ai: f32,
    pki: f32,
) -> ([f32; 3], [f32; 3]) {
    let (vai, vpi) = (F::splat(ai), F::splat(pki));
    let (mut gax, mut gay, mut gaz) = (F::ZERO, F::ZERO, F::ZERO);
    let (mut gpx, mut gpy, mut gpz) = (F::ZERO, F::ZERO, F::ZERO);
    for v in pair_vectors(&blk.j, r) {
        let aj = v.gather(alpha_k);
        let da = aj - vai;
        let (x, y, z) = (v.load(&blk.gx), v.load(&blk.gy), v.load(&blk.gz));
        gax += da * x;
        gay += da * y;
        gaz += da * z;
        if PRESSURE {
            let dp = aj * v.gather(pf) - vpi;
            gpx += dp * x;
            gpy += dp * y;
            gpz += dp * z;
        }
    }
    ([sum(gax), sum(gay), sum(gaz)], [sum(gpx), sum(gpy), sum(gpz)])
}

/// Step 2 of P-Eq. 11, in m/s (both 0 where alpha_f < 0.01):
/// - `s`: the mass-weighted mean phase velocity sum_k c_k v_k, computed as
///   sum_k rho_k w_k / sum_k alpha_k rho_k (so no term divides by alpha_k;
///   c_k grad alpha_k / alpha_k = rho_k grad alpha_k / sum alpha rho);
/// - `m`: the volume-weighted mean phase velocity
///   sum_k alphahat_k v_k = sum_k w_k / alpha_f.
///
/// `alpha[k]`, `density[k]` and `w` are per phase.
pub fn mixture_velocity(alpha: &[&[f32]], alpha_f: &[f32], density: &[f32], w: PhaseVel, s: VelMut, m: VelMut) {
    let np = alpha.len();
    s.x.par_chunks_mut(BLOCK)
        .zip(s.y.par_chunks_mut(BLOCK))
        .zip(s.z.par_chunks_mut(BLOCK))
        .zip(m.x.par_chunks_mut(BLOCK).zip(m.y.par_chunks_mut(BLOCK)).zip(m.z.par_chunks_mut(BLOCK)))
        .enumerate()
        .for_each(|(b, (((sx, sy), sz), ((mx, my), mz)))| {
            for q in 0..sx.len() {
                let i = b * BLOCK + q;
                let af = alpha_f[i];
                let mass: f32 = (0..np).map(|k| alpha[k][i] * density[k]).sum();
                if af < MIN_ALPHA_F || mass <= 0.0 {
                    (sx[q], sy[q], sz[q], mx[q], my[q], mz[q]) = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
                    continue;
                }
                let (mut ms, mut mv) = ([0.0f32; 3], [0.0f32; 3]);
                for (k, rho) in density.iter().enumerate() {
                    let wk = [w.x[k][i], w.y[k][i], w.z[k][i]];
                    for c in 0..3 {
                        ms[c] += rho * wk[c];
                        mv[c] += wk[c];
                    }
                }
                (sx[q], sy[q], sz[q]) = (ms[0] / mass, ms[1] / mass, ms[2] / mass);
                (mx[q], my[q], mz[q]) = (mv[0] / af, mv[1] / af, mv[2] / af);
            }
        });
}

/// Step 3 of P-Eq. 11 for phase k, in m/s: the drift velocity
/// u_mk = v_k - s, written over `v_k`, and the phase flux of the
/// transport, written over `w_k`: with `m` given (the conservative
/// transport), F_k = w_k - alpha_k m = alpha_k (v_k - sum_k' alphahat_k' v_k'),
/// alpha_k times the phase velocity relative to the volume-averaged one
/// (module doc); without, F_k = alpha_k u_mk (the reference form).
pub fn drift_velocity(alpha_k: &[f32], s: Vel, m: Option<Vel>, v_k: VelMut, w_k: VelMut) {
    v_k.x
        .par_chunks_mut(BLOCK)
        .zip(v_k.y.par_chunks_mut(BLOCK))
        .zip(v_k.z.par_chunks_mut(BLOCK))
        .zip(w_k.x.par_chunks_mut(BLOCK).zip(w_k.y.par_chunks_mut(BLOCK)).zip(w_k.z.par_chunks_mut(BLOCK)))
        .enumerate()
        .for_each(|(b, (((ux, uy), uz), ((fx, fy), fz)))| {
            for q in 0..ux.len() {
                let i = b * BLOCK + q;
                let a = alpha_k[i];
                ux[q] -= s.x[i];
                uy[q] -= s.y[i];
                uz[q] -= s.z[i];
                (fx[q], fy[q], fz[q]) = match m {
                    Some(m) => (fx[q] - a * m.x[i], fy[q] - a * m.y[i], fz[q] - a * m.z[i]),
                    None => (a * ux[q], a * uy[q], a * uz[q]),
                };
            }
        });
}

/// Largest drift speed max_k |u_mk| over the particles, m/s (for the time
/// step rule of PHYSICS.md §7; NaN propagates).
pub fn max_drift_speed(u: PhaseVel, n: usize) -> f32 {
    crate::blocks::max_f32(n, |i| {
        let mut m = 0.0f32;
        for k in 0..u.phases() {
            keep_largest(&mut m, (u.x[k][i] * u.x[k][i] + u.y[k][i] * u.y[k][i] + u.z[k][i] * u.z[k][i]).sqrt());
        }
        m
    })
}

/// Inputs of [`max_advective_speed`]: the fractions of P-Eq. 11 (outer:
/// alpha, alpha_f) or P-Eq. 12 (inner: beta, beta_f) and what moves them.
pub struct AdvectiveDrift<'a> {
    pub frac: &'a [&'a [f32]],
    pub frac_f: &'a [f32],
    pub phases: &'a [PhaseConstants],
    /// a^visc and a^p of this step (a = -(a^visc + a^p)), m/s^2.
    pub a_visc: Vel<'a>,
    pub a_p: Vel<'a>,
    /// The porous term `scale` e_k, e_k per phase on the fluid-solid band
    /// (`crate::band`): P-Eq. 11's -phi grad p^pore_k, P-Eq. 12's -tau'
    /// q_k ([`crate::porous::add_phase_term`]).
    pub porous: Option<(BandVel<'a>, f32)>,
}

/// The largest advective drift speed max_k |u_mk - (its diffusion part)|
/// with a shared phase pressure: u_mk^adv = t_k - sum_k' c_k' t_k', with
/// t_k = tau_k rho_k a (+ the porous term) and c_k the mass fractions,
/// over the phases present in the particle (alpha_k >= 0.01 alpha_f, the
/// drift's guard); 0 where frac_f < 0.01, like the drift. m/s (NaN
/// propagates).
///
/// The phases left out: an absent phase's u_mk moves nothing (its flux is
/// alpha_k u_mk = 0), yet P-Eq. 11's porous term gives it the full
/// -phi grad p^pore (Example 6: about 13 m/s where p^pore falls from 5e4 Pa
/// to 0 across one spacing, dt 0.31 ms from the first step); a trace phase
/// below 1 % of the particle is moved conservatively and kept >= 0 by the
/// transport's outflow limiter.
///
/// Why the time step takes this and not max |u_mk| (issue 35): the
/// diffusion part -sigma_k grad alpha_k / alpha_k of u_mk is a Fickian
/// flux divided by the fraction it moves; it grows without bound as the
/// fraction goes to 0 (a phase of beta = 1e-4 next to beta = 0.5, inside
/// the inner guard's beta_k >= 0.01 beta_f at the beta_f = 0.01 cut:
/// 2e-3 x 50 / 1e-4 = 1000 m/s), but the flux it moves, -sigma grad
/// alpha_k, is bounded, its explicit step is stable under the diffusion
/// number 0.1 h^2 / sigma that the rule already has, and the conservative
/// transport's outflow limiter keeps every fraction >= 0. So the CFL
/// number applies to the advective part only.
pub fn max_advective_speed(inp: &AdvectiveDrift) -> f32 {
    let n = inp.frac_f.len();
    let (av, ap) = (inp.a_visc, inp.a_p);
    crate::blocks::max_f32(n, |i| {
        if inp.frac_f[i] < MIN_ALPHA_F {
            return 0.0;
        }
        let a = [-(av.x[i] + ap.x[i]), -(av.y[i] + ap.y[i]), -(av.z[i] + ap.z[i])];
        let t = |k: usize| {
            let c = &inp.phases[k];
            let mut t = a.map(|a| c.tau * c.density * a);
            if let Some((e, scale)) = inp.porous {
                for (t, e) in t.iter_mut().zip(e.get(k, i)) {
                    *t += scale * e;
                }
            }
            t
        };
        let (mut mass, mut s) = (0.0f32, [0.0f32; 3]);
        for (k, frac) in inp.frac.iter().enumerate() {
            let m = frac[i] * inp.phases[k].density;
            let tk = t(k);
            mass += m;
            for c in 0..3 {
                s[c] += m * tk[c];
            }
        }
        if mass <= 0.0 {
            return 0.0;
        }
        let mut largest = 0.0f32;
        for k in 0..inp.frac.len() {
            if inp.frac[k][i] < MIN_PHASE_FRACTION * inp.frac_f[i] {
                // Absent or trace (the drift's own guard): it moves no
                // volume worth a CFL bound; the outflow limiter keeps it >= 0.
                continue;
            }
            let tk = t(k);
            let u = [tk[0] - s[0] / mass, tk[1] - s[1] / mass, tk[2] - s[2] / mass];
            keep_largest(&mut largest, (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt());
        }
        largest
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: P-Eq. 11 with a shared pressure and no diffusion, by
    /// hand in f64: u_k = tau a (rho_k - sum_k' c_k' rho_k'), c the mass
    /// fractions; the largest over the phases present (>= 1 % of the
    /// particle; below, the trace phase's slip is left out).
    #[test]
    fn advective_speed_is_the_buoyancy_slip_of_the_phases_present() {
        for trace in [0.5f32, 0.02, 1e-4, 1e-7] {
            let alpha = [vec![1.0 - trace], vec![trace]];
            let frac: Vec<&[f32]> = alpha.iter().map(|a| a.as_slice()).collect();
            let rho = [1000.0f32, 1500.0];
            let tau = 3e-6f32;
            let phases: Vec<PhaseConstants> =
                rho.iter().map(|&density| PhaseConstants { density, tau, sigma: 1e-3 }).collect();
            let zero = [0.0f32];
            let up = [9.81f32];
            let inp = AdvectiveDrift {
                frac: &frac,
                frac_f: &[1.0],
                phases: &phases,
                a_visc: Vel { x: &zero, y: &zero, z: &zero },
                a_p: Vel { x: &zero, y: &up, z: &zero },
                porous: None,
            };
            let (a0, a1) = (f64::from(1.0 - trace), f64::from(trace));
            let mean = (a0 * 1000.0 * 1000.0 + a1 * 1500.0 * 1500.0) / (a0 * 1000.0 + a1 * 1500.0);
            let present = [a0 >= 0.01, a1 >= 0.01];
            let expected = rho
                .iter()
                .zip(present)
                .filter(|(_, p)| *p)
                .map(|(&r, _)| 3e-6 * 9.81 * (f64::from(r) - mean).abs())
                .fold(0.0, f64::max);
            let got = f64::from(max_advective_speed(&inp));
            // f32 against f64: 1e-5 of the slip scale tau g (rho_h - rho_l).
            assert!((got - expected).abs() < 1e-5 * 3e-6 * 9.81 * 500.0, "trace {trace}: {got} vs {expected}");
        }
    }
}
