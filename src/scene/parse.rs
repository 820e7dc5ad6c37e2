//! TOML -> [`Scene`], with validation.
//!
//! The text is first parsed into a generic TOML table and then walked by hand,
//! so that every problem is reported with the dotted path of the offending key
//! (`fluid[1].box.min[2]`) and a reason that says what was expected and what was
//! found. Nothing here panics on user input: every value is checked for type,
//! finiteness (TOML allows `nan` and `inf`) and range before it is used.

use super::{
    DriftMomentum, FluidBlock, Motion, Phase, PhasePressure, PhaseTransport, Porous, PorousPhase, Scene, SceneError,
    Shape, Simulation, Solid, Wall,
};
use std::path::Path;
use toml::{Table, Value};

/// Default phase colours (linear RGB), assigned by phase index modulo 8.
const PALETTE: [[f32; 3]; 8] = [
    [0.12, 0.47, 0.71], // blue
    [1.00, 0.50, 0.05], // orange
    [0.17, 0.63, 0.17], // green
    [0.84, 0.15, 0.16], // red
    [0.58, 0.40, 0.74], // purple
    [0.55, 0.34, 0.29], // brown
    [0.89, 0.47, 0.76], // pink
    [0.74, 0.74, 0.13], // olive
];

/// Phase fractions of a fluid block must sum to 1 within this tolerance; they
/// are then renormalised.
const FRACTION_SUM_TOLERANCE: f64 = 1e-4;

/// A shape whose bounding box holds more lattice cells than this is rejected:
/// it would not fit in memory, and the usual cause is a length in the wrong unit.
const MAX_LATTICE_CELLS: f64 = 1e9;

/// Coordinates farther than this many particle spacings from the origin are
/// rejected: single-precision positions cannot resolve the lattice there.
const MAX_COORD_SPACINGS: f64 = 1e6;

/// Keys allowed at the top level.
const TOP_KEYS: &[&str] = &["simulation", "phase", "fluid", "wall", "solid"];
const SIMULATION_KEYS: &[&str] = &[
    "particle_spacing",
    "end_time",
    "max_dt",
    "gravity",
    "max_density_error",
    "frame_interval",
    "cfl_number",
    "min_iterations",
    "max_iterations",
    "omega",
    "drift_tau",
    "drift_sigma",
    "drift_momentum",
    "phase_transport",
    "phase_pressure",
    "elastic_tolerance",
    "elastic_max_iterations",
    "pore_drift",
    "inner_drift_tau",
    "inner_drift_sigma",
];
const PHASE_KEYS: &[&str] = &["name", "density", "viscosity", "color", "drift_tau", "drift_sigma"];

/// Default drift weights (P Table 2; tau in m^2/(Pa s), PHYSICS.md §7).
const DEFAULT_DRIFT_TAU: f32 = 3e-6;
const DEFAULT_DRIFT_SIGMA: f32 = 1e-3;
const TAU_WHAT: &str = "the drift relaxation weight tau in m^2/(Pa s) (= m^3 s/kg)";
const SIGMA_WHAT: &str = "the drift diffusion weight sigma in m^2/s";
/// The values of `drift_momentum`.
const DRIFT_MOMENTUM_VALUES: &[(&str, DriftMomentum)] =
    &[("physical", DriftMomentum::Physical), ("plus", DriftMomentum::Plus), ("off", DriftMomentum::Off)];
/// The values of `phase_transport`.
const PHASE_TRANSPORT_VALUES: &[(&str, PhaseTransport)] =
    &[("conservative", PhaseTransport::Conservative), ("reference", PhaseTransport::Reference)];
/// The values of `phase_pressure`.
const PHASE_PRESSURE_VALUES: &[(&str, PhasePressure)] =
    &[("shared", PhasePressure::Shared), ("fraction", PhasePressure::Fraction)];
const SHAPE_KEYS: &[&str] = &["box", "sphere", "cylinder"];
const FLUID_KEYS: &[&str] = &["box", "sphere", "cylinder", "fractions", "velocity"];
const WALL_KEYS: &[&str] = &["box", "sphere", "cylinder", "container", "open_top"];
const SOLID_KEYS: &[&str] = &[
    "name",
    "box",
    "sphere",
    "cylinder",
    "density",
    "shear_modulus",
    "lame_lambda",
    "velocity",
    "fixed",
    "motion",
    "body",
    "porous",
];
const POROUS_KEYS: &[&str] =
    &["porosity", "rest_pore_pressure", "biot_modulus", "swelling", "capillarity", "absorption", "gains_mass", "phase"];
const POROUS_PHASE_KEYS: &[&str] = &["permeability", "outer_pore_pressure"];
const FIXED_KEYS: &[&str] = &["box", "sphere", "cylinder"];
const MOTION_KEYS: &[&str] = &["from", "until", "velocity"];
const BOX_KEYS: &[&str] = &["min", "max"];
const SPHERE_KEYS: &[&str] = &["center", "radius"];
const CYLINDER_KEYS: &[&str] = &["base", "axis", "radius", "height"];

