//! The porous coupling (P §4, §5; PHYSICS.md §4.2): passes 6, 7 and 9 of
//! PHYSICS.md §6 and the absorption exchange of pass 12.
//!
//! Solid-side gathers (solid particles in the sorted order of the solid
//! pair lists):
//! - [`absorbed_volume`]: phi_sk, P-Eq. 15;
//! - [`pore_gradient`]: grad p^pore_s, P-Eq. 19 (sign per PHYSICS.md §8.1);
//! - [`drained_boundary`]: its term at a face open to outer liquid at p_0k.
//!
//! Fluid-side gathers over the fluid-solid pairs, which must still hold the
//! plain kernel gradients grad W_fs (before the pressure solve scales them
//! by pair volumes: an inner particle has no pressure-solve volume, and its
//! porous terms must not vanish with it):
//! - [`capillary_normal`]: sum_s psi_s V_s grad W_fs (P-Eq. 18);
//! - [`fluid_phase_terms`], once per phase: u_betak,f and q_k,f (P-Eqs.
//!   16-17), grad p^pore_fk (P-Eq. 20) and the transfer rate Gamma_k
//!   (P-Eqs. 13, 21, 22, in pair form: see [`FluidPhaseOut::gamma`]).
//!
//! Conventions (PHYSICS.md §0, §8.1): grad W_fs = grad_f W(x_f - x_s),
//! pointing from f towards s; gradients in difference form with the
//! `(A_s - A_f)` order, so P-Eqs. 19-21 get the signs of §4.2: Darcy flow
//! goes down the pore-pressure gradient and Gamma > 0 is absorption.
//!
//! Volumes: V_s = m_s / rho_s with rho_s = sum_SS m W (P §5) for porous
//! solid particles and 0 for the others, so a non-porous solid takes no part
//! in any porous sum. The absorbed volume of P-Eq. 15 is divided by the
//! lattice volume h^3 (= V_s0 of a solid particle sampled on the lattice,
//! and m_f / rho_fm of every fluid particle): with the partition of unity
//! W_fs / N_f, sum_s h^3 phi_sk = sum_f h^3 beta_fk exactly, so the
//! absorbed volume seen by the solids is the fluid's inner volume.

use crate::band::{Band, BandField, BandVel};
use crate::blocks::BLOCK;
use crate::neighbors::PairLists;
use crate::phases::{join, split};
use crate::soa::{Vel, VelMut};
use rayon::prelude::*;

/// Pass 6, P-Eq. 15 for phase k: phi_sk = sum_f beta_fk W_sf / N_f over the
/// solid-fluid pairs `sf`, for the solid particles with `porous[s]` != 0
/// (0 for the others). `beta_over_n` is beta_fk / N_f per fluid particle
/// (0 where N_f = 0).
pub fn absorbed_volume(sf: &PairLists, beta_over_n: &[f32], porous: &[f32], out: &mut [f32]) {
    out.par_chunks_mut(BLOCK).zip(sf.used().par_iter()).enumerate().for_each(|(b, (o, blk))| {
        for (q, o) in o.iter_mut().enumerate() {
            let s = b * BLOCK + q;
            *o = if porous[s] != 0.0 {
                blk.range(q).map(|p| beta_over_n[blk.j[p] as usize] * blk.w[p]).sum::<f32>()
            } else {
                0.0
            };
        }
    });
}

/// Pass 7, P-Eq. 19: grad p^pore_s = sum_s' V_s' (p_s' - p_s) grad W_ss'
/// over the solid-solid pairs `ss`, where `vol` is V_s' (0 for non-porous
/// particles, which neither get nor give a gradient).
pub fn pore_gradient(ss: &PairLists, vol: &[f32], pore_pressure: &[f32], out: VelMut) {
    out.x
        .par_chunks_mut(BLOCK)
        .zip(out.y.par_chunks_mut(BLOCK))
        .zip(out.z.par_chunks_mut(BLOCK))
        .zip(ss.used().par_iter())
        .enumerate()
        .for_each(|(b, (((gx, gy), gz), blk))| {
            for q in 0..gx.len() {
                let s = b * BLOCK + q;
                let mut g = [0.0f32; 3];
                if vol[s] > 0.0 {
                    let ps = pore_pressure[s];
                    for p in blk.range(q) {
                        let j = blk.j[p] as usize;
                        let c = vol[j] * (pore_pressure[j] - ps);
                        g[0] += c * blk.gx[p];
                        g[1] += c * blk.gy[p];
                        g[2] += c * blk.gz[p];
                    }
                }
                (gx[q], gy[q], gz[q]) = (g[0], g[1], g[2]);
            }
        });
}

