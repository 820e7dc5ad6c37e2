//! A run owns its output directory (issue 36, item 1): `porosph run` into a
//! non-empty `--out` is refused with a message that names the directory,
//! says what is in it and what to do; `--overwrite` removes an earlier
//! run's files first, and never a file porosph did not write; `resume`
//! continues its own run, and its frame series lists exactly that run's
//! frames.

mod common;

use common::{porosph, s, text, TempDir, TWO_PHASE};
use std::fs;
use std::path::{Path, PathBuf};

fn scene_file(dir: &TempDir) -> PathBuf {
    let p = dir.path("two_phase.toml");
    fs::write(&p, TWO_PHASE).expect("write scene");
    p
}

/// The sorted names in `dir` (empty if it does not exist).
fn names(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = fs::read_dir(dir)
        .map(|rd| rd.map(|e| e.expect("entry").file_name().into_string().expect("name")).collect())
        .unwrap_or_default();
    v.sort();
    v
}

/// The frame names the series index lists.
fn series_names(out: &Path) -> Vec<String> {
    let text = fs::read_to_string(out.join("frames/frames.vtkhdf.series")).expect("series");
    let v: serde_json::Value = serde_json::from_str(&text).expect("json");
    v["files"].as_array().expect("files").iter().map(|e| e["name"].as_str().expect("name").to_string()).collect()
}

fn frames(n: usize) -> Vec<String> {
    (0..n).map(|i| format!("frame_{i:05}.vtkhdf")).collect()
}

#[test]
fn a_reused_out_is_refused_and_overwrite_removes_the_earlier_run() {
    let dir = TempDir::new("out-reuse");
    let scene = scene_file(&dir);
    let out = dir.path("run");
    // dt = 2 ms: 12 steps with a frame every 4 ms are frames 0..6.
    let first = porosph(&[
        "run",
        s(&scene),
        "--out",
        s(&out),
        "--steps",
        "12",
        "--frame-every",
        "0.004",
        "--checkpoint-every",
        "6steps",
        "--quiet",
    ]);
    assert!(first.status.success(), "{}", text(&first.stderr));
    let mut listing = frames(7);
    listing.push("frames.vtkhdf.series".to_string());
    listing.push("walls.vtkhdf".to_string());
    assert_eq!(names(&out.join("frames")), listing);
    let stats = fs::read(out.join("stats.csv")).expect("stats");

    // Again, without --overwrite: refused, and nothing touched.
    let again = porosph(&["run", s(&scene), "--out", s(&out), "--steps", "2", "--quiet"]);
    let err = text(&again.stderr);
    println!("{err}");
    assert_eq!(again.status.code(), Some(1), "{err}");
    for want in [
        &format!("--out {} holds an earlier porosph run", s(&out))[..],
        "7 frames, the frame series index, the walls file, 2 checkpoints, scene.toml, stats.csv",
        "--overwrite",
        "another --out",
        &format!("porosph resume {}", s(&out.join("checkpoints/ckpt_00000012.h5"))),
    ] {
        assert!(err.contains(want), "missing {want:?}: {err}");
    }
    assert_eq!(names(&out.join("frames")), listing);
    assert_eq!(fs::read(out.join("stats.csv")).expect("stats"), stats);

    // With --overwrite: the old frames, checkpoints and stats are gone; the
    // directory holds exactly the new run (2 steps: frames 0 and 1).
    let over = porosph(&["run", s(&scene), "--out", s(&out), "--steps", "2", "--frame-every", "0.004", "--overwrite"]);
    let err = text(&over.stderr);
    println!("{err}");
    assert!(over.status.success(), "{err}");
    assert!(err.contains(&format!("--overwrite: removed the earlier run in {}: 7 frames", s(&out))), "{err}");
    assert_eq!(names(&out), ["frames", "scene.toml", "stats.csv"]);
    let mut listing = frames(2);
    listing.push("frames.vtkhdf.series".to_string());
    listing.push("walls.vtkhdf".to_string());
    assert_eq!(names(&out.join("frames")), listing);
    assert_eq!(series_names(&out), frames(2));
    assert_eq!(fs::read_to_string(out.join("stats.csv")).expect("stats").lines().count(), 3);
}

