//! When a run writes checkpoints, what they are called, and which are kept.
//!
//! `checkpoints/ckpt_<step>.h5` (step zero-padded to 8 digits) every N
//! simulated seconds or N steps; the newest `keep` are kept. An old
//! checkpoint is deleted only after the new one has its final name, so a
//! failed write (full disk) or a crash never loses the last good one. A
//! failed step leaves `ckpt_<step>_failed.h5`, which rotation never deletes.

use crate::io::checkpoint::{write_checkpoint, RunInfo};
use crate::io::IoError;
use crate::pipeline::Simulation;
use std::fmt;
use std::fs;
use std::path::{Path, PathBuf};
use std::str::FromStr;

/// How often a run writes a checkpoint.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CheckpointEvery {
    /// Every this many simulated seconds (at the first step at or past each
    /// multiple), s.
    Seconds(f64),
    /// Every this many steps (at steps that are multiples of it).
    Steps(u64),
}

impl FromStr for CheckpointEvery {
    type Err = String;

    /// `0.1` or `0.1s`: simulated seconds; `500steps` (or `500step`): steps.
    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim();
        let bad = || {
            format!(
                "{s:?} is not a checkpoint interval: give simulated seconds (`0.1`, `0.1s`) \
                 or a step count (`500steps`)"
            )
        };
        if let Some(n) = t.strip_suffix("steps").or_else(|| t.strip_suffix("step")) {
            let n: u64 = n.trim().parse().map_err(|_| bad())?;
            if n == 0 {
                return Err(format!("{s:?}: the step count must be at least 1"));
            }
            return Ok(CheckpointEvery::Steps(n));
        }
        let x: f64 = t.strip_suffix('s').unwrap_or(t).trim().parse().map_err(|_| bad())?;
        if !(x.is_finite() && x > 0.0) {
            return Err(format!("{s:?}: the interval must be a positive number of seconds"));
        }
        Ok(CheckpointEvery::Seconds(x))
    }
}

impl fmt::Display for CheckpointEvery {
    /// The form [`FromStr`] reads back: `0.1s` or `500steps`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            CheckpointEvery::Seconds(x) => write!(f, "{x:?}s"),
            CheckpointEvery::Steps(n) => write!(f, "{n}steps"),
        }
    }
}

/// The checkpoints of one run.
pub struct Checkpoints {
    dir: PathBuf,
    every: Option<CheckpointEvery>,
    keep: usize,
    /// The newest checkpoint known to be complete.
    last_good: Option<PathBuf>,
    /// The newest checkpoint this run wrote.
    written: Option<PathBuf>,
}

/// Tolerance on simulated time when deciding whether a checkpoint is due, s.
const TIME_EPS: f64 = 1e-9;

impl Checkpoints {
    /// Checkpoints in `dir` on schedule `every`, keeping `keep` (at least 1).
    /// With a schedule, creates the directory now (so an unwritable one is
    /// reported before the run starts). Removes temporary files left by a
    /// run that was killed while writing.
    pub fn new(dir: &Path, every: Option<CheckpointEvery>, keep: usize) -> Result<Self, IoError> {
        let mut c = Self { dir: dir.to_path_buf(), every, keep: keep.max(1), last_good: None, written: None };
        if every.is_some() {
            fs::create_dir_all(dir).map_err(|e| IoError::new(dir, format!("cannot create directory: {e}")))?;
        }
        for name in c.list(|n| n.starts_with(".ckpt_") && n.ends_with(".h5.tmp")) {
            let _ = fs::remove_file(dir.join(name));
        }
        c.last_good = c.regular().last().map(|(_, name)| dir.join(name));
        Ok(c)
    }

    /// The directory checkpoints go to.
    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The newest checkpoint known to be complete, if any.
    pub fn last_good(&self) -> Option<&Path> {
        self.last_good.as_deref()
    }

    /// Whether a checkpoint is due after the step `sim` has just taken.
    pub fn due(&self, sim: &Simulation, previous_time: f64) -> bool {
        match self.every {
            None => false,
            Some(CheckpointEvery::Steps(n)) => sim.step.is_multiple_of(n),
            // Due at the first step that reaches or passes a multiple of the
            // interval: one checkpoint however many multiples a step passes.
            Some(CheckpointEvery::Seconds(s)) => {
                let k = |t: f64| ((t + TIME_EPS) / s).floor();
                k(sim.time) > k(previous_time)
            }
        }
    }

