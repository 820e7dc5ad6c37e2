//! The porous coupling in the step (P §4-5 and Algorithms 2-3; PHYSICS.md
//! §4.2): passes 6-7 and 9 of PHYSICS.md §6, and the porous accelerations
//! a^pore and a^cap of P-Eq. 8. The gathers are in
//! `porosph_kernels::porous`; this module feeds them, in the order the
//! step needs:
//!
//! 1. [`partition`], right after the neighbour search: N_f (P-Eq. 15) and
//!    P Alg. 4's fallback (beta back to alpha where N_f = 0).
//! 2. [`pore_state`], before the pressure solve scales the fluid-solid pair
//!    gradients (it reads the plain `PairSet`, which `pressure::setup`
//!    borrows for the rest of the step once it scales it): phi_sk, the wet mass (optional), p^pore (P-Eq. 9),
//!    grad p^pore, q_k and u_betak on the solids (P-Eqs. 1, 19), and on the
//!    fluid u_betak,f, q_k,f, grad p^pore_fk, Gamma_k and the surface
//!    capillary normal (P-Eqs. 16-18, 20-22).
//! 3. [`accelerations`], after the pressure solve: a^cap and a^pore.
//!
//! The pore pressure uses the volumetric strain tr(eps) of the previous
//! step's elastic solve (the solid store's `strain_trace`): the elastic
//! pass needs p^pore in its stress (P-Eq. 5), so p^pore comes first and
//! the strain it sees lags by one step (0 at the start: strain-free).

use super::neighbours::FluidDensity;
use super::phases;
use super::step::StepCtx;
use super::timing::Pass;
use super::{in_sorted_order, PairSet, Params, Workspace};
use crate::store::{FluidStore, SolidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::band::{Band, BandField, BandVel};
use porosph_kernels::blocks::BLOCK;
use porosph_kernels::iisph::{self};
use porosph_kernels::neighbors::{update_sums, PairLists};
use porosph_kernels::porous::{
    absorbed_volume, capillary_normal, drained_boundary, fluid_phase_terms, pore_gradient, release_outside,
    take_inside, FluidPhase, FluidPhaseOut, Fractions, SolidPhase,
};
use porosph_kernels::soa::{zeros, zeros3, Vel, VelMut};
use rayon::prelude::*;

/// N_f per fluid particle and the porous mask of the solids (1 for a
/// particle of a porous solid), in the sorted order of the solid pair lists.
pub(super) struct Partition<'a> {
    pub n_f: &'a [f32],
    pub mask: &'a [f32],
    /// h^3 sum_s W_fs over the solid particles that absorb phase k (phase
    /// k at `[k n, (k + 1) n)`), for [`settle`].
    pub fill: &'a [f32],
}

