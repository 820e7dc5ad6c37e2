//! The pass interface: the passes of a step that a backend may run, and
//! what each reads and writes (PHYSICS.md §6: pass 0's Morton sort and the
//! tables built from its grid, pass 5's IISPH Jacobi loop, pass 10's drift
//! velocities). The step asks its [`Passes`] for these and does not know
//! which backend answers: the CPU backend ([`super::cpu::Cpu`]) runs them
//! with the `porosph-kernels` passes; the GPU backend
//! ([`super::gpu::GpuBackend`]) runs those its `--gpu-passes` select on the
//! device and hands the others, and any pass whose device run fails, to the
//! CPU. Every other pass of the step runs on the CPU.

use super::BackendKind;
use bumpalo::Bump;
use porosph_kernels::band::BandVel;
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph::Rows;
use porosph_kernels::kernel::Kernel;
use porosph_kernels::neighbors::PairLists;
use porosph_kernels::phases::PhaseConstants;
use porosph_kernels::soa::{Vel, VelMut};
use porosph_kernels::solid_rows::SolidNeighbours;

/// The timed passes of a step, in order, each with its number in
/// PHYSICS.md §6's pipeline. [`Pass::name`] heads the pass's `ms_<pass>`
/// column of `stats.csv` on every backend.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Pass {
    /// 0: neighbour search, with the Morton sort and reorder.
    Neighbors,
    /// 1: phase bookkeeping.
    Phases,
    /// 2 and 4a-b: densities, rest and current volumes.
    Densities,
    /// 3: viscosity and the predicted velocity u*.
    Viscosity,
    /// 4c: sources and diagonal of the pressure system.
    PpeSetup,
    /// 5: the IISPH relaxed Jacobi loop.
    PressureSolve,
    /// 6 and 8: the elastic solids (deformation, stress, conjugate
    /// gradients; 0 ms without solids).
    Elasticity,
    /// 6-7 and 9: the porous coupling (absorbed volume, pore pressure,
    /// Darcy flux, the fluid's porous terms and accelerations; 0 ms without
    /// porous solids).
    Porous,
    /// 10: drift velocities (two or more phases, else 0 ms).
    Drift,
    /// 11: the drift momentum term a^Dm (two or more phases).
    DriftMomentum,
    /// 12: volume-fraction transport (two or more phases).
    PhaseTransport,
    /// 13: integration.
    Integrate,
    /// 14: the volume-fraction correction (two or more phases).
    PhaseCorrection,
    /// 14: the next time step (CFL).
    TimeStep,
}

impl Pass {
    /// Every pass, in the order of the step.
    pub const ALL: [Pass; 14] = [
        Pass::Neighbors,
        Pass::Phases,
        Pass::Densities,
        Pass::Viscosity,
        Pass::PpeSetup,
        Pass::PressureSolve,
        Pass::Elasticity,
        Pass::Porous,
        Pass::Drift,
        Pass::DriftMomentum,
        Pass::PhaseTransport,
        Pass::Integrate,
        Pass::PhaseCorrection,
        Pass::TimeStep,
    ];

    /// Number of passes.
    pub const COUNT: usize = Pass::ALL.len();

    /// The pass's place in [`Pass::ALL`].
    pub const fn index(self) -> usize {
        self as usize
    }

    /// The name of the pass in `stats.csv` and the benchmarks.
    pub const fn name(self) -> &'static str {
        match self {
            Pass::Neighbors => "neighbors",
            Pass::Phases => "phases",
            Pass::Densities => "densities",
            Pass::Viscosity => "viscosity",
            Pass::PpeSetup => "ppe_setup",
            Pass::PressureSolve => "pressure_solve",
            Pass::Elasticity => "elasticity",
            Pass::Porous => "porous",
            Pass::Drift => "drift",
            Pass::DriftMomentum => "drift_momentum",
            Pass::PhaseTransport => "phase_transport",
            Pass::Integrate => "integrate",
            Pass::PhaseCorrection => "phase_correction",
            Pass::TimeStep => "time_step",
        }
    }

    /// The pass of a name ([`Pass::name`]).
    pub fn from_name(name: &str) -> Option<Pass> {
        Pass::ALL.into_iter().find(|p| p.name() == name)
    }
}

