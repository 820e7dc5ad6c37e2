//! Pass 3: fluid-fluid viscosity (P-Eq. 23, the Morris form, PHYSICS.md §5)
//! with the phase pair weights of the mixture, and the prediction
//! u* = u + dt (g + a^visc) (PHYSICS.md §2.4, item 4).

use crate::blocks::{sum_f64, BLOCK};
use crate::lanes::{pair_vectors, sum, Field3, Packed, PairVec, F};
use crate::neighbors::{PairBlock, PairLists};
use crate::soa::{Vel, VelMut};
use rayon::prelude::*;

/// Inputs of the viscosity pass.
pub struct ViscosityInput<'a> {
    /// Fluid-fluid pairs with unscaled gradients grad W_ij.
    pub ff: &'a PairLists,
    pub x: Vel<'a>,
    pub u: Vel<'a>,
    /// `x` and `u` packed ([`Packed`]), where the caller made them: the
    /// pairs' targets are then read with one load each instead of three
    /// gathers (the same values; bench/RESULTS.md, "The Jacobi sweep's a^p
    /// packed").
    pub packed: Option<[&'a [Packed]; 2]>,
    /// Rest (mixture) density rho_fm, kg/m^3.
    pub rest_density: &'a [f32],
    /// Mixture viscosity mu_m, Pa s.
    pub mu: &'a [f32],
    /// Whether every entry of `mu` is the same (one phase): mu_j is then
    /// mu_i, read without a gather per pair (the viscosity pass's gathers
    /// set its cost; bench/RESULTS.md, "One viscosity").
    pub mu_uniform: bool,
    /// `[alpha_0, alpha_1, alpha_2, mu_m]` per particle
    /// ([`crate::drift::pack_fractions`] with mu_m as its fourth entry),
    /// where the caller packed them (at most three phases): the
    /// mixture's pair weights and mu_j are then read with one load a pair
    /// instead of a gather per phase and one for mu (the same values).
    pub phases: Option<&'a [Packed]>,
    /// Particle spacing h, m (regulariser 0.01 h^2).
    pub h: f32,
    pub gravity: [f32; 3],
    pub dt: f32,
}

/// The phase pair weight w_ij of P-Eq. 23 for a vector of pairs.
trait PairWeight: Sync {
    /// mu_j and w_ij for particle i and the pairs of `v` (`None` for w_ij
    /// = 1: the coefficient is then used without a multiply).
    fn neighbours(&self, inp: &ViscosityInput, i: usize, v: &PairVec) -> (F, Option<F>);
}

/// mu_j of the pairs of `v`: mu_i where every mu is the same.
#[inline(always)]
fn mu_j(inp: &ViscosityInput, i: usize, v: &PairVec) -> F {
    if inp.mu_uniform {
        F::splat(inp.mu[i])
    } else {
        v.gather(inp.mu)
    }
}

/// One phase: w_ij = 1, and the coefficient is returned as it is (no
/// multiply), so the one-phase result is exactly that of the Morris form
/// without weights.
struct Unweighted;

impl PairWeight for Unweighted {
    #[inline(always)]
    fn neighbours(&self, inp: &ViscosityInput, i: usize, v: &PairVec) -> (F, Option<F>) {
        (mu_j(inp, i, v), None)
    }
}

/// Several phases: w_ij = sum_k 2 alpha_ik alpha_jk / (alpha_ik + alpha_jk)
/// (PHYSICS.md §5: the harmonic mean, 1 for two particles of the same
/// mixture, 0 for two pure particles of different phases; a phase absent
/// from both particles adds 0). alpha_jk and mu_j come from
/// [`ViscosityInput::phases`] where it is given, else by a gather each.
struct PhaseWeights<'a>(&'a [&'a [f32]]);

/// The harmonic pair weight of one phase, added to `w`.
#[inline(always)]
fn add_weight(w: &mut F, ai: F, aj: F) {
    *w += F::splat(2.0) * ai * aj / (ai + aj).max(F::splat(f32::MIN_POSITIVE));
}

impl PairWeight for PhaseWeights<'_> {
    #[inline(always)]
    fn neighbours(&self, inp: &ViscosityInput, i: usize, v: &PairVec) -> (F, Option<F>) {
        let mut w = F::ZERO;
        if let Some(packed) = inp.phases {
            let [a0, a1, a2, mu] = v.gather4(packed);
            for (a, aj) in self.0.iter().zip([a0, a1, a2]) {
                add_weight(&mut w, F::splat(a[i]), aj);
            }
            return (mu, Some(w));
        }
        for a in self.0 {
            add_weight(&mut w, F::splat(a[i]), v.gather(a));
        }
        (mu_j(inp, i, v), Some(w))
    }
}

