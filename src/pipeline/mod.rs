//! One time step = the ordered list of passes of PHYSICS.md §6 (the paper's
//! Algorithm 1), each timed by name. [`Simulation`] owns the particle store,
//! the neighbour structures and the per-step arena.

mod backend;
pub mod granular;
mod integrate;
mod mixture;
mod neighbours;
mod pass_scratch;
mod phases;
mod porous;
mod prediction;
mod pressure;
mod restore;
mod setup;
pub mod solid;
mod step;
pub mod timing;
mod volumes;

pub use granular::{Granular, Mixed};
pub use restore::SavedState;
pub use solid::{Current, Peer2018, SolidModel, SolidStats};
pub use step::{DtLimit, StepError};
pub use timing::{Pass, PassTimes};

use crate::backend::Passes;
use crate::scene::{Porous, Scene};
use crate::store::{FluidStore, Scratch, SolidStore, WallStore};
use bumpalo::Bump;
use pass_scratch::PassScratch;
use porosph_kernels::elasticity::Lame;
use porosph_kernels::grid::CellGrid;
use porosph_kernels::kernel::Kernel;
use porosph_kernels::neighbors::PairLists;

/// Parameters derived from the scene, in SI units.
#[derive(Clone, Debug, PartialEq)]
pub struct Params {
    /// Particle spacing h = d, m (PHYSICS.md §1).
    pub h: f32,
    /// Kernel support H = 2h, m.
    pub kernel: Kernel,
    /// Gravity, m/s^2.
    pub gravity: [f32; 3],
    /// Upper bound of dt, s.
    pub max_dt: f32,
    /// CFL number.
    pub cfl: f32,
    /// Target mean density error of the pressure solve (fraction).
    pub max_density_error: f32,
    /// Bound on every row's predicted compression (fraction; infinite
    /// without `max_row_density_error`).
    pub max_row_density_error: f32,
    pub min_iterations: u32,
    pub max_iterations: u32,
    /// Jacobi relaxation omega.
    pub omega: f32,
    /// Spectral radius estimate of the Chebyshev semi-iteration over the
    /// Jacobi sweeps, 0 = off (`simulation.chebyshev_radius`).
    pub chebyshev_radius: f32,
    /// The pressure solve starts from half the last pressure and half the
    /// hydrostatic estimate (`simulation.pressure_warm_start`).
    pub hydrostatic_warm_start: bool,
    /// Wall rows with their own part at the lattice volume and the coupled
    /// diagonal (`simulation.wall_rows = "lattice"`).
    pub lattice_wall_rows: bool,
    /// Rest density rho_k of each phase, kg/m^3.
    pub phase_density: Vec<f32>,
    /// Viscosity mu_k of each phase, Pa s.
    pub phase_viscosity: Vec<f32>,
    /// Drift relaxation weight tau_k of each phase, m^2/(Pa s) (P-Eq. 11).
    pub phase_drift_tau: Vec<f32>,
    /// Drift diffusion weight sigma_k of each phase, m^2/s (P-Eq. 11).
    pub phase_drift_sigma: Vec<f32>,
    /// Sign of the drift momentum term a^Dm (PHYSICS.md §8.15): -1 the
    /// physical form, +1 that of [RG] and [AC], 0 left out.
    pub drift_momentum_sign: f32,
    /// The conservative volume-fraction transport (default) rather than the
    /// reference form (`simulation.phase_transport`).
    pub conservative_transport: bool,
    /// Phase pressures p_k = alphahat_k p rather than the default shared
    /// p_k = p (`simulation.phase_pressure`).
    pub fraction_pressure: bool,
    /// Whether each solid (`[[solid]]` order) is granular (`granular.rs`).
    pub solid_granular: Vec<bool>,
    /// Lamé parameters of each solid body (`[[solid]]` order), Pa.
    pub solid_lame: Vec<Lame>,
    /// Viscosity solved implicitly (`simulation.viscosity_solver`): dt is
    /// not held to the explicit bound, and a step longer than
    /// `implicit_viscosity_above` solves it implicitly (0 with
    /// "implicit": every step; the explicit bound with "auto": a step the
    /// explicit form can take keeps it). Then the relative residual of its
    /// conjugate gradients.
    pub implicit_viscosity: bool,
    pub implicit_viscosity_above: f32,
    /// The explicit viscosity's stable step, the least 0.125 h^2 rho_k /
    /// mu_k over the viscous phases (infinite without one), s.
    pub explicit_viscosity_dt: f32,
    pub viscosity_tolerance: f32,
    /// Relative residual of the elastic conjugate gradients.
    pub elastic_tolerance: f32,
    /// Relative CG residual of the solids' prediction (the last response
    /// takes on what it leaves).
    pub elastic_prediction_tolerance: f32,
    /// Largest number of elastic conjugate-gradient iterations.
    pub elastic_max_iterations: u32,
    /// Elastic body of each solid entry: entries with the same `body` name
    /// share an index (rest neighbours, and no pressure pairs between them).
    pub solid_group: Vec<u32>,
    /// Rest mass m_s0 = rho_s d^3 of a particle of each solid entry, kg.
    pub solid_rest_mass: Vec<f32>,
    /// Porous parameters of each solid entry, as the scene gives them
    /// (`None`: not porous).
    pub porous: Vec<Option<Porous>>,
    /// Pore drift weight phi of P-Eq. 11, m^2/(Pa s).
    pub pore_drift: f32,
    /// Inner drift weight tau' of P-Eq. 12.
    pub inner_drift_tau: f32,
    /// Inner diffusion weight sigma' of P-Eq. 12, m^2/s.
    pub inner_drift_sigma: f32,
}