impl std::fmt::Display for Pass {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.pad(self.name())
    }
}

/// The passes a backend runs for the step.
pub trait Passes: Send {
    /// Which backend this is.
    fn kind(&self) -> BackendKind;

    /// Pass 0: the Morton keys of the fluid positions (cells of
    /// `1 / inv_cell`) and the permutation that sorts them: `sort` gets the
    /// (key, index) pairs in ascending order, `perm` the indices (`keys` is
    /// scratch); each slice has one entry per fluid particle. Returns the
    /// device time, ms (0 on the CPU).
    fn sort(&mut self, fluid: Vel, inv_cell: f32, keys: &mut [u64], sort: &mut [(u64, u32)], perm: &mut [u32]) -> f64;

    /// The end of pass 0: what this backend's later passes of the step need
    /// built from the step's grids (the GPU's cell-range tables; nothing on
    /// the CPU). Returns the device time, ms.
    fn prepare(&mut self, fluid_grid: &CellGrid, walls: WallInput, step: StepShape) -> f64;

    /// Pass 5: the pressures that solve the system (warm-started from the
    /// values in `x`), and the final pressure accelerations.
    fn pressure_solve(&mut self, sys: &PressureSystem, x: Unknowns, arena: &Bump) -> SolveReport;

    /// Pass 10: the drift velocities and phase fluxes (P-Eq. 11), and with
    /// porous solids the inner ones into `inner` (P-Eq. 12).
    fn drift(&mut self, prob: &DriftProblem, out: DriftOutput, inner: Option<DriftOutput>, arena: &Bump)
        -> DriftReport;

    /// Why a device pass failed during the last step (the step completed on
    /// the CPU; the run reports it as a step error).
    fn take_error(&mut self) -> Option<String>;

    /// The backend as its own type (`Simulation::gpu` finds the GPU
    /// backend's statistics through it).
    fn as_any(&self) -> &dyn std::any::Any;
}

/// What kind of step the backend prepares for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct StepShape {
    /// The fluid has particles.
    pub fluid: bool,
    /// There are solid particles (solid rows in the pressure solve).
    pub solids: bool,
    /// Two or more phases (the drift pass runs).
    pub mixture: bool,
}

/// The walls of a step as the pressure solve sees them: the static wall
/// grid and positions (sorted once), and the active walls (those with a
/// fluid neighbour, ascending), the rows of the solve.
#[derive(Clone, Copy)]
pub struct WallInput<'a> {
    pub grid: &'a CellGrid,
    pub walls: Vel<'a>,
    pub active: &'a [u32],
}

/// The convergence settings of the Jacobi loop.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SolveSettings {
    pub dt: f32,
    /// Relaxation omega.
    pub omega: f32,
    /// The spectral radius estimate of the Chebyshev semi-iteration over
    /// the sweeps, or 0 for plain relaxed Jacobi
    /// (`porosph_kernels::chebyshev`).
    pub chebyshev_radius: f32,
    pub min_iterations: u32,
    pub max_iterations: u32,
    /// Stop at this mean density error (fraction).
    pub max_density_error: f32,
    /// And only once every row's predicted compression (fluid and solid
    /// rows) is at most this (fraction; infinite: no such bound). CPU
    /// loop only: the GPU backend leaves a solve with a finite bound to
    /// the CPU.
    pub max_row_density_error: f32,
    /// Number of fluid rows (a_ii != 0), the mean's divisor (at least 1).
    pub rows_active: f32,
}