impl Scene {
    /// Reads and validates a scene file.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: file.clone(),
            key: String::new(),
            reason: format!("cannot read the scene file: {e}"),
        })?;
        Scene::from_toml_str(&text, &file)
    }

    /// Parses and validates scene text; `origin` names it in errors.
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Scene, SceneError> {
        let cx = Cx { file: origin };
        let root: Table = toml::from_str(text).map_err(|e| cx.syntax_error(text, &e))?;
        if root.is_empty() {
            return Err(cx.err("", "the scene is empty; it needs a [simulation] table and at least one [[phase]]"));
        }
        cx.allow_keys("", &root, TOP_KEYS)?;

        let simulation = match root.get("simulation") {
            Some(v) => cx.simulation("simulation", v)?,
            None => {
                return Err(cx
                    .err("simulation", "missing the required [simulation] table (particle_spacing, end_time, max_dt)"))
            }
        };
        let d = f64::from(simulation.particle_spacing);

        let phase_tables = match root.get("phase") {
            Some(v) => cx.array_of_tables("phase", v)?,
            None => Vec::new(),
        };
        if phase_tables.is_empty() {
            return Err(
                cx.err("phase", "no phases: at least one [[phase]] with name, density and viscosity is required")
            );
        }
        let mut phases: Vec<Phase> = Vec::with_capacity(phase_tables.len());
        for (i, tbl) in phase_tables.iter().enumerate() {
            let path = format!("phase[{i}]");
            let phase = cx.phase(&path, tbl, i, &simulation)?;
            if let Some(j) = phases.iter().position(|p| p.name == phase.name) {
                return Err(cx.err(
                    &join(&path, "name"),
                    format!(
                        "duplicate phase name \"{}\": phase[{j}] already uses it; names must be unique",
                        phase.name
                    ),
                ));
            }
            phases.push(phase);
        }

        let mut fluids = Vec::new();
        if let Some(v) = root.get("fluid") {
            for (i, tbl) in cx.array_of_tables("fluid", v)?.iter().enumerate() {
                fluids.push(cx.fluid(&format!("fluid[{i}]"), tbl, &phases, d)?);
            }
        }

        let mut walls = Vec::new();
        if let Some(v) = root.get("wall") {
            for (i, tbl) in cx.array_of_tables("wall", v)?.iter().enumerate() {
                walls.push(cx.wall(&format!("wall[{i}]"), tbl, d)?);
            }
        }

        let mut solids: Vec<Solid> = Vec::new();
        if let Some(v) = root.get("solid") {
            for (i, tbl) in cx.array_of_tables("solid", v)?.iter().enumerate() {
                let path = format!("solid[{i}]");
                let solid = cx.solid(&path, tbl, d, &phases)?;
                if let Some(j) = solids.iter().position(|s| s.name == solid.name) {
                    return Err(cx.err(
                        &join(&path, "name"),
                        format!("duplicate solid name \"{}\": solid[{j}] already uses it", solid.name),
                    ));
                }
                solids.push(solid);
            }
        }

        Ok(Scene { simulation, phases, fluids, walls, solids, origin: origin.to_string(), text: text.to_string() })
    }
}

/// The allowed range of a number.
#[derive(Clone, Copy)]
enum Range {
    /// Any finite number.
    Any,
    /// x > 0.
    Positive,
    /// x >= 0.
    NonNegative,
    /// 0 < x <= 1.
    OpenUnit,
    /// 0 <= x <= 1.
    ClosedUnit,
    /// 0 < x <= the bound.
    UpTo(f64),
}

impl Range {
    fn contains(self, x: f64) -> bool {
        match self {
            Range::Any => true,
            Range::Positive => x > 0.0,
            Range::NonNegative => x >= 0.0,
            Range::OpenUnit => x > 0.0 && x <= 1.0,
            Range::ClosedUnit => (0.0..=1.0).contains(&x),
            Range::UpTo(hi) => x > 0.0 && x <= hi,
        }
    }

    fn text(self) -> String {
        match self {
            Range::Any => String::new(),
            Range::Positive => " > 0".to_string(),
            Range::NonNegative => " >= 0".to_string(),
            Range::OpenUnit => " in (0, 1]".to_string(),
            Range::ClosedUnit => " in [0, 1]".to_string(),
            Range::UpTo(hi) => format!(" in (0, {hi}]"),
        }
    }
}

/// The parsing context: the file name for errors, and the typed readers.
struct Cx<'a> {
    file: &'a str,
}

