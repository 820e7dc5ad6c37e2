//! The checkpoint side of the command line: a NaN mid-run stops the run
//! with a diagnostic checkpoint and a non-zero exit; `inspect` tells frames
//! from checkpoints and reports broken checksums; bad arguments and bad
//! files are errors that name what is wrong, never panics.

mod common;

use common::{porosph, s, text, TempDir, TWO_PHASE};
use porosph::io::checkpoint::read_checkpoint;
use std::fs;

/// The two-phase scene as a file in `dir`.
fn scene_file(dir: &TempDir) -> std::path::PathBuf {
    let p = dir.path("two_phase.toml");
    fs::write(&p, TWO_PHASE).expect("write scene");
    p
}

#[test]
fn nan_mid_run_stops_with_a_diagnostic_checkpoint() {
    let dir = TempDir::new("cli-nan");
    let scene = scene_file(&dir);
    for (name, extra) in [("with", &["--checkpoint-every", "2steps"][..]), ("without", &[][..])] {
        let out = dir.path(name);
        let mut args =
            vec!["run", s(&scene), "--out", s(&out), "--steps", "20", "--quiet", "--inject-nan-at-step", "5"];
        args.extend(extra);
        let r = porosph(&args);
        let err = text(&r.stderr);
        println!("{err}");
        assert!(!r.status.success(), "a NaN run must exit non-zero");
        assert!(!err.contains("panicked"), "{err}");
        // The step that failed and the particle.
        assert!(err.contains("step 6 "), "{err}");
        assert!(err.contains("particle id "), "{err}");
        let diag = out.join("checkpoints/ckpt_00000006_failed.h5");
        assert!(err.contains(s(&diag)), "{err}");
        let c = read_checkpoint(&diag).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(c.state.step, 6);
        let reason = c.failure.expect("marked as diagnostic");
        assert!(reason.contains("NaN"), "{reason}");
        assert!(c.state.fluid.ux.iter().any(|u| u.is_nan()));
        // Inspect shows it as a diagnostic checkpoint; resume refuses it.
        let i = porosph(&["inspect", s(&diag)]);
        assert!(i.status.success(), "{}", text(&i.stderr));
        assert!(text(&i.stdout).contains("diagnostic: written when the run failed"));
        let r = porosph(&["resume", s(&diag), "--quiet"]);
        assert!(!r.status.success());
        assert!(text(&r.stderr).contains("a diagnostic checkpoint"));
    }
    // With a schedule, the checkpoints before the failure are still there.
    assert!(dir.path("with/checkpoints/ckpt_00000004.h5").exists());
}

