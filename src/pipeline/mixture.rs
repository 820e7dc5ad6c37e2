//! Passes 10-12 of a step with two or more phases (PHYSICS.md §4; P
//! Alg. 3's drift and transport): the drift velocities (P-Eq. 11; with
//! porous solids its porous term and the inner drift of P-Eq. 12) on the
//! step's backend, the drift momentum term a^Dm (PHYSICS.md §4.1, sign per
//! §8.15), and the transport of the outer fractions over the pressure
//! solve's pairs and of the inner ones (P-Eqs. 6-7) over the h^3 pairs, at
//! the old positions.

use super::phases::PhaseState;
use super::porous::PoreTerms;
use super::prediction::Prediction;
use super::timing::{Pass, PassTimes};
use super::{Params, Workspace};
use crate::backend::passes::{DriftInput, DriftOutput, DriftProblem, PorousDriftInput};
use crate::store::FluidStore;
use bumpalo::Bump;
use porosph_kernels::drift;
use porosph_kernels::drift_momentum::{drift_momentum, DriftMomentumInput};
use porosph_kernels::neighbors::PairLists;
use porosph_kernels::phase_transport::{self, TransportScratch};
use porosph_kernels::phases::{join, PhaseConstants, PhaseVel};
use porosph_kernels::soa::{zeros, zeros3, Vel};
use rayon::prelude::*;

/// The fractions after the transport, phase k at `[k n, (k + 1) n)`, in
/// f64 (the store's alpha + alpha_lo moved, `porosph_kernels::phases::join`).
pub(super) struct NextFractions<'a> {
    pub alpha: &'a mut [f64],
    /// Empty without porous solids.
    pub beta: &'a mut [f64],
}

