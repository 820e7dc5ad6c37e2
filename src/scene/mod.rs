//! Scene files: the TOML schema, its validation, and the sampling of shapes
//! into particles.
//!
//! A scene is parsed and validated in one go ([`Scene::from_file`],
//! [`Scene::from_toml_str`]); every problem is reported as a [`SceneError`] that
//! names the file, the key (a dotted path such as `fluid[1].box.min`) and the
//! reason. Nothing here panics on user input.

mod errors;
mod file;
mod geometry;
mod mesh;
mod parse;

pub use file::{schema, schema_text};
pub use geometry::{sample_fluid, sample_solids, sample_walls, sdf, SampledFluid, SampledSolids, SampledWalls};
pub use mesh::{MeshError, MeshSource, TriMesh};

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use std::fmt;
use std::sync::Arc;

/// A parsed, validated scene. All lengths in m, times in s, SI units throughout.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    pub simulation: Simulation,
    /// Fluid phases, in the order of the file (`[[phase]]`). Phase index k
    /// everywhere in porosph is the position in this list.
    pub phases: Vec<Phase>,
    /// `[[fluid]]` blocks.
    pub fluids: Vec<FluidBlock>,
    /// `[[wall]]` entries: static boundary particles.
    pub walls: Vec<Wall>,
    /// `[[solid]]` entries: elastic solid bodies.
    pub solids: Vec<Solid>,
    /// Where the scene came from (a path, or `<built-in NAME>`), for messages.
    pub origin: String,
    /// The scene text exactly as read (a run makes its mesh paths absolute,
    /// [`Scene::with_absolute_mesh_paths`], and checkpoints store that).
    pub text: String,
}