#[test]
fn files_porosph_did_not_write_are_never_removed() {
    let dir = TempDir::new("out-foreign");
    let scene = scene_file(&dir);
    // A directory of the user's own files.
    let mine = dir.path("mine");
    fs::create_dir_all(mine.join("data")).expect("mkdir");
    fs::write(mine.join("notes.txt"), b"keep me").expect("write");
    for extra in [&[][..], &["--overwrite"][..]] {
        let mut args = vec!["run", s(&scene), "--out", s(&mine), "--steps", "1", "--quiet"];
        args.extend(extra);
        let r = porosph(&args);
        let err = text(&r.stderr);
        println!("{err}");
        assert_eq!(r.status.code(), Some(1), "{extra:?}: {err}");
        assert!(err.contains(&format!("--out {} is not empty", s(&mine))), "{err}");
        assert!(err.contains("data/, notes.txt, which porosph did not write"), "{err}");
        assert!(err.contains("choose another --out"), "{err}");
        assert_eq!(names(&mine), ["data", "notes.txt"]);
    }

    // An earlier run with one foreign file among its frames: --overwrite
    // refuses and removes nothing.
    let out = dir.path("run");
    let r = porosph(&["run", s(&scene), "--out", s(&out), "--steps", "1", "--quiet"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    fs::write(out.join("frames/frame_00000.vtkhdf.bak"), b"a copy").expect("write");
    let before = names(&out.join("frames"));
    let r = porosph(&["run", s(&scene), "--out", s(&out), "--steps", "1", "--quiet", "--overwrite"]);
    let err = text(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    assert!(err.contains("frames/frame_00000.vtkhdf.bak, which porosph did not write"), "{err}");
    assert!(err.contains("never other files"), "{err}");
    assert_eq!(names(&out.join("frames")), before);
    assert!(out.join("stats.csv").exists());

    // A scene file alone is the user's, not a run; an empty directory is
    // fine; a file is not a directory.
    let with_scene = dir.path("with_scene");
    fs::create_dir_all(&with_scene).expect("mkdir");
    fs::write(with_scene.join("scene.toml"), TWO_PHASE).expect("write");
    let r = porosph(&["run", s(&scene), "--out", s(&with_scene), "--steps", "1", "--quiet", "--overwrite"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("scene.toml, which porosph did not write"), "{}", text(&r.stderr));
    let empty = dir.path("empty");
    fs::create_dir_all(&empty).expect("mkdir");
    let r = porosph(&["run", s(&scene), "--out", s(&empty), "--steps", "1", "--quiet"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let r = porosph(&["run", s(&scene), "--out", s(&scene), "--steps", "1", "--quiet"]);
    let want = format!("--out {} names a file, not a directory", s(&scene));
    assert!(text(&r.stderr).contains(&want), "{}", text(&r.stderr));
    assert_eq!(r.status.code(), Some(1));
}

#[test]
fn resume_continues_its_own_run_only() {
    let dir = TempDir::new("out-resume");
    let scene = scene_file(&dir);
    let out = dir.path("run");
    let r = porosph(&[
        "run",
        s(&scene),
        "--out",
        s(&out),
        "--steps",
        "12",
        "--frame-every",
        "0.004",
        "--checkpoint-every",
        "6steps",
        "--quiet",
    ]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let ckpt = out.join("checkpoints/ckpt_00000006.h5");

    // Into its own directory: the frames written after step 6 (frames 4-6,
    // the checkpoint had written 0-3) go, and 2 more steps write frame 4
    // again: the series lists exactly this run's frames.
    let r = porosph(&["resume", s(&ckpt), "--steps", "2"]);
    let err = text(&r.stderr);
    println!("{err}");
    assert!(r.status.success(), "{err}");
    assert!(err.contains("removed 3 frames (frame 4 on) that the run had written after this checkpoint"), "{err}");
    let mut listing = frames(5);
    listing.push("frames.vtkhdf.series".to_string());
    listing.push("walls.vtkhdf".to_string());
    assert_eq!(names(&out.join("frames")), listing);
    assert_eq!(series_names(&out), frames(5));
    // --overwrite on its own run is an error that says why.
    let r = porosph(&["resume", s(&ckpt), "--steps", "2", "--quiet", "--overwrite"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("is the run this checkpoint belongs to"), "{}", text(&r.stderr));

    // Into another run's directory: refused, then --overwrite replaces it.
    let other = dir.path("other");
    let r = porosph(&["run", s(&scene), "--out", s(&other), "--steps", "1", "--quiet"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let r = porosph(&["resume", s(&ckpt), "--out", s(&other), "--steps", "2", "--quiet"]);
    assert_eq!(r.status.code(), Some(1));
    assert!(text(&r.stderr).contains("holds an earlier porosph run"), "{}", text(&r.stderr));
    let r = porosph(&["resume", s(&ckpt), "--out", s(&other), "--steps", "2", "--quiet", "--overwrite"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let stats = fs::read_to_string(other.join("stats.csv")).expect("stats");
    let steps: Vec<&str> = stats.lines().skip(1).map(|l| l.split(',').next().unwrap_or("")).collect();
    assert_eq!(steps, ["7", "8"]);
    // The new directory holds this run's frames only: frame 4 (t = 16 ms).
    assert_eq!(series_names(&other), ["frame_00004.vtkhdf"]);
}