impl Cx<'_> {
    fn err(&self, key: &str, reason: impl Into<String>) -> SceneError {
        SceneError { file: self.file.to_string(), key: key.to_string(), reason: reason.into() }
    }

    /// A TOML syntax error, with the line and column it happened at.
    fn syntax_error(&self, text: &str, e: &toml::de::Error) -> SceneError {
        let message = e.message().trim();
        let reason = match e.span() {
            Some(span) => {
                let (line, column, content) = line_column(text, span.start);
                format!("TOML syntax error at line {line}, column {column}: {message} (line {line} reads `{content}`)")
            }
            None => format!("TOML syntax error: {message}"),
        };
        self.err("", reason)
    }

    /// Rejects keys of `table` (at `path`) that are not in `allowed`.
    fn allow_keys(&self, path: &str, table: &Table, allowed: &[&str]) -> Result<(), SceneError> {
        for key in table.keys() {
            if !allowed.contains(&key.as_str()) {
                let mut reason = format!("unknown key `{key}`");
                if let Some(near) = closest(key, allowed) {
                    reason.push_str(&format!(" (did you mean `{near}`?)"));
                }
                reason.push_str(&format!("; allowed here: {}", allowed.join(", ")));
                return Err(self.err(&join(path, key), reason));
            }
        }
        Ok(())
    }

    /// A required key of `table`; `expected` says what it should hold.
    fn required<'t>(&self, path: &str, table: &'t Table, key: &str, expected: &str) -> Result<&'t Value, SceneError> {
        table
            .get(key)
            .ok_or_else(|| self.err(&join(path, key), format!("missing required key `{key}` (expected {expected})")))
    }

    fn table<'v>(&self, key: &str, v: &'v Value) -> Result<&'v Table, SceneError> {
        match v {
            Value::Table(t) => Ok(t),
            other => Err(self.err(key, format!("expected a table, found {}", describe(other)))),
        }
    }

    /// `[[name]]` entries: an array whose elements are all tables.
    fn array_of_tables<'v>(&self, key: &str, v: &'v Value) -> Result<Vec<&'v Table>, SceneError> {
        match v {
            Value::Array(items) => {
                items.iter().enumerate().map(|(i, item)| self.table(&format!("{key}[{i}]"), item)).collect()
            }
            Value::Table(_) => {
                Err(self
                    .err(key, format!("expected an array of tables (write [[{key}]]), found a single table ([{key}])")))
            }
            other => Err(self.err(key, format!("expected an array of tables ([[{key}]]), found {}", describe(other)))),
        }
    }

    /// A finite number (TOML integer or float).
    fn number(&self, key: &str, v: &Value, what: &str) -> Result<f64, SceneError> {
        let x = match v {
            Value::Float(x) => *x,
            // Integers far beyond 2^53 lose precision; they are rejected by range checks.
            Value::Integer(i) => *i as f64,
            other => return Err(self.err(key, format!("expected {what} (a number), found {}", describe(other)))),
        };
        if !x.is_finite() {
            return Err(self.err(key, format!("expected a finite number, found {}", fmt_f64(x))));
        }
        Ok(x)
    }

    /// A finite number within `range`, as f64.
    fn f64_in(&self, key: &str, v: &Value, what: &str, range: Range) -> Result<f64, SceneError> {
        let x = self.number(key, v, what)?;
        if !range.contains(x) {
            return Err(self.err(key, format!("expected {what}{}, found {}", range.text(), fmt_f64(x))));
        }
        Ok(x)
    }

    /// A finite number within `range`, as f32 (the range is checked after the
    /// conversion, so 1e-60 is not a positive f32).
    fn f32_in(&self, key: &str, v: &Value, what: &str, range: Range) -> Result<f32, SceneError> {
        let x = self.number(key, v, what)?;
        let y = x as f32;
        if !y.is_finite() {
            return Err(self.err(
                key,
                format!(
                    "expected {what}{}, found {}, which is out of single-precision range",
                    range.text(),
                    fmt_f64(x)
                ),
            ));
        }
        if !range.contains(f64::from(y)) {
            return Err(self.err(key, format!("expected {what}{}, found {}", range.text(), fmt_f64(x))));
        }
        Ok(y)
    }

    /// An array of 3 numbers, each within `range`.
    fn vec3(&self, key: &str, v: &Value, what: &str, range: Range) -> Result<[f32; 3], SceneError> {
        let items = match v {
            Value::Array(items) => items,
            other => {
                return Err(self.err(
                    key,
                    format!("expected {what} as an array of 3 numbers [x, y, z], found {}", describe(other)),
                ))
            }
        };
        if items.len() != 3 {
            return Err(
                self.err(key, format!("expected {what} as an array of 3 numbers [x, y, z], found {}", describe(v)))
            );
        }
        let mut out = [0.0f32; 3];
        for (i, item) in items.iter().enumerate() {
            let component = ["the x component", "the y component", "the z component"][i];
            out[i] = self.f32_in(&format!("{key}[{i}]"), item, component, range)?;
        }
        Ok(out)
    }

    /// A position: 3 finite numbers, not absurdly far from the origin.
    fn point(&self, key: &str, v: &Value, what: &str, d: f64) -> Result<[f32; 3], SceneError> {
        let p = self.vec3(key, v, what, Range::Any)?;
        for (i, &c) in p.iter().enumerate() {
            if f64::from(c).abs() > MAX_COORD_SPACINGS * d {
                return Err(self.err(
                    &format!("{key}[{i}]"),
                    format!(
                        "coordinate {c} m is more than {MAX_COORD_SPACINGS:e} particle spacings ({} m) \
                         from the origin, where single-precision positions cannot resolve the lattice; \
                         are the lengths in m?",
                        d as f32
                    ),
                ));
            }
        }
        Ok(p)
    }

    fn integer(&self, key: &str, v: &Value, what: &str, min: i64) -> Result<u32, SceneError> {
        match v {
            Value::Integer(i) if *i >= min && *i <= i64::from(u32::MAX) => Ok(*i as u32),
            Value::Integer(i) => Err(self.err(key, format!("expected {what} (an integer >= {min}), found {i}"))),
            other => Err(self.err(key, format!("expected {what} (an integer >= {min}), found {}", describe(other)))),
        }
    }

    fn boolean(&self, key: &str, v: &Value) -> Result<bool, SceneError> {
        match v {
            Value::Boolean(b) => Ok(*b),
            other => Err(self.err(key, format!("expected true or false, found {}", describe(other)))),
        }
    }

    /// `[simulation]`.
    fn simulation(&self, path: &str, v: &Value) -> Result<Simulation, SceneError> {
        let t = self.table(path, v)?;
        self.allow_keys(path, t, SIMULATION_KEYS)?;
        let key = |k: &str| join(path, k);

        let spacing_what = "the particle spacing in m";
        let particle_spacing = self.f32_in(
            &key("particle_spacing"),
            self.required(path, t, "particle_spacing", spacing_what)?,
            spacing_what,
            Range::Positive,
        )?;
        let end_what = "the end time in s";
        let end_time =
            self.f64_in(&key("end_time"), self.required(path, t, "end_time", end_what)?, end_what, Range::Positive)?;
        let dt_what = "the largest time step in s";
        let max_dt =
            self.f32_in(&key("max_dt"), self.required(path, t, "max_dt", dt_what)?, dt_what, Range::Positive)?;
        // max_dt is stored as f32: compare in f32, or `max_dt = end_time`
        // (0.002 = 0.002) fails by the f32 rounding of 0.002.
        if max_dt > end_time as f32 {
            return Err(self.err(
                &key("max_dt"),
                format!("expected max_dt <= end_time = {end_time} s, found max_dt = {max_dt} s"),
            ));
        }

        let gravity = match t.get("gravity") {
            Some(v) => self.vec3(&key("gravity"), v, "gravity in m/s^2", Range::Any)?,
            None => [0.0, -9.81, 0.0],
        };
        let max_density_error = match t.get("max_density_error") {
            Some(v) => self.f32_in(
                &key("max_density_error"),
                v,
                "the largest mean density error as a fraction of the rest density",
                Range::UpTo(0.1),
            )?,
            None => 0.001,
        };
        let frame_interval = match t.get("frame_interval") {
            Some(v) => self.f64_in(&key("frame_interval"), v, "the time between frames in s", Range::Positive)?,
            None => 0.02,
        };
        let cfl_number = match t.get("cfl_number") {
            Some(v) => self.f32_in(&key("cfl_number"), v, "the CFL number", Range::OpenUnit)?,
            None => 0.4,
        };
        let min_iterations = match t.get("min_iterations") {
            Some(v) => self.integer(&key("min_iterations"), v, "the least number of solver iterations", 1)?,
            None => 2,
        };
        let max_iterations = match t.get("max_iterations") {
            Some(v) => self.integer(&key("max_iterations"), v, "the largest number of solver iterations", 1)?,
            None => 100,
        };
        if max_iterations < min_iterations {
            return Err(self.err(
                &key(if t.contains_key("max_iterations") { "max_iterations" } else { "min_iterations" }),
                format!(
                    "expected max_iterations >= min_iterations, found min_iterations = \
                     {min_iterations} and max_iterations = {max_iterations}"
                ),
            ));
        }
        let omega = match t.get("omega") {
            Some(v) => self.f32_in(&key("omega"), v, "the Jacobi relaxation factor omega", Range::OpenUnit)?,
            None => 0.5,
        };
        let drift_tau = match t.get("drift_tau") {
            Some(v) => self.f32_in(&key("drift_tau"), v, TAU_WHAT, Range::NonNegative)?,
            None => DEFAULT_DRIFT_TAU,
        };
        let drift_sigma = match t.get("drift_sigma") {
            Some(v) => self.f32_in(&key("drift_sigma"), v, SIGMA_WHAT, Range::NonNegative)?,
            None => DEFAULT_DRIFT_SIGMA,
        };
        let drift_momentum = match t.get("drift_momentum") {
            Some(v) => self.choice(&key("drift_momentum"), v, "the drift momentum term", DRIFT_MOMENTUM_VALUES)?,
            None => DriftMomentum::Physical,
        };
        let phase_transport = match t.get("phase_transport") {
            Some(v) => {
                self.choice(&key("phase_transport"), v, "the volume-fraction transport", PHASE_TRANSPORT_VALUES)?
            }
            None => PhaseTransport::Conservative,
        };
        let phase_pressure = match t.get("phase_pressure") {
            Some(v) => self.choice(&key("phase_pressure"), v, "the phase pressure", PHASE_PRESSURE_VALUES)?,
            None => PhasePressure::Shared,
        };

        let elastic_tolerance = match t.get("elastic_tolerance") {
            Some(v) => self.f32_in(
                &key("elastic_tolerance"),
                v,
                "the relative residual of the elastic solve",
                Range::UpTo(1.0),
            )?,
            None => 1e-4,
        };
        let elastic_max_iterations = match t.get("elastic_max_iterations") {
            Some(v) => self.integer(
                &key("elastic_max_iterations"),
                v,
                "the largest number of conjugate-gradient iterations",
                1,
            )?,
            None => 1000,
        };
        let pore_drift = match t.get("pore_drift") {
            Some(v) => {
                self.f32_in(&key("pore_drift"), v, "the pore drift weight phi in m^2/(Pa s)", Range::NonNegative)?
            }
            None => 3e-6,
        };
        let inner_drift_tau = match t.get("inner_drift_tau") {
            Some(v) => self.f32_in(
                &key("inner_drift_tau"),
                v,
                "the inner drift weight tau' (dimensionless)",
                Range::NonNegative,
            )?,
            None => 1e-4,
        };
        let inner_drift_sigma = match t.get("inner_drift_sigma") {
            Some(v) => self.f32_in(
                &key("inner_drift_sigma"),
                v,
                "the inner diffusion weight sigma' in m^2/s",
                Range::NonNegative,
            )?,
            None => 2e-3,
        };

        Ok(Simulation {
            particle_spacing,
            end_time,
            max_dt,
            gravity,
            max_density_error,
            frame_interval,
            cfl_number,
            min_iterations,
            max_iterations,
            omega,
            drift_tau,
            drift_sigma,
            drift_momentum,
            phase_transport,
            phase_pressure,
            elastic_tolerance,
            elastic_max_iterations,
            pore_drift,
            inner_drift_tau,
            inner_drift_sigma,
        })
    }

    /// One of the strings of `values`.
    fn choice<T: Copy>(&self, key: &str, v: &Value, what: &str, values: &[(&str, T)]) -> Result<T, SceneError> {
        let names: Vec<String> = values.iter().map(|(n, _)| format!("\"{n}\"")).collect();
        let expected = format!("{what} as one of {}", names.join(", "));
        match v {
            Value::String(s) => values.iter().find(|(n, _)| n == s).map(|&(_, t)| t).ok_or_else(|| {
                let mut reason = format!("expected {expected}, found the string {s:?}");
                let plain: Vec<&str> = values.iter().map(|(n, _)| *n).collect();
                if let Some(near) = closest(s, &plain) {
                    reason.push_str(&format!(" (did you mean \"{near}\"?)"));
                }
                self.err(key, reason)
            }),
            other => Err(self.err(key, format!("expected {expected} (a string), found {}", describe(other)))),
        }
    }

    /// `[[phase]]` number `index`; drift weights default to those of `sim`.
    fn phase(&self, path: &str, t: &Table, index: usize, sim: &Simulation) -> Result<Phase, SceneError> {
        self.allow_keys(path, t, PHASE_KEYS)?;
        let key = |k: &str| join(path, k);

        let name_what = "a name made of letters, digits, `_` and `-`";
        let name = match self.required(path, t, "name", name_what)? {
            Value::String(s) => s.clone(),
            other => {
                return Err(
                    self.err(&key("name"), format!("expected {name_what} (a string), found {}", describe(other)))
                )
            }
        };
        if name.is_empty() {
            return Err(self.err(&key("name"), format!("expected {name_what}, found an empty string")));
        }
        if let Some(c) = name.chars().find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-')) {
            return Err(self.err(&key("name"), format!("expected {name_what}, found {:?}, which contains {c:?}", name)));
        }

        let density_what = "the rest density in kg/m^3";
        let density = self.f32_in(
            &key("density"),
            self.required(path, t, "density", density_what)?,
            density_what,
            Range::Positive,
        )?;
        let viscosity_what = "the dynamic viscosity in Pa s";
        let viscosity = self.f32_in(
            &key("viscosity"),
            self.required(path, t, "viscosity", viscosity_what)?,
            viscosity_what,
            Range::NonNegative,
        )?;
        let color = match t.get("color") {
            Some(v) => self.vec3(&key("color"), v, "a linear RGB colour", Range::ClosedUnit)?,
            None => PALETTE[index % PALETTE.len()],
        };
        let drift_tau = match t.get("drift_tau") {
            Some(v) => self.f32_in(&key("drift_tau"), v, TAU_WHAT, Range::NonNegative)?,
            None => sim.drift_tau,
        };
        let drift_sigma = match t.get("drift_sigma") {
            Some(v) => self.f32_in(&key("drift_sigma"), v, SIGMA_WHAT, Range::NonNegative)?,
            None => sim.drift_sigma,
        };
        Ok(Phase { name, density, viscosity, color, drift_tau, drift_sigma })
    }

    /// `[[fluid]]`.
    fn fluid(&self, path: &str, t: &Table, phases: &[Phase], d: f64) -> Result<FluidBlock, SceneError> {
        self.allow_keys(path, t, FLUID_KEYS)?;
        let shape = self.shape(path, t, d)?;

        let fractions_key = join(path, "fractions");
        let what = "the volume fraction of each phase, e.g. { water = 1.0 }";
        let ft = self.table(&fractions_key, self.required(path, t, "fractions", what)?)?;
        let mut fractions = vec![0.0f64; phases.len()];
        for (name, v) in ft {
            let k = join(&fractions_key, name);
            let Some(i) = phases.iter().position(|p| &p.name == name) else {
                let names: Vec<&str> = phases.iter().map(|p| p.name.as_str()).collect();
                return Err(self.err(&k, format!("unknown phase `{name}`; the phases are: {}", names.join(", "))));
            };
            fractions[i] = self.f64_in(&k, v, "a volume fraction", Range::ClosedUnit)?;
        }
        let sum: f64 = fractions.iter().sum();
        if (sum - 1.0).abs() > FRACTION_SUM_TOLERANCE {
            return Err(self.err(
                &fractions_key,
                format!("expected fractions that sum to 1 (within {FRACTION_SUM_TOLERANCE:e}), found a sum of {sum}"),
            ));
        }
        let fractions = fractions.iter().map(|&f| (f / sum) as f32).collect();

        let velocity = match t.get("velocity") {
            Some(v) => self.vec3(&join(path, "velocity"), v, "the initial velocity in m/s", Range::Any)?,
            None => [0.0; 3],
        };
        Ok(FluidBlock { shape, fractions, velocity })
    }

    /// `[[wall]]`.
    fn wall(&self, path: &str, t: &Table, d: f64) -> Result<Wall, SceneError> {
        self.allow_keys(path, t, WALL_KEYS)?;
        let shape = self.shape(path, t, d)?;
        let container = match t.get("container") {
            Some(v) => self.boolean(&join(path, "container"), v)?,
            None => false,
        };
        let open_top = match t.get("open_top") {
            Some(v) => self.boolean(&join(path, "open_top"), v)?,
            None => false,
        };
        if container && !matches!(shape, Shape::Box { .. }) {
            return Err(self.err(
                &join(path, "container"),
                format!("container = true is only allowed with a box, found a {}", shape_name(&shape)),
            ));
        }
        if open_top && !container {
            return Err(self.err(
                &join(path, "open_top"),
                "open_top = true is only allowed with container = true, found container = false",
            ));
        }
        Ok(Wall { shape, container, open_top })
    }

    /// `[[solid]]`.
    fn solid(&self, path: &str, t: &Table, d: f64, phases: &[Phase]) -> Result<Solid, SceneError> {
        self.allow_keys(path, t, SOLID_KEYS)?;
        let key = |k: &str| join(path, k);
        let name = match self.required(path, t, "name", "the solid's name")? {
            Value::String(s) if !s.trim().is_empty() => s.clone(),
            other => {
                return Err(self.err(&key("name"), format!("expected a non-empty string, found {}", describe(other))))
            }
        };
        let shape = self.shape(path, t, d)?;
        let what = "the density in kg/m^3";
        let density = self.f32_in(&key("density"), self.required(path, t, "density", what)?, what, Range::Positive)?;
        let what = "the shear modulus mu in Pa";
        let shear_modulus =
            self.f32_in(&key("shear_modulus"), self.required(path, t, "shear_modulus", what)?, what, Range::Positive)?;
        let what = "Lame's first parameter lambda in Pa";
        let lame_lambda =
            self.f32_in(&key("lame_lambda"), self.required(path, t, "lame_lambda", what)?, what, Range::NonNegative)?;
        let velocity = match t.get("velocity") {
            Some(v) => self.vec3(&key("velocity"), v, "the initial velocity in m/s", Range::Any)?,
            None => [0.0; 3],
        };
        let fixed = match t.get("fixed") {
            Some(v) => {
                let ft = self.table(&key("fixed"), v)?;
                self.allow_keys(&key("fixed"), ft, FIXED_KEYS)?;
                Some(self.shape(&key("fixed"), ft, d)?)
            }
            None => None,
        };
        let mut motion: Vec<Motion> = Vec::new();
        if let Some(v) = t.get("motion") {
            let items = match v {
                Value::Array(items) => items,
                other => {
                    return Err(self.err(
                        &key("motion"),
                        format!("expected an array of {{ from, until, velocity }} tables, found {}", describe(other)),
                    ))
                }
            };
            for (i, item) in items.iter().enumerate() {
                let mpath = format!("{}[{i}]", key("motion"));
                let mt = self.table(&mpath, item)?;
                self.allow_keys(&mpath, mt, MOTION_KEYS)?;
                let what = "a time in s";
                let from = self.f64_in(
                    &join(&mpath, "from"),
                    self.required(&mpath, mt, "from", what)?,
                    what,
                    Range::NonNegative,
                )?;
                let until = self.f64_in(
                    &join(&mpath, "until"),
                    self.required(&mpath, mt, "until", what)?,
                    what,
                    Range::NonNegative,
                )?;
                if until <= from {
                    return Err(
                        self.err(&join(&mpath, "until"), format!("expected until > from = {from} s, found {until} s"))
                    );
                }
                let what = "the velocity of the fixed particles in m/s";
                let velocity = self.vec3(
                    &join(&mpath, "velocity"),
                    self.required(&mpath, mt, "velocity", what)?,
                    what,
                    Range::Any,
                )?;
                if let Some(prev) = motion.last() {
                    if from < prev.until {
                        return Err(self.err(
                            &join(&mpath, "from"),
                            format!("intervals must be in time order without overlap: this one starts at {from} s, before the previous one ends at {} s", prev.until),
                        ));
                    }
                }
                motion.push(Motion { from, until, velocity });
            }
            if fixed.is_none() && !motion.is_empty() {
                return Err(
                    self.err(&key("motion"), "motion moves the fixed particles, but the solid has no `fixed` shape")
                );
            }
        }
        let body = match t.get("body") {
            Some(Value::String(s)) if !s.trim().is_empty() => s.clone(),
            Some(other) => {
                return Err(self.err(
                    &key("body"),
                    format!(
                        "expected the name of the body this solid belongs to (a non-empty string), found {}",
                        describe(other)
                    ),
                ))
            }
            None => name.clone(),
        };
        let porous = match t.get("porous") {
            Some(v) => Some(self.porous(&key("porous"), v, phases)?),
            None => None,
        };
        Ok(Solid { name, shape, density, shear_modulus, lame_lambda, velocity, fixed, motion, body, porous })
    }

    /// `[solid.porous]` at `path`.
    fn porous(&self, path: &str, v: &Value, phases: &[Phase]) -> Result<Porous, SceneError> {
        let t = self.table(path, v)?;
        self.allow_keys(path, t, POROUS_KEYS)?;
        let key = |k: &str| join(path, k);
        let what = "the porosity e (0 < e <= 1)";
        let porosity =
            self.f32_in(&key("porosity"), self.required(path, t, "porosity", what)?, what, Range::Positive)?;
        if porosity > 1.0 {
            return Err(self.err(&key("porosity"), format!("expected {what}, found {porosity}")));
        }
        let what = "the rest pore pressure p0 in Pa";
        let rest_pore_pressure = self.f32_in(
            &key("rest_pore_pressure"),
            self.required(path, t, "rest_pore_pressure", what)?,
            what,
            Range::Positive,
        )?;
        let optional = |k: &str, what: &str, default: f32| -> Result<f32, SceneError> {
            match t.get(k) {
                Some(v) => self.f32_in(&key(k), v, what, Range::NonNegative),
                None => Ok(default),
            }
        };
        let biot_modulus = optional("biot_modulus", "the Biot modulus B in Pa", rest_pore_pressure)?;
        let swelling = optional("swelling", "the pore stress factor eta", 0.0)?;
        let capillarity = optional("capillarity", "the capillary strength psi in m^2/s^2", 0.0)?;
        let absorption = optional("absorption", "the absorption ratio K", 1.0)?;
        let gains_mass = match t.get("gains_mass") {
            Some(v) => self.boolean(&key("gains_mass"), v)?,
            None => false,
        };
        let mut out = vec![None; phases.len()];
        if let Some(v) = t.get("phase") {
            let pt = self.table(&key("phase"), v)?;
            for (name, v) in pt {
                let k = join(&key("phase"), name);
                let Some(i) = phases.iter().position(|p| &p.name == name) else {
                    let names: Vec<&str> = phases.iter().map(|p| p.name.as_str()).collect();
                    return Err(self.err(&k, format!("unknown phase `{name}`; the phases are: {}", names.join(", "))));
                };
                let ptab = self.table(&k, v)?;
                self.allow_keys(&k, ptab, POROUS_PHASE_KEYS)?;
                let what = "the permeability k_w in m^2";
                let permeability = self.f32_in(
                    &join(&k, "permeability"),
                    self.required(&k, ptab, "permeability", what)?,
                    what,
                    Range::NonNegative,
                )?;
                let what = "the outer pore pressure p0k in Pa";
                let outer_pore_pressure = self.f32_in(
                    &join(&k, "outer_pore_pressure"),
                    self.required(&k, ptab, "outer_pore_pressure", what)?,
                    what,
                    Range::NonNegative,
                )?;
                if outer_pore_pressure > porosity * rest_pore_pressure {
                    return Err(self.err(
                        &join(&k, "outer_pore_pressure"),
                        format!(
                            "expected outer_pore_pressure <= porosity x rest_pore_pressure = {} Pa (the strain-free \
                             saturation p0k / p0 cannot exceed the porosity), found {outer_pore_pressure} Pa",
                            porosity * rest_pore_pressure
                        ),
                    ));
                }
                out[i] = Some(PorousPhase { permeability, outer_pore_pressure });
            }
        }
        Ok(Porous {
            porosity,
            rest_pore_pressure,
            biot_modulus,
            swelling,
            capillarity,
            absorption,
            gains_mass,
            phases: out,
        })
    }

    /// Exactly one of `box`, `sphere`, `cylinder` in the table at `path`.
    fn shape(&self, path: &str, t: &Table, d: f64) -> Result<Shape, SceneError> {
        let present: Vec<(&str, &Value)> = SHAPE_KEYS.iter().filter_map(|k| t.get(*k).map(|v| (*k, v))).collect();
        let (kind, v) = match present.as_slice() {
            [(k, v)] => (*k, *v),
            [] => {
                return Err(self.err(
                    path,
                    "expected exactly one shape: box = { min, max }, sphere = { center, radius } \
                     or cylinder = { base, axis, radius, height }; found none",
                ))
            }
            [(a, _), (b, _), ..] => {
                return Err(self.err(
                    path,
                    format!("expected exactly one shape (box, sphere or cylinder), found both `{a}` and `{b}`"),
                ))
            }
        };
        let spath = join(path, kind);
        let st = self.table(&spath, v)?;
        let key = |k: &str| join(&spath, k);
        let length = "a length in m";
        let shape = match kind {
            "box" => {
                self.allow_keys(&spath, st, BOX_KEYS)?;
                let corner = "a corner position in m";
                let min = self.point(&key("min"), self.required(&spath, st, "min", corner)?, corner, d)?;
                let max = self.point(&key("max"), self.required(&spath, st, "max", corner)?, corner, d)?;
                for axis in 0..3 {
                    let name = ["x", "y", "z"][axis];
                    if min[axis] >= max[axis] {
                        return Err(self.err(
                            &spath,
                            format!(
                                "expected min < max on every axis, found min = {} >= max = {} on the {name} axis",
                                min[axis], max[axis]
                            ),
                        ));
                    }
                    let extent = f64::from(max[axis]) - f64::from(min[axis]);
                    if (extent / d).round() < 1.0 {
                        return Err(self.err(
                            &spath,
                            format!(
                                "the box is {} m thick on the {name} axis, less than half the \
                                 particle spacing {} m, so it would hold no particles",
                                extent as f32, d as f32
                            ),
                        ));
                    }
                }
                Shape::Box { min, max }
            }
            "sphere" => {
                self.allow_keys(&spath, st, SPHERE_KEYS)?;
                let what = "the centre position in m";
                let center = self.point(&key("center"), self.required(&spath, st, "center", what)?, what, d)?;
                let radius = self.f32_in(
                    &key("radius"),
                    self.required(&spath, st, "radius", length)?,
                    "the radius in m",
                    Range::Positive,
                )?;
                Shape::Sphere { center, radius }
            }
            _ => {
                self.allow_keys(&spath, st, CYLINDER_KEYS)?;
                let what = "the centre of the base in m";
                let base = self.point(&key("base"), self.required(&spath, st, "base", what)?, what, d)?;
                let what = "the direction from the base to the top";
                let a = self.vec3(&key("axis"), self.required(&spath, st, "axis", what)?, what, Range::Any)?;
                let a64 = a.map(f64::from);
                let norm = (a64[0] * a64[0] + a64[1] * a64[1] + a64[2] * a64[2]).sqrt();
                if !(norm > 0.0 && norm.is_finite()) {
                    return Err(self.err(
                        &key("axis"),
                        format!("expected a non-zero direction vector, found [{}, {}, {}]", a[0], a[1], a[2]),
                    ));
                }
                let axis = a64.map(|c| (c / norm) as f32);
                let radius = self.f32_in(
                    &key("radius"),
                    self.required(&spath, st, "radius", length)?,
                    "the radius in m",
                    Range::Positive,
                )?;
                let height = self.f32_in(
                    &key("height"),
                    self.required(&spath, st, "height", length)?,
                    "the height in m",
                    Range::Positive,
                )?;
                Shape::Cylinder { base, axis, radius, height }
            }
        };
        let cells = lattice_cells(&shape, d);
        if cells > MAX_LATTICE_CELLS {
            return Err(self.err(
                &spath,
                format!(
                    "the {kind} spans about {cells:.3e} lattice cells at particle_spacing = {} m \
                     (limit {MAX_LATTICE_CELLS:e}); are the lengths in m?",
                    d as f32
                ),
            ));
        }
        Ok(shape)
    }
}

