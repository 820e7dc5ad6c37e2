//! Passes 10-12 of a step with two or more phases (PHYSICS.md §4; P
//! Alg. 3's drift and transport), one stage each: [`drift`], the drift
//! velocities (P-Eq. 11; with porous solids its porous term and the inner
//! drift of P-Eq. 12) on the step's backend; [`drift_momentum`], the drift
//! momentum term a^Dm (PHYSICS.md §4.1, sign per §8.15); [`transport`], the
//! transport of the outer fractions over the pressure solve's pairs and of
//! the inner ones (P-Eqs. 6-7) over the h^3 pairs, at the old positions.

use super::phases::PhaseState;
use super::porous::PoreTerms;
use super::prediction::Prediction;
use super::step::StepCtx;
use super::timing::Pass;
use super::Params;
use crate::backend::passes::{DriftInput, DriftOutput, DriftProblem, Passes, PorousDriftInput};
use crate::store::FluidStore;
use bumpalo::Bump;
use porosph_kernels::drift;
use porosph_kernels::drift_momentum::{self as dm, DriftMomentumInput};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::neighbors::PairLists;
use porosph_kernels::phase_transport::{self, TransportScratch};
use porosph_kernels::phases::{join, PhaseConstants, PhaseVel};
use porosph_kernels::soa::{zeros, zeros3, Vel, VelMut};
use rayon::prelude::*;

/// The fractions after the transport, phase k at `[k n, (k + 1) n)`, in
/// f64 (the store's alpha + alpha_lo moved, `porosph_kernels::phases::join`).
pub(super) struct NextFractions<'a> {
    pub alpha: &'a mut [f64],
    /// Empty without porous solids.
    pub beta: &'a mut [f64],
}

/// The fluid-fluid pairs of the mixture passes.
#[derive(Clone, Copy)]
pub(super) struct MixturePairs<'a> {
    /// The pressure solve's pairs (V̄_ij grad W_ij), of the outer phases.
    pub ff: &'a PairLists,
    /// With porous solids, the pairs with h^3 grad W_ij of the inner ones.
    pub ffb: Option<&'a PairLists>,
}

/// What pass 10 gives passes 11 and 12.
pub(super) struct Drift<'a> {
    /// u_mk per phase as the drift momentum term takes it: without
    /// P-Eq. 11's porous term (`porosph_kernels::porous::without_phase_term`),
    /// m/s.
    pub u: PhaseVel<'a>,
    /// The outer phase fluxes F_k, and with porous solids the inner ones,
    /// m/s.
    pub flux: PhaseVel<'a>,
    pub inner_flux: Option<PhaseVel<'a>>,
    /// The largest drift speed max_k |u_mk|, outer and inner, m/s.
    pub max_speed: f32,
    /// The largest advective drift speed (`drift::max_advective_speed`),
    /// the time step's, m/s.
    pub cfl_speed: f32,
}

/// Each phase's fractions as a list of slices.
fn per_phase<'a>(arena: &'a Bump, f: &'a [Vec<f32>]) -> &'a [&'a [f32]] {
    arena.alloc_slice_fill_iter(f.iter().map(|a| a.as_slice()))
}

