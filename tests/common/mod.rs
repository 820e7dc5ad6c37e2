//! Helpers shared by the integration tests.
#![allow(dead_code)]

use porosph::pipeline::Simulation;
use porosph::scene::Scene;
use std::path::PathBuf;

/// Runs the `porosph` binary with `args`.
pub fn porosph(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_porosph")).args(args).output().expect("run porosph")
}

/// Bytes (a process's output) as text.
pub fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A path as a command-line argument.
pub fn s(p: &std::path::Path) -> &str {
    p.to_str().expect("utf-8 path")
}

/// A scene from `scenes/` in the repository.
pub fn scene_file(name: &str) -> Scene {
    let p = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("scenes").join(name);
    Scene::from_file(&p).unwrap_or_else(|e| panic!("{e}"))
}

/// A scene from TOML text.
pub fn scene_text(text: &str) -> Scene {
    Scene::from_toml_str(text, "<test>").unwrap_or_else(|e| panic!("{e}"))
}

/// Runs `f` on a rayon pool of `threads` threads.
pub fn with_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool").install(f)
}

/// Steps until simulated time `t`, panicking with the step error if any.
pub fn run_until(sim: &mut Simulation, t: f64) {
    while sim.time < t - 1e-9 {
        if let Err(e) = sim.step() {
            panic!("{e}");
        }
    }
}

/// A fresh, empty directory for one test, removed when dropped.
pub struct TempDir(pub PathBuf);