/// `[simulation]`: global settings.
///
/// The first line of each field's doc comment is what error messages and
/// the JSON Schema (`porosph schema`) call the value: a noun phrase with
/// its unit.
#[derive(Clone, Debug, PartialEq, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Simulation {
    /// The particle spacing in m
    ///
    /// d = h; the kernel support is H = 2 d (PHYSICS.md §1).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub particle_spacing: f32,
    /// The end time in s
    ///
    /// Simulated time at which `porosph run` stops.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub end_time: f64,
    /// The largest time step in s
    ///
    /// An upper bound; the CFL rule (PHYSICS.md §7) may pick less. At most `end_time`.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub max_dt: f32,
    /// The acceleration of gravity in m/s^2
    #[serde(default = "defaults::gravity")]
    pub gravity: [f32; 3],
    /// The largest mean density error as a fraction of the rest density
    ///
    /// IISPH stops when the mean predicted density error is at most this
    /// (0.001 = 0.1 %).
    #[serde(default = "defaults::max_density_error")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 0.1))]
    pub max_density_error: f32,
    /// The largest predicted compression of any one row, as a fraction
    ///
    /// Optional (default: no such bound). With it the solve also goes on
    /// until no fluid or solid row is compressed by more than this: the
    /// mean of `max_density_error` hides a few rows far off, such as the
    /// foot of a released column or a dry body's contact rows, which a
    /// solve that stops after two sweeps leaves there (bench/RESULTS.md,
    /// "A stop criterion on the largest row with the hydrostatic start").
    /// With `pressure_warm_start = "hydrostatic"` 0.02 keeps Example 1 at
    /// the paper's size free of kicks with implicit viscosity. The GPU
    /// backend leaves solves with this bound to the CPU.
    #[serde(default)]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub max_row_density_error: Option<f32>,
    /// The time between frames in s
    #[serde(default = "defaults::frame_interval")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub frame_interval: f64,
    /// The CFL number
    ///
    /// lambda in dt <= lambda h / max|u|.
    #[serde(default = "defaults::cfl_number")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub cfl_number: f32,
    /// The least number of solver iterations
    ///
    /// IISPH iterations per step.
    #[serde(default = "defaults::min_iterations")]
    #[schemars(range(min = 1))]
    pub min_iterations: u32,
    /// The largest number of solver iterations
    ///
    /// IISPH iterations per step; at least `min_iterations`.
    #[serde(default = "defaults::max_iterations")]
    #[schemars(range(min = 1))]
    pub max_iterations: u32,
    /// The Jacobi relaxation factor omega
    #[serde(default = "defaults::omega")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub omega: f32,
    /// The Chebyshev semi-iteration of the pressure solve
    ///
    /// An estimate rho of the relaxed Jacobi sweeps' spectral radius, in
    /// [0, 1); 0.9 by default, 0 for plain relaxed Jacobi. With rho > 0
    /// each sweep after the second is extrapolated from the last two
    /// (kernels/src/chebyshev.rs): deep pools converge in about half of
    /// the sweeps (Example 1 at the paper's size 12.8 -> 6.9 per step, at
    /// d = 4 mm to 0.3 s 10.4 -> 5.7 and no step at the sweep cap;
    /// bench/RESULTS.md), the tank at rest as still as without it, but the
    /// pressure's smooth part varies more from step to step
    /// (tests/hydrostatic.rs: more so from 0.95 on). A smaller rho than the
    /// true one only accelerates less. Both backends (the GPU loop matches
    /// the CPU's, tests/gpu_iisph.rs).
    #[serde(default = "defaults::chebyshev_radius")]
    #[schemars(extend("minimum" = 0, "exclusiveMaximum" = 1))]
    pub chebyshev_radius: f32,
    /// The warm start of the pressure solve
    ///
    /// Where each step's pressure solve starts (PHYSICS.md §2.2): "half"
    /// (default) half the last step's pressure; "hydrostatic" half of it
    /// plus half rho |g| depth, the depth under the top of the particle's
    /// connected column of fluid along gravity
    /// (kernels/src/hydrostatic.rs): deep pools in a fraction of the
    /// sweeps (the hydrostatic column 10,814 -> 1,223 sweeps in 1 s;
    /// Example 1 at d = 4 mm 35.6 -> 2.0 a step). The depth is scaled by
    /// the fluid-at-rest factor of its cell (the coarse potential problem
    /// with p = 0 in air beside the fluid), so the estimate does not press
    /// a released column outwards (Example 1 at d = 4 mm: 0.14 m/s after
    /// the first step, 0.039 with `wall_rows = "lattice"`, against 0.34
    /// with the column's depth alone and 0.02 with "half";
    /// bench/RESULTS.md).
    #[serde(default = "defaults::pressure_warm_start")]
    pub pressure_warm_start: PressureWarmStart,
    /// What a wall row counts as the wall's own part of its sigma
    ///
    /// "akinci" (default): the Akinci rest volumes, sum_b' V0_b' W_bb'
    /// (PHYSICS.md §2.3). Where walls meet (a container's edges and
    /// corners) those volumes are smaller, so these rows read 0.93 beside
    /// a fluid at rest, never resist compression and keep p = 0; the fluid
    /// beside them carries 2.1 (edges) and 3.5 (corners) times rho g depth
    /// at first. "lattice": the lattice's d^3 sum_b' W_bb', so every wall
    /// row reads 1 beside a fluid lattice at rest, and the wall rows take
    /// a Jacobi diagonal for the mode in which the rows around a fluid
    /// particle rise together (`iisph::wall_row_sigma`,
    /// `iisph::wall_setup`). Measured (bench/RESULTS.md, "The container's
    /// edges and corners"): the edges and corners at rho g depth within 7
    /// %, a Wendland C2 tank at rest with half the pressure error and a
    /// third less motion; but a quasi-2D Rayleigh-Taylor box (two layers
    /// between walls) inverts later.
    #[serde(default = "defaults::wall_rows")]
    pub wall_rows: WallRowsChoice,
    /// The drift relaxation weight tau in m^2/(Pa s) (= m^3 s/kg)
    ///
    /// tau of P-Eq. 11 (PHYSICS.md §7, §8.13: the paper's "m/(Pa s)" is a
    /// unit slip), the default of every phase (P Table 2). Not divided by
    /// the viscosity (PHYSICS.md §4.1: [AC] does; here a Stokes-like
    /// tau ~ d^2/(18 mu) is folded into the value).
    #[serde(default = "defaults::drift_tau")]
    #[schemars(range(min = 0))]
    pub drift_tau: f32,
    /// The drift diffusion weight sigma in m^2/s
    ///
    /// sigma of P-Eq. 11, the default of every phase (P Table 2).
    #[serde(default = "defaults::drift_sigma")]
    #[schemars(range(min = 0))]
    pub drift_sigma: f32,
    /// The smoothing kernel
    ///
    /// Its shape at support H = 2 d (PHYSICS.md §1, kernels/src/kernel.rs).
    #[serde(default = "defaults::kernel")]
    pub kernel: KernelChoice,
    /// The drift momentum term
    ///
    /// a^Dm of the mixture (PHYSICS.md §4.1, §8.15).
    #[serde(default = "defaults::drift_momentum")]
    pub drift_momentum: DriftMomentum,
    /// The volume-fraction transport
    ///
    /// Its form (PHYSICS.md §4.1).
    #[serde(default = "defaults::phase_transport")]
    pub phase_transport: PhaseTransport,
    /// The phase pressure
    ///
    /// The phase pressures p_k of the drift velocities (P-Eq. 11).
    #[serde(default = "defaults::phase_pressure")]
    pub phase_pressure: PhasePressure,
    /// The viscosity solver
    ///
    /// How P-Eq. 23's viscosity enters the step (PHYSICS.md §5, §7).
    #[serde(default = "defaults::viscosity_solver")]
    pub viscosity_solver: ViscositySolver,
    /// The relative residual of the implicit viscosity solve
    ///
    /// |r| / |r_0| at which its conjugate gradients stop (r_0 the residual
    /// of u + dt g).
    #[serde(default = "defaults::viscosity_tolerance")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub viscosity_tolerance: f32,
    /// The relative residual of the elastic solve
    ///
    /// |r| / |b| at which the conjugate gradients stop (PHYSICS.md §3.3).
    #[serde(default = "defaults::elastic_tolerance")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub elastic_tolerance: f32,
    /// The relative residual of the solids' prediction
    ///
    /// |r| / |b| at which the conjugate gradients of the prediction (the
    /// solids' velocities without the fluid's pressure, which the pressure
    /// solve's solid rows read) stop. What it leaves unsolved the step's
    /// last response to the pressure forces takes on, to
    /// `elastic_tolerance`, so the solids' new velocities solve the
    /// implicit step to that tolerance either way (PHYSICS.md §3.3).
    #[serde(default = "defaults::elastic_prediction_tolerance")]
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub elastic_prediction_tolerance: f32,
    /// The largest number of conjugate-gradient iterations
    ///
    /// The unpreconditioned CG of the elastic solve needs about
    /// 4 (c dt / d) iterations, c the speed of sound of the solid, so stiff
    /// solids need many.
    #[serde(default = "defaults::elastic_max_iterations")]
    #[schemars(range(min = 1))]
    pub elastic_max_iterations: u32,
    /// The pore drift weight phi in m^2/(Pa s)
    ///
    /// phi of P-Eq. 11's porous term (the units of tau, PHYSICS.md §7; P Table 2).
    #[serde(default = "defaults::pore_drift")]
    #[schemars(range(min = 0))]
    pub pore_drift: f32,
    /// The inner drift weight tau' (dimensionless)
    ///
    /// tau' of P-Eq. 12 (it multiplies a velocity, PHYSICS.md §8.11; P Table 2).
    #[serde(default = "defaults::inner_drift_tau")]
    #[schemars(range(min = 0))]
    pub inner_drift_tau: f32,
    /// The inner diffusion weight sigma' in m^2/s
    ///
    /// sigma' of P-Eq. 12 (P Table 2).
    #[serde(default = "defaults::inner_drift_sigma")]
    #[schemars(range(min = 0))]
    pub inner_drift_sigma: f32,
}

