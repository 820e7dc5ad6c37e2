//! One step (P Alg. 1-4; PHYSICS.md §6): [`step_passes`] is the list of
//! its stages, each a function of its own module with explicit inputs and
//! outputs. With one phase the mixture passes (10-12 and the correction)
//! take no time, nor without solids the solid passes, nor without porous
//! solids the porous ones.

use super::mixture::MixturePairs;
use super::pass_scratch::PassScratch;
use super::solid::SolidModel;
use super::timing::{Pass, PassTimes};
use super::{integrate, mixture, neighbours, phases, porous, prediction, pressure, solid, volumes};
use super::{PairSet, Params, Simulation, StepStats, Workspace};
use crate::backend::Passes;
use crate::store::{FluidStore, SolidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::blocks::max_f32;
use porosph_kernels::granular::Walls;
use std::fmt;

/// A step that cannot go on: a NaN or an exploding velocity.
#[derive(Clone, Debug, PartialEq)]
pub struct StepError {
    pub step: u64,
    pub time: f64,
    /// Stable id of the first offending particle; `None` when the step
    /// stopped for a reason that is not a particle's (a GPU pass failed),
    /// and then position and velocity are NaN.
    pub particle: Option<u32>,
    pub position: [f32; 3],
    pub velocity: [f32; 3],
    pub reason: String,
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "step {} (t = {:.6} s): {}", self.step, self.time, self.reason)?;
        match self.particle {
            Some(id) => write!(f, ": particle id {id} at {:?} m with velocity {:?} m/s", self.position, self.velocity),
            None => Ok(()),
        }
    }
}

impl std::error::Error for StepError {}

impl Simulation {
    /// Advances by one step of length [`Simulation::dt`], then picks the next dt.
    pub fn step(&mut self) -> Result<&StepStats, StepError> {
        let dt = self.dt;
        // Prescribed velocities of the fixed solid particles for this step.
        for (i, &b) in self.solids.body.iter().enumerate() {
            if self.solids.fixed[i] != 0 {
                let v = self.scene.solids[b as usize].fixed_velocity(self.time);
                (self.solids.vx[i], self.solids.vy[i], self.solids.vz[i]) = (v[0], v[1], v[2]);
            }
        }
        let Simulation { params, fluid, walls, solids, solid_model, backend, work, pairs, arena, scratch, .. } = self;
        let bodies = Bodies { store: solids, model: solid_model.as_mut() };
        let cx = StepCtx { p: params, dt, arena, scratch, tm: PassTimes::default() };
        let mut stats = step_passes(cx, fluid, walls, bodies, backend.as_mut(), work, pairs);
        self.arena_used = self.arena_used.max(arena.allocated_bytes() - arena.chunk_capacity());
        scratch.note_used();
        arena.reset();
        if let Some(reason) = backend.take_error() {
            let nan = [f32::NAN; 3];
            return Err(StepError {
                step: self.step,
                time: self.time,
                particle: None,
                position: nan,
                velocity: nan,
                reason,
            });
        }
        self.time += dt as f64;
        self.step += 1;
        let t = std::time::Instant::now();
        let speed = self.max_speed();
        if !speed.is_finite() || speed > self.blowup_speed() {
            return Err(self.blowup(speed));
        }
        let (dt_next, by) = self.dt_rule(speed, stats.cfl_drift_speed.max(stats.max_darcy_speed));
        (self.dt, stats.next_dt_limit) = (dt_next, Some(by));
        stats.times.add(Pass::TimeStep, t.elapsed().as_secs_f64() * 1e3);
        stats.max_speed = speed;
        stats.dt = dt;
        self.last = stats;
        Ok(&self.last)
    }

    /// Largest fluid or solid speed, m/s (NaN if any velocity is NaN).
    pub fn max_speed(&self) -> f32 {
        let f = &self.fluid;
        let s = &self.solids;
        let fluid = max_f32(f.len(), |i| (f.ux[i] * f.ux[i] + f.uy[i] * f.uy[i] + f.uz[i] * f.uz[i]).sqrt());
        let solid = max_f32(s.len(), |i| (s.vx[i] * s.vx[i] + s.vy[i] * s.vy[i] + s.vz[i] * s.vz[i]).sqrt());
        if fluid.is_nan() || solid.is_nan() {
            f32::NAN
        } else {
            fluid.max(solid)
        }
    }

