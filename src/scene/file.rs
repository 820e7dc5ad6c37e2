//! The scene file as serde reads it and as `porosph schema` publishes it.
//!
//! These types mirror the TOML one to one: `deny_unknown_fields`
//! everywhere, the defaults beside the fields, and the ranges in
//! `#[schemars(...)]` attributes, so that the JSON Schema says everything
//! a value must satisfy on its own. The first line of each field's doc
//! comment is a noun phrase with the unit ("the rest density in kg/m^3"):
//! error messages quote it ("expected the rest density in kg/m^3 (a
//! number), found ..."), and editors show the whole comment. What involves
//! more than one value (max_dt <= end_time, phase names, exactly one
//! shape) is checked in `parse.rs`, which builds the [`super::Scene`].

use super::{InitialStress, Motion, PorousPhase, Simulation, SolidModelChoice, YieldCone};
use schemars::generate::SchemaSettings;
use schemars::JsonSchema;
use serde::Deserialize;
use serde_json::Value;
use std::collections::BTreeMap;

/// A porosph scene: phases, fluid blocks, walls and solids, and the
/// simulation settings. TOML; all quantities in SI units.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "porosph scene")]
pub(super) struct SceneFile {
    /// The simulation settings
    ///
    /// `[simulation]`: particle spacing, end time, time step, solver settings.
    #[schemars(required)]
    pub simulation: Option<Simulation>,
    /// The fluid phases
    ///
    /// `[[phase]]`, at least one; phase k everywhere in porosph is the k-th entry.
    #[serde(default)]
    #[schemars(required, length(min = 1))]
    pub phase: Vec<PhaseFile>,
    /// The fluid blocks
    ///
    /// `[[fluid]]`, any number.
    #[serde(default)]
    pub fluid: Vec<FluidFile>,
    /// The static walls
    ///
    /// `[[wall]]`, any number: boundary particles.
    #[serde(default)]
    pub wall: Vec<WallFile>,
    /// The elastic (and porous) solids
    ///
    /// `[[solid]]`, any number (PHYSICS.md §3).
    #[serde(default)]
    pub solid: Vec<SolidFile>,
}

/// `[[phase]]`: one fluid phase.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct PhaseFile {
    /// A name made of letters, digits, `_` and `-`
    ///
    /// Unique among the phases; `fractions` and `[solid.porous.phase.NAME]` use it.
    #[schemars(regex(pattern = r"^[A-Za-z0-9_-]+$"))]
    pub name: String,
    /// The rest density in kg/m^3
    ///
    /// rho_k.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub density: f32,
    /// The dynamic viscosity in Pa s
    ///
    /// mu_k.
    #[schemars(range(min = 0))]
    pub viscosity: f32,
    /// A linear RGB colour
    ///
    /// Each component in [0, 1]; default: from a fixed palette by phase index.
    #[schemars(inner(range(min = 0, max = 1)))]
    pub color: Option<[f32; 3]>,
    /// The drift relaxation weight tau in m^2/(Pa s) (= m^3 s/kg)
    ///
    /// tau_k of this phase (P-Eq. 11); default `simulation.drift_tau`.
    #[schemars(range(min = 0))]
    pub drift_tau: Option<f32>,
    /// The drift diffusion weight sigma in m^2/s
    ///
    /// sigma_k of this phase (P-Eq. 11); default `simulation.drift_sigma`.
    #[schemars(range(min = 0))]
    pub drift_sigma: Option<f32>,
}

/// The shape keys of a `[[fluid]]`, `[[wall]]`, `[[solid]]` or `fixed`
/// table: exactly one of them is given.
pub(super) trait ShapeKeys {
    fn shapes(&self) -> [(&'static str, Option<ShapeFile<'_>>); 4];
}