/// The defaults of `[simulation]`.
mod defaults {
    use super::{
        DriftMomentum, KernelChoice, PhasePressure, PhaseTransport, PressureWarmStart, ViscositySolver, WallRowsChoice,
    };

    pub fn gravity() -> [f32; 3] {
        [0.0, -9.81, 0.0]
    }
    pub fn max_density_error() -> f32 {
        0.001
    }
    pub fn frame_interval() -> f64 {
        0.02
    }
    pub fn cfl_number() -> f32 {
        0.4
    }
    pub fn min_iterations() -> u32 {
        2
    }
    pub fn max_iterations() -> u32 {
        100
    }
    pub fn omega() -> f32 {
        0.5
    }
    pub fn chebyshev_radius() -> f32 {
        0.9
    }
    /// P Table 2 (tau in m^2/(Pa s), PHYSICS.md §7).
    pub fn drift_tau() -> f32 {
        3e-6
    }
    /// P Table 2.
    pub fn drift_sigma() -> f32 {
        1e-3
    }
    pub fn kernel() -> KernelChoice {
        KernelChoice::CubicSpline
    }
    pub fn drift_momentum() -> DriftMomentum {
        DriftMomentum::Physical
    }
    pub fn phase_transport() -> PhaseTransport {
        PhaseTransport::Conservative
    }
    pub fn phase_pressure() -> PhasePressure {
        PhasePressure::Shared
    }
    /// Explicit: with "auto", Example 1 at the paper's size (d = 2.4 mm)
    /// steps at 2 ms instead of 0.72 ms, and its pressure solve then
    /// reaches its 100-iteration cap (steps 4-7, 14) and blows up at step
    /// 19 (bench/RESULTS.md, "Implicit viscosity").
    pub fn pressure_warm_start() -> PressureWarmStart {
        PressureWarmStart::Half
    }
    pub fn wall_rows() -> WallRowsChoice {
        WallRowsChoice::Akinci
    }
    pub fn viscosity_solver() -> ViscositySolver {
        ViscositySolver::Explicit
    }
    pub fn viscosity_tolerance() -> f32 {
        1e-3
    }
    pub fn elastic_tolerance() -> f32 {
        1e-4
    }
    pub fn elastic_prediction_tolerance() -> f32 {
        1e-2
    }
    pub fn elastic_max_iterations() -> u32 {
        1000
    }
    /// P Table 2.
    pub fn pore_drift() -> f32 {
        3e-6
    }
    /// P Table 2.
    pub fn inner_drift_tau() -> f32 {
        1e-4
    }
    /// P Table 2.
    pub fn inner_drift_sigma() -> f32 {
        2e-3
    }
}