/// The system of pass 5 (P-Eqs. 25-29 with pressure boundaries, PHYSICS.md
/// §2.2-2.4). The pair lists hold V̄_ij grad W_ij (`iisph::fluid_setup`).
pub struct PressureSystem<'a> {
    /// The scene's kernel (the GPU passes recompute g_ij with it).
    pub kernel: &'a Kernel,
    pub fluid_grid: &'a CellGrid,
    pub fluid: Vel<'a>,
    pub walls: WallInput<'a>,
    /// Fluid-fluid, fluid-wall and active-wall-fluid pairs.
    pub ff: &'a PairLists,
    pub fb: &'a PairLists,
    pub bf: &'a PairLists,
    /// Fluid current volume V and V/m.
    pub vol: &'a [f32],
    pub vm: &'a [f32],
    /// Fluid rows (S, a_ii).
    pub rows: Rows<'a>,
    /// Current volume of every wall (0 for inactive walls), m^3.
    pub vol_wall: &'a [f32],
    /// Rows of the active walls.
    pub wall_rows: Rows<'a>,
    /// The solid rows, if the scene has solids.
    pub solids: Option<SolidSystem<'a>>,
    pub settings: SolveSettings,
}

/// The solid rows of pass 5 (`porosph_kernels::solid_rows`), in the
/// sorted solid order of the pair lists.
pub struct SolidSystem<'a> {
    /// Fluid-solid pairs (fluid rows), the solid rows' solid-fluid,
    /// solid-wall and solid-solid pairs, and the active walls' wall-solid
    /// pairs (the order of `WallInput::active`).
    pub fs: &'a PairLists,
    pub solid: SolidNeighbours<'a>,
    pub bs: &'a PairLists,
    /// Current volume V_s of each solid particle, m^3.
    pub vol: &'a [f32],
    /// Solid rows (S, a_ii).
    pub rows: Rows<'a>,
}

/// How the solid particles move within the pressure solve: the elastic
/// bodies' response a^p_s = C F_s to the pressure forces (C the compliance
/// of their implicit step), so that the solve sees each body give way as it
/// will (strong coupling: a body lighter than the fluid is stable, whose
/// surface alone would face the fluid's added mass).
pub trait Compliance {
    /// The accelerations of the solid particles (sorted order) under the
    /// forces `force` (N), into `accel` (m/s^2), which holds the last
    /// answer on entry (the warm start). `exact`: to the model's tolerance
    /// (the final answer of the solve); else a few iterations.
    fn respond(&mut self, force: Vel, accel: VelMut, exact: bool);
}

/// The unknowns of pass 5: the pressures (read as the warm start, written
/// as the solution) and the final pressure accelerations.
pub struct Unknowns<'a> {
    /// Fluid pressures, Pa.
    pub p: &'a mut [f32],
    /// Pressure of every wall (inactive walls: 0 on entry, left so), Pa.
    pub p_wall: &'a mut [f32],
    /// Pressures of the active walls (the order of `WallInput::active`), Pa.
    pub p_active: &'a mut [f32],
    /// Fluid a^p, m/s^2.
    pub ap: VelMut<'a>,
    /// The solids' unknowns, with the solid rows.
    pub solids: Option<SolidUnknowns<'a>>,
}

/// The solids' part of [`Unknowns`].
pub struct SolidUnknowns<'a> {
    /// Solid pressures (sorted order), Pa.
    pub p: &'a mut [f32],
    /// a^p_s = C F_s (sorted order), m/s^2.
    pub accel: VelMut<'a>,
    /// How the bodies respond to the pressure forces.
    pub response: &'a mut dyn Compliance,
}

/// How pass 5 went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SolveReport {
    pub iterations: u32,
    pub density_error: f32,
    /// Restarts with a smaller omega after the error grew
    /// (`iisph::Divergence`; CPU loop only).
    pub restarts: u32,
    /// Mean predicted compression of the solid rows after the solve.
    pub solid_error: f32,
    /// Largest predicted compression of a fluid or solid row after the
    /// solve (CPU loop only; 0 on the GPU).
    pub largest_error: f32,
    /// Device time of the loop from timestamp queries, ms (None where the
    /// loop ran on the CPU or the adapter has none).
    pub gpu_ms: Option<f64>,
    /// Submissions (host round trips) the loop took (GPU only).
    pub submits: u32,
}