/// The drained boundary of P-Eq. 19 for phase k, added to `out` (grad
/// p^pore_s of [`pore_gradient`]): sum_f V^out_fk (p_0k - p^pore_s)
/// grad W_sf over the solid-fluid pairs `sf`, with V^out_fk = alpha_fk h^3
/// the outer liquid of phase k next to s (`alpha` the fluid's volume
/// fractions alpha_fk, `cell` = h^3, m^3) and p_0k its pore
/// pressure (`outer_pressure`, per solid particle in the sorted order;
/// `absorbs[s]` = 0 where s is not porous or its region does not absorb
/// phase k). [`pore_gradient`]'s difference form leaves the missing
/// neighbours of a surface particle out, as if they held p^pore_s: a
/// surface in contact with no liquid is then no-flow, as it should be,
/// but so was a face in a pool, where the pores open to liquid at p_0k
/// (P-Eq. 9's equilibrium with the outside). The outer liquid around s
/// stands for those neighbours here, so the Darcy flux through such a
/// face is -(k/mu)(p^pore_s - p_0k) over the distance to the liquid;
/// inner liquid (alpha = 0), walls and non-absorbing solids add nothing
/// (no-flow). Measured on the squeezed sponge of `tests/deformable.rs`
/// (`squeeze_release_time_constant`): without it the rest of the sponge's
/// interior stayed at +3.9 kPa 0.5 s into the hold, with it +2.1 kPa.
pub fn drained_boundary(
    sf: &PairLists,
    (alpha, cell): (&[f32], f32),
    outer_pressure: &[f32],
    absorbs: &[f32],
    pore_pressure: &[f32],
    out: VelMut,
) {
    out.x
        .par_chunks_mut(BLOCK)
        .zip(out.y.par_chunks_mut(BLOCK))
        .zip(out.z.par_chunks_mut(BLOCK))
        .zip(sf.used().par_iter())
        .enumerate()
        .for_each(|(b, (((gx, gy), gz), blk))| {
            for q in 0..gx.len() {
                let s = b * BLOCK + q;
                if absorbs[s] == 0.0 {
                    continue;
                }
                let dp = outer_pressure[s] - pore_pressure[s];
                let mut g = [0.0f32; 3];
                for p in blk.range(q) {
                    let c = (alpha[blk.j[p] as usize] * cell) * dp;
                    g[0] += c * blk.gx[p];
                    g[1] += c * blk.gy[p];
                    g[2] += c * blk.gz[p];
                }
                gx[q] += g[0];
                gy[q] += g[1];
                gz[q] += g[2];
            }
        });
}

/// Pass 9, P-Eqs. 14 and 18: per fluid particle of the band (`out` per
/// slot; 0 elsewhere, `crate::band`), the capillary normal
/// sum_s psi_s V_s grad W_fs over the fluid-solid pairs `fs` (psi_s the
/// capillary strength of the solid's region): psi times the unnormalised
/// colour gradient of the porous solids, which points into the solid and
/// fades inside it (PHYSICS.md §8.9). a^cap = (sum_k beta_k) times this.
pub fn capillary_normal(fs: &PairLists, band: Band, vol: &[f32], psi: &[f32], out: VelMut) {
    let blocks = fs.used();
    out.x.par_iter_mut().zip(out.y.par_iter_mut()).zip(out.z.par_iter_mut()).zip(band.idx.par_iter()).for_each(
        |(((cx, cy), cz), &f)| {
            let (blk, q) = (&blocks[f as usize / BLOCK], f as usize % BLOCK);
            let mut c = [0.0f32; 3];
            for p in blk.range(q) {
                let s = blk.j[p] as usize;
                let vp = vol[s] * psi[s];
                c[0] += vp * blk.gx[p];
                c[1] += vp * blk.gy[p];
                c[2] += vp * blk.gz[p];
            }
            (*cx, *cy, *cz) = (c[0], c[1], c[2]);
        },
    );
}