/// One of the four shape tables.
pub(super) enum ShapeFile<'a> {
    Box(&'a BoxFile),
    Sphere(&'a SphereFile),
    Cylinder(&'a CylinderFile),
    Mesh(&'a MeshFile),
}

macro_rules! shape_keys {
    ($t:ty) => {
        impl ShapeKeys for $t {
            fn shapes(&self) -> [(&'static str, Option<ShapeFile<'_>>); 4] {
                [
                    ("box", self.r#box.as_ref().map(ShapeFile::Box)),
                    ("sphere", self.sphere.as_ref().map(ShapeFile::Sphere)),
                    ("cylinder", self.cylinder.as_ref().map(ShapeFile::Cylinder)),
                    ("mesh", self.mesh.as_ref().map(ShapeFile::Mesh)),
                ]
            }
        }
    };
}

shape_keys!(FluidFile);
shape_keys!(WallFile);
shape_keys!(SolidFile);
shape_keys!(FixedFile);

/// `box = { min, max }`: an axis-aligned box.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct BoxFile {
    /// The lower corner in m
    ///
    /// Smallest x, y and z; the box is snapped to whole lattice cells from here.
    pub min: [f32; 3],
    /// The upper corner in m
    pub max: [f32; 3],
}

/// `sphere = { center, radius }`.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct SphereFile {
    /// The centre position in m
    pub center: [f32; 3],
    /// The radius in m
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub radius: f32,
}

/// `cylinder = { base, axis, radius, height }`: a capped cylinder from
/// `base` along `axis`.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct CylinderFile {
    /// The centre of the base in m
    pub base: [f32; 3],
    /// The direction from the base to the top
    ///
    /// Any length but zero; normalised.
    pub axis: [f32; 3],
    /// The radius in m
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub radius: f32,
    /// The height in m
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub height: f32,
}

/// `mesh = { path, scale, translate }`: the inside of a closed triangle
/// mesh, each vertex moved to `scale * v + translate`.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct MeshFile {
    /// The mesh file, relative to the scene file
    ///
    /// Wavefront OBJ (`.obj`) or STL (`.stl`, ASCII or binary): a closed,
    /// consistently oriented triangle surface (polygons are split into
    /// triangles).
    #[schemars(length(min = 1))]
    pub path: String,
    /// The factor the mesh's coordinates are multiplied by
    ///
    /// For example 0.001 for a mesh in mm; the result is in m.
    #[serde(default = "one")]
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub scale: f32,
    /// The offset added after scaling, in m
    #[serde(default)]
    pub translate: [f32; 3],
}

fn one() -> f32 {
    1.0
}

/// `[[fluid]]`: a block of fluid particles.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct FluidFile {
    /// The box the fluid fills
    pub r#box: Option<BoxFile>,
    /// The sphere the fluid fills
    pub sphere: Option<SphereFile>,
    /// The cylinder the fluid fills
    pub cylinder: Option<CylinderFile>,
    /// The closed mesh the fluid fills
    pub mesh: Option<MeshFile>,
    /// The volume fraction of each phase, e.g. { water = 1.0 }
    ///
    /// By phase name; summing to 1 (within 1e-4, then renormalised); a phase
    /// not listed is 0.
    #[schemars(extend("additionalProperties" = {
        "type": "number",
        "minimum": 0,
        "maximum": 1,
        "description": "A volume fraction"
    }))]
    pub fractions: BTreeMap<String, f64>,
    /// The initial velocity in m/s
    #[serde(default)]
    pub velocity: [f32; 3],
}

/// `[[wall]]`: static boundary particles.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct WallFile {
    /// The box of the wall
    ///
    /// A two-layer shell inside its faces, or with `container` a tank around it.
    pub r#box: Option<BoxFile>,
    /// The sphere of the wall
    ///
    /// A two-layer shell inside its surface.
    pub sphere: Option<SphereFile>,
    /// The cylinder of the wall
    ///
    /// A two-layer shell inside its surface.
    pub cylinder: Option<CylinderFile>,
    /// The closed mesh of the wall
    ///
    /// A two-layer shell inside its surface.
    pub mesh: Option<MeshFile>,
    /// Whether the box is the inside of a tank
    ///
    /// Boxes only: two wall layers are laid outside its faces.
    #[serde(default)]
    pub container: bool,
    /// Whether the tank's top (+y) face is open
    ///
    /// Only with `container = true`.
    #[serde(default)]
    pub open_top: bool,
}