/// Pass 10: the drift velocities u_mk and phase fluxes F_k (P-Eq. 11),
/// outer and, with porous solids (`terms`), inner (P-Eq. 12), on
/// `backend`, with a = -(a^visc + ap); `ap` holds a^p (+ a^pore + a^cap).
#[allow(clippy::too_many_arguments)]
pub(super) fn drift<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &FluidStore,
    grid: &CellGrid,
    pairs: MixturePairs,
    backend: &mut dyn Passes,
    inp: (&PhaseState, &[f32], &Prediction),
    terms: Option<&PoreTerms>,
    ap: Vel,
) -> Drift<'a> {
    let (p, arena) = (cx.p, cx.arena);
    let (ph, vol, pred) = inp;
    let n = fluid.len();
    let np = fluid.alpha.len();
    let porous = terms.is_some();
    // With pass 11's porous form (`without_phase_term`) the drift
    // velocities of P-Eq. 11 become its form in place.
    let momentum = terms.filter(|_| p.pore_drift != 0.0 && p.drift_momentum_sign != 0.0);
    let tmp = cx.scratch.fresh();
    let alpha = per_phase(arena, &fluid.alpha);
    let mut u = zeros3(arena, np * n);
    let mut f = zeros3(arena, np * n);
    let ni = if porous { np * n } else { 0 };
    // The inner drift velocities are only the inner fluxes' input.
    let (mut bu, mut bf) = (zeros3(tmp, ni), zeros3(arena, ni));
    let (beta, beta_f): (&[&[f32]], &[f32]) = if porous {
        let beta = per_phase(tmp, &fluid.beta);
        let beta_f = zeros(tmp, n);
        beta_f.par_iter_mut().enumerate().for_each(|(i, o)| *o = beta.iter().map(|b| b[i]).sum::<f32>());
        (beta, &*beta_f)
    } else {
        (&[], &[])
    };
    let phases: &[PhaseConstants] = tmp.alloc_slice_fill_iter((0..np).map(|k| PhaseConstants {
        density: p.phase_density[k],
        tau: p.phase_drift_tau[k],
        sigma: p.phase_drift_sigma[k],
    }));
    let report = cx.tm.time(Pass::Drift, || {
        let pf = zeros(tmp, if p.fraction_pressure { n } else { 0 });
        if p.fraction_pressure {
            drift::pressure_per_fraction(&fluid.pressure, ph.alpha_f, pf);
        }
        let prob = DriftProblem {
            input: DriftInput {
                kernel: &p.kernel,
                fluid_grid: grid,
                fluid: Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z },
                vol,
                alpha,
                alpha_f: ph.alpha_f,
                p_per_fraction: p.fraction_pressure.then_some(&*pf),
                a_visc: pred.a_visc,
                a_p: ap,
                phases,
                conservative: p.conservative_transport,
                porous: terms.map(|t| PorousDriftInput {
                    grad_pore: t.grad_pore,
                    pore_drift: p.pore_drift,
                    beta,
                    beta_f,
                    q: t.q,
                    inner_tau: p.inner_drift_tau,
                    inner_sigma: p.inner_drift_sigma,
                    cell_volume: p.cell_volume(),
                }),
            },
            ff: pairs.ff,
            ffb: pairs.ffb.filter(|_| porous),
        };
        let out = DriftOutput { u: u.reborrow(), f: f.reborrow() };
        let inner = porous.then_some(DriftOutput { u: bu.reborrow(), f: bf.reborrow() });
        backend.drift(&prob, out, inner, tmp)
    });
    cx.tm.set_gpu(Pass::Drift, report.gpu_ms);
    // The drift speed of the time step rule: the advective part (P-Eq. 11
    // without its diffusion term; with phase pressures p_k = alphahat_k p
    // all of u_mk, whose grad p_k part is a diffusion-like term too).
    let cfl_speed = if p.fraction_pressure {
        report.max_speed
    } else {
        cx.tm.time(Pass::Drift, || {
            let outer = drift::AdvectiveDrift {
                frac: alpha,
                frac_f: ph.alpha_f,
                phases,
                a_visc: pred.a_visc,
                a_p: ap,
                porous: terms.map(|t| (t.grad_pore, -p.pore_drift)),
            };
            let inner = terms.map(|t| drift::AdvectiveDrift {
                frac: beta,
                frac_f: beta_f,
                phases,
                a_visc: pred.a_visc,
                a_p: ap,
                porous: Some((t.q, -p.inner_drift_tau)),
            });
            drift::max_advective_speed(&outer).max(inner.map_or(0.0, |i| drift::max_advective_speed(&i)))
        })
    };
    if let Some(t) = momentum {
        cx.tm.time(Pass::DriftMomentum, || {
            porosph_kernels::porous::without_phase_term(
                alpha,
                ph.alpha_f,
                &p.phase_density,
                t.grad_pore,
                -p.pore_drift,
                u.reborrow(),
                zeros3(tmp, t.grad_pore.band.len()),
            );
        });
    }
    Drift {
        u: PhaseVel::split(arena, u.into_view(), n),
        flux: PhaseVel::split(arena, f.into_view(), n),
        inner_flux: porous.then(|| PhaseVel::split(arena, bf.into_view(), n)),
        max_speed: report.max_speed,
        cfl_speed,
    }
}