/// The number of lattice cells of spacing `d` in the bounding box of `shape`.
fn lattice_cells(shape: &Shape, d: f64) -> f64 {
    let extent = |lo: f64, hi: f64| (hi - lo) / d + 1.0;
    match shape {
        Shape::Box { min, max } => (0..3).map(|i| extent(f64::from(min[i]), f64::from(max[i]))).product(),
        Shape::Sphere { radius, .. } => extent(0.0, 2.0 * f64::from(*radius)).powi(3),
        Shape::Cylinder { axis, radius, height, .. } => (0..3)
            .map(|i| {
                // Bounding box of a capped cylinder: the axis segment plus the
                // disc's reach r sqrt(1 - a_i^2) on each side.
                let a = f64::from(axis[i]);
                let reach = f64::from(*radius) * (1.0 - a * a).max(0.0).sqrt();
                extent(0.0, (f64::from(*height) * a).abs() + 2.0 * reach)
            })
            .product(),
    }
}

fn shape_name(shape: &Shape) -> &'static str {
    match shape {
        Shape::Box { .. } => "box",
        Shape::Sphere { .. } => "sphere",
        Shape::Cylinder { .. } => "cylinder",
    }
}

/// `path.key`, quoting the key when it is not a bare TOML key.
fn join(path: &str, key: &str) -> String {
    let bare = !key.is_empty() && key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    let key = if bare { key.to_string() } else { format!("{key:?}") };
    if path.is_empty() {
        key
    } else {
        format!("{path}.{key}")
    }
}