/// Solid-side inputs of [`fluid_phase_terms`] for one phase k, per solid
/// particle in the sorted order.
#[derive(Clone, Copy)]
pub struct SolidPhase<'a> {
    /// V_s = m_s / rho_s (0 for non-porous particles), m^3.
    pub vol: &'a [f32],
    /// p^pore_s, Pa.
    pub pore_pressure: &'a [f32],
    /// phi_sk.
    pub phi: &'a [f32],
    /// p_0k of the particle's region, Pa.
    pub outer_pressure: &'a [f32],
    /// K k_wk / mu_k of the particle's region, m^2/(Pa s) (0: phase k is
    /// not absorbed there).
    pub conductivity: &'a [f32],
    /// u_betak,s = q_k,s / e + v_s, m/s.
    pub u_beta: Vel<'a>,
    /// Darcy flux q_k,s, m/s.
    pub q: Vel<'a>,
}

/// Fluid-side inputs of [`fluid_phase_terms`] for one phase k.
#[derive(Clone, Copy)]
pub struct FluidPhase<'a> {
    /// alpha_fk.
    pub alpha: &'a [f32],
    /// 1 / N_f (0 where N_f = 0).
    pub inv_n: &'a [f32],
}

/// Outputs of [`fluid_phase_terms`] for one phase k, per slot of the
/// fluid-solid band (`crate::band`; every other fluid particle has no solid
/// neighbour, and every term is 0 there).
pub struct FluidPhaseOut<'a> {
    /// u_betak,f = sum_s u_betak,s W_fs / N_f (P-Eq. 16), m/s.
    pub u_beta: VelMut<'a>,
    /// q_k,f = sum_s q_k,s W_fs / N_f (P-Eq. 17), m/s.
    pub q: VelMut<'a>,
    /// grad p^pore_fk = sum_s V_s (p^pore_s - p_0k) grad W_fs (P-Eq. 20),
    /// Pa/m.
    pub grad_pore: VelMut<'a>,
    /// The transfer rate Gamma_k, 1/s, > 0 absorption: the divergence of
    /// the absorption flux D_k = -K k_wk / mu_k (alpha_k + phi_sk)
    /// grad p^pore_k (P-Eq. 13) in pair form,
    ///
    /// Gamma_k = sum_s V_s^2 K k_wk / mu_k (alpha_fk + phi_sk)
    ///           (p_0k - p^pore_s) |grad W_fs|^2,
    ///
    /// each fluid-solid pair exchanging in proportion to its own pore
    /// pressure difference [inferred]. P-Eqs. 21-22 write it as D_f . n_f,
    /// D_f = sum_s V_s (..) grad W_fs and n_f = sum_s V_s grad W_fs, which
    /// both vanish inside the solid, where the solid's colour field is
    /// flat: a partly absorbed particle that the pore and capillary
    /// accelerations have drawn inside then keeps its outer fraction for
    /// good, and its row in the pressure solve fights the solid rows around
    /// it (measured: the soak of `tests/porous.rs` at K = 4, k_w = 4e-7
    /// reached its equilibrium and then blew up at t = 1.2 s). The pair
    /// form has the same sign, the same equilibrium p^pore = p_0k and the
    /// same K k_wk scaling (the paper's Fig. 4 trends), and goes on
    /// converting such a particle until its solids are saturated.
    pub gamma: &'a mut [f32],
}

