//! Helpers shared by the integration tests.
#![allow(dead_code)]

use porosph::pipeline::Simulation;
use porosph::scene::Scene;
use std::path::PathBuf;

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
