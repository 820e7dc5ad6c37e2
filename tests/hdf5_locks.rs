//! HDF5 file locks never make a frame or checkpoint unreadable.
//!
//! The HDF5 C library (1.10 and later) takes a `flock` on every file it opens
//! (exclusive for writing, shared for reading) and opens it without
//! close-on-exec. A process spawned while porosph had a file open for
//! writing inherited the descriptor and with it the exclusive lock, which
//! outlives porosph's own close; a later open of the file then failed with
//! "unable to lock file, errno = 11" (a CI run of `tests/render.rs` met it
//! when another test thread spawned `porosph` during a frame write). porosph
//! writes every file to a fresh temporary name and renames it into place,
//! so no lock protects anything; it opens HDF5 files without locks and with
//! close-on-exec (`porosph::io::h5`). These tests provoke both halves of the
//! race deterministically: a child spawned while porosph has a file open,
//! and a lock held by another process while `porosph` reads.

mod common;

use common::{TempDir, TWO_PHASE};
use porosph::io::checkpoint::{write_checkpoint, RunInfo};
use porosph::io::{write_frame, ArrayData, Frame, PointArray};
use std::fs;
use std::os::fd::AsRawFd;
use std::path::Path;
use std::process::{Child, Command, Output, Stdio};

fn porosph(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_porosph")).args(args).output().expect("run porosph")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

fn frame() -> Frame {
    let points: Vec<[f32; 3]> = (0..64).map(|i| [i as f32 * 0.01, 0.0, 0.0]).collect();
    let n = points.len();
    let array = |name: &str, c, data| PointArray { name: name.into(), unit: String::new(), components: c, data };
    Frame {
        time: 0.5,
        step: 10,
        points,
        arrays: vec![
            array("velocity", 3, ArrayData::F32(vec![0.1; 3 * n])),
            array("pressure", 1, ArrayData::F32(vec![1.0; n])),
            array("color", 3, ArrayData::F32(vec![0.5; 3 * n])),
            array("kind", 1, ArrayData::U8(vec![0; n])),
            array("id", 1, ArrayData::U32((0..n as u32).collect())),
        ],
    }
}

/// Whether another open of `path` can take an exclusive lock right now
/// (no process holds a lock on it).
fn unlocked(path: &Path) -> bool {
    let f = fs::File::open(path).expect("open");
    // SAFETY: flock on a descriptor this function owns.
    let r = unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) };
    r == 0
}

/// A process that holds an exclusive `flock` on `path` until killed, as an
/// HDF5 writer elsewhere (h5py, another porosph build, a viewer) would.
struct Locker(Child);

impl Locker {
    fn new(path: &Path) -> Self {
        let f = fs::File::open(path).expect("open");
        // SAFETY: flock on a descriptor owned here; the child inherits the
        // open file description (and so the lock) through its stdin.
        assert_eq!(unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) }, 0);
        let child = Command::new("sleep").arg("60").stdin(Stdio::from(f)).spawn().expect("spawn sleep");
        assert!(!unlocked(path), "the child holds the lock");
        Locker(child)
    }
}

impl Drop for Locker {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn a_child_spawned_while_a_file_is_open_for_writing_inherits_no_lock() {
    let dir = TempDir::new("h5-inherit");
    let path = dir.path("x.h5");
    let file = porosph::io::h5::create(&path).expect("create");
    file.new_attr::<f64>().create("t").expect("attr").write_scalar(&1.0).expect("write");
    // A process started by another thread while the file is open.
    let mut child = Command::new("sleep").arg("60").spawn().expect("spawn sleep");
    file.close().expect("close");
    let free = unlocked(&path);
    let _ = child.kill();
    let _ = child.wait();
    assert!(free, "{} is still locked after porosph closed it: the child inherited the lock", path.display());
    // And nothing inherited the descriptor either (close-on-exec).
    let held = porosph::io::h5::create(&path).expect("create");
    let mut child = Command::new("sleep").arg("60").spawn().expect("spawn sleep");
    let fds: Vec<_> = fs::read_dir(format!("/proc/{}/fd", child.id())).expect("fds").flatten().collect();
    let leaked = fds.iter().any(|e| fs::read_link(e.path()).is_ok_and(|t| t == path));
    let _ = child.kill();
    let _ = child.wait();
    drop(held);
    assert!(!leaked, "the child holds a descriptor of {}", path.display());
}

#[test]
fn render_and_inspect_read_a_frame_another_process_has_locked() {
    let dir = TempDir::new("h5-frame-lock");
    let frames = dir.path("run/frames");
    fs::create_dir_all(&frames).unwrap();
    let path = frames.join("frame_00000.vtkhdf");
    write_frame(&path, &frame()).unwrap();
    let _lock = Locker::new(&path);
    let png = dir.path("f.png");
    let out = porosph(&["render", s(&path), "-o", s(&png), "--width", "32", "--height", "24"]);
    assert!(out.status.success(), "render: {}", String::from_utf8_lossy(&out.stderr));
    let out = porosph(&["inspect", s(&path)]);
    assert!(out.status.success(), "inspect: {}", String::from_utf8_lossy(&out.stderr));
    porosph::io::read_frame(&path).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn inspect_and_resume_read_a_checkpoint_another_process_has_locked() {
    let dir = TempDir::new("h5-ckpt-lock");
    let scene = common::scene_text(TWO_PHASE);
    let mut sim = porosph::pipeline::Simulation::new(scene);
    common::run_until(&mut sim, 0.004);
    let path = dir.path("ckpt.h5");
    let info = RunInfo {
        frames_written: 0,
        next_frame_time: 0.01,
        frame_every: 0.01,
        stop_time: Some(0.02),
        stop_step: None,
        checkpoint_every: String::new(),
        keep: 3,
        compress: false,
    };
    write_checkpoint(&path, &sim, &info, None).unwrap();
    let _lock = Locker::new(&path);
    let out = porosph(&["inspect", s(&path)]);
    assert!(out.status.success(), "inspect: {}", String::from_utf8_lossy(&out.stderr));
    let out = porosph(&["resume", s(&path), "--steps", "2", "--out", s(&dir.path("out")), "--quiet"]);
    assert!(out.status.success(), "resume: {}", String::from_utf8_lossy(&out.stderr));
}