/// What one step did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StepStats {
    /// The step's dt, s.
    pub dt: f32,
    /// Jacobi iterations of the pressure solve (all sweeps, restarts included).
    pub iterations: u32,
    /// Times the pressure solve diverged and started over with a smaller
    /// relaxation factor (`iisph::Divergence`).
    pub solve_restarts: u32,
    /// Mean predicted density error after the solve (fraction of rest density).
    pub density_error: f32,
    /// Mean predicted compression of the solid rows after the solve.
    pub solid_density_error: f32,
    /// Largest predicted compression of a fluid or solid row after the
    /// solve (CPU solve; 0 where the GPU solved).
    pub largest_density_error: f32,
    /// Largest fluid speed after the step, m/s.
    pub max_speed: f32,
    /// Largest drift speed max_k |u_mk| of the step, outer and inner, m/s
    /// (0 for one phase).
    pub max_drift_speed: f32,
    /// The drift speed of the time step rule: max_k |u_mk| without
    /// P-Eq. 11's (12's) diffusion term
    /// (`porosph_kernels::drift::max_advective_speed`), m/s.
    pub cfl_drift_speed: f32,
    /// Largest Darcy speed max_k |u_rk| on the porous solids, m/s.
    pub max_darcy_speed: f32,
    /// Conjugate-gradient iterations of the implicit viscosity solve (0
    /// when explicit).
    pub viscosity_iterations: u32,
    /// Conjugate-gradient iterations of the elastic solve (0 without solids).
    pub cg_iterations: u32,
    /// Relative residual |r|/|b| after the elastic solve: that of the
    /// pressure solve's last response, which also solves what the
    /// prediction left (`elastic_prediction_tolerance`).
    pub cg_residual: f32,
    /// Explicit sub-steps of the granular continuum within the step (0
    /// without granular solids).
    pub granular_substeps: u32,
    /// The term of the time step rule that set the next step's dt (`None`
    /// where it is not known: before the first step of a resumed run).
    pub next_dt_limit: Option<DtLimit>,
    /// Milliseconds per pass.
    pub times: PassTimes,
}

