//! TOML -> [`Scene`], with validation.
//!
//! The text is parsed once into a TOML document with spans; serde reads
//! that document into the types of `file.rs` (so unknown keys, missing
//! keys and wrong types are found by the derived code), every number is
//! checked against the schema's bounds, and this file then checks what
//! involves more than one value and builds the [`Scene`]. Every error names
//! the file, the dotted key path (`fluid[1].box.min[2]`), the line and
//! column, and says what was expected and what was found (`errors.rs`).
//! Nothing here panics on user input.

use super::errors::{check_numbers, line_column, Doc, KeyPath, Schema};
use super::file::{
    BoxFile, CylinderFile, FluidFile, MeshFile, PhaseFile, PorousFile, SceneFile, ShapeFile, ShapeKeys, SolidFile,
    SphereFile, WallFile, WallSlipFile,
};
use super::geometry::{first_flat_particle, FlatParticle};
use super::mesh::{MeshSource, TriMesh};
use super::{
    FluidBlock, Granular, Motion, Phase, Porous, Scene, SceneError, Shape, Simulation, Solid, SolidMaterial,
    SolidModelChoice, Wall,
};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use toml::de::DeTable;

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

impl Scene {
    /// Reads and validates a scene file; mesh paths in it are relative to
    /// the file's directory.
    pub fn from_file(path: &Path) -> Result<Scene, SceneError> {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: file.clone(),
            key: String::new(),
            position: None,
            reason: format!("cannot read the scene file: {e}"),
        })?;
        Scene::from_toml_str(&text, &file)
    }

    /// Parses and validates scene text; `origin` names it in errors, and
    /// mesh paths are relative to the directory of `origin` (the current
    /// directory for a bare file name or a built-in scene).
    pub fn from_toml_str(text: &str, origin: &str) -> Result<Scene, SceneError> {
        let root = DeTable::parse(text).map_err(|e| syntax_error(origin, text, &e))?;
        let doc = Doc { file: origin, text, root: &root };
        let top = KeyPath::default();
        if root.get_ref().is_empty() {
            return Err(doc.err(&top, "the scene is empty; it needs a [simulation] table and at least one [[phase]]"));
        }
        let de = toml::de::Deserializer::from(root.clone());
        let file: SceneFile = serde_path_to_error::deserialize(de).map_err(|e| doc.serde_error(e))?;
        check_numbers(&doc)?;
        let cx = Cx { doc: &doc, schema: Schema::get(), base: mesh_base(origin) };
        let scene = cx.scene(file)?;
        Ok(Scene { origin: origin.to_string(), text: text.to_string(), ..scene })
    }

    /// The scene text with every mesh path (`mesh = { path = ... }`) made
    /// absolute, so that the text reads the same meshes from any
    /// directory: what a run writes to `OUT/scene.toml` and its
    /// checkpoints. Everything else (comments, layout) is kept; a scene
    /// without meshes, or with absolute mesh paths, comes back unchanged.
    pub fn with_absolute_mesh_paths(&self) -> String {
        let Ok(root) = DeTable::parse(&self.text) else { return self.text.clone() };
        let mut paths = Vec::new();
        mesh_paths(root.get_ref(), &mut paths);
        paths.sort_by_key(|(span, _)| span.start);
        let base = mesh_base(&self.origin);
        let mut out = String::with_capacity(self.text.len());
        let mut at = 0;
        for (span, path) in paths {
            let p = Path::new(&path);
            if p.is_absolute() || span.start < at {
                continue;
            }
            let joined = base.join(p);
            let Some(abs) = joined.canonicalize().or_else(|_| std::path::absolute(&joined)).ok() else { continue };
            let Some(abs) = abs.to_str() else { continue };
            out.push_str(&self.text[at..span.start]);
            out.push_str(&toml::Value::String(abs.to_string()).to_string());
            at = span.end;
        }
        out.push_str(&self.text[at..]);
        out
    }
}

/// The directory mesh paths of the scene text from `origin` are relative
/// to: the directory of `origin`, or the current one for a bare file name
/// or a built-in scene.
fn mesh_base(origin: &str) -> PathBuf {
    match Path::new(origin).parent() {
        Some(dir) if !origin.starts_with('<') => dir.to_path_buf(),
        _ => PathBuf::new(),
    }
}