/// `[[solid]]`: an elastic solid body or a region of one.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct SolidFile {
    /// The solid's name
    ///
    /// Unique among the solids.
    #[schemars(length(min = 1))]
    pub name: String,
    /// The box the solid fills
    pub r#box: Option<BoxFile>,
    /// The sphere the solid fills
    pub sphere: Option<SphereFile>,
    /// The cylinder the solid fills
    pub cylinder: Option<CylinderFile>,
    /// The closed mesh the solid fills
    pub mesh: Option<MeshFile>,
    /// The density in kg/m^3
    ///
    /// Particle mass = density d^3.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub density: f32,
    /// The shear modulus mu in Pa
    ///
    /// The paper's "nu" (PHYSICS.md §8.6).
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub shear_modulus: f32,
    /// Lame's first parameter lambda in Pa
    #[schemars(range(min = 0))]
    pub lame_lambda: f32,
    /// The initial velocity in m/s
    #[serde(default)]
    pub velocity: [f32; 3],
    /// The shape of the fixed particles
    ///
    /// Particles inside it are kinematic: they move with `motion` (at rest
    /// outside its intervals).
    pub fixed: Option<FixedFile>,
    /// The motion of the fixed particles
    ///
    /// Velocities over time intervals [from, until), in time order.
    #[serde(default)]
    pub motion: Vec<Motion>,
    /// The name of the body this solid belongs to
    ///
    /// Entries with the same body form one elastic body (rest neighbours
    /// across them, one elastic response in the pressure solve) with
    /// regions of different material; default: the solid's own name.
    #[schemars(length(min = 1))]
    pub body: Option<String>,
    /// The porous parameters
    ///
    /// `[solid.porous]`: the solid absorbs liquid (P §4-5, PHYSICS.md §4.2).
    pub porous: Option<PorousFile>,
    /// How the solid deforms
    ///
    /// `"elastic"` (default): corotated linear elasticity (Peer et al. 2018)
    /// with fixed rest neighbours. `"granular"`: an elasto-plastic continuum
    /// with a Drucker-Prager yield surface and no fixed neighbours, which
    /// flows without limit (sand; kernels/src/granular.rs). Every entry of a body
    /// has the same model.
    #[serde(default)]
    pub model: SolidModelChoice,
    /// The friction angle phi in degrees (granular only)
    ///
    /// The Mohr-Coulomb angle that the Drucker-Prager cone is fitted to
    /// (see `yield_cone`); default 30.
    #[schemars(extend("exclusiveMinimum" = 0, "exclusiveMaximum" = 90))]
    pub friction_angle: Option<f32>,
    /// Which stress path the Drucker-Prager cone matches Mohr-Coulomb on (granular only)
    ///
    /// `"plane_strain"` (default): flow without strain along one axis (a
    /// quasi-2D channel, a long bank; Bui et al. 2008). `"triaxial_compression"`:
    /// the compression meridian (a triaxial test), about 1.8 times stronger
    /// in plane strain at 30 degrees.
    pub yield_cone: Option<YieldCone>,
    /// The dilatancy angle psi in degrees (granular only)
    ///
    /// 0 (default): no plastic volume change; at most the friction angle.
    #[schemars(range(min = 0))]
    pub dilatancy_angle: Option<f32>,
    /// The cohesion c in Pa (granular only)
    ///
    /// The dry value; 0 (default) for sand that holds no tension.
    #[schemars(range(min = 0))]
    pub cohesion: Option<f32>,
    /// The wet cohesion in Pa (granular only)
    ///
    /// The largest cohesion that partly filled pores add; needs
    /// `[solid.porous]` or a fixed `saturation`. The cohesion is `cohesion + wet_cohesion
    /// g(S) / g_max` at saturation S = sum_k phi_sk / porosity, g the
    /// suction stress of Lu & Likos (2006): 0 when dry and when saturated,
    /// largest in between (kernels/src/granular.rs); default 0.
    #[schemars(range(min = 0))]
    pub wet_cohesion: Option<f32>,
    /// The van Genuchten n of the wet cohesion law (granular only)
    ///
    /// The pore size spread of the retention curve; n > 2 (at n <= 2 the
    /// law does not vanish when dry); sand 3-8; default 4 (the wettest
    /// cohesion at S = 0.74).
    #[schemars(extend("exclusiveMinimum" = 2))]
    pub suction_n: Option<f32>,
    /// A moisture held fixed, the saturation S of the pores (granular only)
    ///
    /// For damp sand without `[solid.porous]`: S sets the wet cohesion
    /// (`wet_cohesion`) as the absorbed water would, but nothing flows and
    /// there is no pore pressure. 0 to 1; with `[solid.porous]` S comes
    /// from the absorbed phases instead (an error here).
    #[schemars(range(min = 0, max = 1))]
    pub saturation: Option<f32>,
    /// Which walls are frictionless for this solid (granular only)
    ///
    /// false (default): the walls hold the grains without slip, so their
    /// friction is the material's own (a rough base); true: free slip on
    /// every wall (smooth, e.g. glass, walls); a list of axes, e.g.
    /// `["z"]`: free slip on the walls facing those axes only (the smooth
    /// side walls of a channel with a rough floor). Walls are taken to face
    /// the coordinate axes; a wall particle behind walls of which one does
    /// not slip (an edge of a smooth and a rough wall) holds without slip.
    pub wall_slip: Option<WallSlipFile>,
    /// The stress the solid starts with (granular only)
    ///
    /// `"zero"` (default): released from no stress, as if its weight were
    /// switched on at the start; it settles, ringing in its elastic modes
    /// (a 0.3 m column at d = 1 cm for about 8 s). `"lithostatic"`: at rest
    /// under its own weight, as sand behind a gate: vertical stress rho g
    /// depth below the body's own top (the highest particle of its column
    /// along gravity, + d/2) and (1 - sin phi) of it sideways (Jaky's K0).
    pub initial_stress: Option<InitialStress>,
}