/// Neighbour structures and reused buffers (capacity persists across steps).
#[derive(Default)]
struct Workspace {
    reorder: Scratch,
    fluid_grid: CellGrid,
    wall_grid: CellGrid,
    /// With porous solids and several phases: the fluid-fluid pairs with
    /// h^3 grad W_ij, the full-particle volumes of the inner (beta)
    /// gradients and transport, which the pressure solve's pair volumes
    /// (0 for an inner particle) would cut off; only of the particles with
    /// inner fluid nearby (`porous::near_inner_fluid`).
    ffb: PairLists,
    /// Cells within one cell of a wall cell (static).
    wall_near: CellGrid,
    /// Wall particles with at least one fluid neighbour, ascending.
    active: Vec<u32>,
    /// 1 for the active walls (reset each step through `active`).
    wall_flag: Vec<u8>,
    /// Per block of fluid-fluid pairs: the implicit viscosity's pair
    /// coefficients (kept for its capacity).
    visc_coef: Vec<Vec<f32>>,
    /// Solid Morton keys (sorted after the sort).
    solid_keys: Vec<u64>,
    solid_sort: Vec<(u64, u32)>,
    /// Sorted solid index -> store index.
    solid_perm: Vec<u32>,
    /// Store index -> sorted solid index (the inverse of `solid_perm`):
    /// store-order results are gathered in parallel through it instead of
    /// scattered through `solid_perm` on one thread.
    solid_inv: Vec<u32>,
    /// Solid positions in sorted order.
    solid_sorted: [Vec<f32>; 3],
    solid_grid: CellGrid,
    /// Cells within one cell of a solid cell, and their keys: only fluid
    /// queries there can have solid neighbours; rebuilt when the solids'
    /// occupied cells (`solid_near_of`, those it was built from) change.
    solid_near: CellGrid,
    solid_near_keys: Vec<u64>,
    solid_near_of: Vec<u64>,
    /// omega_s, each solid particle's own body's share of its pressure
    /// row's neighbourhood, and V0_s, its rest volume in the solve (store
    /// order; `volumes::rest_rows`).
    solid_own: Vec<f32>,
    solid_v0: Vec<f32>,
    /// 0..number of solids (the identity row map of the solid rows).
    solid_rows: Vec<u32>,
}

/// The pair lists of a step (pass 0). Their gradients are plain, grad
/// W_ij, until pass 4c (`pressure::setup`) scales them in place by the pair
/// volumes V̄_ij and hands them on as [`pressure::ScaledPairs`], borrowed
/// for the rest of the step: a stage that needs plain gradients
/// (`porous::solid_terms`, the prediction, the volumes) cannot run after
/// it, which the compiler checks.
#[derive(Default)]
struct PairSet {
    /// Fluid-fluid pairs (incl. self).
    ff: PairLists,
    /// Fluid-wall pairs.
    fb: PairLists,
    /// Active-wall-fluid pairs.
    bf: PairLists,
    /// Fluid-solid pairs (solid targets in sorted order).
    fs: PairLists,
    /// Solid-fluid pairs (solid queries in sorted order).
    sf: PairLists,
    /// Solid-solid pairs, current (sorted order).
    ss: PairLists,
    /// Solid-wall pairs (solid queries in sorted order).
    sb: PairLists,
    /// Active-wall-solid pairs (solid targets in sorted order).
    bs: PairLists,
}

/// A running simulation: state, time, and what it needs to step.
pub struct Simulation {
    pub scene: Scene,
    pub params: Params,
    pub fluid: FluidStore,
    pub walls: WallStore,
    pub solids: SolidStore,
    /// How the solids deform.
    pub solid_model: Box<dyn SolidModel>,
    /// Who runs the passes a backend may run (`Simulation::use_gpu`; the
    /// CPU by default).
    backend: Box<dyn Passes>,
    pairs: PairSet,
    /// Simulated time, s.
    pub time: f64,
    /// Steps taken.
    pub step: u64,
    /// dt of the next step, s.
    pub dt: f32,
    /// What the last step did.
    pub last: StepStats,
    work: Workspace,
    arena: Bump,
    /// The most bytes of the arena one step has used (its high-water mark:
    /// what it touches, of [`Bump::allocated_bytes`]).
    arena_used: usize,
    /// The passes' own temporaries, one pass at a time.
    scratch: PassScratch,
}