/// `phase_pressure`: the phase pressure p_k in P-Eq. 11
/// (`porosph_kernels::drift` explains the difference).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum PhasePressure {
    /// `"shared"` (default): p_k = p for every phase; the two pressure
    /// terms of P-Eq. 11 cancel and the drift is the buoyancy slip
    /// tau (rho_k - sum c rho) a of Manninen's mixture model.
    Shared,
    /// `"fraction"`: p_k = alphahat_k p, as PHYSICS.md §4.1 writes it after
    /// [AC]. It depends on the pressure's zero, adds a diffusion of about
    /// 2 tau p (limiting dt), and stops gravity separation at a mixed
    /// composition.
    Fraction,
}

/// `pressure_warm_start`: where the pressure solve starts
/// (`porosph_kernels::hydrostatic`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum PressureWarmStart {
    /// `"half"` (default): half the last step's pressure.
    Half,
    /// `"hydrostatic"`: half the last step's pressure and half the weight
    /// per unit area of the fluid and solids in the column above (rho |g|
    /// depth in one fluid; the plain half without gravity along one axis).
    Hydrostatic,
}

/// `wall_rows`: the wall's own part of a wall row's sigma
/// (`porosph_kernels::iisph::wall_row_sigma`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum WallRowsChoice {
    /// `"akinci"` (default): the Akinci rest volumes.
    Akinci,
    /// `"lattice"`: the lattice volume d^3, and the walls' coupled
    /// diagonal.
    Lattice,
}