/// `wall_slip`: every wall, none, or the walls facing some axes.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(untagged)]
pub(super) enum WallSlipFile {
    /// true: free slip on every wall; false: on none.
    All(bool),
    /// Free slip on the walls facing these axes ("x", "y", "z").
    Axes(Vec<String>),
}

/// `fixed = { box = .. }`: the kinematic part of a solid.
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct FixedFile {
    /// The box of the fixed particles
    pub r#box: Option<BoxFile>,
    /// The sphere of the fixed particles
    pub sphere: Option<SphereFile>,
    /// The cylinder of the fixed particles
    pub cylinder: Option<CylinderFile>,
    /// The closed mesh of the fixed particles
    pub mesh: Option<MeshFile>,
}

/// `[solid.porous]`: a porous solid (P §4, PHYSICS.md §4.2, §7).
#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub(super) struct PorousFile {
    /// The porosity e
    ///
    /// The saturated absorbed volume ratio sum_k phi_sk.
    #[schemars(extend("exclusiveMinimum" = 0, "maximum" = 1))]
    pub porosity: f32,
    /// The rest pore pressure p0 in Pa
    ///
    /// p_0 of P-Eq. 9.
    #[schemars(extend("exclusiveMinimum" = 0))]
    pub rest_pore_pressure: f32,
    /// The Biot modulus B in Pa
    ///
    /// B of P-Eq. 9 ("Biot's ratio constant"); default `rest_pore_pressure`.
    #[schemars(range(min = 0))]
    pub biot_modulus: Option<f32>,
    /// The pore stress factor eta
    ///
    /// eta of P-Eq. 5: the pore stress -eta p^pore I (swelling).
    #[serde(default)]
    #[schemars(range(min = 0))]
    pub swelling: f32,
    /// The capillary strength psi in m^2/s^2
    ///
    /// psi of P-Eq. 14.
    #[serde(default)]
    #[schemars(range(min = 0))]
    pub capillarity: f32,
    /// The absorption ratio K
    ///
    /// K of P-Eq. 13.
    #[serde(default = "one")]
    #[schemars(range(min = 0))]
    pub absorption: f32,
    /// Whether wet particles gain the absorbed mass
    ///
    /// As in the paper's Example 3.
    #[serde(default)]
    pub gains_mass: bool,
    /// How each phase is absorbed
    ///
    /// One table per absorbed phase, by name; a phase not listed is not absorbed.
    #[serde(default)]
    pub phase: BTreeMap<String, PorousPhase>,
}