/// Pass 9 for phase k over the fluid-solid pairs `fs` (module doc), for
/// the particles of `band`.
pub fn fluid_phase_terms(fs: &PairLists, band: Band, solid: SolidPhase, fluid: FluidPhase, out: FluidPhaseOut) {
    let FluidPhaseOut { u_beta, q, grad_pore, gamma } = out;
    let blocks = fs.used();
    u_beta
        .x
        .par_iter_mut()
        .zip(u_beta.y.par_iter_mut())
        .zip(u_beta.z.par_iter_mut())
        .zip(q.x.par_iter_mut().zip(q.y.par_iter_mut()).zip(q.z.par_iter_mut()))
        .zip(grad_pore.x.par_iter_mut().zip(grad_pore.y.par_iter_mut()).zip(grad_pore.z.par_iter_mut()))
        .zip(gamma.par_iter_mut().zip(band.idx.par_iter()))
        .for_each(|(((((ubx, uby), ubz), ((qx, qy), qz)), ((gx, gy), gz)), (ga, &f))| {
            let f = f as usize;
            let (blk, l) = (&blocks[f / BLOCK], f % BLOCK);
            let (inv_n, af) = (fluid.inv_n[f], fluid.alpha[f]);
            let (mut ub, mut qf, mut gp, mut rate) = ([0.0f32; 3], [0.0f32; 3], [0.0f32; 3], 0.0f32);
            for p in blk.range(l) {
                let s = blk.j[p] as usize;
                let v = solid.vol[s];
                if v == 0.0 {
                    continue;
                }
                let wn = blk.w[p] * inv_n;
                let g = [blk.gx[p], blk.gy[p], blk.gz[p]];
                let dp = solid.pore_pressure[s] - solid.outer_pressure[s];
                let g2 = g[0] * g[0] + g[1] * g[1] + g[2] * g[2];
                rate -= v * v * solid.conductivity[s] * (af + solid.phi[s]) * dp * g2;
                let us = [solid.u_beta.x[s], solid.u_beta.y[s], solid.u_beta.z[s]];
                let qs = [solid.q.x[s], solid.q.y[s], solid.q.z[s]];
                for c in 0..3 {
                    ub[c] += wn * us[c];
                    qf[c] += wn * qs[c];
                    gp[c] += v * dp * g[c];
                }
            }
            (*ubx, *uby, *ubz) = (ub[0], ub[1], ub[2]);
            (*qx, *qy, *qz) = (qf[0], qf[1], qf[2]);
            (*gx, *gy, *gz) = (gp[0], gp[1], gp[2]);
            *ga = rate;
        });
}

/// Adds a velocity term e (scaled by `scale`) to the phase velocities of
/// the drift passes (`drift::phase_velocity`): v_k += scale e and
/// w_k += scale alpha_k e, where the particle's fraction sum `frac_f` is at
/// least `crate::phases::MIN_ALPHA_F` (elsewhere the drift is 0). With
/// e = grad p^pore_fk and scale = -phi this is the porous term of P-Eq. 11,
/// with e = q_k,f and scale = -tau' the Darcy term of P-Eq. 12: after
/// `drift::mixture_velocity` and `drift::drift_velocity` both appear as
/// e_k - sum_k' c_k' e_k'. `e` is phase k's of a field on the fluid-solid
/// band (`crate::band`).
pub fn add_phase_term(frac_k: &[f32], frac_f: &[f32], e: BandVel, k: usize, scale: f32, v: VelMut, w: VelMut) {
    v.x.par_chunks_mut(BLOCK)
        .zip(v.y.par_chunks_mut(BLOCK))
        .zip(v.z.par_chunks_mut(BLOCK))
        .zip(w.x.par_chunks_mut(BLOCK).zip(w.y.par_chunks_mut(BLOCK)).zip(w.z.par_chunks_mut(BLOCK)))
        .enumerate()
        .for_each(|(b, (((vx, vy), vz), ((wx, wy), wz)))| {
            for q in 0..vx.len() {
                let i = b * BLOCK + q;
                if frac_f[i] < crate::phases::MIN_ALPHA_F {
                    continue;
                }
                let t = e.get(k, i).map(|e| scale * e);
                let a = frac_k[i];
                vx[q] += t[0];
                vy[q] += t[1];
                vz[q] += t[2];
                wx[q] += a * t[0];
                wy[q] += a * t[1];
                wz[q] += a * t[2];
            }
        });
}