/// The pair coefficients k_ij = w_ij (mu_i + mu_j) (x_j - x_i).grad W_ij /
/// (|x_ij|^2 + 0.01 h^2) of P-Eq. 23's Morris form for the pairs
/// `v` of particle `i` in `blk` (>= 0, symmetric; 0 in the lanes past
/// the vector's pairs).
#[inline(always)]
fn pair_coefficients<W: PairWeight>(inp: &ViscosityInput, blk: &PairBlock, v: &PairVec, i: usize, wt: &W) -> F {
    let eps = 0.01 * inp.h * inp.h;
    let x = inp.x;
    let [xj, yj, zj] = match inp.packed {
        Some([xp, _]) => xp.gather3(v),
        None => x.gather3(v),
    };
    let (dx, dy, dz) = (F::splat(x.x[i]) - xj, F::splat(x.y[i]) - yj, F::splat(x.z[i]) - zj);
    let r2 = dx * dx + dy * dy + dz * dz;
    // (x_j - x_i).grad W_ij = -x_ij.grad W_ij >= 0
    let xg = -(dx * v.load(&blk.gx) + dy * v.load(&blk.gy) + dz * v.load(&blk.gz));
    let (mu_j, w) = wt.neighbours(inp, i, v);
    let c = (F::splat(inp.mu[i]) + mu_j) * xg / (r2 + F::splat(eps));
    match w {
        Some(w) => c * w,
        None => c,
    }
}