/// `viscosity_solver`: explicit or implicit viscosity (P-Eq. 23;
/// `porosph_kernels::viscosity`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum ViscositySolver {
    /// `"auto"`: dt is not held to the explicit bound 0.125 d^2 rho_k /
    /// mu_k where that is below `max_dt`, and each step longer than the
    /// bound solves the viscosity implicitly, each step within it
    /// explicitly (a step held below it by another term, such as the CFL
    /// rule in a fast flow, skips the solve; the same result as explicit
    /// where the bound never holds dt).
    Auto,
    /// `"explicit"` (default): a^visc from the velocities at the step's
    /// start; dt is held to 0.125 d^2 rho_k / mu_k.
    Explicit,
    /// `"implicit"`: backward Euler, a linear solve per step (conjugate
    /// gradients); no viscosity bound on dt.
    Implicit,
}

/// `phase_transport`: the form of the volume-fraction transport (P-Eq. 2);
/// `porosph_kernels::phase_transport` explains both.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum PhaseTransport {
    /// `"conservative"` (default): volume-weighted phase fluxes with a
    /// positivity limiter and no alpha div u_m term; conserves every
    /// phase's volume to rounding.
    Conservative,
    /// `"reference"`: the symmetric form exactly as [RG], [AC] and
    /// PHYSICS.md §4.1 write it; each phase's volume drifts through the
    /// correction.
    Reference,
}

/// `kernel`: the smoothing kernel's shape (kernels/src/kernel.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KernelChoice {
    /// `"cubic_spline"` (default): the SPlisHSPlasH form.
    CubicSpline,
    /// `"wendland_c2"`: Wendland C2, its lattice sum and gradient
    /// calibrated on the start lattice; its lattice holds at positive
    /// pressure, so a fluid at rest moves about three times less.
    WendlandC2,
}

/// `drift_momentum`: how the drift momentum term
/// a^Dm = -(1/rho) div sum_k alpha_k rho_k u_mk (x) u_mk enters the mixture
/// momentum (PHYSICS.md §4.1; the sign discussion is §8.15).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum DriftMomentum {
    /// `"physical"` (default): with the minus sign of the mixture momentum
    /// equation (Manninen et al. 1996).
    Physical,
    /// `"plus"`: with the plus sign of the reference codes [RG] and [AC].
    Plus,
    /// `"off"`: left out.
    Off,
}

/// `[[phase]]`: one fluid phase.
#[derive(Clone, Debug, PartialEq)]
pub struct Phase {
    pub name: String,
    /// Rest density rho_k, kg/m^3.
    pub density: f32,
    /// Dynamic viscosity mu_k, Pa s.
    pub viscosity: f32,
    /// Display colour, linear RGB in [0, 1] (default: from a fixed palette by index).
    pub color: [f32; 3],
    /// Drift relaxation weight tau_k of this phase, m^2/(Pa s) (the key
    /// `drift_tau` of the phase; default `simulation.drift_tau`).
    pub drift_tau: f32,
    /// Drift diffusion weight sigma_k of this phase, m^2/s (the key
    /// `drift_sigma` of the phase; default `simulation.drift_sigma`).
    pub drift_sigma: f32,
}

/// A region of space. Lattice points inside it become particles.
#[derive(Clone, Debug, PartialEq)]
pub enum Shape {
    /// Axis-aligned box, `box = { min = [..], max = [..] }`.
    Box { min: [f32; 3], max: [f32; 3] },
    /// `sphere = { center = [..], radius = r }`.
    Sphere { center: [f32; 3], radius: f32 },
    /// `cylinder = { base = [..], axis = [..], radius = r, height = l }`:
    /// a cylinder from `base` along the unit vector `axis` for `height`.
    Cylinder { base: [f32; 3], axis: [f32; 3], radius: f32, height: f32 },
    /// `mesh = { path, scale, translate }`: the inside of a closed triangle
    /// mesh (OBJ or STL), read, scaled and moved when the scene is parsed.
    Mesh(Arc<TriMesh>),
}