/// The part of the drift velocity u_mk that P-Eq. 11's porous term gives
/// (after [`add_phase_term`] and the mixture sums of `drift`), subtracted:
/// `out` = u_mk - (t_k - sum_k' c_k' t_k'), t_k = `scale` e_k, c_k the mass
/// fractions alpha_k rho_k / sum_k' alpha_k' rho_k'; where `frac_f` <
/// `crate::phases::MIN_ALPHA_F` or the particle has no mass the drift has
/// no such part and `out` = u_mk. In place: `u` holds u_mk and becomes
/// `out`; phase k at `[k n, (k + 1) n)` of each component; `e` on the
/// fluid-solid band, `mean` scratch of the band's length.
///
/// What it is for: the drift momentum term a^Dm (`drift_momentum`) of the
/// phases' buoyancy slip and diffusion, without the momentum flux of the
/// pore drift, -(1/rho) div(sum_k alpha_k rho_k u^pore_mk u^pore_mk).
/// The pore drift is P's model of the suction at a porous surface
/// (P §4.2: "sucking or propelling effects due to absorption or emission
/// near the porous solid surface"): phi (p_0k - p^pore_s) across the one
/// support that P-Eq. 20's one-sided sum spans, u ~ phi dp / H, several m/s
/// at P Table 2's values in the fluid layer next to the surface and 0 one
/// support away. As a momentum flux rho alpha u^2 that is a pressure of
/// about 8 kPa (rho 1000, alpha 1/3, u 5 m/s), a third of the pore
/// pressure difference itself and growing as 1/H^2 under refinement, with
/// no counterpart in the poroelastic model it stands for (P-Eq. 8 has no
/// drift momentum term; PHYSICS.md §4.1 takes a^Dm from the mixture model
/// of Ren et al. 2014, where u_mk is a real slip). Example 5 measured
/// (bench/RESULTS.md): with it, 310 m/s^2 in the first step from rest and
/// fluid particles above 3 m/s in 102 of 661 steps to 0.3 s; without it,
/// gravity alone in the first step and none above 2.6 m/s.
#[allow(clippy::too_many_arguments)]
pub fn without_phase_term(
    frac: &[&[f32]],
    frac_f: &[f32],
    density: &[f32],
    e: BandVel,
    scale: f32,
    u: VelMut,
    mean: VelMut,
) {
    let n = frac_f.len();
    let np = frac.len();
    // sum_k' c_k' t_k' per band slot; outside the band every e_k is 0 and
    // so is this sum (+0.0, as the sum over the zero terms gives).
    let band = e.band;
    mean.x.par_iter_mut().zip(mean.y.par_iter_mut()).zip(mean.z.par_iter_mut()).zip(band.idx.par_iter()).for_each(
        |(((mx, my), mz), &i)| {
            let i = i as usize;
            let mass: f32 = (0..np).map(|k| frac[k][i] * density[k]).sum();
            let mut m = [0.0f32; 3];
            if frac_f[i] >= crate::phases::MIN_ALPHA_F && mass > 0.0 {
                for (k, rho) in density.iter().enumerate() {
                    let c = frac[k][i] * rho;
                    let e = e.get(k, i);
                    m[0] += c * (scale * e[0]);
                    m[1] += c * (scale * e[1]);
                    m[2] += c * (scale * e[2]);
                }
                m = m.map(|m| m / mass);
            }
            (*mx, *my, *mz) = (m[0], m[1], m[2]);
        },
    );
    for (c, (o, m)) in [u.x, u.y, u.z].into_iter().zip([&*mean.x, &*mean.y, &*mean.z]).enumerate() {
        o.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
            for (q, o) in o.iter_mut().enumerate() {
                let r = b * BLOCK + q;
                let (k, i) = (r / n, r % n);
                if frac_f[i] >= crate::phases::MIN_ALPHA_F {
                    let m = band.slot(i).map_or(0.0, |s| m[s]);
                    *o -= scale * e.get(k, i)[c] - m;
                }
            }
        });
    }
}