impl TempDir {
    pub fn new(test: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("porosph-{}-{test}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("create temp dir");
        Self(dir)
    }

    pub fn path(&self, name: &str) -> PathBuf {
        self.0.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Every registered array of both stores as raw bits, by `store/name`
/// (per-phase arrays one entry per phase).
pub fn store_bits(fluid: &porosph::store::FluidStore, walls: &porosph::store::WallStore) -> Vec<(String, Vec<u32>)> {
    use porosph::store::Column;
    let mut out = Vec::new();
    let mut add = |store: &str, name: &str, c: Column<'_>| match c {
        Column::F32(v) => out.push((format!("{store}/{name}"), v.iter().map(|x| x.to_bits()).collect())),
        Column::U32(v) => out.push((format!("{store}/{name}"), v.to_vec())),
        Column::PerPhase(vs) => {
            for (k, v) in vs.iter().enumerate() {
                out.push((format!("{store}/{name}[{k}]"), v.iter().map(|x| x.to_bits()).collect()));
            }
        }
    };
    fluid.for_each_column(|n, _, c| add("fluid", n, c));
    walls.for_each_column(|n, _, c| add("walls", n, c));
    out
}

/// Every registered array of a solid store as bit patterns.
pub fn solid_bits(solids: &porosph::store::SolidStore) -> Vec<(String, Vec<u32>)> {
    use porosph::store::Column;
    let mut out = Vec::new();
    solids.for_each_column(|name, _, c| match c {
        Column::F32(v) => out.push((format!("solids/{name}"), v.iter().map(|x| x.to_bits()).collect())),
        Column::U32(v) => out.push((format!("solids/{name}"), v.to_vec())),
        Column::PerPhase(_) => unreachable!("solids have no per-phase arrays"),
    });
    out
}

/// A closed tank (inside [0, tank]) filled with water of `viscosity` up to
/// `water`, holding an elastic block [`lo`, `hi`] of `density` (mu = 1e5 Pa,
/// lambda = `lambda`), at particle spacing `d`.
pub struct TankWithBlock {
    pub d: f32,
    pub tank: [f32; 3],
    pub water: f32,
    pub viscosity: f32,
    pub lo: [f32; 3],
    pub hi: [f32; 3],
    pub density: f32,
    pub lambda: f32,
}

impl TankWithBlock {
    /// The scene text.
    pub fn text(&self) -> String {
        let [tx, ty, tz] = self.tank;
        let ([ax, ay, az], [bx, by, bz]) = (self.lo, self.hi);
        format!(
            r#"
[simulation]
particle_spacing = {}
end_time = 10.0
max_dt = 0.003
[[phase]]
name = "water"
density = 1000.0
viscosity = {}
[[wall]]
box = {{ min = [0.0, 0.0, 0.0], max = [{tx}, {ty}, {tz}] }}
container = true
[[fluid]]
box = {{ min = [0.0, 0.0, 0.0], max = [{tx}, {}, {tz}] }}
fractions = {{ water = 1.0 }}
[[solid]]
name = "block"
box = {{ min = [{ax}, {ay}, {az}], max = [{bx}, {by}, {bz}] }}
density = {}
shear_modulus = 1e5
lame_lambda = {}
"#,
            self.d, self.viscosity, self.water, self.density, self.lambda
        )
    }
}

/// A small tank with a floating elastic block (fluid, walls and a solid).
pub fn floating_block() -> String {
    TankWithBlock {
        d: 0.01,
        tank: [0.3, 0.3, 0.06],
        water: 0.12,
        viscosity: 0.01,
        lo: [0.06, 0.09, 0.0],
        hi: [0.24, 0.17, 0.06],
        density: 600.0,
        lambda: 0.0,
    }
    .text()
}

/// Asserts that two states agree bit for bit in every registered array,
/// naming the first array and index that differ.
pub fn assert_same_bits(a: &[(String, Vec<u32>)], b: &[(String, Vec<u32>)]) {
    assert_eq!(a.len(), b.len(), "different sets of arrays");
    for ((na, va), (nb, vb)) in a.iter().zip(b) {
        assert_eq!(na, nb);
        assert_eq!(va.len(), vb.len(), "{na}: lengths differ");
        if let Some(i) = va.iter().zip(vb).position(|(x, y)| x != y) {
            panic!(
                "{na}[{i}] differs: {:#010x} vs {:#010x} ({} vs {})",
                va[i],
                vb[i],
                f32::from_bits(va[i]),
                f32::from_bits(vb[i])
            );
        }
    }
}

/// A small two-phase dam break (about 2000 fluid particles): water, and a
/// water-oil mixture beside it, in an open tank. Steps in milliseconds.
pub const TWO_PHASE: &str = r#"
[simulation]
particle_spacing = 0.02
end_time = 1.0
max_dt = 0.002
frame_interval = 0.01

[[phase]]
name = "water"
density = 1000.0
viscosity = 0.01

[[phase]]
name = "oil"
density = 800.0
viscosity = 0.05

[[fluid]]
box = { min = [0.0, 0.0, 0.0], max = [0.2, 0.3, 0.2] }
fractions = { water = 1.0 }

[[fluid]]
box = { min = [0.2, 0.0, 0.0], max = [0.3, 0.2, 0.2] }
fractions = { water = 0.3, oil = 0.7 }

[[wall]]
box = { min = [0.0, 0.0, 0.0], max = [0.6, 0.5, 0.2] }
container = true
open_top = true
"#;

/// A water tank with a fixed porous sponge (0.1 m cube) in it, which
/// soaks from the first steps: 2.4k fluid, 180 solid particles.
pub const POROUS_SOAK: &str = r#"
[simulation]
particle_spacing = 0.015
end_time = 1.0
max_dt = 0.002
frame_interval = 0.01

[[phase]]
name = "water"
density = 1000.0
viscosity = 1.0

[[wall]]
box = { min = [0.0, 0.0, 0.0], max = [0.3, 0.3, 0.1] }
container = true

[[fluid]]
box = { min = [0.0, 0.0, 0.0], max = [0.3, 0.15, 0.1] }
fractions = { water = 1.0 }

[[solid]]
name = "sponge"
box = { min = [0.1, 0.02, 0.0], max = [0.2, 0.12, 0.1] }
density = 600.0
shear_modulus = 2e4
lame_lambda = 1e4
fixed = { box = { min = [0.1, 0.02, 0.0], max = [0.2, 0.12, 0.1] } }

[solid.porous]
porosity = 0.6
rest_pore_pressure = 5e4
biot_modulus = 4.9e4
swelling = 7.5e-4
capillarity = 2.0
absorption = 1.0

[solid.porous.phase.water]
permeability = 1e-7
outer_pore_pressure = 2.5e4
"#;

/// A small dam break (1,800 fluid particles, h = 1 cm) in an open tank, the
/// CPU-GPU comparison scene of tests/gpu_dam_break.rs and gpu_wendland.rs.
pub const SMALL_DAM_BREAK: &str = r#"[simulation]
particle_spacing = 0.01
end_time = 1.0
max_dt = 0.002
frame_interval = 1.0
[[phase]]
name = "water"
density = 1000.0
viscosity = 0.01
[[fluid]]
box = { min = [0.0, 0.0, 0.0], max = [0.15, 0.2, 0.06] }
fractions = { water = 1.0 }
[[wall]]
box = { min = [0.0, 0.0, 0.0], max = [0.5, 0.3, 0.06] }
container = true
open_top = true
"#;