/// Passes 10-12, or with one phase and porous solids just the fractions as
/// they are (nothing drifts; they change only by absorption); with one
/// phase and no porous solid nothing. Adds a^Dm to `ap`, which holds a^p
/// (+ a^pore + a^cap) on entry, the drift's a = -(a^visc + ap). Returns
/// the next fractions, the largest drift speed max_k |u_mk| and the
/// largest advective drift speed (`drift::max_advective_speed`, the time
/// step's), m/s.
#[allow(clippy::too_many_arguments)]
pub(super) fn drift_and_transport<'a>(
    p: &Params,
    fluid: &FluidStore,
    w: &mut Workspace,
    ph: &PhaseState,
    vol: &[f32],
    pred: &Prediction,
    terms: Option<&PoreTerms>,
    ap: [&mut [f32]; 3],
    dt: f32,
    arena: &'a Bump,
    tm: &mut PassTimes,
) -> (NextFractions<'a>, f32, f32) {
    let n = fluid.len();
    let np = fluid.alpha.len();
    let mixture = p.mixture() && n > 0;
    let porous = terms.is_some();
    let nt = if mixture || porous { n } else { 0 };
    let alpha_next = arena.alloc_slice_fill_copy(np * nt, 0.0f64);
    let beta_next = arena.alloc_slice_fill_copy(if porous { np * n } else { 0 }, 0.0f64);
    if !mixture {
        if porous {
            let joined = |out: &mut [f64], hi: &[f32], lo: &[f32]| {
                out.par_iter_mut().zip(hi.par_iter().zip(lo.par_iter())).for_each(|(o, (&h, &l))| *o = join(h, l));
            };
            joined(alpha_next, &fluid.alpha[0], &fluid.alpha_lo[0]);
            joined(beta_next, &fluid.beta[0], &fluid.beta_lo[0]);
        }
        return (NextFractions { alpha: alpha_next, beta: beta_next }, 0.0, 0.0);
    }
    let [apx, apy, apz] = ap;
    let alpha: &[&[f32]] = arena.alloc_slice_fill_iter(fluid.alpha.iter().map(|a| a.as_slice()));
    // Pass 10: u_mk and the phase fluxes F_k, outer and (porous) inner.
    let (mut u, mut f) = (zeros3(arena, np * n), zeros3(arena, np * n));
    let ni = if porous { np * n } else { 0 };
    let (mut bu, mut bf) = (zeros3(arena, ni), zeros3(arena, ni));
    let (beta, beta_f): (&[&[f32]], &[f32]) = if porous {
        let beta = arena.alloc_slice_fill_iter(fluid.beta.iter().map(|b| b.as_slice()));
        (beta, arena.alloc_slice_fill_iter((0..n).map(|i| beta.iter().map(|b| b[i]).sum::<f32>())))
    } else {
        (&[], &[])
    };
    let phases: &[PhaseConstants] = arena.alloc_slice_fill_iter((0..np).map(|k| PhaseConstants {
        density: p.phase_density[k],
        tau: p.phase_drift_tau[k],
        sigma: p.phase_drift_sigma[k],
    }));
    let report = tm.time(Pass::Drift, || {
        let pf = zeros(arena, if p.fraction_pressure { n } else { 0 });
        if p.fraction_pressure {
            drift::pressure_per_fraction(&fluid.pressure, ph.alpha_f, pf);
        }
        let prob = DriftProblem {
            input: DriftInput {
                kernel: &p.kernel,
                fluid_grid: &w.fluid_grid,
                fluid: Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z },
                vol,
                alpha,
                alpha_f: ph.alpha_f,
                p_per_fraction: p.fraction_pressure.then_some(&*pf),
                a_visc: pred.a_visc,
                a_p: Vel { x: apx, y: apy, z: apz },
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
            ff: &w.ff,
            ffb: porous.then_some(&w.ffb),
        };
        let out = DriftOutput { u: u.reborrow(), f: f.reborrow() };
        let inner = porous.then_some(DriftOutput { u: bu.reborrow(), f: bf.reborrow() });
        w.backend.drift(&prob, out, inner, arena)
    });
    tm.set_gpu(Pass::Drift, report.gpu_ms);
    let u_drift = PhaseVel::split(arena, u.into_view(), n);
    // The drift speed of the time step rule: the advective part (P-Eq. 11
    // without its diffusion term; with phase pressures p_k = alphahat_k p
    // all of u_mk, whose grad p_k part is a diffusion-like term too).
    let cfl_speed = if p.fraction_pressure {
        report.max_speed
    } else {
        tm.time(Pass::Drift, || {
            let a_p = Vel { x: &*apx, y: &*apy, z: &*apz };
            let outer = drift::AdvectiveDrift {
                frac: alpha,
                frac_f: ph.alpha_f,
                phases,
                a_visc: pred.a_visc,
                a_p,
                porous: terms.map(|t| (t.grad_pore, -p.pore_drift)),
            };
            let inner = terms.map(|t| drift::AdvectiveDrift {
                frac: beta,
                frac_f: beta_f,
                phases,
                a_visc: pred.a_visc,
                a_p,
                porous: Some((t.q, -p.inner_drift_tau)),
            });
            drift::max_advective_speed(&outer).max(inner.map_or(0.0, |i| drift::max_advective_speed(&i)))
        })
    };

    // Pass 11: a^Dm, added to a^p.
    if p.drift_momentum_sign != 0.0 {
        tm.time(Pass::DriftMomentum, || {
            let mut d = zeros3(arena, n);
            let inp = DriftMomentumInput {
                ff: &w.ff,
                alpha,
                u_drift,
                density: &p.phase_density,
                rest_density: ph.rest_density,
                sign: p.drift_momentum_sign,
            };
            drift_momentum(&inp, d.reborrow());
            for (a, d) in [(&mut *apx, &*d.x), (&mut *apy, &*d.y), (&mut *apz, &*d.z)] {
                a.par_iter_mut().zip(d.par_iter()).for_each(|(a, d)| *a += d);
            }
        });
    }

    // Pass 12: transport of every phase at the old positions (P-Eq. 2).
    tm.time(Pass::PhaseTransport, || {
        let u = Vel { x: &fluid.ux, y: &fluid.uy, z: &fluid.uz };
        let tr = Transport { p, arena, n, dt, u };
        tr.run(&w.ff, alpha, &fluid.alpha_lo, PhaseVel::split(arena, f.into_view(), n), alpha_next);
        if porous {
            tr.run(&w.ffb, beta, &fluid.beta_lo, PhaseVel::split(arena, bf.into_view(), n), beta_next);
        }
    });
    (NextFractions { alpha: alpha_next, beta: beta_next }, report.max_speed, cfl_speed)
}

/// The volume-fraction transport of pass 12 for one set of fractions.
struct Transport<'a> {
    p: &'a Params,
    arena: &'a Bump,
    n: usize,
    dt: f32,
    u: Vel<'a>,
}

impl Transport<'_> {
    /// Moves the fractions `frac` + `lo` (per phase) by the fluxes `flux`
    /// over the pairs `ff` into `next` (phase k at `[k n, (k + 1) n)`).
    fn run(&self, ff: &PairLists, frac: &[&[f32]], lo: &[Vec<f32>], flux: PhaseVel, next: &mut [f64]) {
        let (arena, n, dt, np) = (self.arena, self.n, self.dt, frac.len());
        if self.p.conservative_transport {
            let scratch = TransportScratch {
                limit: zeros(arena, np * n),
                net: zeros(arena, np * n),
                least: zeros(arena, n),
                next: arena.alloc_slice_fill_copy(np * n, 0.0f64),
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