#[test]
fn inspect_tells_frames_from_checkpoints_and_reports_damage() {
    let dir = TempDir::new("cli-inspect");
    let scene = scene_file(&dir);
    let out = dir.path("run");
    let r = porosph(&["run", s(&scene), "--out", s(&out), "--steps", "3", "--checkpoint-every", "3steps", "--quiet"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let frame = porosph(&["inspect", s(&out.join("frames/frame_00000.vtkhdf"))]);
    assert!(frame.status.success());
    assert!(text(&frame.stdout).contains("points:"));
    let ckpt = out.join("checkpoints/ckpt_00000003.h5");
    let i = porosph(&["inspect", s(&ckpt)]);
    let report = text(&i.stdout);
    println!("{report}");
    assert!(i.status.success(), "{}", text(&i.stderr));
    for want in [
        "porosph checkpoint, format version 1",
        "step:       3",
        "water",
        "oil",
        "m^3",
        // scene + 11 fluid + 8 wall + 22 solid arrays (empty without solids).
        "checksums:  all 51 datasets hold",
    ] {
        assert!(report.contains(want), "missing {want:?}");
    }
    // One flipped byte in /fluid/uy: inspect names it and exits 1.
    let off = hdf5::File::open(&ckpt)
        .and_then(|f| f.dataset("fluid/uy"))
        .map(|d| d.offset().expect("contiguous") as usize)
        .expect("offset");
    let mut bytes = fs::read(&ckpt).expect("read");
    bytes[off + 5] ^= 1;
    fs::write(&ckpt, &bytes).expect("write");
    let i = porosph(&["inspect", s(&ckpt)]);
    assert!(!i.status.success());
    assert!(text(&i.stdout).contains("dataset /fluid/uy is corrupt"));
    assert!(text(&i.stderr).contains("checksums do not hold"));
    // Resuming it is refused with the same reason.
    let r = porosph(&["resume", s(&ckpt), "--quiet"]);
    assert!(!r.status.success());
    assert!(text(&r.stderr).contains("dataset /fluid/uy is corrupt"));
    // Neither kind of file.
    let junk = dir.path("junk.h5");
    fs::write(&junk, b"junk").expect("write");
    let i = porosph(&["inspect", s(&junk)]);
    assert!(!i.status.success());
    assert!(text(&i.stderr).contains("not a readable HDF5 file"));
    assert!(!text(&i.stderr).contains("panicked"));
}

#[test]
fn unwritable_checkpoint_directory_fails_before_running() {
    let dir = TempDir::new("cli-unwritable");
    let scene = scene_file(&dir);
    let out = dir.path("run");
    fs::create_dir_all(&out).expect("mkdir");
    fs::write(out.join("checkpoints"), b"").expect("a file in the way");
    // A file where porosph makes a folder: not porosph's, so even
    // --overwrite leaves it and the run is refused before it starts.
    for extra in [&[][..], &["--overwrite"][..]] {
        let mut args = vec!["run", s(&scene), "--out", s(&out), "--steps", "3", "--checkpoint-every", "1steps"];
        args.extend(extra);
        let r = porosph(&args);
        let err = text(&r.stderr);
        assert!(!r.status.success());
        assert!(err.contains("holds checkpoints, which porosph did not write"), "{err}");
        assert!(!out.join("stats.csv").exists(), "the run started");
    }
}

#[test]
fn bad_checkpoint_arguments_are_rejected() {
    for (args, want) in [
        (&["run", "--checkpoint-every", "0"][..], "positive number of seconds"),
        (&["run", "--checkpoint-every", "12 parsecs"][..], "not a checkpoint interval"),
        (&["run", "--checkpoint-every", "0steps"][..], "at least 1"),
        (&["run", "--checkpoint-every", "1", "--keep", "0"][..], "--keep must be at least 1"),
        (&["resume", "/nonexistent/ckpt.h5"][..], "/nonexistent/ckpt.h5: cannot read"),
    ] {
        let r = porosph(args);
        let err = text(&r.stderr);
        assert!(!r.status.success(), "{args:?} accepted");
        assert!(err.contains(want), "{args:?}: {err}");
    }
}

#[test]
fn checkpoints_every_simulated_interval() {
    let dir = TempDir::new("cli-seconds");
    let scene = scene_file(&dir);
    let out = dir.path("run");
    // dt = 0.002 s (max_dt; the CFL step is longer at these speeds): the
    // first steps at or past 0.01, 0.02, 0.03 s are steps 5, 10, 15.
    let r = porosph(&[
        "run",
        s(&scene),
        "--out",
        s(&out),
        "--until",
        "0.032",
        "--checkpoint-every",
        "0.01s",
        "--keep",
        "5",
        "--quiet",
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let mut names: Vec<String> = fs::read_dir(out.join("checkpoints"))
        .expect("checkpoints/")
        .map(|e| e.expect("entry").file_name().into_string().expect("name"))
        .collect();
    names.sort();
    assert_eq!(names, ["ckpt_00000005.h5", "ckpt_00000010.h5", "ckpt_00000015.h5"]);
    let c = read_checkpoint(&out.join("checkpoints/ckpt_00000015.h5")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(c.run.checkpoint_every, "0.01s");
    assert_eq!(c.run.stop_time, Some(0.032));
}
