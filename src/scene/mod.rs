//! Scene files: the TOML schema, its validation, and the sampling of shapes
//! into particles.
//!
//! A scene is parsed and validated in one go ([`Scene::from_file`],
//! [`Scene::from_toml_str`]); every problem is reported as a [`SceneError`] that
//! names the file, the key (a dotted path such as `fluid[1].box.min`) and the
//! reason. Nothing here panics on user input.

mod geometry;
mod parse;

pub use geometry::{sample_fluid, sample_solids, sample_walls, sdf, SampledFluid, SampledSolids, SampledWalls};

use std::fmt;

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
    /// The scene text exactly as read (checkpoints store it).
    pub text: String,
}

/// `[simulation]`: global settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// Particle spacing d = h, m. The kernel support is H = 2 d (PHYSICS.md §1).
    pub particle_spacing: f32,
    /// Simulated time at which `porosph run` stops, s.
    pub end_time: f64,
    /// Upper bound of the time step, s; the CFL rule (PHYSICS.md §7) may pick less.
    pub max_dt: f32,
    /// Gravity, m/s^2.
    pub gravity: [f32; 3],
    /// IISPH stops when the mean predicted density error is at most this
    /// fraction of the rest density (default 0.001 = 0.1 %).
    pub max_density_error: f32,
    /// Simulated time between written frames, s.
    pub frame_interval: f64,
    /// CFL number lambda in dt <= lambda h / max|u| (default 0.4).
    pub cfl_number: f32,
    /// Minimum IISPH iterations per step (default 2).
    pub min_iterations: u32,
    /// Maximum IISPH iterations per step (default 100).
    pub max_iterations: u32,
    /// Relaxation factor omega of the Jacobi update (default 0.5).
    pub omega: f32,
    /// Drift relaxation weight tau of P-Eq. 11, in m^2/(Pa s) = m^3 s/kg
    /// (PHYSICS.md §7, §8.13: the paper's "m/(Pa s)" is a unit slip), the
    /// default of every phase (default 3e-6, P Table 2). Not divided by the
    /// viscosity (PHYSICS.md §4.1: [AC] does; here a Stokes-like
    /// tau ~ d^2/(18 mu) is folded into the value).
    pub drift_tau: f32,
    /// Drift diffusion weight sigma of P-Eq. 11, in m^2/s, the default of
    /// every phase (default 1e-3, P Table 2).
    pub drift_sigma: f32,
    /// The drift momentum term a^Dm of the mixture (PHYSICS.md §4.1, §8.15).
    pub drift_momentum: DriftMomentum,
    /// The form of the volume-fraction transport (PHYSICS.md §4.1).
    pub phase_transport: PhaseTransport,
    /// The phase pressures p_k of the drift velocities (P-Eq. 11).
    pub phase_pressure: PhasePressure,
    /// Relative residual |r| / |b| at which the conjugate gradients of the
    /// elastic solve stop (default 1e-4, PHYSICS.md §3.3).
    pub elastic_tolerance: f32,
    /// Largest number of conjugate-gradient iterations (default 1000: the
    /// unpreconditioned CG needs about 4 (c dt / d) iterations, c the
    /// speed of sound of the solid, so stiff solids need many).
    pub elastic_max_iterations: u32,
    /// Pore drift weight phi of P-Eq. 11's porous term, m^2/(Pa s) (the
    /// units of tau, PHYSICS.md §7; default 3e-6, P Table 2).
    pub pore_drift: f32,
    /// Inner drift weight tau' of P-Eq. 12, dimensionless (it multiplies a
    /// velocity, PHYSICS.md §8.11; default 1e-4, P Table 2).
    pub inner_drift_tau: f32,
    /// Inner diffusion weight sigma' of P-Eq. 12, m^2/s (default 2e-3,
    /// P Table 2).
    pub inner_drift_sigma: f32,
}

/// `phase_pressure`: the phase pressure p_k in P-Eq. 11
/// (`porosph_kernels::drift` explains the difference).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

/// `phase_transport`: the form of the volume-fraction transport (P-Eq. 2);
/// `porosph_kernels::phase_transport` explains both.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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

/// `drift_momentum`: how the drift momentum term
/// a^Dm = -(1/rho) div sum_k alpha_k rho_k u_mk (x) u_mk enters the mixture
/// momentum (PHYSICS.md §4.1; the sign discussion is §8.15).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
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
    /// body (rest neighbours across them, one rigid motion in the pressure
    /// solve) with regions of different material (default: its own name).
    pub body: String,
    /// `[solid.porous]`: the porous parameters of this solid (region).
    pub porous: Option<Porous>,
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
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PorousPhase {
    /// Permeability k_wk of P-Eq. 1, m^2 (PHYSICS.md §7: flux = -k/mu grad p).
    pub permeability: f32,
    /// Outer pore pressure p_0k, Pa: absorption stops where p^pore = p_0k.
    pub outer_pore_pressure: f32,
}

/// One interval of prescribed motion of a solid's fixed particles.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Motion {
    /// Start time, s.
    pub from: f64,
    /// End time, s (exclusive).
    pub until: f64,
    /// Velocity, m/s.
    pub velocity: [f32; 3],
}

impl Solid {
    /// The velocity of the fixed particles at time `t`, m/s.
    pub fn fixed_velocity(&self, t: f64) -> [f32; 3] {
        self.motion.iter().find(|m| m.from <= t && t < m.until).map_or([0.0; 3], |m| m.velocity)
    }
}

/// A scene problem: which file, which key, and why.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// File path, or `<built-in NAME>`.
    pub file: String,
    /// Dotted key path, e.g. `fluid[0].box.min`; empty for file-level errors.
    pub key: String,
    pub reason: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.key.is_empty() {
            write!(f, "{}: {}", self.file, self.reason)
        } else {
            write!(f, "{}: key `{}`: {}", self.file, self.key, self.reason)
        }
    }
}

impl std::error::Error for SceneError {}