/// Below this fraction the absorption exchange moves all of it
/// (PHYSICS.md §4.2, after [AC] `ComputeFluidChange`).
pub const MIN_EXCHANGE_FRACTION: f32 = 0.001;

/// Pass 12, the absorption exchange of phase k within each fluid particle
/// (P-Eqs. 6-7: +div D_k in alpha, -div D_k in beta): x = dt Gamma_k moves
/// from `alpha` to `beta` (x > 0, absorption) or back (x < 0, emission),
/// at most what the source holds, and all of it where less than
/// [`MIN_EXCHANGE_FRACTION`] would be left. alpha_k + beta_k is unchanged
/// up to f64 rounding, so every phase's mass is conserved (the fractions
/// are the f64 ones of the step's transport, `phases::join`). Gamma_k is
/// phase k's of `gamma`, on the fluid-solid band (0 elsewhere: x = 0
/// moves nothing, as before the band).
pub fn exchange(gamma: BandField, k: usize, dt: f32, alpha: &mut [f64], beta: &mut [f64]) {
    let min = f64::from(MIN_EXCHANGE_FRACTION);
    alpha.par_chunks_mut(BLOCK).zip(beta.par_chunks_mut(BLOCK)).enumerate().for_each(|(b, (a, be))| {
        for q in 0..a.len() {
            let x = f64::from(dt * gamma.get(k, b * BLOCK + q));
            let moved = if x > 0.0 {
                let src = a[q].max(0.0);
                if src - x < min {
                    src
                } else {
                    x
                }
            } else if x < 0.0 {
                let src = be[q].max(0.0);
                if src + x < min {
                    -src
                } else {
                    x
                }
            } else {
                0.0
            };
            a[q] -= moved;
            be[q] += moved;
        }
    });
}

/// P Alg. 4's fallback, at the start of a step: a fluid particle with no
/// porous solid within reach (N_f = 0) has nothing to be inside of, so its
/// inner fractions become outer ones, alpha_k += beta_k, beta_k = 0.
pub fn release_outside(n_f: &[f32], alpha: Fractions, beta: Fractions) {
    move_between(alpha, beta, |i, a, b| (n_f[i] <= 0.0 && b != 0.0).then_some((a + b, 0.0)));
}

/// One phase's fractions in the store: `hi` and `lo` of `phases::join`.
pub struct Fractions<'a> {
    pub hi: &'a mut [f32],
    pub lo: &'a mut [f32],
}

/// Per fluid particle i, `f(i, alpha, beta)` on the joined outer and inner
/// fraction of one phase; where it gives new ones, they are stored split.
fn move_between(alpha: Fractions, beta: Fractions, f: impl Fn(usize, f64, f64) -> Option<(f64, f64)> + Sync) {
    let outer = alpha.hi.par_chunks_mut(BLOCK).zip(alpha.lo.par_chunks_mut(BLOCK));
    let inner = beta.hi.par_chunks_mut(BLOCK).zip(beta.lo.par_chunks_mut(BLOCK));
    outer.zip(inner).enumerate().for_each(|(b, ((ah, al), (bh, bl)))| {
        for q in 0..ah.len() {
            if let Some((a, be)) = f(b * BLOCK + q, join(ah[q], al[q]), join(bh[q], bl[q])) {
                (ah[q], al[q]) = split(a);
                (bh[q], bl[q]) = split(be);
            }
        }
    });
}

