//! "A resumed run is the same run": N steps, a checkpoint, and M more steps
//! from the loaded checkpoint give bitwise the state of N + M steps without
//! stopping (CPU), in every registered array of both stores, time and dt.
//! Checked for a two-phase scene, through the library (resuming on another
//! thread count) and through the CLI, and for a floating elastic block and a
//! soaking porous cube through the library (fluid, walls and solids).

mod common;

use common::{assert_same_bits, floating_block, solid_bits, store_bits, TempDir, POROUS_SOAK, TWO_PHASE};
use porosph::io::checkpoint::{
    load_checkpoint, phase_volumes, read_checkpoint, read_checkpoint_with, write_checkpoint, ReadMethod, RunInfo,
};
use porosph::pipeline::Simulation;
use std::fs;
use std::path::Path;
use std::process::Command;

fn run_info() -> RunInfo {
    RunInfo {
        frames_written: 3,
        next_frame_time: 0.125,
        frame_every: 0.01,
        stop_time: Some(1.0),
        stop_step: None,
        checkpoint_every: "10steps".to_string(),
        keep: 3,
        compress: false,
    }
}

fn steps(sim: &mut Simulation, n: u64) {
    for _ in 0..n {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn resumed_run_is_bitwise_the_uninterrupted_run() {
    let (n, m) = (30, 30);
    let dir = TempDir::new("restart-bitwise");
    let ckpt = dir.path("ckpt.h5");
    common::with_threads(2, || {
        let mut straight = Simulation::new(common::scene_text(TWO_PHASE));
        steps(&mut straight, n + m);

        let mut first = Simulation::new(common::scene_text(TWO_PHASE));
        steps(&mut first, n);
        write_checkpoint(&ckpt, &first, &run_info(), None).unwrap_or_else(|e| panic!("{e}"));
        drop(first);
        // Resumed on one thread: neither the restart nor the thread count
        // may change what is computed.
        let resumed = common::with_threads(1, || {
            let (mut resumed, run) = load_checkpoint(&ckpt).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(run, run_info());
            steps(&mut resumed, m);
            resumed
        });

        println!(
            "{} fluid + {} wall particles, {} phases, t = {} s after {} steps",
            straight.fluid.len(),
            straight.walls.len(),
            straight.scene.phases.len(),
            straight.time,
            straight.step
        );
        assert_eq!(resumed.step, straight.step);
        assert_eq!(resumed.time.to_bits(), straight.time.to_bits());
        assert_eq!(resumed.dt.to_bits(), straight.dt.to_bits());
        assert_same_bits(&store_bits(&resumed.fluid, &resumed.walls), &store_bits(&straight.fluid, &straight.walls));
        // The state moved: this is not a comparison of two resting states.
        let start = Simulation::new(common::scene_text(TWO_PHASE));
        assert_ne!(store_bits(&start.fluid, &start.walls), store_bits(&straight.fluid, &straight.walls));
    });
}

/// The same with an elastic solid in the fluid: the solid store (positions,
/// velocities, rotations, pressures) is saved, and the elastic model's rest
/// data is rebuilt from the rest positions exactly.
#[test]
fn resumed_run_with_a_solid_is_bitwise_the_uninterrupted_run() {
    let (n, m) = (20, 20);
    let dir = TempDir::new("restart-solid");
    let ckpt = dir.path("ckpt.h5");
    common::with_threads(2, || {
        let mut straight = Simulation::new(common::scene_text(&floating_block()));
        steps(&mut straight, n + m);
        let mut first = Simulation::new(common::scene_text(&floating_block()));
        steps(&mut first, n);
        write_checkpoint(&ckpt, &first, &run_info(), None).unwrap_or_else(|e| panic!("{e}"));
        drop(first);
        let resumed = common::with_threads(1, || {
            let (mut resumed, _) = load_checkpoint(&ckpt).unwrap_or_else(|e| panic!("{e}"));
            steps(&mut resumed, m);
            resumed
        });
        println!("{} fluid + {} solid particles, t = {} s", straight.fluid.len(), straight.solids.len(), straight.time);
        assert!(!straight.solids.is_empty() && straight.last.cg_iterations > 0);
        assert_eq!(resumed.dt.to_bits(), straight.dt.to_bits());
        assert_same_bits(&store_bits(&resumed.fluid, &resumed.walls), &store_bits(&straight.fluid, &straight.walls));
        assert_same_bits(&solid_bits(&resumed.solids), &solid_bits(&straight.solids));
        let start = Simulation::new(common::scene_text(&floating_block()));
        assert_ne!(solid_bits(&start.solids), solid_bits(&straight.solids));
    });
}

/// The same with a porous solid while it absorbs: the inner fractions beta
/// of the fluid and the solid's saturation and pore pressure are saved, and
/// every registered array of fluid, walls and solids continues bit for bit.
#[test]
fn resumed_run_with_a_soaking_porous_solid_is_bitwise_the_uninterrupted_run() {
    let (n, m) = (20, 20);
    let dir = TempDir::new("restart-porous");
    let ckpt = dir.path("ckpt.h5");
    common::with_threads(2, || {
        let mut straight = Simulation::new(common::scene_text(POROUS_SOAK));
        steps(&mut straight, n + m);
        let mut first = Simulation::new(common::scene_text(POROUS_SOAK));
        steps(&mut first, n);
        // Absorption is under way at the checkpoint.
        let inner: f64 = first.phase_volumes_split().1.iter().sum();
        let wet_fluid = first.fluid.beta[0].iter().filter(|&&b| b > 0.0).count();
        let wet_solid = first.solids.saturation.iter().filter(|&&s| s > 0.0).count();
        println!(
            "{} fluid + {} solid particles; at the checkpoint (step {n}) inner volume {inner:.3e} m^3, {wet_fluid} fluid \
             particles with beta > 0, {wet_solid} solid particles with saturation > 0",
            first.fluid.len(),
            first.solids.len()
        );
        assert!(inner > 0.0 && wet_fluid > 0 && wet_solid > 0);
        write_checkpoint(&ckpt, &first, &run_info(), None).unwrap_or_else(|e| panic!("{e}"));
        drop(first);
        let resumed = common::with_threads(1, || {
            let (mut resumed, _) = load_checkpoint(&ckpt).unwrap_or_else(|e| panic!("{e}"));
            steps(&mut resumed, m);
            resumed
        });
        assert_eq!(resumed.step, straight.step);
        assert_eq!(resumed.time.to_bits(), straight.time.to_bits());
        assert_eq!(resumed.dt.to_bits(), straight.dt.to_bits());
        assert_same_bits(&store_bits(&resumed.fluid, &resumed.walls), &store_bits(&straight.fluid, &straight.walls));
        assert_same_bits(&solid_bits(&resumed.solids), &solid_bits(&straight.solids));
        // The soak went on after the checkpoint.
        let inner_end: f64 = straight.phase_volumes_split().1.iter().sum();
        assert!(inner_end > inner, "inner volume {inner_end:.3e} after {} steps, {inner:.3e} after {n}", n + m);
    });
}

#[test]
fn round_trip_keeps_every_array_and_scalar_with_either_reader() {
    let dir = TempDir::new("restart-roundtrip");
    let path = dir.path("ckpt.h5");
    let mut sim = Simulation::new(common::scene_text(TWO_PHASE));
    steps(&mut sim, 5);
    write_checkpoint(&path, &sim, &run_info(), None).unwrap_or_else(|e| panic!("{e}"));
    assert!(!dir.path(".ckpt.h5.tmp").exists(), "temporary file left");
    for method in [ReadMethod::Hdf5, ReadMethod::Mmap] {
        let c = read_checkpoint_with(&path, method).unwrap_or_else(|e| panic!("{e}"));
        assert_same_bits(&store_bits(&c.state.fluid, &c.state.walls), &store_bits(&sim.fluid, &sim.walls));
        assert_eq!(c.state.scene, sim.scene);
        assert_eq!(c.state.time.to_bits(), sim.time.to_bits());
        assert_eq!(c.state.dt.to_bits(), sim.dt.to_bits());
        assert_eq!(c.state.step, 5);
        assert_eq!(c.failure, None);
        assert_eq!(c.format_version, 1);
        // Outer volume per phase = h^3 sum alpha_k (P §6.1, with the low
        // parts of the fractions): water in the first block and 30 % of
        // the second, oil 70 % of the second.
        let v = phase_volumes(&c.state).0;
        let h3 = f64::from(0.02f32).powi(3);
        assert_eq!(v.len(), 2);
        for (k, vk) in v.iter().enumerate() {
            let (hi, lo) = (&sim.fluid.alpha[k], &sim.fluid.alpha_lo[k]);
            let alpha: f64 = hi.iter().zip(lo).map(|(&a, &l)| f64::from(a) + f64::from(l)).sum();
            assert!((vk - h3 * alpha).abs() <= 1e-12 * vk, "phase {k}: {vk}");
        }
        // The mixture block (0.1 x 0.2 x 0.2 m, 5 x 10 x 10 particles) holds
        // 0.7 x 500 h^3 of oil.
        assert!((v[1] - 0.7 * 500.0 * h3).abs() < 1e-9, "oil {}", v[1]);
    }
}

/// The `porosph` binary with `args`, returning (success, stderr).
fn porosph(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_porosph")).args(args).output().expect("run porosph");
    (out.status.success(), String::from_utf8_lossy(&out.stderr).into_owned())
}

fn stats_steps(path: &Path) -> Vec<u64> {
    fs::read_to_string(path)
        .expect("stats.csv")
        .lines()
        .skip(1)
        .map(|l| l.split(',').next().unwrap_or("").parse().expect("step"))
        .collect()
}

#[test]
fn cli_resume_continues_the_run_in_its_directory() {
    let dir = TempDir::new("restart-cli");
    let scene = dir.path("two_phase.toml");
    fs::write(&scene, TWO_PHASE).expect("write scene");
    let out = dir.path("run");
    let out_s = out.to_str().expect("utf-8 path");
    let (ok, err) = porosph(&[
        "run",
        scene.to_str().expect("utf-8 path"),
        "--out",
        out_s,
        "--steps",
        "24",
        "--checkpoint-every",
        "8steps",
        "--keep",
        "2",
        "--quiet",
    ]);
    assert!(ok, "{err}");
    let ckpts = out.join("checkpoints");
    // keep 2: steps 16 and 24 remain.
    let mut names: Vec<String> = fs::read_dir(&ckpts)
        .expect("checkpoints/")
        .map(|e| e.expect("entry").file_name().into_string().expect("name"))
        .collect();
    names.sort();
    assert_eq!(names, ["ckpt_00000016.h5", "ckpt_00000024.h5"]);
    let straight = read_checkpoint(&ckpts.join("ckpt_00000024.h5")).unwrap_or_else(|e| panic!("{e}"));
    let series = fs::read_to_string(out.join("frames/frames.vtkhdf.series")).expect("series");
    let frames_before: Vec<String> = fs::read_dir(out.join("frames"))
        .expect("frames/")
        .map(|e| e.expect("entry").file_name().into_string().expect("name"))
        .collect();
    assert_eq!(stats_steps(&out.join("stats.csv")), (1..=24).collect::<Vec<_>>());

    // Resume from step 16 into the same directory (the default) and run to
    // where the saved run was going to stop (step 24).
    fs::rename(ckpts.join("ckpt_00000024.h5"), dir.path("straight_24.h5")).expect("move");
    let (ok, err) = porosph(&["resume", ckpts.join("ckpt_00000016.h5").to_str().expect("utf-8 path"), "--quiet"]);
    assert!(ok, "{err}");
    let resumed = read_checkpoint(&ckpts.join("ckpt_00000024.h5")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(resumed.state.step, 24);
    assert_eq!(resumed.state.time.to_bits(), straight.state.time.to_bits());
    assert_eq!(resumed.state.dt.to_bits(), straight.state.dt.to_bits());
    assert_eq!(resumed.run, straight.run);
    assert_same_bits(
        &store_bits(&resumed.state.fluid, &resumed.state.walls),
        &store_bits(&straight.state.fluid, &straight.state.walls),
    );
    // stats.csv: one row per step, continued; frames: same names, same times.
    assert_eq!(stats_steps(&out.join("stats.csv")), (1..=24).collect::<Vec<_>>());
    assert_eq!(fs::read_to_string(out.join("frames/frames.vtkhdf.series")).expect("series"), series);
    let mut frames_after: Vec<String> = fs::read_dir(out.join("frames"))
        .expect("frames/")
        .map(|e| e.expect("entry").file_name().into_string().expect("name"))
        .collect();
    frames_after.sort();
    let mut frames_before = frames_before;
    frames_before.sort();
    assert_eq!(frames_after, frames_before);

    // Into another directory, for 3 more steps: frames continue numbering.
    let other = dir.path("other");
    let (ok, err) = porosph(&[
        "resume",
        ckpts.join("ckpt_00000024.h5").to_str().expect("utf-8 path"),
        "--out",
        other.to_str().expect("utf-8 path"),
        "--steps",
        "5",
        "--quiet",
    ]);
    assert!(ok, "{err}");
    assert_eq!(stats_steps(&other.join("stats.csv")), (25..=29).collect::<Vec<_>>());
    let listed = fs::read_to_string(other.join("frames/frames.vtkhdf.series")).expect("series");
    assert!(listed.contains(".vtkhdf") && !listed.contains("frame_00000.vtkhdf"), "numbering restarted: {listed}");
}
