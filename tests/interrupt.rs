//! SIGINT and SIGTERM sent to a real `porosph run` child (issue 36, item
//! 2): the run finishes its step, writes a checkpoint (checkpoints are off
//! here) and prints the `porosph resume` command, exiting 130 or 143; that
//! command then completes the run, and its final state, `stats.csv` and
//! frame series are bitwise those of the run without the interrupt. A
//! second signal exits at once and still leaves files a resume can use.

mod common;

use common::{assert_same_bits, s, solid_bits, store_bits, TempDir, TWO_PHASE};
use porosph::io::checkpoint::read_checkpoint;
use porosph::run::newest_checkpoint;
use std::fs;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_porosph");

/// Steps of the runs (about 6 ms each): long enough to be interrupted.
const STEPS: u64 = 300;

fn stats_steps(out: &Path) -> Vec<u64> {
    fs::read_to_string(out.join("stats.csv"))
        .unwrap_or_default()
        .lines()
        .skip(1)
        .filter(|l| !l.is_empty())
        .map(|l| l.split(',').next().unwrap_or("").parse().expect("step"))
        .collect()
}

/// Starts `porosph args`, its stderr lines sent to the receiver.
fn start(args: &[&str]) -> (Child, mpsc::Receiver<String>) {
    let mut child =
        Command::new(BIN).args(args).stdout(Stdio::null()).stderr(Stdio::piped()).spawn().expect("start porosph");
    let err = child.stderr.take().expect("stderr");
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(err).lines() {
            let Ok(line) = line else { break };
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    (child, rx)
}

fn signal(child: &Child, sig: i32) {
    // SAFETY: kill(2) on our own child's pid.
    let r = unsafe { libc::kill(child.id() as libc::pid_t, sig) };
    assert_eq!(r, 0, "kill: {}", std::io::Error::last_os_error());
}

/// Waits until `out/stats.csv` has at least `rows` steps.
fn wait_for_steps(child: &mut Child, out: &Path, rows: usize) {
    let t0 = Instant::now();
    while stats_steps(out).len() < rows {
        if let Ok(Some(status)) = child.try_wait() {
            panic!("the run ended before it was interrupted: {status}");
        }
        assert!(t0.elapsed() < Duration::from_secs(60), "the run does not start");
        std::thread::sleep(Duration::from_millis(2));
    }
}

/// The checkpoint in the `porosph resume <checkpoint>` line of `stderr`.
fn resume_command(stderr: &str) -> PathBuf {
    let line = stderr
        .lines()
        .find_map(|l| l.trim().strip_prefix("porosph resume "))
        .unwrap_or_else(|| panic!("no resume command in:\n{stderr}"));
    PathBuf::from(line)
}

#[test]
fn sigterm_and_sigint_leave_a_checkpoint_that_resumes_bitwise() {
    let dir = TempDir::new("interrupt");
    let scene = dir.path("two_phase.toml");
    fs::write(&scene, TWO_PHASE).expect("write scene");
    let every = format!("{STEPS}steps");
    let steps = STEPS.to_string();
    let run_args = |out: &Path| -> Vec<String> {
        ["run", s(&scene), "--out", s(out), "--steps", &steps, "--quiet"].iter().map(|a| a.to_string()).collect()
    };
    // The run without an interrupt; a checkpoint of its end (the one
    // scheduled checkpoint) to compare with.
    let straight = dir.path("straight");
    let mut args = run_args(&straight);
    args.extend(["--checkpoint-every".to_string(), every.clone()]);
    let r = Command::new(BIN).args(&args).output().expect("run");
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let end =
        read_checkpoint(&straight.join(format!("checkpoints/ckpt_{STEPS:08}.h5"))).unwrap_or_else(|e| panic!("{e}"));
    let series = fs::read_to_string(straight.join("frames/frames.vtkhdf.series")).expect("series");

    for (sig, status) in [(libc::SIGTERM, 143), (libc::SIGINT, 130)] {
        let out = dir.path(&format!("sig{sig}"));
        let args = run_args(&out);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let (mut child, lines) = start(&args);
        wait_for_steps(&mut child, &out, 5);
        signal(&child, sig);
        let code = child.wait().expect("wait").code();
        let stderr: String = lines.iter().collect::<Vec<_>>().join("\n");
        println!("signal {sig}:\n{stderr}");
        assert_eq!(code, Some(status), "{stderr}");
        // The checkpoint (checkpoints were off: the only one) and the
        // exact command.
        let ckpt = resume_command(&stderr);
        assert_eq!(newest_checkpoint(&out.join("checkpoints")).as_deref(), Some(ckpt.as_path()));
        let saved = read_checkpoint(&ckpt).unwrap_or_else(|e| panic!("{e}"));
        let k = saved.state.step;
        assert!((5..STEPS).contains(&k), "stopped at step {k}");
        assert_eq!(saved.run.checkpoint_every, "");
        assert_eq!(stats_steps(&out), (1..=k).collect::<Vec<_>>(), "stats.csv up to the checkpoint");
        assert!(out.join("frames/frames.vtkhdf.series").exists());

        // The printed command, with the straight run's end checkpoint to
        // compare: the final state is bitwise the uninterrupted run's.
        let r = Command::new(BIN)
            .args(["resume", s(&ckpt), "--quiet", "--checkpoint-every", &every])
            .output()
            .expect("resume");
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        let resumed =
            read_checkpoint(&out.join(format!("checkpoints/ckpt_{STEPS:08}.h5"))).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(resumed.state.step, STEPS);
        assert_eq!(resumed.state.time.to_bits(), end.state.time.to_bits());
        assert_eq!(resumed.state.dt.to_bits(), end.state.dt.to_bits());
        assert_same_bits(
            &store_bits(&resumed.state.fluid, &resumed.state.walls),
            &store_bits(&end.state.fluid, &end.state.walls),
        );
        assert_same_bits(&solid_bits(&resumed.state.solids), &solid_bits(&end.state.solids));
        assert_eq!(stats_steps(&out), (1..=STEPS).collect::<Vec<_>>());
        assert_eq!(fs::read_to_string(out.join("frames/frames.vtkhdf.series")).expect("series"), series);
        println!("signal {sig}: stopped at step {k}, exit {status}, resumed to step {STEPS}: bitwise equal");
    }
}

#[test]
fn a_second_signal_stops_at_once_and_leaves_usable_files() {
    let dir = TempDir::new("interrupt-twice");
    // 8x the particles: about 40 ms a step, so that the second signal
    // arrives while the step is still running.
    let scene = dir.path("fine.toml");
    fs::write(&scene, TWO_PHASE.replace("particle_spacing = 0.02", "particle_spacing = 0.01")).expect("write scene");
    // The second signal may (rarely) come after the run has already
    // stopped; try until it came in time.
    for attempt in 0..5 {
        let out = dir.path(&format!("run{attempt}"));
        let (mut child, lines) = start(&[
            "run",
            s(&scene),
            "--out",
            s(&out),
            "--steps",
            "100000",
            "--checkpoint-every",
            "2steps",
            "--quiet",
        ]);
        wait_for_steps(&mut child, &out, 3);
        signal(&child, libc::SIGTERM);
        let t0 = Instant::now();
        let mut stderr = Vec::new();
        while !stderr.iter().any(|l: &String| l.contains("interrupted:")) {
            assert!(t0.elapsed() < Duration::from_secs(30), "no message after the first signal");
            if let Ok(l) = lines.recv_timeout(Duration::from_secs(30)) {
                stderr.push(l);
            }
        }
        signal(&child, libc::SIGTERM);
        let code = child.wait().expect("wait").code();
        stderr.extend(lines.iter());
        let stderr = stderr.join("\n");
        println!("attempt {attempt}:\n{stderr}");
        assert_eq!(code, Some(143), "{stderr}");
        // Whatever the moment: the newest checkpoint loads (checksums), the
        // series index parses, and a resume continues stats.csv.
        let newest = newest_checkpoint(&out.join("checkpoints")).expect("a checkpoint");
        let c = read_checkpoint(&newest).unwrap_or_else(|e| panic!("{e}"));
        let text = fs::read_to_string(out.join("frames/frames.vtkhdf.series")).expect("series");
        serde_json::from_str::<serde_json::Value>(&text).expect("the series index is JSON");
        let r = Command::new(BIN).args(["resume", s(&newest), "--steps", "2", "--quiet"]).output().expect("resume");
        assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
        assert_eq!(stats_steps(&out).last(), Some(&(c.state.step + 2)));
        if stderr.contains("second signal: stopped at once") {
            assert!(!stderr.contains("porosph resume"), "{stderr}");
            println!(
                "attempt {attempt}: the second signal stopped the run at once; resumed from step {}",
                c.state.step
            );
            return;
        }
    }
    panic!("the second signal never arrived before the run stopped");
}