/// Pass 2's part of the porous coupling: N_f = sum_s W_fs over the porous
/// solid particles within reach of each fluid particle (P-Eq. 15's
/// weights), and P Alg. 4's fallback: where N_f = 0 every beta_k moves back
/// to alpha_k; and the fill of each phase's absorbing solids around each
/// fluid particle, for [`settle`] at the end of the step. The release
/// changes the rest volumes V0 of the particles it moves: `density` (the
/// neighbour pass's V0 and sum_j V0_j W_ij) follows them.
pub(super) fn partition<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &mut FluidStore,
    solids: &SolidStore,
    walls: &WallStore,
    w: &Workspace,
    pairs: &PairSet,
    density: &mut FluidDensity<'a>,
) -> Partition<'a> {
    let (p, arena) = (cx.p, cx.arena);
    let tmp = cx.scratch.fresh();
    let tm = &mut cx.tm;
    tm.time(Pass::Porous, || {
        let mask = in_sorted_order(arena, &w.solid_perm, |i| p.porous[solids.body[i] as usize].is_some() as u32 as f32);
        let n_f = zeros(arena, fluid.len());
        iisph::kernel_sums(&pairs.fs, mask, n_f);
        for (alpha, beta) in outer_inner(fluid) {
            release_outside(n_f, alpha, beta);
        }
        let v0 = zeros(arena, fluid.len());
        phases::rest_volumes(p.cell_volume(), fluid, v0);
        let x = Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        update_sums(&pairs.ff, x, &p.kernel, density.v0, v0, density.own);
        density.v0 = v0;
        // The fill of each phase's absorbing solids, for `settle`: each
        // solid particle counts with its current volume h^3 (1 + tr eps)
        // (the strain of the last step), so that a squeezed solid does not
        // read as fuller than a relaxed one (with h^3 alone, a sponge
        // squeezed to tr(eps) = -0.12 read as full up to its faces, and no
        // liquid could leave it).
        let (n, cell) = (fluid.len(), p.cell_volume());
        let fill = zeros(arena, fluid.alpha.len() * n);
        for (k, fill) in fill.chunks_mut(n.max(1)).enumerate() {
            let absorbs = in_sorted_order(tmp, &w.solid_perm, |i| {
                let r = p.porous[solids.body[i] as usize].as_ref();
                let volume = cell * (1.0 + solids.strain_trace[i]).max(0.0);
                r.is_some_and(|r| r.phases[k].is_some()) as u32 as f32 * volume
            });
            iisph::kernel_sums(&pairs.fs, absorbs, fill);
        }
        // Walls fill the neighbourhood as well as the solid does: a partly
        // absorbed particle inside a soaking block next to the tank's floor
        // and front wall (solid fill 0.8, walls the rest) kept its row,
        // compressed by both, and its pressure rose tenfold per step to
        // 2.7e9 Pa.
        let walls_fill = zeros(tmp, n);
        iisph::kernel_sums(&pairs.fb, &walls.rest_volume, walls_fill);
        for fill in fill.chunks_mut(n.max(1)) {
            fill.par_iter_mut().zip(walls_fill.par_iter()).for_each(|(f, &b)| {
                if *f > 0.0 {
                    *f += b;
                }
            });
        }
        Partition { n_f, mask, fill }
    })
}

/// The end of the step (P Alg. 4, after the fractions' correction): where a
/// solid that absorbs phase k fills a fluid particle's neighbourhood,
/// alpha_k moves into beta_k (`porosph_kernels::porous::take_inside`).
/// Applied after the step's exchange, so that the solids' wet mass of the
/// next step sees the inner volume the step ends with.
pub(super) fn settle(cx: &mut StepCtx, fluid: &mut FluidStore, part: &Partition) {
    let tm = &mut cx.tm;
    let n = fluid.len();
    tm.time(Pass::Porous, || {
        for (k, (alpha, beta)) in outer_inner(fluid).enumerate() {
            take_inside(&part.fill[k * n..(k + 1) * n], alpha, beta);
        }
    });
}

/// Each phase's outer and inner fractions in the store, with their low parts.
fn outer_inner(fluid: &mut FluidStore) -> impl Iterator<Item = (Fractions<'_>, Fractions<'_>)> {
    let outer = fluid.alpha.iter_mut().zip(fluid.alpha_lo.iter_mut());
    let inner = fluid.beta.iter_mut().zip(fluid.beta_lo.iter_mut());
    outer.zip(inner).map(|((ah, al), (bh, bl))| (Fractions { hi: ah, lo: al }, Fractions { hi: bh, lo: bl }))
}

/// P Alg. 2 and the solid side of Alg. 3 ([`pore_state`]), before the
/// pressure solve scales the fluid-solid pair gradients by pair volumes;
/// with several phases also the fluid pairs of the inner transport
/// (`w.ffb`: h^3 grad W, the full-particle volumes that the pressure
/// solve's pair volumes, 0 for an inner particle, would cut off).
pub(super) fn solid_terms<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &FluidStore,
    solids: &mut SolidStore,
    w: &mut Workspace,
    pairs: &PairSet,
    part: &Partition,
    mixture: bool,
) -> PoreTerms<'a> {
    let (p, arena) = (cx.p, cx.arena);
    let scratch = &mut *cx.scratch;
    let tm = &mut cx.tm;
    tm.time(Pass::Porous, || {
        if mixture {
            let active = near_inner_fluid(fluid, &pairs.ff, scratch.fresh());
            w.ffb.copy_scaled_where(&pairs.ff, p.cell_volume(), active);
        }
        pore_state(p, fluid, solids, w, pairs, (arena, scratch.fresh()), part)
    })
}

