//! A run: steps the simulation to its end, writes frames on schedule and a
//! stats row per step, and shows progress.

mod frame;

pub use frame::kind;

use crate::io::{write_frame, IoError, SeriesWriter, StatsWriter};
use crate::pipeline::{Simulation, StepError, PASSES};
use crate::scene::Phase;
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// When a run stops and what it writes.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// Output directory (created if missing).
    pub out: PathBuf,
    /// Stop at this simulated time, s (default: the scene's end_time).
    pub until: Option<f64>,
    /// Stop after this many steps (overrides `until`).
    pub steps: Option<u64>,
    /// Simulated time between frames, s (default: the scene's frame_interval).
    pub frame_every: Option<f64>,
    /// No progress bar.
    pub quiet: bool,
}

/// What a finished run did.
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    pub steps: u64,
    pub frames: u64,
    pub wall_seconds: f64,
    pub particle_steps_per_second: f64,
}

/// Why a run stopped early.
#[derive(Debug)]
pub enum RunError {
    Io(IoError),
    Step(StepError),
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Io(e) => write!(f, "{e}"),
            RunError::Step(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for RunError {}

impl From<IoError> for RunError {
    fn from(e: IoError) -> Self {
        RunError::Io(e)
    }
}

/// Header of `stats.csv` for a scene with `phases`: then `volume_<phase>`
/// (m^3, [`Simulation::phase_volumes`]) per phase in scene order, and
/// `ms_<pass>` per pass.
pub fn stats_columns(phases: &[Phase]) -> Vec<String> {
    let mut c: Vec<String> =
        ["step", "time", "dt", "iterations", "density_error", "max_speed", "max_drift_speed", "fluid_particles"]
            .iter()
            .map(|s| s.to_string())
            .collect();
    c.extend(phases.iter().map(|p| format!("volume_{}", p.name)));
    c.extend(PASSES.iter().map(|p| format!("ms_{p}")));
    c.push("ms_step".to_string());
    c
}

fn create_dir(p: &Path) -> Result<(), IoError> {
    std::fs::create_dir_all(p).map_err(|e| IoError::new(p, format!("cannot create directory: {e}")))
}

/// Runs `sim` as `opts` says.
pub fn run(sim: &mut Simulation, opts: &RunOptions) -> Result<RunSummary, RunError> {
    let frames_dir = opts.out.join("frames");
    create_dir(&frames_dir)?;
    let scene_copy = opts.out.join("scene.toml");
    std::fs::write(&scene_copy, &sim.scene.text).map_err(|e| IoError::new(&scene_copy, e))?;
    let mut stats = StatsWriter::create(&opts.out.join("stats.csv"), &stats_columns(&sim.scene.phases))?;
    let mut series = SeriesWriter::new(&frames_dir.join("frames.vtkhdf.series"));
    let end_time = opts.until.unwrap_or(sim.scene.simulation.end_time);
    let frame_every = opts.frame_every.unwrap_or(sim.scene.simulation.frame_interval);

    let bar = if opts.quiet {
        ProgressBar::hidden()
    } else {
        let (len, unit) = match opts.steps {
            Some(s) => (s, "steps"),
            None => ((end_time * 1000.0).round() as u64, "ms simulated"),
        };
        let b = ProgressBar::new(len);
        b.set_style(
            ProgressStyle::with_template(&format!("{{bar:40}} {{pos}}/{{len}} {unit}  {{msg}}  eta {{eta}}"))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };

    let mut frames = 0u64;
    let mut next_frame = 0.0f64;
    let write = |sim: &Simulation, frames: &mut u64, series: &mut SeriesWriter| -> Result<(), IoError> {
        let name = format!("frame_{:05}.vtkhdf", *frames);
        write_frame(&frames_dir.join(&name), &sim.frame())?;
        series.add(&name, sim.time)?;
        *frames += 1;
        Ok(())
    };
    if sim.time >= next_frame {
        write(sim, &mut frames, &mut series)?;
        next_frame = sim.time + frame_every;
    }
    let start = Instant::now();
    let first_step = sim.step;
    let n = sim.fluid.len() as f64;
    let done = |sim: &Simulation| match opts.steps {
        Some(s) => sim.step - first_step >= s,
        None => sim.time >= end_time - 1e-9,
    };
    while !done(sim) {
        let t = Instant::now();
        let result = sim.step().copied();
        let st = match result {
            Ok(st) => st,
            Err(e) => {
                bar.abandon();
                // Keep the last state for diagnosis.
                let name = format!("frame_{:05}_failed.vtkhdf", frames);
                let _ = write_frame(&frames_dir.join(name), &sim.frame());
                return Err(RunError::Step(e));
            }
        };
        let ms_step = t.elapsed().as_secs_f64() * 1e3;
        let mut row = vec![
            sim.step as f64,
            sim.time,
            st.dt as f64,
            st.iterations as f64,
            st.density_error as f64,
            st.max_speed as f64,
            st.max_drift_speed as f64,
            n,
        ];
        row.extend(sim.phase_volumes());
        row.extend(st.times.ms);
        row.push(ms_step);
        stats.row(&row)?;
        if sim.time >= next_frame - 1e-9 {
            write(sim, &mut frames, &mut series)?;
            next_frame += frame_every;
        }
        let el = start.elapsed().as_secs_f64().max(1e-9);
        let taken = (sim.step - first_step) as f64;
        bar.set_position(match opts.steps {
            Some(_) => sim.step - first_step,
            None => (sim.time * 1000.0).round() as u64,
        });
        bar.set_message(format!("t = {:.3} s, {:.1} steps/s, {} it", sim.time, taken / el, st.iterations));
    }
    bar.finish_and_clear();
    let wall = start.elapsed().as_secs_f64();
    let steps = sim.step - first_step;
    Ok(RunSummary { steps, frames, wall_seconds: wall, particle_steps_per_second: n * steps as f64 / wall.max(1e-9) })
}