    /// The time step rule of PHYSICS.md §7:
    /// dt = min(max_dt, lambda h / max|u|, 0.125 h^2 rho_k / mu_k (explicit
    /// viscosity only: [`explicit_viscosity_bound`])), and with
    /// two or more phases also lambda h / max_k|u_mk| and
    /// 0.1 h^2 / max_k sigma_k; `max_drift` is the largest of the last
    /// step's outer and inner advective drift speeds (u_mk without its
    /// diffusion term, which the diffusion number bounds) and Darcy
    /// speeds |u_rk| (the
    /// step passes max(cfl_drift_speed, max_darcy_speed); PHYSICS.md writes
    /// 0.4 = lambda's default).
    pub fn next_dt(&self, max_speed: f32, max_drift: f32) -> f32 {
        self.dt_rule(max_speed, max_drift).0
    }

    /// [`Simulation::next_dt`] and the term of its rule that set it (of
    /// equal terms, the first in the rule's order).
    pub fn dt_rule(&self, max_speed: f32, max_drift: f32) -> (f32, DtLimit) {
        let p = &self.params;
        let mut dt = (p.max_dt, DtLimit::MaxDt);
        // As f32::min: a smaller term wins, an equal or NaN one does not.
        let mut bound = |v: f32, by: DtLimit| {
            if v < dt.0 {
                dt = (v, by);
            }
        };
        if max_speed > 0.0 {
            bound(p.cfl * p.h / max_speed, DtLimit::Cfl);
        }
        if !p.implicit_viscosity {
            bound(p.explicit_viscosity_dt, DtLimit::Viscosity);
        }
        if p.mixture() {
            if max_drift > 0.0 {
                bound(p.cfl * p.h / max_drift, DtLimit::Drift);
            }
            let sigma = p.drift_diffusivity();
            if sigma > 0.0 {
                bound(0.1 * p.h * p.h / sigma, DtLimit::Diffusion);
            }
        }
        dt
    }

    /// A speed at which the CFL step would fall below 1e-4 max_dt: the run
    /// has exploded.
    fn blowup_speed(&self) -> f32 {
        self.params.cfl * self.params.h / (1e-4 * self.params.max_dt)
    }

    fn blowup(&self, speed: f32) -> StepError {
        let (f, s) = (&self.fluid, &self.solids);
        let limit = self.blowup_speed();
        let bad = |x: [f32; 3], v: [f32; 3]| {
            let speed = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            !speed.is_finite() || speed > limit || !x.iter().all(|c| c.is_finite())
        };
        let fluid_bad = (0..f.len()).find(|&i| bad([f.x[i], f.y[i], f.z[i]], [f.ux[i], f.uy[i], f.uz[i]]));
        let solid_bad = (0..s.len()).find(|&i| bad([s.x[i], s.y[i], s.z[i]], [s.vx[i], s.vy[i], s.vz[i]]));
        // The offending particle: a fluid one if any, else a solid one.
        let nan = [f32::NAN; 3];
        let (what, id, position, velocity) = match (fluid_bad, solid_bad) {
            (None, Some(b)) => ("solid velocity", Some(s.id[b]), [s.x[b], s.y[b], s.z[b]], [s.vx[b], s.vy[b], s.vz[b]]),
            (Some(b), _) => ("velocity", Some(f.id[b]), [f.x[b], f.y[b], f.z[b]], [f.ux[b], f.uy[b], f.uz[b]]),
            (None, None) => ("velocity", None, nan, nan),
        };
        StepError {
            step: self.step,
            time: self.time,
            particle: id,
            position,
            velocity,
            reason: if speed.is_finite() {
                format!("{what} exploded ({speed:.3e} m/s > {limit:.3e} m/s)")
            } else {
                format!("{what} is NaN or infinite")
            },
        }
    }
}

/// The term of the time step rule ([`Simulation::dt_rule`]) that set a dt.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DtLimit {
    /// `max_dt` of the scene.
    MaxDt,
    /// lambda h / max|u|.
    Cfl,
    /// 0.125 h^2 rho_k / mu_k of the explicit viscosity.
    Viscosity,
    /// lambda h / max_k|u_mk|, the drift and Darcy speeds.
    Drift,
    /// 0.1 h^2 / max_k sigma_k, the drift diffusion.
    Diffusion,
}

impl DtLimit {
    /// Every term, in the order of the rule.
    pub const ALL: [DtLimit; 5] =
        [DtLimit::MaxDt, DtLimit::Cfl, DtLimit::Viscosity, DtLimit::Drift, DtLimit::Diffusion];

    /// How the end-of-run summary names it.
    pub fn name(self) -> &'static str {
        match self {
            DtLimit::MaxDt => "max_dt",
            DtLimit::Cfl => "CFL",
            DtLimit::Viscosity => "viscosity",
            DtLimit::Drift => "drift/Darcy",
            DtLimit::Diffusion => "drift diffusion",
        }
    }
}

