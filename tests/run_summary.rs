//! The end of a run (issue 36, item 7): a summary that says how far the
//! run went, what held its time step, how fast it ran (fluid and solid
//! particles) and how each phase's mass changed; `resume` lists the solids
//! as `run` does, and a mesh scene resumes, and its `OUT/scene.toml`
//! reruns, from another directory.

mod common;

use common::{TempDir, TWO_PHASE};
use std::fs;
use std::path::Path;
use std::process::{Command, Output};

fn porosph(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_porosph")).current_dir(dir).args(args).output().expect("run porosph")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

#[test]
fn the_summary_says_what_held_dt_how_fast_and_the_mass_change() {
    let dir = TempDir::new("summary");
    // The mixture moves at 8 m/s: lambda h / |u| = 0.4 * 0.02 / 8 = 1 ms,
    // under max_dt = 2 ms, so CFL holds dt at first.
    let scene = TWO_PHASE.replace(
        "fractions = { water = 0.3, oil = 0.7 }",
        "fractions = { water = 0.3, oil = 0.7 }\nvelocity = [8.0, 0.0, 0.0]",
    );
    fs::write(dir.path("s.toml"), scene).expect("write scene");
    let r = porosph(&dir.0, &["run", "s.toml", "--out", "o", "--steps", "6", "--checkpoint-every", "3steps"]);
    let err = text(&r.stderr);
    println!("{err}");
    assert!(r.status.success(), "{err}");
    assert!(err.contains("porosph: done: t = 0.0000 to 0.0"), "{err}");
    assert!(err.contains("in 6 steps,") && err.contains("2 checkpoints"), "{err}");
    let line = |key: &str| err.lines().find(|l| l.contains(key)).unwrap_or_else(|| panic!("no {key:?} in\n{err}"));
    let dt = line("dt: mean");
    // Gravity speeds it up: a little less than 1 ms.
    assert!(dt.contains("least 0.9") && dt.ends_with(" ms; steps held by CFL 6"), "{dt}");
    let speed = line("wall per simulated s");
    assert!(speed.contains("M particle-steps/s (") && speed.contains(" fluid + 0 solid particles)"), "{speed}");
    assert!(line("pressure solve:").contains("iterations per step (mean), "));
    // The peak resident memory of the run's process: a plausibility bound
    // only, as the process has exited and its own record cannot be read
    // here (checked by hand against `/usr/bin/time -v`: the built-in
    // scene's line read 33.8 MB where it reported 32,996 kB).
    let mem = line("memory: peak ");
    let mb: f64 = mem.split("peak ").nth(1).and_then(|r| r.split(' ').next()).and_then(|v| v.parse().ok()).unwrap();
    assert!(mb > 1.0 && mb < 1000.0 && mem.contains(" B per fluid + solid particle)"), "{mem}");
    let mass = line("mass change over the run (relative): water ");
    assert!(mass.contains(", oil "), "{mass}");
}

/// The summary's pressure-solve line against the run's own stats.csv: the
/// steps whose solve ran to the sweep cap (here 3 sweeps, so that some
/// do) and the largest row compression any solve left, with its step,
/// are the count and the maximum of the file's `iterations` and
/// `largest_density_error` columns. (A solve that stops on its mean error
/// can leave single rows far more compressed than the mean's bound:
/// bench/RESULTS.md, "Example 1 at the paper's size with CFL 0.8".)
#[test]
fn the_summary_reports_capped_solves_and_the_largest_row_as_stats_csv_has_them() {
    let dir = TempDir::new("summary_rows");
    let scene = TWO_PHASE.replace("max_dt = 0.002", "max_dt = 0.002\nmax_iterations = 3");
    assert_ne!(scene, TWO_PHASE);
    fs::write(dir.path("s.toml"), scene).expect("write scene");
    let r = porosph(&dir.0, &["run", "s.toml", "--out", "o", "--steps", "12", "--threads", "2"]);
    let err = text(&r.stderr);
    assert!(r.status.success(), "{err}");
    let line = err.lines().find(|l| l.contains("pressure solve:")).unwrap_or_else(|| panic!("no solve line in\n{err}"));
    println!("{line}");
    let csv = fs::read_to_string(dir.path("o/stats.csv")).expect("stats.csv");
    let mut rows = csv.lines();
    let head: Vec<&str> = rows.next().expect("header").split(',').collect();
    let col = |name: &str| head.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no column {name}"));
    let (c_step, c_it, c_row) = (col("step"), col("iterations"), col("largest_density_error"));
    let (mut capped, mut largest, mut at) = (0u64, 0.0f64, 0u64);
    for row in rows {
        let v: Vec<&str> = row.split(',').collect();
        capped += u64::from(v[c_it].parse::<u32>().expect("iterations") >= 3);
        let e: f64 = v[c_row].parse().expect("largest_density_error");
        if e > largest {
            (largest, at) = (e, v[c_step].parse().expect("step"));
        }
    }
    assert!(capped > 0 && largest > 0.0, "the run shows nothing: {capped} capped, largest row {largest}");
    let cap = match capped {
        1 => "1 step at the cap of 3".to_string(),
        n => format!("{n} steps at the cap of 3"),
    };
    assert!(line.contains(&cap), "{line}: expected {cap:?}");
    let expected =
        format!("largest row compression left {:.2} % (step {at}; the mean's bound 0.10 %)", 100.0 * largest);
    assert!(line.ends_with(&expected), "{line}: expected {expected:?}");
}

/// A closed cube [0, 0.1]^3, as OBJ.
const CUBE: &str = "v 0 0 0\nv 0.1 0 0\nv 0 0.1 0\nv 0.1 0.1 0\nv 0 0 0.1\nv 0.1 0 0.1\nv 0 0.1 0.1\nv 0.1 0.1 0.1\n\
                    f 1 3 2\nf 2 3 4\nf 5 6 7\nf 6 8 7\nf 1 2 5\nf 2 6 5\nf 3 7 4\nf 4 7 8\nf 1 5 3\nf 3 5 7\n\
                    f 2 4 6\nf 4 8 6\n";

/// Water around an elastic cube read from `meshes/cube.obj`.
const MESH_SCENE: &str = r#"
[simulation]
particle_spacing = 0.02
end_time = 1.0
max_dt = 0.002
[[phase]]
name = "water"
density = 1000.0
viscosity = 0.01
[[wall]]
box = { min = [0.0, 0.0, 0.0], max = [0.3, 0.3, 0.2] }
container = true
open_top = true
[[fluid]]
box = { min = [0.0, 0.0, 0.0], max = [0.3, 0.1, 0.2] }
fractions = { water = 1.0 }
[[solid]]
name = "cube"
mesh = { path = "meshes/cube.obj", translate = [0.1, 0.14, 0.04] }  # kept as written
density = 600.0
shear_modulus = 1e5
lame_lambda = 0.0
"#;

#[test]
fn a_mesh_scene_resumes_and_reruns_from_another_directory() {
    let dir = TempDir::new("summary-mesh");
    let (a, b) = (dir.path("a"), dir.path("b"));
    fs::create_dir_all(a.join("meshes")).expect("mkdir");
    fs::create_dir_all(&b).expect("mkdir");
    fs::write(a.join("meshes/cube.obj"), CUBE).expect("write mesh");
    fs::write(a.join("scene.toml"), MESH_SCENE).expect("write scene");
    let r = porosph(&a, &["run", "scene.toml", "--out", "../o", "--steps", "4", "--checkpoint-every", "2steps"]);
    let err = text(&r.stderr);
    assert!(r.status.success(), "{err}");
    let banner = err.lines().next().expect("banner");
    assert!(banner.contains(" fluid + 125 solid + "), "{banner}");
    // OUT/scene.toml names the mesh by its absolute path, the rest as written.
    let copy = fs::read_to_string(dir.path("o/scene.toml")).expect("scene copy");
    let abs = a.join("meshes/cube.obj").canonicalize().expect("mesh");
    assert_eq!(copy, MESH_SCENE.replace("\"meshes/cube.obj\"", &format!("\"{}\"", abs.display())));

    // From b, where meshes/cube.obj does not exist.
    let r = porosph(&b, &["resume", "../o/checkpoints/ckpt_00000002.h5"]);
    let err = text(&r.stderr);
    println!("{err}");
    assert!(r.status.success(), "{err}");
    assert!(err.contains("at step 2 (t = ") && err.contains(" fluid + 125 solid + "), "{err}");
    assert!(err.contains("steps held by max_dt 1, the checkpoint's dt 1"), "{err}");
    assert!(err.contains(" fluid + 125 solid particles)"), "{err}");
    let r = porosph(&b, &["run", "../o/scene.toml", "--out", "o2", "--steps", "1", "--quiet"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
}