/// The fluid particles that have inner fluid (some beta_k,i > 0) or a
/// neighbour with it: only there do the inner drift (P-Eq. 12, 0 where
/// beta_f < `MIN_ALPHA_F`) and the inner transport (pair fluxes
/// (F_k,i + F_k,j) . grad W, F_k = 0 where beta_f < `MIN_ALPHA_F`) have a
/// nonzero term, so only their pairs go into `w.ffb` (bit for bit the same
/// fractions; most of a pool never touches a porous solid).
fn near_inner_fluid<'a>(fluid: &FluidStore, ff: &PairLists, arena: &'a Bump) -> &'a [bool] {
    let n = fluid.len();
    let wet = arena.alloc_slice_fill_copy(n, false);
    wet.par_iter_mut().enumerate().for_each(|(i, w)| *w = fluid.beta.iter().any(|b| b[i] > 0.0));
    // Marked from the wet particles' own pairs (few: the pool around a
    // sponge is dry), which the symmetric lists allow: j is i's neighbour
    // if i is j's (the same distance test). Scanning every particle's pairs for a wet one took about
    // 7 ms a step in the porous bench at 261k fluid particles (its porous
    // pass 33.7 -> 27.6 ms, bench/RESULTS.md).
    let active = arena.alloc_slice_fill_copy(n, false);
    let blocks = ff.used();
    for i in (0..n).filter(|&i| wet[i]) {
        active[i] = true;
        let blk = &blocks[i / BLOCK];
        for &j in &blk.j[blk.range(i % BLOCK)] {
            active[j as usize] = true;
        }
    }
    active
}

/// The absorption exchange of pass 12 (P-Eqs. 6-7, 22) within each
/// particle, after the transport: alpha_k -= dt Gamma_k, beta_k += dt
/// Gamma_k on the next fractions (phase k at `[k n, (k + 1) n)`).
pub(super) fn exchange(cx: &mut StepCtx, terms: &PoreTerms, n: usize, alpha_next: &mut [f64], beta_next: &mut [f64]) {
    let dt = cx.dt;
    let tm = &mut cx.tm;
    tm.time(Pass::PhaseTransport, || {
        for (k, (a, b)) in alpha_next.chunks_mut(n).zip(beta_next.chunks_mut(n)).enumerate() {
            porosph_kernels::porous::exchange(terms.gamma, k, dt, a, b);
        }
    });
}

/// The fluid-side porous fields of one step, on the band of the fluid
/// particles with a solid neighbour (`porosph_kernels::band`: 0 at every
/// other fluid particle, where no pair adds to them).
pub(super) struct PoreTerms<'a> {
    /// sum_s psi_s V_s grad W_fs: a^cap = (sum_k beta_k) times this (P-Eq. 18).
    pub capillary: BandVel<'a>,
    /// sum_k beta_k rho_k u_betak,f (u_betak,f of P-Eq. 16), kg/(m^2 s).
    pub inner_flux: BandVel<'a>,
    /// q_k,f (P-Eq. 17), m/s.
    pub q: BandVel<'a>,
    /// grad p^pore_fk (P-Eq. 20), Pa/m.
    pub grad_pore: BandVel<'a>,
    /// Gamma_k (P-Eq. 22), 1/s.
    pub gamma: BandField<'a>,
    /// eta p^pore per solid particle (store order), Pa, for the stress
    /// (P-Eq. 5); `None` where no porous solid swells.
    pub pore_stress: Option<&'a [f32]>,
    /// Largest Darcy speed max_k |u_rk| on the solids, m/s (time step).
    pub max_darcy_speed: f32,
}