/// The largest stable dt of the explicit viscosity of a phase of density
/// `rho` and viscosity `mu` at spacing `h`: 0.125 h^2 rho / mu (PHYSICS.md
/// §7). The implicit solve has none.
pub(super) fn explicit_viscosity_bound(h: f32, rho: f32, mu: f32) -> f32 {
    0.125 * h * h * rho / mu
}

/// The solid particles and their model.
struct Bodies<'a> {
    store: &'a mut SolidStore,
    model: &'a mut dyn SolidModel,
}

/// What every stage of a step reads besides its own inputs, and where it
/// times itself.
pub(super) struct StepCtx<'a> {
    /// The scene's parameters.
    pub p: &'a Params,
    /// The step's dt, s.
    pub dt: f32,
    /// Scratch of the step (reset after it): the stages' outputs live here.
    pub arena: &'a Bump,
    /// Scratch of one pass (`PassScratch::fresh`): its temporaries.
    pub scratch: &'a mut PassScratch,
    /// Milliseconds per pass.
    pub tm: PassTimes,
}

/// The stages of one step, in the order of P Alg. 1 (with Alg. 2-4 where
/// it calls them); scratch comes from `arena`. Where a later distributed
/// run exchanges halo data, it is between these stages: the positions
/// after the neighbour search, the volumes and rows before the solve, the
/// pressures within it (the backend's loop), the velocities before the
/// transport.
fn step_passes<'a>(
    mut cx: StepCtx<'a>,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    bodies: Bodies,
    backend: &mut dyn Passes,
    w: &mut Workspace,
    pairs: &'a mut PairSet,
) -> StepStats {
    let mut st = StepStats::default();
    let (p, dt) = (cx.p, cx.dt);
    let cx = &mut cx;
    let Bodies { store: solids, model } = bodies;
    let porous = p.porous() && !solids.is_empty() && !fluid.is_empty();

    // Alg. 1: the neighbours; N_f (P §5) and Alg. 4's fallback (beta back
    // to alpha where no porous solid is near).
    let mut density = neighbours::search(cx, fluid, walls, solids, w, pairs, backend);
    let part = porous.then(|| porous::partition(cx, fluid, solids, walls, w, pairs, &mut density));
    // Alg. 1: phase bookkeeping (P-Eq. 10), densities and volumes (P §5,
    // §6.1), the outer fluid's viscosity and u* (P-Eq. 23).
    let ph = phases::bookkeeping(cx, fluid, porous, density.v0);
    let vols = volumes::volumes(cx, fluid, walls, solids, w, pairs, &ph, density.own);
    let pred = prediction::predict(cx, fluid, &pairs.ff, &mut w.visc_coef, &ph);
    st.viscosity_iterations = pred.iterations;
    // Alg. 2: the solids' strain (P-Eq. 4); phi, p^pore, Darcy flux and
    // u_beta on the solids (P-Eqs. 1, 9, 15, 19); and Alg. 3's fluid terms
    // that need plain gradients: u_beta,f, q_f, grad p^pore_f, Gamma
    // (P-Eqs. 13, 16-22); the solids' stress (P-Eq. 5) and the velocities
    // they would have without the fluid's pressure.
    if !solids.is_empty() {
        solid::strain(cx, solids, model);
    }
    let terms = part.as_ref().map(|part| porous::solid_terms(cx, fluid, solids, w, pairs, part, p.mixture()));
    if let Some(t) = &terms {
        st.max_darcy_speed = t.max_darcy_speed;
    }
    if !solids.is_empty() {
        let [sx, sy, sz] = &w.solid_sorted;
        let near = solid::Current {
            ss: &pairs.ss,
            sb: &pairs.sb,
            perm: &w.solid_perm,
            x: [sx, sy, sz],
            walls: Walls { x: [&walls.x, &walls.y, &walls.z] },
        };
        let cg = solid::predict(cx, solids, model, terms.as_ref().and_then(|t| t.pore_stress), &near);
        st.cg_iterations = cg.iterations;
        st.cg_residual = cg.residual;
        st.granular_substeps = model.substeps();
    }
    // Alg. 1: a^press, the pressure solve with pressure boundaries (P-Eqs.
    // 25-29), in which the bodies give way with their compliance; Alg. 2's
    // boundary forces on the solids and Alg. 4's velocities of the solids.
    let rows = pressure::setup(cx, fluid, walls, (solids, model), w, pairs, (&ph, &vols, &pred));
    let solved = pressure::solve(cx, fluid, walls, (solids, model), w, backend, &vols, rows);
    st.iterations = solved.report.iterations;
    st.density_error = solved.report.density_error;
    st.solid_density_error = solved.report.solid_error;
    st.largest_density_error = solved.report.largest_error;
    st.solve_restarts = solved.report.restarts;
    st.cg_iterations += solved.solid_stats.iterations;
    if !solids.is_empty() {
        // The last response also solved what the prediction left (its
        // looser tolerance): its residual is the step's.
        st.cg_residual = solved.solid_stats.residual;
    }
    let mut ap = solved.ap;
    // From here on the pairs are V̄_ij grad W_ij.
    let scaled = solved.pairs.lists();
    if !solids.is_empty() {
        solid::finish(cx, solids, model, solved.accel_solid, solved.p_solid, &w.solid_inv);
        let [sx, sy, sz] = &w.solid_sorted;
        let near = solid::Current {
            ss: &scaled.ss,
            sb: &scaled.sb,
            perm: &w.solid_perm,
            x: [sx, sy, sz],
            walls: Walls { x: [&walls.x, &walls.y, &walls.z] },
        };
        cx.tm.time(Pass::Elasticity, || model.wall_contact(solids, &near));
    }
    // Alg. 3: a^cap and a^pore (P-Eqs. 10, 14), added to a^p.
    if let Some(t) = &terms {
        let ap = [&mut *ap.x, &mut *ap.y, &mut *ap.z];
        cx.tm.time(Pass::Porous, || porous::accelerations(p, fluid, t, ph.rest_density, pred.u_star, dt, ap));
    }
    // Alg. 3 with two or more phases: the drift velocities (pass 10, P-Eqs.
    // 11-12), whose a reads a^p + a^pore + a^cap, and the drift momentum
    // a^Dm, added to a^p (pass 11).
    let mixture_pairs = MixturePairs { ff: &scaled.ff, ffb: porous.then_some(&w.ffb) };
    let drift = (p.mixture() && !fluid.is_empty()).then(|| {
        let inp = (&ph, vols.vol, &pred);
        mixture::drift(cx, fluid, &w.fluid_grid, mixture_pairs, backend, inp, terms.as_ref(), ap.view())
    });
    if let Some(d) = &drift {
        mixture::drift_momentum(cx, fluid, &scaled.ff, &ph, d, ap.reborrow());
        st.max_drift_speed = d.max_speed;
        st.cfl_drift_speed = d.cfl_speed;
    }
    // Alg. 3: the transport (pass 12, P-Eqs. 2, 6-7) at the old positions,
    // then the absorption exchange (P-Eq. 22).
    let next = mixture::transport(cx, fluid, mixture_pairs, drift.as_ref(), porous);
    if let Some(t) = &terms {
        porous::exchange(cx, t, fluid.len(), &mut *next.alpha, &mut *next.beta);
        let ap = [&mut *ap.x, &mut *ap.y, &mut *ap.z];
        cx.tm.time(Pass::Porous, || porous::wall_guard(p, fluid, walls, &scaled.fb, pred.u_star, dt, ap));
    }
    // Alg. 4: integration of P-Eqs. 6-8, then sum_k (alpha_k + beta_k) = 1.
    integrate::positions(cx, fluid, solids, pred.u_star, ap.view());
    integrate::correct_fractions(cx, fluid, next);
    if let Some(part) = &part {
        porous::settle(cx, fluid, part);
    }
    st.times = cx.tm;
    st
}

#[cfg(test)]
mod tests {
    use super::StepError;

    /// A step stopped by a failed GPU pass names no particle (it named
    /// particle id 0 at NaN, as if one had blown up); a blow-up names its
    /// particle.
    #[test]
    fn a_step_error_names_a_particle_only_when_one_caused_it() {
        let nan = [f32::NAN; 3];
        let e = StepError {
            step: 3,
            time: 0.006,
            particle: None,
            position: nan,
            velocity: nan,
            reason: "GPU pressure solve failed: device lost".into(),
        };
        assert_eq!(e.to_string(), "step 3 (t = 0.006000 s): GPU pressure solve failed: device lost");
        let e = StepError { particle: Some(42), position: [0.0, 1.0, 2.0], velocity: [3.0; 3], ..e };
        assert!(
            e.to_string().ends_with(": particle id 42 at [0.0, 1.0, 2.0] m with velocity [3.0, 3.0, 3.0] m/s"),
            "{e}"
        );
    }
}