/// a^visc_i (P-Eq. 23) of particle `i`, the query `q` of block `blk`.
#[inline(always)]
fn viscous_acceleration<W: PairWeight>(inp: &ViscosityInput, blk: &PairBlock, q: usize, i: usize, wt: &W) -> [f32; 3] {
    let u = inp.u;
    let (mut ax, mut ay, mut az) = (F::ZERO, F::ZERO, F::ZERO);
    let (uxi, uyi, uzi) = (F::splat(u.x[i]), F::splat(u.y[i]), F::splat(u.z[i]));
    let rhoi = inp.rest_density[i];
    for v in pair_vectors(&blk.j, blk.range(q)) {
        let c = pair_coefficients(inp, blk, &v, i, wt);
        let [uxj, uyj, uzj] = match inp.packed {
            Some([_, up]) => up.gather3(&v),
            None => u.gather3(&v),
        };
        ax += c * (uxj - uxi);
        ay += c * (uyj - uyi);
        az += c * (uzj - uzi);
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

/// What the implicit viscosity solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ImplicitStats {
    pub iterations: u32,
    /// |r| / |r_0| at the end (r_0 the residual of the start u + dt g).
    pub residual: f32,
}

/// Per-particle scratch of [`predict_velocity_implicit`], n values each
/// (from the step's arena).
pub struct ImplicitScratch<'a> {
    /// The Jacobi preconditioner D_i (the matrix diagonal).
    pub diag: &'a mut [f32],
    /// Residual, preconditioned residual, search direction and A p, each
    /// three components.
    pub r: [&'a mut [f32]; 3],
    pub z: [&'a mut [f32]; 3],
    pub p: [&'a mut [f32]; 3],
    pub ap: [&'a mut [f32]; 3],
    /// Block partial sums, [`crate::blocks::nblocks`]`(n)` values.
    pub parts: &'a mut [f64],
}

/// The coefficients k_ij of [`pair_coefficients`], one per pair, in `coef`
/// (one vector per block of `ff`, kept for its capacity). Writes
/// D_i = rho_i + dt h^3 sum_j k_ij.
fn implicit_coefficients<W: PairWeight>(inp: &ViscosityInput, wt: &W, coef: &mut [Vec<f32>], diag: &mut [f32]) {
    let scale = inp.dt * inp.h * inp.h * inp.h;
    coef.par_iter_mut().zip(diag.par_chunks_mut(BLOCK)).zip(inp.ff.used().par_iter()).enumerate().for_each(
        |(b, ((c, dg), blk))| {
            c.clear();
            c.resize(blk.len(), 0.0);
            for (q, dg) in dg.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                let mut total = F::ZERO;
                for v in pair_vectors(&blk.j, blk.range(q)) {
                    let kij = pair_coefficients(inp, blk, &v, i, wt);
                    v.store(c, kij);
                    total += kij;
                }
                *dg = inp.rest_density[i] + scale * sum(total);
            }
        },
    );
}

/// out = A v for the three components: (A v)_i = rho_i v_i +
/// dt h^3 sum_j k_ij (v_i - v_j).
fn implicit_apply(inp: &ViscosityInput, coef: &[Vec<f32>], v: [&[f32]; 3], out: &mut [&mut [f32]; 3]) {
    let scale = inp.dt * inp.h * inp.h * inp.h;
    let [ox, oy, oz] = out;
    ox.par_chunks_mut(BLOCK)
        .zip(oy.par_chunks_mut(BLOCK))
        .zip(oz.par_chunks_mut(BLOCK))
        .zip(coef.par_iter().zip(inp.ff.used().par_iter()))
        .enumerate()
        .for_each(|(b, (((ox, oy), oz), (c, blk)))| {
            for q in 0..ox.len() {
                let i = b * BLOCK + q;
                let (vxi, vyi, vzi) = (F::splat(v[0][i]), F::splat(v[1][i]), F::splat(v[2][i]));
                let (mut sx, mut sy, mut sz) = (F::ZERO, F::ZERO, F::ZERO);
                for pv in pair_vectors(&blk.j, blk.range(q)) {
                    let kij = pv.load(c);
                    sx += kij * (vxi - pv.gather(v[0]));
                    sy += kij * (vyi - pv.gather(v[1]));
                    sz += kij * (vzi - pv.gather(v[2]));
                }
                let rho = inp.rest_density[i];
                ox[q] = rho * v[0][i] + scale * sum(sx);
                oy[q] = rho * v[1][i] + scale * sum(sy);
                oz[q] = rho * v[2][i] + scale * sum(sz);
            }
        });
}

/// P-Eq. 23 implicit (backward Euler): u*_i = u_i + dt (g + a^visc_i(u*)),
/// i.e. with masses m_i = rho_i h^3, the symmetric positive definite system
///   rho_i u*_i + dt h^3 sum_j k_ij (u*_i - u*_j) = rho_i (u_i + dt g)
/// (k_ij of [`pair_coefficients`], >= 0 and symmetric: the viscous
/// forces are pairwise equal and opposite, so linear momentum is conserved,
/// and the step is stable for any dt). Solved for the three components at
/// once by conjugate gradients with the Jacobi preconditioner, from
/// u + dt g, until |r| <= `tol` |r_0| or `max_iterations`. `alpha`: the
/// phase fractions of the pair weights (None: one phase, w_ij = 1). The
/// explicit form [`predict_velocity`] limits dt to 0.125 h^2 rho / mu; this
/// one does not (PHYSICS.md §7; Weiler et al. 2018 solve the same
/// backward-Euler step for a strain-rate form).
pub fn predict_velocity_implicit(
    inp: &ViscosityInput,
    alpha: Option<&[&[f32]]>,
    coef: &mut Vec<Vec<f32>>,
    s: ImplicitScratch,
    tol: f32,
    max_iterations: u32,
    u_star: VelMut,
) -> ImplicitStats {
    let n = inp.rest_density.len();
    let nb = inp.ff.used().len();
    if coef.len() < nb {
        coef.resize_with(nb, Vec::new);
    }
    let coef = &mut coef[..nb];
    let ImplicitScratch { diag, r, mut z, p, mut ap, parts } = s;
    match alpha {
        Some(a) => implicit_coefficients(inp, &PhaseWeights(a), coef, diag),
        None => implicit_coefficients(inp, &Unweighted, coef, diag),
    }
    let x = [u_star.x, u_star.y, u_star.z];
    let (u, g, dt) = (inp.u, inp.gravity, inp.dt);
    let start = [u.x, u.y, u.z];
    for c in 0..3 {
        x[c].par_iter_mut().zip(start[c].par_iter()).for_each(|(x, u)| *x = u + dt * g[c]);
    }
    // r = b - A x with b = rho x: r = rho x - A x.
    implicit_apply(inp, coef, [&*x[0], &*x[1], &*x[2]], &mut ap);
    for c in 0..3 {
        r[c].par_iter_mut().enumerate().for_each(|(i, r)| *r = inp.rest_density[i] * x[c][i] - ap[c][i]);
    }
    let dot = |parts: &mut [f64], a: &[&mut [f32]; 3], b: &[&mut [f32]; 3]| {
        sum_f64(n, parts, |i| (0..3).map(|c| f64::from(a[c][i]) * f64::from(b[c][i])).sum())
    };
    let precondition = |r: &[&mut [f32]; 3], z: &mut [&mut [f32]; 3]| {
        for c in 0..3 {
            z[c].par_iter_mut().enumerate().for_each(|(i, z)| *z = r[c][i] / diag[i]);
        }
    };
    let r0 = dot(parts, &r, &r);
    let goal = f64::from(tol).powi(2) * r0;
    let mut rr = r0;
    let mut it = 0;
    if r0 > 0.0 {
        precondition(&r, &mut z);
        for c in 0..3 {
            p[c].copy_from_slice(z[c]);
        }
        let mut rz = dot(parts, &r, &z);
        while it < max_iterations && rr > goal {
            implicit_apply(inp, coef, [&*p[0], &*p[1], &*p[2]], &mut ap);
            let pap = dot(parts, &p, &ap);
            if pap.is_nan() || pap <= 0.0 {
                break;
            }
            let a = (rz / pap) as f32;
            for c in 0..3 {
                x[c].par_iter_mut().zip(p[c].par_iter()).for_each(|(x, p)| *x += a * p);
                r[c].par_iter_mut().zip(ap[c].par_iter()).for_each(|(r, q)| *r -= a * q);
            }
            rr = dot(parts, &r, &r);
            precondition(&r, &mut z);
            let rz_new = dot(parts, &r, &z);
            let beta = (rz_new / rz) as f32;
            rz = rz_new;
            for c in 0..3 {
                p[c].par_iter_mut().zip(z[c].par_iter()).for_each(|(p, z)| *p = z + beta * *p);
            }
            it += 1;
        }
    }
    let residual = if r0 > 0.0 { (rr / r0).sqrt() as f32 } else { 0.0 };
    ImplicitStats { iterations: it, residual }
}