/// `[[fluid]]`: a block of fluid particles.
#[derive(Clone, Debug, PartialEq)]
pub struct FluidBlock {
    pub shape: Shape,
    /// Volume fraction of each phase, indexed like [`Scene::phases`], summing to 1.
    pub fractions: Vec<f32>,
    /// Initial velocity, m/s (default 0).
    pub velocity: [f32; 3],
}

/// `[[wall]]`: static boundary particles.
#[derive(Clone, Debug, PartialEq)]
pub struct Wall {
    pub shape: Shape,
    /// `container = true` (boxes only): the box is the inside of a tank, and
    /// walls are laid around it on the outside of its faces.
    pub container: bool,
    /// With `container = true`: leave the top (+y) face open.
    pub open_top: bool,
}

/// `[[solid]]`: an elastic solid body (PHYSICS.md §3), sampled on the
/// lattice like a fluid block.
#[derive(Clone, Debug, PartialEq)]
pub struct Solid {
    pub name: String,
    pub shape: Shape,
    /// Density, kg/m^3 (particle mass = density d^3).
    pub density: f32,
    /// Shear modulus mu, Pa (the paper's "nu", PHYSICS.md §8.6).
    pub shear_modulus: f32,
    /// Lame's first parameter lambda, Pa.
    pub lame_lambda: f32,
    /// Initial velocity, m/s (default 0).
    pub velocity: [f32; 3],
    /// `fixed = { box = .. }`: particles inside this shape are kinematic:
    /// they move with [`Solid::motion`] (at rest outside its intervals).
    pub fixed: Option<Shape>,
    /// `motion = [{ from, until, velocity }, ..]`: the velocity of the fixed
    /// particles over time intervals [from, until) s.
    pub motion: Vec<Motion>,
    /// `body = "NAME"`: entries with the same body name form one elastic
    /// body (rest neighbours across them, one elastic response in the
    /// pressure solve) with regions of different material (default: its
    /// own name).
    pub body: String,
    /// `[solid.porous]`: the porous parameters of this solid (region).
    pub porous: Option<Porous>,
    /// `model`: how the solid deforms (default elastic).
    pub model: SolidMaterial,
}

/// `model`: the name of a solid's deformation model.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SolidModelChoice {
    /// `"elastic"` (default): corotated SPH elasticity (Peer et al. 2018).
    #[default]
    Elastic,
    /// `"granular"`: the Drucker-Prager elasto-plastic continuum.
    Granular,
}

/// `yield_cone`: the stress path on which a granular solid's
/// Drucker-Prager cone matches Mohr-Coulomb (kernels/src/drucker_prager.rs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum YieldCone {
    /// `"plane_strain"` (default): plastic flow without strain along one axis.
    #[default]
    PlaneStrain,
    /// `"triaxial_compression"`: the compression meridian.
    TriaxialCompression,
}

/// `initial_stress`: the stress a granular solid starts with.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum InitialStress {
    /// `"zero"` (default): released from no stress, as if its weight were
    /// switched on at the start (it settles, ringing in its elastic modes).
    #[default]
    Zero,
    /// `"lithostatic"`: sand at rest under its own weight (a column behind
    /// a gate): vertical stress rho g depth under the body's own top, and
    /// (1 - sin phi) of it sideways (Jaky's K0).
    Lithostatic,
}

/// How a solid deforms, with the model's parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum SolidMaterial {
    /// Corotated linear elasticity with the body's rest neighbours.
    Elastic,
    /// The Drucker-Prager elasto-plastic continuum (kernels/src/granular.rs).
    Granular(Granular),
}