/// Passes 6, 7 and 9 (module doc). `n_f` and `mask` come from
/// [`partition`]; `pairs.fs` must still hold plain kernel gradients. The
/// terms go to `arena`, the fields they come from to `tmp` (pass
/// scratch).
fn pore_state<'a>(
    p: &Params,
    fluid: &FluidStore,
    solids: &mut SolidStore,
    w: &Workspace,
    pairs: &PairSet,
    (arena, tmp): (&'a Bump, &Bump),
    part: &Partition,
) -> PoreTerms<'a> {
    let (n_f, mask) = (part.n_f, part.mask);
    let (n, ns, np) = (fluid.len(), solids.len(), fluid.alpha.len());
    let perm = &w.solid_perm;
    let cell = p.cell_volume();
    let region = |k: usize| p.porous[solids.body[perm[k] as usize] as usize].as_ref();
    let inv_n = zeros(tmp, n);
    inv_n.par_iter_mut().zip(n_f.par_iter()).for_each(|(o, &x)| *o = if x > 0.0 { 1.0 / x } else { 0.0 });

    // P-Eq. 15: phi_sk (sorted order), phase by phase.
    let phi = zeros(tmp, np * ns);
    let beta_over_n = zeros(tmp, n);
    for (k, out) in phi.chunks_mut(ns.max(1)).enumerate().take(np) {
        beta_over_n.par_iter_mut().zip(fluid.beta[k].par_iter()).zip(inv_n.par_iter()).for_each(|((o, b), i)| {
            *o = b * i;
        });
        absorbed_volume(&pairs.sf, beta_over_n, mask, out);
    }
    let phi: &[&[f32]] = tmp.alloc_slice_fill_iter(phi.chunks(ns.max(1)).take(np));

    // The wet mass of the paper's Example 3: m_s = m_s0 + sum_k phi_sk rho_k V_s0.
    for (k, &i) in perm.iter().enumerate() {
        let i = i as usize;
        let b = solids.body[i] as usize;
        if p.porous[b].as_ref().is_some_and(|r| r.gains_mass) {
            let wet: f32 = (0..np).map(|ph| phi[ph][k] * p.phase_density[ph]).sum();
            solids.mass[i] = p.solid_rest_mass[b] + wet * cell;
        }
    }

    // P-Eq. 9: p^pore = p_0 sum_k phi_sk - B tr(eps); V_s = m_s / rho_s (P §5).
    let pore = zeros(tmp, ns);
    let vol = zeros(tmp, ns);
    {
        let mass_s = in_sorted_order(tmp, perm, |i| solids.mass[i]);
        let rho_s = zeros(tmp, ns);
        iisph::kernel_sums(&pairs.ss, mass_s, rho_s);
        let sat = zeros(tmp, ns);
        let strain = &solids.strain_trace;
        let state = pore.par_chunks_mut(BLOCK).zip(vol.par_chunks_mut(BLOCK)).zip(sat.par_chunks_mut(BLOCK));
        state.enumerate().for_each(|(b, ((pore, vol), sat))| {
            for o in 0..pore.len() {
                let k = b * BLOCK + o;
                sat[o] = (0..np).map(|ph| phi[ph][k]).sum();
                if let Some(r) = region(k) {
                    pore[o] = r.rest_pore_pressure * sat[o] - r.biot_modulus * strain[perm[k] as usize];
                    vol[o] = if rho_s[k] > 0.0 { mass_s[k] / rho_s[k] } else { 0.0 };
                }
            }
        });
        let store = solids.saturation.par_iter_mut().zip(solids.pore_pressure.par_iter_mut());
        store.zip(w.solid_inv.par_iter()).for_each(|((s, p), &k)| (*s, *p) = (sat[k as usize], pore[k as usize]));
    }

    // P-Eqs. 19, 1: grad p^pore, q_k = -(k_wk / mu_k) grad p^pore,
    // u_rk = q_k / e, u_betak = u_rk + v_s.
    let VelMut { x: gx, y: gy, z: gz } = zeros3(tmp, ns);
    pore_gradient(&pairs.ss, vol, pore, VelMut { x: &mut *gx, y: &mut *gy, z: &mut *gz });
    // The drained boundary: the outer liquid of each absorbed phase stands
    // for a surface particle's missing neighbours at p_0k.
    for k in 0..np {
        let (p0k, absorbs) = (zeros(tmp, ns), zeros(tmp, ns));
        p0k.par_iter_mut().zip(absorbs.par_iter_mut()).enumerate().for_each(|(s, (p0k, absorbs))| {
            let phase = region(s).and_then(|r| r.phases[k]);
            *p0k = phase.map_or(0.0, |ph| ph.outer_pore_pressure);
            *absorbs = (vol[s] > 0.0 && phase.is_some()) as u32 as f32;
        });
        let g = VelMut { x: &mut *gx, y: &mut *gy, z: &mut *gz };
        drained_boundary(&pairs.sf, (&fluid.alpha[k], cell), p0k, absorbs, pore, g);
    }
    let mut max_darcy = 0.0f32;
    let mut solid_phase = |k: usize| {
        let VelMut { x: qx, y: qy, z: qz } = zeros3(tmp, ns);
        let VelMut { x: ux, y: uy, z: uz } = zeros3(tmp, ns);
        let p0k = zeros(tmp, ns);
        let cond = zeros(tmp, ns);
        let mu = p.phase_viscosity[k];
        let (g, v) = ([&*gx, &*gy, &*gz], [&solids.vx, &solids.vy, &solids.vz]);
        let q = qx.par_chunks_mut(BLOCK).zip(qy.par_chunks_mut(BLOCK)).zip(qz.par_chunks_mut(BLOCK));
        let u = ux.par_chunks_mut(BLOCK).zip(uy.par_chunks_mut(BLOCK)).zip(uz.par_chunks_mut(BLOCK));
        let c = p0k.par_chunks_mut(BLOCK).zip(cond.par_chunks_mut(BLOCK));
        let fastest = q.zip(u).zip(c).enumerate().map(|(b, ((((qx, qy), qz), ((ux, uy), uz)), (p0k, cond)))| {
            let mut fastest = 0.0f32;
            for o in 0..qx.len() {
                let s = b * BLOCK + o;
                let i = perm[s] as usize;
                let Some(r) = region(s) else { continue };
                let phase = r.phases[k];
                let kw = match phase {
                    Some(ph) if mu > 0.0 => ph.permeability / mu,
                    _ => 0.0,
                };
                (qx[o], qy[o], qz[o]) = (-kw * g[0][s], -kw * g[1][s], -kw * g[2][s]);
                let e = r.porosity;
                (ux[o], uy[o], uz[o]) = (qx[o] / e + v[0][i], qy[o] / e + v[1][i], qz[o] / e + v[2][i]);
                fastest = fastest.max((qx[o] * qx[o] + qy[o] * qy[o] + qz[o] * qz[o]).sqrt() / e);
                p0k[o] = phase.map_or(0.0, |ph| ph.outer_pore_pressure);
                cond[o] = r.absorption * kw;
            }
            fastest
        });
        max_darcy = max_darcy.max(fastest.reduce(|| 0.0, f32::max));
        (Vel { x: qx, y: qy, z: qz }, Vel { x: ux, y: uy, z: uz }, &*p0k, &*cond)
    };
    let per_solid = tmp.alloc_slice_fill_iter((0..np).map(&mut solid_phase));

    // Pass 9 on the fluid, on the band of the fluid particles with a solid
    // neighbour (every term is 0 elsewhere).
    let fs = pairs.fs.used();
    let band = Band::new(arena, n, |i| !fs[i / BLOCK].range(i % BLOCK).is_empty());
    let m = band.len();
    let VelMut { x: cx, y: cy, z: cz } = zeros3(arena, m);
    let psi = zeros(tmp, ns);
    psi.par_iter_mut().enumerate().for_each(|(k, psi)| *psi = region(k).map_or(0.0, |r| r.capillarity));
    capillary_normal(&pairs.fs, band, vol, psi, VelMut { x: &mut *cx, y: &mut *cy, z: &mut *cz });
    let flat = |arena: &'a Bump| [zeros(arena, np * m), zeros(arena, np * m), zeros(arena, np * m)];
    // u_betak,f of one phase at a time (pass scratch), summed into the
    // inner mass flux sum_k beta_k rho_k u_betak,f, all that a^pore reads.
    let [ubx, uby, ubz] = [zeros(tmp, m), zeros(tmp, m), zeros(tmp, m)];
    let mut u_in = [zeros(arena, m), zeros(arena, m), zeros(arena, m)];
    let [qfx, qfy, qfz] = flat(arena);
    let [gpx, gpy, gpz] = flat(arena);
    let gamma = zeros(arena, np * m);
    for (k, &(q_s, u_s, p0k, cond)) in per_solid.iter().enumerate() {
        let r = k * m..(k + 1) * m;
        let solid = SolidPhase {
            vol,
            pore_pressure: pore,
            phi: phi[k],
            outer_pressure: p0k,
            conductivity: cond,
            u_beta: u_s,
            q: q_s,
        };
        let fl = FluidPhase { alpha: &fluid.alpha[k], inv_n };
        let out = FluidPhaseOut {
            u_beta: VelMut { x: &mut *ubx, y: &mut *uby, z: &mut *ubz },
            q: VelMut { x: &mut qfx[r.clone()], y: &mut qfy[r.clone()], z: &mut qfz[r.clone()] },
            grad_pore: VelMut { x: &mut gpx[r.clone()], y: &mut gpy[r.clone()], z: &mut gpz[r.clone()] },
            gamma: &mut gamma[r],
        };
        fluid_phase_terms(&pairs.fs, band, solid, fl, out);
        let (rho, beta, [sx, sy, sz]) = (p.phase_density[k], &fluid.beta[k], &mut u_in);
        (&mut **sx, &mut **sy, &mut **sz).into_par_iter().enumerate().for_each(|(s, (x, y, z))| {
            let mass = beta[band.idx[s] as usize] * rho;
            (*x, *y, *z) = (*x + mass * ubx[s], *y + mass * uby[s], *z + mass * ubz[s]);
        });
    }

    let swells = p.porous.iter().flatten().any(|r| r.swelling > 0.0);
    let pore_stress = swells.then(|| {
        let out = zeros(arena, ns);
        out.par_iter_mut().zip(w.solid_inv.par_iter()).for_each(|(o, &k)| {
            let k = k as usize;
            *o = region(k).map_or(0.0, |r| r.swelling) * pore[k];
        });
        &*out
    });
    let [ix, iy, iz] = u_in;
    PoreTerms {
        capillary: BandVel { band, x: cx, y: cy, z: cz },
        inner_flux: BandVel { band, x: ix, y: iy, z: iz },
        q: BandVel { band, x: qfx, y: qfy, z: qfz },
        grad_pore: BandVel { band, x: gpx, y: gpy, z: gpz },
        gamma: BandField { band, v: gamma },
        pore_stress,
        max_darcy_speed: max_darcy,
    }
}

