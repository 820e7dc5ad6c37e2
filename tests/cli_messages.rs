//! Command-line messages that name the problem (issue 36, item 8): a
//! negative `--until` is read as a number and refused with its bound, a
//! `--out` that is a file says so, and `render` on a checkpoint says what
//! the file is and where the frames are. (Mesh files that are directories
//! or bad OBJ lines: tests/scene_mesh.rs.)

mod common;

use common::{porosph, s, text, TempDir, TWO_PHASE};
use std::fs;
use std::path::Path;

/// Runs `args`, which must fail with exit status `code` and `message` in stderr.
fn fails(args: &[&str], code: i32, message: &str) {
    let r = porosph(args);
    let err = text(&r.stderr);
    assert_eq!(r.status.code(), Some(code), "{args:?}: {err}");
    assert!(err.contains(message), "{args:?}: wanted {message:?} in\n{err}");
}

#[test]
fn negative_times_and_steps_are_numbers_refused_with_their_bound() {
    let dir = TempDir::new("msg-until");
    let scene = dir.path("s.toml");
    fs::write(&scene, TWO_PHASE).expect("write scene");
    let out = dir.path("o");
    let base = ["run", s(&scene), "--out", s(&out)];
    let run = |extra: &[&'static str]| -> Vec<&str> { base.iter().chain(extra).copied().collect() };
    fails(&run(&["--until", "-1"]), 1, "porosph: error: --until must be > 0 s, got -1");
    fails(&run(&["--until", "0"]), 1, "--until must be > 0 s, got 0");
    fails(&run(&["--frame-every", "-0.5"]), 1, "--frame-every must be > 0 s, got -0.5");
    fails(&run(&["--steps", "-1"]), 2, "expected a whole number of steps (0 or more), got \"-1\"");
    fails(&["resume", s(&dir.path("c.h5")), "--until", "-2"], 1, "--until must be > 0 s, got -2");
    assert!(!out.exists(), "a refused run wrote {}", out.display());
}

#[test]
fn an_out_that_is_a_file_and_a_checkpoint_given_to_render_are_named() {
    let dir = TempDir::new("msg-out");
    let scene = dir.path("s.toml");
    fs::write(&scene, TWO_PHASE).expect("write scene");
    let file = dir.path("afile");
    fs::write(&file, "mine").expect("write");
    let run = |out: &Path| porosph(&["run", s(&scene), "--out", s(out), "--steps", "1", "--quiet"]);
    let r = run(&file);
    assert_eq!(r.status.code(), Some(1));
    let want = format!("--out {} names a file, not a directory", s(&file));
    assert!(text(&r.stderr).contains(&want), "{}", text(&r.stderr));
    let below = file.join("x");
    let r = run(&below);
    assert_eq!(r.status.code(), Some(1));
    let want = format!("--out {}: {} is a file, not a directory", s(&below), s(&file));
    assert!(text(&r.stderr).contains(&want), "{}", text(&r.stderr));
    assert_eq!(fs::read_to_string(&file).expect("read"), "mine");

    let out = dir.path("o");
    let r = porosph(&["run", s(&scene), "--out", s(&out), "--steps", "2", "--checkpoint-every", "2steps", "--quiet"]);
    assert!(r.status.success(), "{}", text(&r.stderr));
    let ckpt = out.join("checkpoints/ckpt_00000002.h5");
    let r = porosph(&["render", s(&ckpt)]);
    let err = text(&r.stderr);
    assert_eq!(r.status.code(), Some(1), "{err}");
    for want in [
        format!("{}: a porosph checkpoint, not a frame", s(&ckpt)),
        format!("`porosph inspect {}`", s(&ckpt)),
        format!("(`porosph render {}/frame_NNNNN.vtkhdf`)", s(&out.join("frames"))),
    ] {
        assert!(err.contains(&want), "wanted {want:?} in\n{err}");
    }
    assert!(!ckpt.with_extension("png").exists());
}