/// The span and text of every string at a key `path` of a table `mesh`,
/// anywhere in `table`.
fn mesh_paths(table: &DeTable<'_>, out: &mut Vec<(std::ops::Range<usize>, String)>) {
    use toml::de::DeValue;
    fn walk(key: &str, v: &toml::Spanned<DeValue<'_>>, out: &mut Vec<(std::ops::Range<usize>, String)>) {
        match v.get_ref() {
            DeValue::Table(t) => {
                if key == "mesh" {
                    if let Some(p) = t.get("path") {
                        if let DeValue::String(s) = p.get_ref() {
                            out.push((p.span(), s.to_string()));
                        }
                    }
                }
                mesh_paths(t, out);
            }
            DeValue::Array(a) => a.iter().for_each(|e| walk(key, e, out)),
            _ => {}
        }
    }
    for (k, v) in table.iter() {
        walk(k.get_ref(), v, out);
    }
}

/// A TOML syntax error, with the line and column it happened at.
fn syntax_error(file: &str, text: &str, e: &toml::de::Error) -> SceneError {
    let message = e.message().trim();
    let reason = match e.span() {
        Some(span) => {
            let (line, column, content) = line_column(text, span.start);
            format!("TOML syntax error at line {line}, column {column}: {message} (line {line} reads `{content}`)")
        }
        None => format!("TOML syntax error: {message}"),
    };
    SceneError { file: file.to_string(), key: String::new(), position: None, reason }
}

/// The conversion from the file's types to a [`Scene`]: checks of more than
/// one value, and the errors for them.
struct Cx<'a> {
    doc: &'a Doc<'a>,
    schema: Schema,
    /// The directory mesh paths are relative to.
    base: PathBuf,
}