/// The porous accelerations of P-Eq. 8, added to `ap` (which holds a^p):
/// - a^cap = psi (sum_k beta_k) n_f (P-Eqs. 14, 18);
/// - a^pore = sum_k beta_k (rho_k u_betak,f - rho_betam u_m) / (rho_fm dt)
///   (P-Eq. 10) = sum_k beta_k rho_k (u_betak,f - u_m) / (rho_fm dt), with
///   u_m = u* + dt (a^p + a^cap) the velocity the particle would have
///   without it. So u^{n+1} = B ubar_beta + (1 - B) u_m with
///   B = sum_k beta_k rho_k / rho_fm, the inner mass fraction, and
///   ubar_beta the inner phases' mass-weighted velocity: a fully inner
///   particle moves with the Darcy velocity of its solid in one step, as
///   PHYSICS.md §4.2 says.
pub(super) fn accelerations(
    p: &Params,
    fluid: &FluidStore,
    terms: &PoreTerms,
    rest_density: &[f32],
    u_star: Vel,
    dt: f32,
    ap: [&mut [f32]; 3],
) {
    let np = fluid.beta.len();
    let [apx, apy, apz] = ap;
    apx.par_chunks_mut(BLOCK).zip(apy.par_chunks_mut(BLOCK)).zip(apz.par_chunks_mut(BLOCK)).enumerate().for_each(
        |(b, ((ax, ay), az))| {
            for q in 0..ax.len() {
                let i = b * BLOCK + q;
                let (mut bsum, mut bmass) = (0.0f32, 0.0f32);
                for k in 0..np {
                    let bk = fluid.beta[k][i];
                    bsum += bk;
                    bmass += bk * p.phase_density[k];
                }
                let u_in = terms.inner_flux.get(0, i);
                if bsum <= 0.0 {
                    continue;
                }
                let cap = terms.capillary.get(0, i).map(|c| bsum * c);
                let a = [&mut ax[q], &mut ay[q], &mut az[q]];
                let us = [u_star.x[i], u_star.y[i], u_star.z[i]];
                let rho = rest_density[i];
                for (c, a) in a.into_iter().enumerate() {
                    let um = us[c] + dt * (*a + cap[c]);
                    let pore = (u_in[c] - bmass * um) / (rho * dt);
                    *a += cap[c] + pore;
                }
            }
        },
    );
}