/// Pass 11: a^Dm (PHYSICS.md §4.1, sign per §8.15), added to `ap`; nothing
/// where the scene leaves it out (`drift_momentum_sign` 0).
pub(super) fn drift_momentum(
    cx: &mut StepCtx,
    fluid: &FluidStore,
    ff: &PairLists,
    ph: &PhaseState,
    drift: &Drift,
    ap: VelMut,
) {
    let p = cx.p;
    if p.drift_momentum_sign == 0.0 {
        return;
    }
    let tmp = cx.scratch.fresh();
    cx.tm.time(Pass::DriftMomentum, || {
        let mut d = zeros3(tmp, fluid.len());
        let inp = DriftMomentumInput {
            ff,
            alpha: per_phase(tmp, &fluid.alpha),
            u_drift: drift.u,
            density: &p.phase_density,
            rest_density: ph.rest_density,
            sign: p.drift_momentum_sign,
        };
        let n = fluid.len();
        let t = [tmp.alloc_slice_fill_copy(n, [0.0f32; 4]), tmp.alloc_slice_fill_copy(n, [0.0f32; 4])];
        dm::drift_momentum(&inp, d.reborrow(), t);
        for (a, d) in [(ap.x, &*d.x), (ap.y, &*d.y), (ap.z, &*d.z)] {
            a.par_iter_mut().zip(d.par_iter()).for_each(|(a, d)| *a += d);
        }
    });
}

/// Pass 12: the transport of every phase at the old positions (P-Eq. 2),
/// outer over `pairs.ff` and, with porous solids, inner over `pairs.ffb`
/// with the fluxes of `drift` (pass 10). With one phase nothing drifts:
/// with porous solids the next fractions are the fractions as they are
/// (they change only by absorption), without them there are none.
pub(super) fn transport<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &FluidStore,
    pairs: MixturePairs,
    drift: Option<&Drift>,
    porous: bool,
) -> NextFractions<'a> {
    let (p, arena, dt) = (cx.p, cx.arena, cx.dt);
    let n = fluid.len();
    let np = fluid.alpha.len();
    let nt = if drift.is_some() || porous { n } else { 0 };
    let alpha_next = arena.alloc_slice_fill_copy(np * nt, 0.0f64);
    let beta_next = arena.alloc_slice_fill_copy(if porous { np * n } else { 0 }, 0.0f64);
    let Some(drift) = drift else {
        if porous {
            let joined = |out: &mut [f64], hi: &[f32], lo: &[f32]| {
                out.par_iter_mut().zip(hi.par_iter().zip(lo.par_iter())).for_each(|(o, (&h, &l))| *o = join(h, l));
            };
            joined(alpha_next, &fluid.alpha[0], &fluid.alpha_lo[0]);
            joined(beta_next, &fluid.beta[0], &fluid.beta_lo[0]);
        }
        return NextFractions { alpha: alpha_next, beta: beta_next };
    };
    let scratch = &mut *cx.scratch;
    cx.tm.time(Pass::PhaseTransport, || {
        let u = Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz };
        let tr = Transport { p, n, dt, u };
        tr.run(scratch.fresh(), pairs.ff, &fluid.alpha, &fluid.alpha_lo, drift.flux, alpha_next);
        if let (true, Some(ffb), Some(g)) = (porous, pairs.ffb, drift.inner_flux) {
            tr.run(scratch.fresh(), ffb, &fluid.beta, &fluid.beta_lo, g, beta_next);
        }
    });
    NextFractions { alpha: alpha_next, beta: beta_next }
}

/// The volume-fraction transport of pass 12 for one set of fractions.
struct Transport<'a> {
    p: &'a Params,
    n: usize,
    dt: f32,
    u: Vel<'a>,
}

impl Transport<'_> {
    /// Moves the fractions `frac` + `lo` (per phase) by the fluxes `flux`
    /// over the pairs `ff` into `next` (phase k at `[k n, (k + 1) n)`);
    /// its temporaries from `arena`.
    fn run(&self, arena: &Bump, ff: &PairLists, frac: &[Vec<f32>], lo: &[Vec<f32>], flux: PhaseVel, next: &mut [f64]) {
        let (n, dt, np) = (self.n, self.dt, frac.len());
        let frac = per_phase(arena, frac);
        if self.p.conservative_transport {
            let scratch = TransportScratch {
                limit: zeros(arena, np * n),
                net: zeros(arena, np * n),
                least: zeros(arena, n),
                flux: arena.alloc_slice_fill_copy(np * n, [0.0f32; 4]),
                near: arena.alloc_slice_fill_copy(n, false),
            };
            let lo = arena.alloc_slice_fill_iter(lo.iter().map(|l| l.as_slice()));
            phase_transport::transport(ff, frac, lo, flux, dt, scratch, next);
        } else {
            for (k, out) in next.chunks_mut(n).enumerate() {
                phase_transport::transport_reference(ff, self.u, frac[k], &lo[k], flux.phase(k), dt, out);
            }
        }
    }
}