/// The JSON Schema (draft 7) of scene files, as `porosph schema` prints it
/// and `docs/scene.schema.json` keeps it.
pub fn schema() -> Value {
    let mut schema = SchemaSettings::draft07().into_generator().into_root_schema_for::<SceneFile>().to_value();
    tidy(&mut schema);
    schema
}

/// [`schema`] as pretty-printed JSON with a final newline: the text of
/// `porosph schema` and of `docs/scene.schema.json`.
pub fn schema_text() -> String {
    // A JSON value always serializes.
    let mut text = serde_json::to_string_pretty(&schema()).unwrap_or_default();
    text.push('\n');
    text
}

/// Tidies what schemars gives for scene files: TOML has no null, so an
/// `Option` field is absent or has a value (the `null` alternatives are
/// removed; a lone `$ref` left is wrapped in `allOf`, as draft 7 ignores
/// keywords beside a `$ref`), and the defaults of `f32` fields are written
/// as the decimals of the file (0.001, not 0.0010000000474974513).
fn tidy(v: &mut Value) {
    match v {
        Value::Object(map) => {
            if let Some(Value::Array(types)) = map.get_mut("type") {
                types.retain(|t| t != "null");
                if types.len() == 1 {
                    let t = types.remove(0);
                    map.insert("type".to_string(), t);
                }
            }
            if let Some(Value::Array(any)) = map.get("anyOf") {
                let rest: Vec<Value> =
                    any.iter().filter(|s| s.get("type") != Some(&Value::from("null"))).cloned().collect();
                if let [one] = rest.as_slice() {
                    map.remove("anyOf");
                    if one.get("$ref").is_some() {
                        map.insert("allOf".to_string(), Value::Array(vec![one.clone()]));
                    } else if let Value::Object(inner) = one {
                        for (k, x) in inner {
                            map.entry(k.clone()).or_insert_with(|| x.clone());
                        }
                    }
                }
            }
            let float = |s: Option<&Value>| s.and_then(|s| s.get("format")) == Some(&Value::from("float"));
            let (scalar, items) = (float(Some(&*v)), float(v.get("items")));
            if let Some(d) = v.get_mut("default") {
                match d {
                    Value::Number(_) if scalar => *d = f32_decimal(d),
                    Value::Array(xs) if items => xs.iter_mut().for_each(|x| *x = f32_decimal(x)),
                    _ => {}
                }
            }
            if let Value::Object(map) = v {
                map.values_mut().for_each(tidy);
            }
        }
        Value::Array(items) => items.iter_mut().for_each(tidy),
        _ => {}
    }
}

/// A number that holds an `f32`, as the shortest decimal of that `f32`.
fn f32_decimal(x: &Value) -> Value {
    let Some(f) = x.as_f64() else { return x.clone() };
    format!("{}", f as f32).parse::<f64>().map_or_else(|_| x.clone(), Value::from)
}