/// Keeps absorbed liquid out of the walls. A particle whose outer fraction
/// is below 1 has a weak pressure row or none (`iisph::row_weight`), so the
/// walls' pressure no longer holds it, and the Darcy velocity a^pore gives
/// it may point through a wall a porous solid stands on (measured: an inner
/// particle left a soaked block through the tank floor at 17 m/s after
/// 3 s). For such a particle closer than d to a wall particle, `ap` loses
/// what would carry the new velocity u* + dt ap into the wall: its
/// component along the wall normal n (the direction of
/// sum_b W_fb (x_f - x_b) over the wall neighbours b), where negative
/// (frictionless, inelastic).
pub(super) fn wall_guard(
    p: &Params,
    fluid: &FluidStore,
    walls: &WallStore,
    fb: &PairLists,
    u_star: Vel,
    dt: f32,
    ap: [&mut [f32]; 3],
) {
    let d2 = p.h * p.h;
    let [apx, apy, apz] = ap;
    apx.par_chunks_mut(BLOCK)
        .zip(apy.par_chunks_mut(BLOCK))
        .zip(apz.par_chunks_mut(BLOCK))
        .zip(fb.used().par_iter())
        .enumerate()
        .for_each(|(b, (((ax, ay), az), blk))| {
            for q in 0..ax.len() {
                let i = b * BLOCK + q;
                if fluid.beta.iter().all(|be| be[i] <= 0.0) {
                    continue;
                }
                let (xi, yi, zi) = (fluid.x[i], fluid.y[i], fluid.z[i]);
                let (mut touching, mut n) = (false, [0.0f32; 3]);
                for pr in blk.range(q) {
                    let j = blk.j[pr] as usize;
                    let r = [xi - walls.x[j], yi - walls.y[j], zi - walls.z[j]];
                    touching |= r[0] * r[0] + r[1] * r[1] + r[2] * r[2] < d2;
                    for c in 0..3 {
                        n[c] += blk.w[pr] * r[c];
                    }
                }
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                if !touching || len <= 0.0 {
                    continue;
                }
                let n = [n[0] / len, n[1] / len, n[2] / len];
                let u = [u_star.x[i] + dt * ax[q], u_star.y[i] + dt * ay[q], u_star.z[i] + dt * az[q]];
                let un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2];
                if un < 0.0 {
                    ax[q] -= un * n[0] / dt;
                    ay[q] -= un * n[1] / dt;
                    az[q] -= un * n[2] / dt;
                }
            }
        });
}
