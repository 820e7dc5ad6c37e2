//! kill -9 at pseudo-random moments: a run that checkpoints every step is
//! killed with SIGKILL after a delay drawn from a fixed LCG (so every run of
//! this test kills at the same moments relative to the first checkpoint).
//! Each time, the newest checkpoint must load (every checksum holds) and
//! `porosph resume` must continue from it. A kill while a checkpoint is
//! being written leaves only its temporary file, which the resume removes.

mod common;

use common::{TempDir, TWO_PHASE};
use porosph::io::checkpoint::read_checkpoint;
use porosph::run::newest_checkpoint;
use std::fs;
use std::os::unix::process::ExitStatusExt;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// Kills, at least 10 as the issue asks.
const KILLS: usize = 12;

/// Knuth's MMIX LCG; the high bits as the draw.
fn lcg(state: &mut u64) -> u64 {
    *state = state.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
    *state >> 33
}

fn has_checkpoint(dir: &Path) -> bool {
    newest_checkpoint(dir).is_some()
}

fn temporaries(dir: &Path) -> usize {
    fs::read_dir(dir)
        .map(|rd| rd.filter_map(|e| e.ok()?.file_name().into_string().ok()).filter(|n| n.ends_with(".tmp")).count())
        .unwrap_or(0)
}

#[test]
fn newest_checkpoint_survives_kill_9_and_resumes() {
    let dir = TempDir::new("kill9");
    let scene = dir.path("two_phase.toml");
    fs::write(&scene, TWO_PHASE).expect("write scene");
    let bin = env!("CARGO_BIN_EXE_porosph");
    let mut seed = 0x0005_eed0_u64;
    let mut during_write = 0;
    for k in 0..KILLS {
        let out = dir.path(&format!("run{k}"));
        let ckpts = out.join("checkpoints");
        let mut child = Command::new(bin)
            .args([
                "run",
                scene.to_str().expect("utf-8"),
                "--out",
                out.to_str().expect("utf-8"),
                "--steps",
                "1000000",
                "--checkpoint-every",
                "1steps",
                "--keep",
                "2",
                "--quiet",
            ])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start porosph");
        // Wait for the first checkpoint, then a pseudo-random 0-150 ms.
        let start = Instant::now();
        while !has_checkpoint(&ckpts) {
            if let Ok(Some(status)) = child.try_wait() {
                panic!("run {k} ended before its first checkpoint: {status}");
            }
            assert!(start.elapsed() < Duration::from_secs(60), "no checkpoint");
            std::thread::sleep(Duration::from_millis(2));
        }
        let delay = lcg(&mut seed) % 150;
        std::thread::sleep(Duration::from_millis(delay));
        child.kill().expect("SIGKILL");
        let status = child.wait().expect("wait");
        assert_eq!(status.signal(), Some(9), "run {k} was not killed: {status}");

        let torn = temporaries(&ckpts);
        during_write += usize::from(torn > 0);
        let newest = newest_checkpoint(&ckpts).expect("a checkpoint");
        let c =
            read_checkpoint(&newest).unwrap_or_else(|e| panic!("kill {k} after {delay} ms: newest checkpoint: {e}"));
        let step = c.state.step;
        let r = Command::new(bin)
            .args(["resume", newest.to_str().expect("utf-8"), "--steps", "3", "--quiet"])
            .output()
            .expect("resume");
        assert!(r.status.success(), "kill {k}: resume from step {step}: {}", String::from_utf8_lossy(&r.stderr));
        let stats = fs::read_to_string(out.join("stats.csv")).expect("stats.csv");
        let last: u64 =
            stats.lines().last().and_then(|l| l.split(',').next()).and_then(|s| s.parse().ok()).expect("a last row");
        assert_eq!(last, step + 3, "kill {k}: stats.csv continues to step {last}");
        assert_eq!(temporaries(&ckpts), 0, "resume leaves no temporary file");
        println!(
            "kill {k}: after {delay:3} ms, newest checkpoint step {step}, \
             {torn} temporary file(s) left, resumed to step {last}"
        );
    }
    println!("{KILLS} kills, {during_write} while a checkpoint was being written");
}