/// What a value is, for "found ..." in messages.
fn describe(v: &Value) -> String {
    match v {
        Value::String(s) => {
            let short: String = s.chars().take(40).collect();
            if short.len() < s.len() {
                format!("the string {short:?}...")
            } else {
                format!("the string {s:?}")
            }
        }
        Value::Integer(i) => format!("the integer {i}"),
        Value::Float(x) => format!("the number {}", fmt_f64(*x)),
        Value::Boolean(b) => format!("the boolean {b}"),
        Value::Datetime(t) => format!("the date-time {t}"),
        Value::Array(a) if a.len() == 1 => "an array of 1 element".to_string(),
        Value::Array(a) => format!("an array of {} elements", a.len()),
        Value::Table(_) => "a table".to_string(),
    }
}

/// Formats a float the way TOML spells it (`nan`, `inf`).
fn fmt_f64(x: f64) -> String {
    if x.is_nan() {
        "nan".to_string()
    } else if x.is_infinite() {
        if x > 0.0 { "inf" } else { "-inf" }.to_string()
    } else {
        format!("{x}")
    }
}

/// 1-based line and column (in characters) of byte `offset`, and that line's text.
fn line_column(text: &str, offset: usize) -> (usize, usize, String) {
    let mut line_start = 0;
    let mut line = 1;
    let mut column = 1;
    for (i, c) in text.char_indices() {
        if i >= offset {
            break;
        }
        if c == '\n' {
            line += 1;
            column = 1;
            line_start = i + 1;
        } else {
            column += 1;
        }
    }
    let rest = text.get(line_start..).unwrap_or("");
    let content = rest.lines().next().unwrap_or("").trim_end();
    let mut shown: String = content.chars().take(80).collect();
    if shown.len() < content.len() {
        shown.push_str("...");
    }
    (line, column, shown)
}

/// The allowed key closest to `key` by edit distance, if it is plausibly a typo.
fn closest<'a>(key: &str, allowed: &[&'a str]) -> Option<&'a str> {
    allowed
        .iter()
        .map(|a| (edit_distance(key, a), *a))
        .filter(|(dist, a)| *dist <= 2.max(a.len() / 3))
        .min_by_key(|(dist, _)| *dist)
        .map(|(_, a)| a)
}

/// Levenshtein distance between two short strings.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.chars().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let subst = prev[j] + usize::from(ca != *cb);
            cur[j + 1] = subst.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}