    /// The path of the checkpoint of step `step`.
    pub fn path(&self, step: u64) -> PathBuf {
        self.dir.join(format!("ckpt_{step:08}.h5"))
    }

    /// Writes the checkpoint of the current step, then deletes the oldest
    /// ones beyond `keep` (never one of a later step: a resumed run leaves
    /// those of the run it continues until it overwrites them).
    pub fn write(&mut self, sim: &Simulation, run: &RunInfo) -> Result<PathBuf, IoError> {
        let path = self.path(sim.step);
        write_checkpoint(&path, sim, run, None)?;
        self.last_good = Some(path.clone());
        self.written = Some(path.clone());
        let older: Vec<(u64, String)> = self.regular().into_iter().filter(|&(s, _)| s < sim.step).collect();
        let excess = (older.len() + 1).saturating_sub(self.keep);
        for (_, name) in older.iter().take(excess) {
            // A checkpoint that cannot be deleted stays; the next rotation
            // tries again.
            let _ = fs::remove_file(self.dir.join(name));
        }
        Ok(path)
    }

    /// The checkpoint of the current step, whatever the schedule (a run
    /// that is interrupted): the one just written on schedule, or a new
    /// one (creating the directory, rotating as [`Checkpoints::write`]).
    pub fn write_now(&mut self, sim: &Simulation, run: &RunInfo) -> Result<PathBuf, IoError> {
        let path = self.path(sim.step);
        if self.written.as_deref() == Some(path.as_path()) {
            return Ok(path);
        }
        fs::create_dir_all(&self.dir).map_err(|e| IoError::new(&self.dir, format!("cannot create directory: {e}")))?;
        self.write(sim, run)
    }

    /// Writes the diagnostic checkpoint of a failed step,
    /// `ckpt_<step>_failed.h5`, creating the directory if needed.
    pub fn write_failed(&self, sim: &Simulation, run: &RunInfo, reason: &str) -> Result<PathBuf, IoError> {
        fs::create_dir_all(&self.dir).map_err(|e| IoError::new(&self.dir, format!("cannot create directory: {e}")))?;
        let path = self.dir.join(format!("ckpt_{:08}_failed.h5", sim.step));
        write_checkpoint(&path, sim, run, Some(reason))?;
        Ok(path)
    }

    /// Regular checkpoints in the directory, `(step, file name)`, by step.
    fn regular(&self) -> Vec<(u64, String)> {
        let mut v: Vec<(u64, String)> = self
            .list(|n| n.starts_with("ckpt_") && n.ends_with(".h5"))
            .into_iter()
            .filter_map(|name| {
                let digits = name.strip_prefix("ckpt_")?.strip_suffix(".h5")?;
                if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
                    return None;
                }
                Some((digits.parse().ok()?, name))
            })
            .collect();
        v.sort();
        v
    }

    /// Files in the directory whose names pass `keep`.
    fn list(&self, keep: impl Fn(&str) -> bool) -> Vec<String> {
        let Ok(rd) = fs::read_dir(&self.dir) else {
            return Vec::new();
        };
        rd.filter_map(|e| e.ok()?.file_name().into_string().ok()).filter(|n| keep(n)).collect()
    }
}

/// The newest regular checkpoint (`ckpt_<step>.h5`) in `dir`, if any.
pub fn newest_checkpoint(dir: &Path) -> Option<PathBuf> {
    let c = Checkpoints { dir: dir.to_path_buf(), every: None, keep: 1, last_good: None, written: None };
    c.regular().last().map(|(_, name)| dir.join(name))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_seconds_and_steps() {
        assert_eq!("0.1".parse(), Ok(CheckpointEvery::Seconds(0.1)));
        assert_eq!("0.25s".parse(), Ok(CheckpointEvery::Seconds(0.25)));
        assert_eq!("500steps".parse(), Ok(CheckpointEvery::Steps(500)));
        assert_eq!("1step".parse(), Ok(CheckpointEvery::Steps(1)));
        for bad in ["", "0", "-1", "nan", "inf", "0steps", "1.5steps", "x", "5 m"] {
            assert!(bad.parse::<CheckpointEvery>().is_err(), "accepted {bad:?}");
        }
        for c in [CheckpointEvery::Seconds(0.1), CheckpointEvery::Steps(7)] {
            assert_eq!(c.to_string().parse(), Ok(c));
        }
    }
}