/// The problem of pass 10 (PHYSICS.md §4.1): the fluid sorted by the cells
/// of `fluid_grid`, the pressure solve's pairs `ff` (V̄_ij grad W_ij) and,
/// with porous solids, the pairs `ffb` with h^3 grad W_ij of the inner drift.
pub struct DriftProblem<'a> {
    pub input: DriftInput<'a>,
    pub ff: &'a PairLists,
    pub ffb: Option<&'a PairLists>,
}

/// What the drift pass reads.
pub struct DriftInput<'a> {
    /// The scene's kernel (the GPU passes recompute g_ij with it).
    pub kernel: &'a Kernel,
    pub fluid_grid: &'a CellGrid,
    pub fluid: Vel<'a>,
    /// Current volume V of each particle (the volume of the harmonic pair
    /// volumes the CPU pair lists are scaled by), m^3.
    pub vol: &'a [f32],
    /// alpha_k per phase.
    pub alpha: &'a [&'a [f32]],
    pub alpha_f: &'a [f32],
    /// p / alpha_f (`drift::pressure_per_fraction`) for phase pressures
    /// p_k = alphahat_k p; `None` for a shared pressure.
    pub p_per_fraction: Option<&'a [f32]>,
    pub a_visc: Vel<'a>,
    pub a_p: Vel<'a>,
    pub phases: &'a [PhaseConstants],
    /// The conservative transport's fluxes F_k = w_k - alpha_k m.
    pub conservative: bool,
    /// Porous solids: P-Eq. 11's porous term and the inner drift (P-Eq. 12).
    pub porous: Option<PorousDriftInput<'a>>,
}

/// The porous terms of the drift (PHYSICS.md §4.2): the outer phase
/// velocities get -phi grad p^pore_fk (P-Eq. 11); the inner drift (P-Eq.
/// 12) is the same pass over the inner fractions beta with sigma', no phase
/// pressure, -tau' q_k,f, and every volume h^3.
pub struct PorousDriftInput<'a> {
    /// grad p^pore_fk per phase on the fluid-solid band
    /// (`porosph_kernels::band`), Pa/m.
    pub grad_pore: BandVel<'a>,
    /// phi of P-Eq. 11, m^2/(Pa s).
    pub pore_drift: f32,
    /// beta_k per phase.
    pub beta: &'a [&'a [f32]],
    /// beta_f = sum_k beta_k.
    pub beta_f: &'a [f32],
    /// q_k,f per phase on the fluid-solid band, m/s.
    pub q: BandVel<'a>,
    /// tau' of P-Eq. 12.
    pub inner_tau: f32,
    /// sigma' of P-Eq. 12, m^2/s.
    pub inner_sigma: f32,
    /// h^3, the volume of the inner pairs' gradients h^3 grad W_ij, m^3.
    pub cell_volume: f32,
}

/// What the drift pass writes, phase-major (phase k at `[k n, (k + 1) n)`):
/// the drift velocities u_mk and the phase fluxes F_k, m/s.
pub struct DriftOutput<'a> {
    /// u_mk.
    pub u: VelMut<'a>,
    /// F_k.
    pub f: VelMut<'a>,
}

impl DriftOutput<'_> {
    /// The same arrays, borrowed again.
    pub fn reborrow(&mut self) -> DriftOutput<'_> {
        DriftOutput { u: self.u.reborrow(), f: self.f.reborrow() }
    }
}

/// How pass 10 went.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DriftReport {
    /// Largest outer and inner drift speed, m/s.
    pub max_speed: f32,
    /// Device time, ms (0 on the CPU).
    pub gpu_ms: f64,
}
