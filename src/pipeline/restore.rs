//! Rebuilding a [`Simulation`] from saved state (a checkpoint): the scene,
//! the particle stores, time, step and dt. Everything else a step needs is
//! either derived from the scene (the parameters) or rebuilt the way
//! [`Simulation::new`] builds it (the wall grid), so the restored simulation
//! steps bit for bit like the one that was saved.

use super::setup::wall_workspace;
use super::{PairSet, Params, Simulation, StepStats};
use crate::backend::Passes;
use crate::scene::Scene;
use crate::store::{Column, FluidStore, SolidStore, WallStore};
use bumpalo::Bump;

/// The persistent state of a simulation, as a checkpoint holds it.
#[derive(Clone, Debug, PartialEq)]
pub struct SavedState {
    pub scene: Scene,
    pub fluid: FluidStore,
    pub walls: WallStore,
    pub solids: SolidStore,
    /// Simulated time, s.
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// dt of the next step, s.
    pub dt: f32,
}

impl Simulation {
    /// A simulation that continues from `state`, exactly as the simulation
    /// it was saved from would have.
    ///
    /// Checks that the state is consistent (every column of a store has the
    /// store's particle count, one alpha column per scene phase, a finite
    /// time and a positive finite dt) and says what is not.
    pub fn from_saved_state(state: SavedState) -> Result<Simulation, String> {
        let SavedState { scene, fluid, mut walls, solids, time, step, dt } = state;
        let phases = scene.phases.len();
        check_columns("fluid", fluid.len(), |f| fluid.for_each_column(f), phases)?;
        check_columns("walls", walls.len(), |f| walls.for_each_column(f), phases)?;
        check_columns("solids", solids.len(), |f| solids.for_each_column(f), phases)?;
        if let Some(&b) = solids.body.iter().find(|&&b| b as usize >= scene.solids.len()) {
            return Err(format!("solids/body holds body {b}, but the scene has {} solids", scene.solids.len()));
        }
        if fluid.alpha.len() != phases {
            return Err(format!("fluid alpha has {} phases but the scene has {phases}", fluid.alpha.len()));
        }
        if !(time.is_finite() && time >= 0.0) {
            return Err(format!("time {time} s is not a finite time >= 0"));
        }
        if !(dt.is_finite() && dt > 0.0) {
            return Err(format!("dt {dt} s is not a positive finite time step"));
        }
        let params = Params::from_scene(&scene);
        let mut work = wall_workspace(&mut walls, &params);
        (work.solid_own, work.solid_v0) = super::volumes::rest_rows(&params, &solids);
        let solid_model = params.solid_model(&scene, &solids);
        Ok(Simulation {
            scene,
            params,
            fluid,
            walls,
            solids,
            solid_model,
            backend: Box::<dyn Passes>::default(),
            pairs: PairSet::default(),
            time,
            step,
            dt,
            last: StepStats::default(),
            work,
            arena: Bump::new(),
            arena_used: 0,
            scratch: Default::default(),
        })
    }
}

/// Every registered column of a store holds `n` values (per phase for
/// per-phase columns).
fn check_columns(
    store: &str,
    n: usize,
    visit: impl FnOnce(&mut dyn FnMut(&'static str, &'static str, Column<'_>)),
    phases: usize,
) -> Result<(), String> {
    let mut problem = None;
    visit(&mut |name, _, c| {
        if problem.is_some() {
            return;
        }
        let bad = match c {
            Column::F32(v) => (v.len() != n).then(|| v.len().to_string()),
            Column::U32(v) => (v.len() != n).then(|| v.len().to_string()),
            Column::PerPhase(vs) => {
                if vs.len() != phases {
                    Some(format!("{} phases", vs.len()))
                } else {
                    vs.iter().find(|v| v.len() != n).map(|v| v.len().to_string())
                }
            }
        };
        if let Some(got) = bad {
            problem = Some(format!("{store}/{name} has {got} values, expected {n} (the {store} particle count)"));
        }
    });
    problem.map_or(Ok(()), Err)
}