impl Simulation {
    /// Bytes of memory held, by what holds them (stores, neighbour pair
    /// lists by kind: f = fluid, b = wall, s = solid, `ffb` the inner
    /// transport's copy of `ff`; the solids' rest rows; the step arena and
    /// the pass scratch, which holds the fluid sort's buffers), capacities
    /// included.
    pub fn memory(&self) -> Vec<(&'static str, usize)> {
        let (w, pairs) = (&self.work, &self.pairs);
        vec![
            ("fluid store", self.fluid.bytes()),
            ("wall store", self.walls.bytes()),
            ("solid store", self.solids.bytes()),
            ("solid model", self.solid_model.bytes()),
            ("pairs ff", pairs.ff.bytes()),
            ("pairs ffb", w.ffb.bytes()),
            ("pairs fb", pairs.fb.bytes()),
            ("pairs bf", pairs.bf.bytes()),
            (
                "pairs fs, sf, ss, sb, bs",
                pairs.fs.bytes() + pairs.sf.bytes() + pairs.ss.bytes() + pairs.sb.bytes() + pairs.bs.bytes(),
            ),
            ("solid rest rows", 4 * (w.solid_own.capacity() + w.solid_v0.capacity())),
            ("step arena", self.arena.allocated_bytes()),
            ("pass scratch", self.scratch.bytes()),
        ]
    }

    /// The most bytes of the step arena that a step has used so far (of
    /// the "step arena" of [`Simulation::memory`], which counts its chunks'
    /// capacity).
    pub fn arena_used(&self) -> usize {
        self.arena_used
    }

    /// The most bytes of the pass scratch that one pass has used so far (of
    /// the "pass scratch" of [`Simulation::memory`]).
    pub fn scratch_used(&self) -> usize {
        self.scratch.used()
    }

    /// Bytes of memory held per fluid particle: [`Simulation::memory`]
    /// summed, divided by the number of fluid particles.
    pub fn bytes_per_particle(&self) -> f64 {
        let bytes: usize = self.memory().iter().map(|(_, b)| b).sum();
        bytes as f64 / self.fluid.len().max(1) as f64
    }

    /// Volume of each phase in the fluid, sum_i h^3 (alpha_k,i + beta_k,i)
    /// over the fluid particles (the particle volume h^3 = V0 / alpha_f,
    /// P §6.1), m^3; summed in f64 in particle order.
    pub fn phase_volumes(&self) -> Vec<f64> {
        let (outer, inner) = self.phase_volumes_split();
        outer.iter().zip(&inner).map(|(a, b)| a + b).collect()
    }

    /// Outer and inner volume of each phase, sum_i h^3 alpha_k,i and
    /// sum_i h^3 beta_k,i, m^3 (f64 sums in particle order, of the stored
    /// fractions with their low parts, `FluidStore::alpha_lo`).
    pub fn phase_volumes_split(&self) -> (Vec<f64>, Vec<f64>) {
        self.fluid.phase_volumes(f64::from(self.params.cell_volume()))
    }

    /// Mass of each phase in the fluid, rho_k times its volume, kg.
    pub fn phase_masses(&self) -> Vec<f64> {
        self.phase_volumes().iter().zip(&self.params.phase_density).map(|(v, &r)| v * f64::from(r)).collect()
    }

    /// Number of fluid-fluid and fluid-wall pairs of the last step.
    pub fn pair_counts(&self) -> (usize, usize) {
        (self.pairs.ff.pairs(), self.pairs.fb.pairs())
    }
}

/// `f(perm[k])` for every k: a per-solid value of the store (index i) in
/// the sorted order of the solid pair lists (`perm`: sorted index -> store
/// index), gathered in parallel into `arena`.
fn in_sorted_order<'a, T: Copy + Default + Send + Sync>(
    arena: &'a Bump,
    perm: &[u32],
    f: impl Fn(usize) -> T + Sync,
) -> &'a mut [T] {
    use rayon::prelude::*;
    let out = arena.alloc_slice_fill_copy(perm.len(), T::default());
    out.par_iter_mut().zip(perm.par_iter()).for_each(|(o, &i)| *o = f(i as usize));
    out
}