/// A granular solid's plastic parameters (its elastic ones are the solid's
/// `shear_modulus` and `lame_lambda`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Granular {
    /// Friction angle phi, degrees.
    pub friction_angle: f32,
    /// Dilatancy angle psi, degrees.
    pub dilatancy_angle: f32,
    /// The stress path the cone is fitted on.
    pub yield_cone: YieldCone,
    /// Cohesion c (dry), Pa.
    pub cohesion: f32,
    /// The largest added cohesion of partly filled pores, Pa (0: none).
    pub wet_cohesion: f32,
    /// van Genuchten's n of the wet cohesion law (> 2).
    pub suction_n: f32,
    /// A saturation held fixed (no `[solid.porous]`), or `None`.
    pub saturation: Option<f32>,
    /// Per axis x, y, z: the walls facing it are frictionless (free slip)
    /// for this solid; else no slip.
    pub wall_slip: [bool; 3],
    /// The stress it starts with.
    pub initial_stress: InitialStress,
}

/// `[solid.porous]`: a porous solid (P §4, PHYSICS.md §4.2, §7).
#[derive(Clone, Debug, PartialEq)]
pub struct Porous {
    /// Porosity e: the saturated absorbed volume ratio sum_k phi_sk.
    pub porosity: f32,
    /// Rest pore pressure p_0 of P-Eq. 9, Pa.
    pub rest_pore_pressure: f32,
    /// B of P-Eq. 9 ("Biot's ratio constant"), Pa.
    pub biot_modulus: f32,
    /// eta of P-Eq. 5: the pore stress -eta p^pore I (swelling).
    pub swelling: f32,
    /// psi of P-Eq. 14, m^2/s^2.
    pub capillarity: f32,
    /// Absorption ratio K of P-Eq. 13.
    pub absorption: f32,
    /// Wet particles gain the absorbed mass (the paper's Example 3).
    pub gains_mass: bool,
    /// Per phase (indexed like [`Scene::phases`]): `None` = not absorbed.
    pub phases: Vec<Option<PorousPhase>>,
}

/// `[solid.porous.phase.NAME]`: how a porous solid absorbs one phase.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PorousPhase {
    /// The permeability k_w in m^2
    ///
    /// k_wk of P-Eq. 1 (PHYSICS.md §7: flux = -k/mu grad p).
    #[schemars(range(min = 0))]
    pub permeability: f32,
    /// The outer pore pressure p0k in Pa
    ///
    /// Absorption stops where p^pore = p_0k; at most porosity x rest_pore_pressure.
    #[schemars(range(min = 0))]
    pub outer_pore_pressure: f32,
}

/// One interval of prescribed motion of a solid's fixed particles.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Motion {
    /// The start time in s
    #[schemars(range(min = 0))]
    pub from: f64,
    /// The end time in s
    ///
    /// Exclusive; after `from`, and intervals must not overlap.
    #[schemars(range(min = 0))]
    pub until: f64,
    /// The velocity of the fixed particles in m/s
    pub velocity: [f32; 3],
}

impl Solid {
    /// The velocity of the fixed particles at time `t`, m/s.
    pub fn fixed_velocity(&self, t: f64) -> [f32; 3] {
        self.motion.iter().find(|m| m.from <= t && t < m.until).map_or([0.0; 3], |m| m.velocity)
    }
}

/// A scene problem: which file, which key, where, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// File path, or `<built-in NAME>`.
    pub file: String,
    /// Dotted key path, e.g. `fluid[0].box.min`; empty for file-level errors.
    pub key: String,
    /// 1-based line and column of the key or value at fault, where the
    /// scene text has one (a TOML syntax error says it in `reason`).
    pub position: Option<(usize, usize)>,
    pub reason: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.file)?;
        if let Some((line, column)) = self.position {
            write!(f, ":{line}:{column}")?;
        }
        if self.key.is_empty() {
            write!(f, ": {}", self.reason)
        } else {
            write!(f, ": key `{}`: {}", self.key, self.reason)
        }
    }
}

impl std::error::Error for SceneError {}