impl Cx<'_> {
    fn err(&self, path: &KeyPath, reason: impl Into<String>) -> SceneError {
        self.doc.err(path, reason)
    }

    fn what(&self, path: &KeyPath) -> String {
        self.schema.what(&path.0)
    }

    fn scene(&self, file: SceneFile) -> Result<Scene, SceneError> {
        let top = KeyPath::default();
        let Some(simulation) = file.simulation else {
            return Err(self.err(
                &top.key("simulation"),
                "missing the required [simulation] table (particle_spacing, end_time, max_dt)",
            ));
        };
        self.simulation(&top.key("simulation"), &simulation)?;
        let d = f64::from(simulation.particle_spacing);
        if file.phase.is_empty() {
            return Err(self.err(
                &top.key("phase"),
                "no phases: at least one [[phase]] with name, density and viscosity is required",
            ));
        }
        let mut phases: Vec<Phase> = Vec::with_capacity(file.phase.len());
        for (i, p) in file.phase.into_iter().enumerate() {
            let path = top.key("phase").index(i);
            let phase = self.phase(&path, p, i, &simulation)?;
            if let Some(j) = phases.iter().position(|q| q.name == phase.name) {
                return Err(self.err(
                    &path.key("name"),
                    format!(
                        "duplicate phase name \"{}\": phase[{j}] already uses it; names must be unique",
                        phase.name
                    ),
                ));
            }
            phases.push(phase);
        }
        let fluids = (file.fluid.iter().enumerate())
            .map(|(i, f)| self.fluid(&top.key("fluid").index(i), f, &phases, d))
            .collect::<Result<Vec<_>, _>>()?;
        let walls = (file.wall.iter().enumerate())
            .map(|(i, w)| self.wall(&top.key("wall").index(i), w, d))
            .collect::<Result<Vec<_>, _>>()?;
        let mut solids: Vec<Solid> = Vec::new();
        for (i, s) in file.solid.into_iter().enumerate() {
            let path = top.key("solid").index(i);
            let solid = self.solid(&path, s, d, &phases)?;
            if let Some(j) = solids.iter().position(|t| t.name == solid.name) {
                return Err(self.err(
                    &path.key("name"),
                    format!("duplicate solid name \"{}\": solid[{j}] already uses it", solid.name),
                ));
            }
            if let Some(j) = solids.iter().position(|t| {
                t.body == solid.body
                    && matches!(t.model, SolidMaterial::Granular(_))
                        != matches!(solid.model, SolidMaterial::Granular(_))
            }) {
                return Err(self.err(
                    &path.key("model"),
                    format!(
                        "solid[{j}] of the same body \"{}\" has another model: a body is elastic or granular throughout",
                        solid.body
                    ),
                ));
            }
            solids.push(solid);
        }
        self.bodies_have_volume(&top, &solids, d)?;
        Ok(Scene { simulation, phases, fluids, walls, solids, origin: String::new(), text: String::new() })
    }

    /// Every elastic body is sampled with a three-dimensional neighbourhood
    /// at each of its particles that is not fixed (see
    /// [`FlatParticle`]): a body of one or two particles, or a rod or sheet
    /// one particle thick, has no elastic response across itself, and
    /// once it moves with the fluid nothing holds it together (issue 34's
    /// placement 367, a 2.2 cm dumbbell sampled as 2 particles at d = 1 cm,
    /// left the closed container at 600 m/s).
    fn bodies_have_volume(&self, top: &KeyPath, solids: &[Solid], d: f64) -> Result<(), SceneError> {
        let mut seen: Vec<&str> = Vec::new();
        for s in solids {
            if seen.contains(&s.body.as_str()) || matches!(s.model, SolidMaterial::Granular(_)) {
                continue;
            }
            seen.push(&s.body);
            let members: Vec<usize> = (0..solids.len()).filter(|&i| solids[i].body == s.body).collect();
            let shapes: Vec<(&Shape, Option<&Shape>)> =
                members.iter().map(|&i| (&solids[i].shape, solids[i].fixed.as_ref())).collect();
            let Some(flat) = first_flat_particle(&shapes, d) else { continue };
            let FlatParticle { shape, position: p, neighbours, particles, flat } = flat;
            let i = members[shape];
            let body = if members.len() > 1 { format!("body \"{}\"", s.body) } else { "solid".to_string() };
            return Err(self.err(
                &top.key("solid").index(i),
                format!(
                    "the {body} is sampled as {particles} particle(s) at particle_spacing = {} m, and {flat} of \
                     them (the first at [{}, {}, {}] m, with {neighbours} neighbour(s) within the kernel support \
                     2 d) have neighbours that do not span three dimensions, so the elastic strain (P-Eq. 4) \
                     does not exist there; make the solid at least two particle spacings thick everywhere, or \
                     the particle_spacing smaller",
                    d as f32, p[0], p[1], p[2]
                ),
            ));
        }
        Ok(())
    }

    /// `[simulation]`: the checks that involve two settings.
    fn simulation(&self, path: &KeyPath, sim: &Simulation) -> Result<(), SceneError> {
        // max_dt is stored as f32: compare in f32, or `max_dt = end_time`
        // (0.002 = 0.002) fails by the f32 rounding of 0.002.
        if sim.max_dt > sim.end_time as f32 {
            return Err(self.err(
                &path.key("max_dt"),
                format!("expected max_dt <= end_time = {} s, found max_dt = {} s", sim.end_time, sim.max_dt),
            ));
        }
        if sim.max_iterations < sim.min_iterations {
            let given = self.doc.value(&path.key("max_iterations").0).is_some();
            return Err(self.err(
                &path.key(if given { "max_iterations" } else { "min_iterations" }),
                format!(
                    "expected max_iterations >= min_iterations, found min_iterations = {} and max_iterations = {}",
                    sim.min_iterations, sim.max_iterations
                ),
            ));
        }
        Ok(())
    }

    /// `[[phase]]` number `index`; drift weights default to those of `sim`.
    fn phase(&self, path: &KeyPath, p: PhaseFile, index: usize, sim: &Simulation) -> Result<Phase, SceneError> {
        let key = path.key("name");
        let what = self.what(&key);
        if p.name.is_empty() {
            return Err(self.err(&key, format!("expected {what}, found an empty string")));
        }
        if let Some(c) = p.name.chars().find(|c| !(c.is_ascii_alphanumeric() || *c == '_' || *c == '-')) {
            return Err(self.err(&key, format!("expected {what}, found {:?}, which contains {c:?}", p.name)));
        }
        Ok(Phase {
            name: p.name,
            density: p.density,
            viscosity: p.viscosity,
            color: p.color.unwrap_or(PALETTE[index % PALETTE.len()]),
            drift_tau: p.drift_tau.unwrap_or(sim.drift_tau),
            drift_sigma: p.drift_sigma.unwrap_or(sim.drift_sigma),
        })
    }

    /// `[[fluid]]`.
    fn fluid(&self, path: &KeyPath, f: &FluidFile, phases: &[Phase], d: f64) -> Result<FluidBlock, SceneError> {
        let shape = self.shape(path, f, d)?;
        let key = path.key("fractions");
        let mut fractions = vec![0.0f64; phases.len()];
        for (name, &x) in &f.fractions {
            let i = self.phase_index(&key.key(name), name, phases)?;
            fractions[i] = x;
        }
        let sum: f64 = fractions.iter().sum();
        if (sum - 1.0).abs() > FRACTION_SUM_TOLERANCE {
            return Err(self.err(
                &key,
                format!("expected fractions that sum to 1 (within {FRACTION_SUM_TOLERANCE:e}), found a sum of {sum}"),
            ));
        }
        let fractions = fractions.iter().map(|&x| (x / sum) as f32).collect();
        self.point_in_range(&path.key("velocity"), f.velocity, None)?;
        Ok(FluidBlock { shape, fractions, velocity: f.velocity })
    }

    /// The index of the phase called `name`, or an error at `path`.
    fn phase_index(&self, path: &KeyPath, name: &str, phases: &[Phase]) -> Result<usize, SceneError> {
        phases.iter().position(|p| p.name == name).ok_or_else(|| {
            let names: Vec<&str> = phases.iter().map(|p| p.name.as_str()).collect();
            self.err(path, format!("unknown phase `{name}`; the phases are: {}", names.join(", ")))
        })
    }

    /// `[[wall]]`.
    fn wall(&self, path: &KeyPath, w: &WallFile, d: f64) -> Result<Wall, SceneError> {
        let shape = self.shape(path, w, d)?;
        if w.container && !matches!(shape, Shape::Box { .. }) {
            return Err(self.err(
                &path.key("container"),
                format!("container = true is only allowed with a box, found a {}", shape_name(&shape)),
            ));
        }
        if w.open_top && !w.container {
            return Err(self.err(
                &path.key("open_top"),
                "open_top = true is only allowed with container = true, found container = false",
            ));
        }
        Ok(Wall { shape, container: w.container, open_top: w.open_top })
    }

    /// `[[solid]]`.
    fn solid(&self, path: &KeyPath, s: SolidFile, d: f64, phases: &[Phase]) -> Result<Solid, SceneError> {
        if s.name.trim().is_empty() {
            let key = path.key("name");
            return Err(self.err(
                &key,
                format!("expected {} (a non-empty string), found the string {:?}", self.what(&key), s.name),
            ));
        }
        let shape = self.shape(path, &s, d)?;
        let fixed = match &s.fixed {
            Some(f) => Some(self.shape(&path.key("fixed"), f, d)?),
            None => None,
        };
        let mut prev: Option<&Motion> = None;
        for (i, m) in s.motion.iter().enumerate() {
            let mpath = path.key("motion").index(i);
            if m.until <= m.from {
                return Err(
                    self.err(&mpath.key("until"), format!("expected until > from = {} s, found {} s", m.from, m.until))
                );
            }
            if let Some(p) = prev.filter(|p| m.from < p.until) {
                return Err(self.err(
                    &mpath.key("from"),
                    format!(
                        "intervals must be in time order without overlap: this one starts at {} s, before the \
                         previous one ends at {} s",
                        m.from, p.until
                    ),
                ));
            }
            prev = Some(m);
        }
        if fixed.is_none() && !s.motion.is_empty() {
            return Err(
                self.err(&path.key("motion"), "motion moves the fixed particles, but the solid has no `fixed` shape")
            );
        }
        let model = self.solid_material(path, &s)?;
        let body = match s.body {
            Some(b) if b.trim().is_empty() => {
                let key = path.key("body");
                return Err(self
                    .err(&key, format!("expected {} (a non-empty string), found the string {b:?}", self.what(&key))));
            }
            Some(b) => b,
            None => s.name.clone(),
        };
        let porous = match &s.porous {
            Some(p) => Some(self.porous(&path.key("porous"), p, phases)?),
            None => None,
        };
        Ok(Solid {
            name: s.name,
            shape,
            density: s.density,
            shear_modulus: s.shear_modulus,
            lame_lambda: s.lame_lambda,
            velocity: s.velocity,
            fixed,
            motion: s.motion,
            body,
            porous,
            model,
        })
    }

    /// `model` of the `[[solid]]` at `path`, with the granular keys (which
    /// only a granular solid may have).
    fn solid_material(&self, path: &KeyPath, s: &SolidFile) -> Result<SolidMaterial, SceneError> {
        let keys = [
            ("friction_angle", s.friction_angle.is_some()),
            ("dilatancy_angle", s.dilatancy_angle.is_some()),
            ("cohesion", s.cohesion.is_some()),
            ("wall_slip", s.wall_slip.is_some()),
            ("yield_cone", s.yield_cone.is_some()),
            ("wet_cohesion", s.wet_cohesion.is_some()),
            ("suction_n", s.suction_n.is_some()),
            ("saturation", s.saturation.is_some()),
            ("initial_stress", s.initial_stress.is_some()),
        ];
        if s.model == SolidModelChoice::Elastic {
            if let Some((key, _)) = keys.iter().find(|(_, given)| *given) {
                return Err(self.err(
                    &path.key(key),
                    format!("{key} is a granular solid's parameter, but this solid's model is \"elastic\" (set model = \"granular\")"),
                ));
            }
            return Ok(SolidMaterial::Elastic);
        }
        let g = Granular {
            friction_angle: s.friction_angle.unwrap_or(30.0),
            dilatancy_angle: s.dilatancy_angle.unwrap_or(0.0),
            yield_cone: s.yield_cone.unwrap_or_default(),
            cohesion: s.cohesion.unwrap_or(0.0),
            wet_cohesion: s.wet_cohesion.unwrap_or(0.0),
            suction_n: s.suction_n.unwrap_or(4.0),
            saturation: s.saturation,
            wall_slip: self.wall_slip(path, s.wall_slip.as_ref())?,
            initial_stress: s.initial_stress.unwrap_or_default(),
        };
        if !(g.friction_angle > 0.0 && g.friction_angle < 90.0) {
            let key = path.key("friction_angle");
            return Err(self.err(&key, format!("expected 0 < friction_angle < 90 degrees, found {}", g.friction_angle)));
        }
        if !(g.dilatancy_angle >= 0.0 && g.dilatancy_angle <= g.friction_angle) {
            let key = path.key("dilatancy_angle");
            return Err(self.err(
                &key,
                format!(
                    "expected 0 <= dilatancy_angle <= friction_angle = {} degrees, found {}",
                    g.friction_angle, g.dilatancy_angle
                ),
            ));
        }
        if g.cohesion.is_nan() || g.cohesion < 0.0 {
            return Err(self.err(&path.key("cohesion"), format!("expected cohesion >= 0 Pa, found {}", g.cohesion)));
        }
        if g.wet_cohesion.is_nan() || g.wet_cohesion < 0.0 {
            let key = path.key("wet_cohesion");
            return Err(self.err(&key, format!("expected wet_cohesion >= 0 Pa, found {}", g.wet_cohesion)));
        }
        if let Some(sat) = g.saturation {
            let key = path.key("saturation");
            if !(0.0..=1.0).contains(&sat) {
                return Err(self.err(&key, format!("expected 0 <= saturation <= 1, found {sat}")));
            }
            if s.porous.is_some() {
                return Err(self.err(
                    &key,
                    "a porous solid's saturation comes from the water it absorbs: give saturation only without [solid.porous]",
                ));
            }
        }
        if s.wet_cohesion.is_some() && s.porous.is_none() && g.saturation.is_none() {
            return Err(self.err(
                &path.key("wet_cohesion"),
                "a wet cohesion follows the saturation of the pores: this solid needs a [solid.porous] table or a fixed saturation",
            ));
        }
        if !(g.suction_n > 2.0 && g.suction_n.is_finite()) {
            let key = path.key("suction_n");
            return Err(self.err(
                &key,
                format!(
                    "expected suction_n > 2 (at n <= 2 the wet cohesion does not vanish when dry), found {}",
                    g.suction_n
                ),
            ));
        }
        Ok(SolidMaterial::Granular(g))
    }

    /// `wall_slip` of the `[[solid]]` at `path`: per axis x, y, z.
    fn wall_slip(&self, path: &KeyPath, w: Option<&WallSlipFile>) -> Result<[bool; 3], SceneError> {
        match w {
            None => Ok([false; 3]),
            Some(WallSlipFile::All(b)) => Ok([*b; 3]),
            Some(WallSlipFile::Axes(axes)) => {
                let mut out = [false; 3];
                for a in axes {
                    let Some(k) = ["x", "y", "z"].iter().position(|n| n == a) else {
                        return Err(self.err(
                            &path.key("wall_slip"),
                            format!("expected true, false or a list of axes \"x\", \"y\", \"z\", found axis {a:?}"),
                        ));
                    };
                    out[k] = true;
                }
                Ok(out)
            }
        }
    }

    /// `[solid.porous]` at `path`.
    fn porous(&self, path: &KeyPath, p: &PorousFile, phases: &[Phase]) -> Result<Porous, SceneError> {
        let mut out = vec![None; phases.len()];
        for (name, ph) in &p.phase {
            let key = path.key("phase").key(name);
            let i = self.phase_index(&key, name, phases)?;
            let limit = p.porosity * p.rest_pore_pressure;
            if ph.outer_pore_pressure > limit {
                return Err(self.err(
                    &key.key("outer_pore_pressure"),
                    format!(
                        "expected outer_pore_pressure <= porosity x rest_pore_pressure = {limit} Pa (the strain-free \
                         saturation p0k / p0 cannot exceed the porosity), found {} Pa",
                        ph.outer_pore_pressure
                    ),
                ));
            }
            out[i] = Some(*ph);
        }
        Ok(Porous {
            porosity: p.porosity,
            rest_pore_pressure: p.rest_pore_pressure,
            biot_modulus: p.biot_modulus.unwrap_or(p.rest_pore_pressure),
            swelling: p.swelling,
            capillarity: p.capillarity,
            absorption: p.absorption,
            gains_mass: p.gains_mass,
            phases: out,
        })
    }

    /// Exactly one of `box`, `sphere`, `cylinder`, `mesh` in the table at `path`.
    fn shape(&self, path: &KeyPath, t: &impl ShapeKeys, d: f64) -> Result<Shape, SceneError> {
        let shapes = t.shapes();
        let present: Vec<(&str, &ShapeFile<'_>)> =
            shapes.iter().filter_map(|(k, s)| s.as_ref().map(|s| (*k, s))).collect();
        let (kind, s) = match present.as_slice() {
            [(k, s)] => (*k, *s),
            [] => {
                return Err(self.err(
                    path,
                    "expected exactly one shape: box = { min, max }, sphere = { center, radius }, \
                     cylinder = { base, axis, radius, height } or mesh = { path, scale, translate }; found none",
                ))
            }
            [(a, _), (b, _), ..] => {
                return Err(self.err(
                    path,
                    format!("expected exactly one shape (box, sphere, cylinder or mesh), found both `{a}` and `{b}`"),
                ))
            }
        };
        let spath = path.key(kind);
        let shape = match s {
            ShapeFile::Box(b) => self.box_shape(&spath, b, d)?,
            ShapeFile::Sphere(SphereFile { center, radius }) => {
                self.point_in_range(&spath.key("center"), *center, Some(d))?;
                Shape::Sphere { center: *center, radius: *radius }
            }
            ShapeFile::Cylinder(c) => self.cylinder(&spath, c, d)?,
            ShapeFile::Mesh(m) => self.mesh(&spath, m, d)?,
        };
        let cells = lattice_cells(&shape, d);
        if cells > MAX_LATTICE_CELLS {
            let what = match &shape {
                Shape::Mesh(m) => format!("mesh of {}", m.source().path.display()),
                _ => kind.to_string(),
            };
            return Err(self.err(
                &spath,
                format!(
                    "the {what} spans about {cells:.3e} lattice cells at particle_spacing = {} m \
                     (limit {MAX_LATTICE_CELLS:e}); are the lengths in m?",
                    d as f32
                ),
            ));
        }
        Ok(shape)
    }

    fn box_shape(&self, spath: &KeyPath, b: &BoxFile, d: f64) -> Result<Shape, SceneError> {
        let (min, max) = (b.min, b.max);
        self.point_in_range(&spath.key("min"), min, Some(d))?;
        self.point_in_range(&spath.key("max"), max, Some(d))?;
        for axis in 0..3 {
            let name = ["x", "y", "z"][axis];
            if min[axis] >= max[axis] {
                return Err(self.err(
                    spath,
                    format!(
                        "expected min < max on every axis, found min = {} >= max = {} on the {name} axis",
                        min[axis], max[axis]
                    ),
                ));
            }
            let extent = f64::from(max[axis]) - f64::from(min[axis]);
            if (extent / d).round() < 1.0 {
                return Err(self.err(
                    spath,
                    format!(
                        "the box is {} m thick on the {name} axis, less than half the particle spacing {} m, \
                         so it would hold no particles",
                        extent as f32, d as f32
                    ),
                ));
            }
        }
        Ok(Shape::Box { min, max })
    }

    fn cylinder(&self, spath: &KeyPath, c: &CylinderFile, d: f64) -> Result<Shape, SceneError> {
        self.point_in_range(&spath.key("base"), c.base, Some(d))?;
        let a = c.axis;
        let a64 = a.map(f64::from);
        let norm = (a64[0] * a64[0] + a64[1] * a64[1] + a64[2] * a64[2]).sqrt();
        if !(norm > 0.0 && norm.is_finite()) {
            return Err(self.err(
                &spath.key("axis"),
                format!("expected a non-zero direction vector, found [{}, {}, {}]", a[0], a[1], a[2]),
            ));
        }
        let axis = a64.map(|x| (x / norm) as f32);
        Ok(Shape::Cylinder { base: c.base, axis, radius: c.radius, height: c.height })
    }

    /// `mesh = { path, scale, translate }`: reads the file and checks that it
    /// is a closed surface within reach of the lattice.
    fn mesh(&self, spath: &KeyPath, m: &MeshFile, d: f64) -> Result<Shape, SceneError> {
        self.point_in_range(&spath.key("translate"), m.translate, Some(d))?;
        let file = self.base.join(&m.path);
        let source = MeshSource { path: file.clone(), scale: m.scale, translate: m.translate };
        let mesh = TriMesh::load(source).map_err(|e| {
            let at = match e.line {
                Some(line) => format!("{}:{line}", file.display()),
                None => file.display().to_string(),
            };
            self.err(&spath.key("path"), format!("mesh file {at}: {}", e.reason))
        })?;
        let (lo, hi) = mesh.bounds();
        for (corner, p) in [("lowest", lo), ("highest", hi)] {
            if let Some((i, c)) = p.iter().enumerate().find(|(_, c)| c.abs() > MAX_COORD_SPACINGS * d) {
                return Err(self.err(
                    spath,
                    format!(
                        "mesh file {}: its {corner} {} coordinate, {c} m after scale and translate, is more than \
                         {MAX_COORD_SPACINGS:e} particle spacings from the origin; is the scale right?",
                        file.display(),
                        ["x", "y", "z"][i]
                    ),
                ));
            }
        }
        Ok(Shape::Mesh(Arc::new(mesh)))
    }

    /// A vector whose components, if `d` is given, are positions: not
    /// absurdly far from the origin.
    fn point_in_range(&self, key: &KeyPath, p: [f32; 3], d: Option<f64>) -> Result<(), SceneError> {
        let Some(d) = d else { return Ok(()) };
        for (i, &c) in p.iter().enumerate() {
            if f64::from(c).abs() > MAX_COORD_SPACINGS * d {
                return Err(self.err(
                    &key.index(i),
                    format!(
                        "coordinate {c} m is more than {MAX_COORD_SPACINGS:e} particle spacings ({} m) \
                         from the origin, where single-precision positions cannot resolve the lattice; \
                         are the lengths in m?",
                        d as f32
                    ),
                ));
            }
        }
        Ok(())
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
        Shape::Mesh(m) => {
            let (lo, hi) = m.bounds();
            (0..3).map(|i| extent(lo[i], hi[i])).product()
        }
    }
}

fn shape_name(shape: &Shape) -> &'static str {
    match shape {
        Shape::Box { .. } => "box",
        Shape::Sphere { .. } => "sphere",
        Shape::Cylinder { .. } => "cylinder",
        Shape::Mesh(_) => "mesh",
    }
}