/// Liquid amid a porous solid is in its pores: a fluid particle whose
/// neighbourhood the porous solid fills moves its outer fraction of phase
/// k into its inner one within the particle, alpha_k -> beta_k ([AC]
/// `FindNearbySolid` moves all of it above a neighbour count). `fill_k`
/// is the fill by the solids that absorb phase k and the walls
/// (h^3 sum_s (1 + tr eps_s) W_fs + sum_b V0_b W_fb, `pipeline::porous`):
/// 1 deep inside, 0.725 at a solid's surface layer, about 0.86 half a
/// spacing inside it. Each step moves the share `inside_share(fill)` of
/// alpha_k: nothing below [`INSIDE_FILL`], all of it from a full
/// neighbourhood, a smoothstep between (a cut would turn rounding
/// differences into whole particles moved). Partly absorbed particles left
/// deep inside a soaked solid (emission, or absorption stopped at
/// saturation around them) would otherwise keep pressure rows that the
/// solid compresses and nothing relieves (measured: alpha_f 0.8 particles
/// inside a held soaking block with 1e7 Pa and densities of 2,000 kg/m^3,
/// kicked to 30 m/s). Emission (beta -> alpha, P-Eq. 22 with p^pore >
/// p_0k) then sticks only near the surface, where the liquid leaves the
/// solid; inside, the liquid reaches it by Darcy flow.
pub fn take_inside(fill_k: &[f32], alpha: Fractions, beta: Fractions) {
    move_between(alpha, beta, |i, a, b| {
        let share = inside_share(fill_k[i]);
        (share > 0.0 && a != 0.0).then(|| {
            let moved = if share >= 1.0 { a } else { f64::from(share) * a };
            (a - moved, b + moved)
        })
    });
}

/// The fill from which [`take_inside`] moves outer liquid inside: about
/// half a spacing beneath a solid's surface layer.
pub const INSIDE_FILL: f32 = 0.95;

/// The share of alpha_k that [`take_inside`] moves at a fill: 0 up to
/// [`INSIDE_FILL`], 1 from 1, a smoothstep between.
#[inline]
pub fn inside_share(fill: f32) -> f32 {
    if fill <= INSIDE_FILL {
        0.0
    } else if fill >= 1.0 {
        1.0
    } else {
        let t = (fill - INSIDE_FILL) / (1.0 - INSIDE_FILL);
        t * t * (3.0 - 2.0 * t)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exchange_conserves_each_particle_and_clamps() {
        // Particle 4 is outside the band: Gamma 0 there.
        let arena = bumpalo::Bump::new();
        let band = Band::new(&arena, 5, |i| i < 4);
        let gamma = BandField { band, v: &[10.0, -10.0, 500.0, -500.0] };
        let mut a = vec![0.5, 0.5, 0.4, 0.5, 0.3];
        let mut b = vec![0.5, 0.5, 0.6, 0.2, 0.7];
        let (a0, b0) = (a.clone(), b.clone());
        exchange(gamma, 0, 1e-3, &mut a, &mut b);
        for i in 0..5 {
            assert!((a[i] + b[i] - a0[i] - b0[i]).abs() < 1e-7, "particle {i}");
        }
        assert!((a[0] - 0.49).abs() < 1e-7 && (b[1] - 0.49).abs() < 1e-7);
        // dt Gamma = 0.5 > alpha = 0.4: all of alpha moves, no more.
        assert_eq!((a[2], b[2]), (0.0, 1.0));
        // Emission of 0.5 > beta = 0.2: all of beta moves back.
        assert_eq!((a[3], b[3]), (0.7, 0.0));
        assert_eq!((a[4], b[4]), (0.3, 0.7));
    }

    #[test]
    fn release_outside_moves_beta_to_alpha_only_without_solids() {
        let n = [0.0, 3.0];
        let (mut a, mut b) = (vec![0.2, 0.2], vec![0.8, 0.8]);
        let (mut al, mut bl) = (vec![0.0; 2], vec![0.0; 2]);
        release_outside(&n, Fractions { hi: &mut a, lo: &mut al }, Fractions { hi: &mut b, lo: &mut bl });
        assert_eq!((a, b), (vec![1.0, 0.2], vec![0.0, 0.8]));
        assert_eq!((al[1], bl), (0.0, vec![0.0; 2]));
    }
}
