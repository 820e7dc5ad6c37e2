//! A run: steps the simulation to its end, writes frames and checkpoints on
//! schedule and a stats row per step, and shows progress. A run that
//! resumes from a checkpoint goes on where the saved run stood: the same
//! frame numbers and schedule, appending to the same `stats.csv`; frames
//! the run had written after the checkpoint (before a crash) are removed,
//! so the frame series lists exactly the resumed run's frames.

mod checkpoints;
mod frame;
pub mod interrupt;
pub mod output;
mod summary;

pub use checkpoints::{newest_checkpoint, CheckpointEvery, Checkpoints};
pub use frame::{kind, INNER_SHADE, WALL_ARRAYS_PER_FRAME};
pub use summary::RunSummary;

use crate::backend::GpuPasses;
use crate::io::checkpoint::RunInfo;
use crate::io::{write_frame, write_frame_as, FrameLayout, IoError, SeriesWriter, SharedRows, StatsWriter};
use crate::pipeline::{Pass, Simulation, StepError};
use crate::scene::{Phase, Solid};
use indicatif::{ProgressBar, ProgressStyle};
use std::fmt;
use std::path::{Path, PathBuf};
use std::time::Instant;
use summary::Tally;

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
    /// Checkpoint schedule (none: only a diagnostic checkpoint if a step fails).
    pub checkpoint_every: Option<CheckpointEvery>,
    /// Checkpoints kept (the newest ones; at least 1).
    pub keep: usize,
    /// Where a resumed run's output continues (`None`: a new run).
    pub resume: Option<Continuation>,
    /// Testing aid: sets a fluid velocity to NaN just before the step that
    /// starts at this step number, to exercise the failure path.
    pub inject_nan_at_step: Option<u64>,
    /// Deflate the frames (`porosph run --compress`): smaller files, a
    /// little more time per frame.
    pub compress: bool,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            out: PathBuf::from("out"),
            until: None,
            steps: None,
            frame_every: None,
            quiet: false,
            checkpoint_every: None,
            keep: DEFAULT_KEEP,
            resume: None,
            inject_nan_at_step: None,
            compress: false,
        }
    }
}

/// Checkpoints kept by default.
pub const DEFAULT_KEEP: usize = 3;

/// Where the output of a resumed run continues.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Continuation {
    /// Frames the run had written: the number of its next frame.
    pub frames: u64,
    /// Simulated time of its next frame, s.
    pub next_frame: f64,
}

/// Why a run stopped early.
#[derive(Debug)]
pub enum RunError {
    Io(IoError),
    /// A step failed (NaN, explosion); the diagnostic checkpoint holds the
    /// state after it, or says why it could not be written.
    Step {
        error: StepError,
        diagnostic: Result<PathBuf, IoError>,
    },
    /// A checkpoint could not be written; nothing already written is lost,
    /// and `last_good` is the newest complete checkpoint.
    Checkpoint {
        error: IoError,
        last_good: Option<PathBuf>,
    },
    /// SIGINT or SIGTERM ([`interrupt`]): the run stopped after step
    /// `step` and wrote `checkpoint` (or says why it could not).
    Interrupted {
        signal: i32,
        step: u64,
        time: f64,
        checkpoint: Result<PathBuf, IoError>,
    },
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            RunError::Io(e) => write!(f, "{e}"),
            RunError::Step { error, diagnostic } => {
                write!(f, "simulation stopped at {error}; ")?;
                match diagnostic {
                    Ok(p) => write!(f, "diagnostic checkpoint: {}", p.display()),
                    Err(e) => write!(f, "could not write the diagnostic checkpoint: {e}"),
                }
            }
            RunError::Checkpoint { error, last_good } => {
                write!(f, "cannot write a checkpoint: {error}; ")?;
                match last_good {
                    Some(p) => {
                        write!(f, "nothing already written was lost, the newest complete checkpoint is {}", p.display())
                    }
                    None => write!(f, "no earlier checkpoint of this run exists"),
                }
            }
            RunError::Interrupted { signal, step, time, checkpoint } => {
                write!(f, "interrupted by {} after step {step} (t = {time} s); ", interrupt::name(*signal))?;
                match checkpoint {
                    Ok(p) => write!(f, "checkpoint: {}", p.display()),
                    Err(e) => write!(f, "could not write a checkpoint: {e}"),
                }
            }
        }
    }
}

impl std::error::Error for RunError {}

impl From<IoError> for RunError {
    fn from(e: IoError) -> Self {
        RunError::Io(e)
    }
}

/// Header of `stats.csv` for a scene with `phases` and `solids`: then per
/// phase in scene order `volume_<phase>` (outer + inner, m^3,
/// [`Simulation::phase_volumes`]), `volume_outer_<phase>`,
/// `volume_inner_<phase>` (the part inside porous solids) and
/// `mass_<phase>` (kg), then per porous solid (`[[solid]]` with
/// `[solid.porous]`, by name) `absorbed_<solid>` (m^3) and
/// `saturation_<solid>` ([`porous_solids`]), then `ms_<pass>` per pass,
/// `ms_step`, and `gpu_ms_<pass>` (device time, 0 on the CPU) per pass the
/// GPU backend can run.
pub fn stats_columns(phases: &[Phase], solids: &[Solid]) -> Vec<String> {
    let mut c: Vec<String> = [
        "step",
        "time",
        "dt",
        "iterations",
        "density_error",
        "max_speed",
        "max_drift_speed",
        "cg_iterations",
        "cg_residual",
        "granular_substeps",
        "viscosity_iterations",
        "largest_density_error",
        "fluid_particles",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    c.extend(phases.iter().map(|p| format!("volume_{}", p.name)));
    c.extend(phases.iter().map(|p| format!("volume_outer_{}", p.name)));
    c.extend(phases.iter().map(|p| format!("volume_inner_{}", p.name)));
    c.extend(phases.iter().map(|p| format!("mass_{}", p.name)));
    let porous = || solids.iter().filter(|s| s.porous.is_some());
    c.extend(porous().map(|s| format!("absorbed_{}", s.name)));
    c.extend(porous().map(|s| format!("saturation_{}", s.name)));
    c.extend(Pass::ALL.iter().map(|p| format!("ms_{p}")));
    c.push("ms_step".to_string());
    c.extend(GpuPasses::PASSES.iter().map(|p| format!("gpu_ms_{p}")));
    c
}

/// Per porous solid of the scene (a `[[solid]]` with `[solid.porous]`, in
/// scene order): the liquid it holds, sum_i S_i h^3 over its particles,
/// m^3, and its mean saturation S = sum_k phi_k (P-Eq. 15: absorbed volume
/// per particle volume; at most its porosity), as two lists.
pub fn porous_solids(sim: &Simulation) -> (Vec<f64>, Vec<f64>) {
    let n = sim.scene.solids.len();
    let (mut sum, mut count) = (vec![0.0f64; n], vec![0usize; n]);
    for (&b, &s) in sim.solids.body.iter().zip(&sim.solids.saturation) {
        if let (Some(x), Some(c)) = (sum.get_mut(b as usize), count.get_mut(b as usize)) {
            *x += f64::from(s);
            *c += 1;
        }
    }
    let cell = f64::from(sim.params.cell_volume());
    let porous: Vec<usize> = (0..n).filter(|&b| sim.scene.solids[b].porous.is_some()).collect();
    let absorbed = porous.iter().map(|&b| sum[b] * cell).collect();
    let mean = porous.iter().map(|&b| if count[b] > 0 { sum[b] / count[b] as f64 } else { 0.0 }).collect();
    (absorbed, mean)
}

fn create_dir(p: &Path) -> Result<(), IoError> {
    std::fs::create_dir_all(p).map_err(|e| IoError::new(p, format!("cannot create directory: {e}")))
}

/// The run's static walls, in `frames/`: their positions and every array
/// but [`WALL_ARRAYS_PER_FRAME`], written once; each frame maps its wall
/// rows to this file (`io::SharedRows`), so ParaView and `porosph render`
/// still see the walls in every frame.
pub const WALLS_FILE: &str = "walls.vtkhdf";

/// The number `n` of a frame file `frame_<n>.vtkhdf`.
fn frame_number(name: &str) -> Option<u64> {
    let digits = name.strip_prefix("frame_")?.strip_suffix(".vtkhdf")?;
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    digits.parse().ok()
}

/// For a run that resumes with `frames` frames written: removes the frame
/// files numbered `frames` and on (written after the checkpoint, by the run
/// before it stopped) and their series entries. Returns how many files went.
fn remove_later_frames(dir: &Path, series: &mut SeriesWriter, frames: u64) -> Result<usize, IoError> {
    series.retain(|name| frame_number(name).is_none_or(|n| n < frames))?;
    let Ok(rd) = std::fs::read_dir(dir) else {
        return Ok(0);
    };
    let mut removed = 0;
    for e in rd.flatten() {
        let name = e.file_name();
        if name.to_str().and_then(frame_number).is_some_and(|n| n >= frames) {
            let p = e.path();
            std::fs::remove_file(&p).map_err(|err| IoError::new(&p, format!("cannot remove: {err}")))?;
            removed += 1;
        }
    }
    Ok(removed)
}

/// Runs `sim` as `opts` says.
pub fn run(sim: &mut Simulation, opts: &RunOptions) -> Result<RunSummary, RunError> {
    let frames_dir = opts.out.join("frames");
    create_dir(&frames_dir)?;
    // The scene as run, rerunnable from anywhere: mesh paths made absolute
    // (so also in the checkpoints, which store this text).
    sim.scene.text = sim.scene.with_absolute_mesh_paths();
    let scene_copy = opts.out.join("scene.toml");
    std::fs::write(&scene_copy, &sim.scene.text).map_err(|e| IoError::new(&scene_copy, e))?;
    let stats_path = opts.out.join("stats.csv");
    let series_path = frames_dir.join("frames.vtkhdf.series");
    let (mut stats, mut series, mut frames, mut next_frame) = match opts.resume {
        None => (
            StatsWriter::create(&stats_path, &stats_columns(&sim.scene.phases, &sim.scene.solids))?,
            SeriesWriter::new(&series_path),
            0u64,
            0.0f64,
        ),
        Some(c) => {
            let stats =
                StatsWriter::append(&stats_path, &stats_columns(&sim.scene.phases, &sim.scene.solids), sim.step)?;
            let mut series = SeriesWriter::open_existing(&series_path)?;
            let later = remove_later_frames(&frames_dir, &mut series, c.frames)?;
            if later > 0 && !opts.quiet {
                eprintln!(
                    "porosph: removed {later} frame{} (frame {} on) that the run had written \
                     after this checkpoint",
                    if later == 1 { "" } else { "s" },
                    c.frames
                );
            }
            (stats, series, c.frames, c.next_frame)
        }
    };
    let first_frame = frames;
    let mut checkpoints = Checkpoints::new(&opts.out.join("checkpoints"), opts.checkpoint_every, opts.keep)?;
    let first_step = sim.step;
    let (stop_time, stop_step) = match opts.steps {
        Some(s) => (None, Some(first_step.saturating_add(s))),
        None => (Some(opts.until.unwrap_or(sim.scene.simulation.end_time)), None),
    };
    let frame_every = opts.frame_every.unwrap_or(sim.scene.simulation.frame_interval);
    let run_info = |frames: u64, next_frame: f64| RunInfo {
        frames_written: frames,
        next_frame_time: next_frame,
        frame_every,
        stop_time,
        stop_step,
        checkpoint_every: opts.checkpoint_every.map(|c| c.to_string()).unwrap_or_default(),
        keep: u32::try_from(opts.keep).unwrap_or(u32::MAX),
        compress: opts.compress,
    };

    let bar = if opts.quiet {
        ProgressBar::hidden()
    } else {
        let (len, unit) = match opts.steps {
            Some(s) => (s, "steps"),
            None => ((stop_time.unwrap_or(0.0) * 1000.0).round() as u64, "ms simulated"),
        };
        let b = ProgressBar::new(len);
        b.set_style(
            ProgressStyle::with_template(&format!("{{bar:40}} {{pos}}/{{len}} {unit}  {{msg}}  eta {{eta}}"))
                .unwrap_or_else(|_| ProgressStyle::default_bar()),
        );
        b
    };

    // The walls once (again if a resumed run's file went missing; they
    // never move, so it is the same file).
    let walls_path = frames_dir.join(WALLS_FILE);
    if !sim.walls.is_empty() && (opts.resume.is_none() || !walls_path.is_file()) {
        let layout = FrameLayout { compress: opts.compress, shared: None };
        write_frame_as(&walls_path, &sim.frame().rows(sim.wall_rows()), &layout)?;
    }
    let write = |sim: &Simulation, frames: &mut u64, series: &mut SeriesWriter| -> Result<(), IoError> {
        let name = format!("frame_{:05}.vtkhdf", *frames);
        let frame = sim.frame();
        let static_arrays: Vec<&str> =
            frame.arrays.iter().map(|a| a.name.as_str()).filter(|n| !WALL_ARRAYS_PER_FRAME.contains(n)).collect();
        // The fluid comes first: its count may change, the walls' does not.
        let shared = (!sim.walls.is_empty()).then(|| SharedRows {
            file: WALLS_FILE,
            rows: sim.wall_rows(),
            arrays: &static_arrays,
        });
        write_frame_as(&frames_dir.join(&name), &frame, &FrameLayout { compress: opts.compress, shared })?;
        series.add(&name, sim.time)?;
        *frames += 1;
        Ok(())
    };
    if opts.resume.is_none() && sim.time >= next_frame {
        write(sim, &mut frames, &mut series)?;
        next_frame = sim.time + frame_every;
    }
    let start = Instant::now();
    let n = sim.fluid.len() as f64;
    let mut tally = Tally::start(sim);
    let done = |sim: &Simulation| match (stop_step, stop_time) {
        (Some(s), _) => sim.step >= s,
        (None, Some(t)) => sim.time >= t - 1e-9,
        (None, None) => true,
    };
    while !done(sim) {
        if let Some(signal) = interrupt::requested() {
            bar.abandon();
            // The series index is rewritten after every frame; once more,
            // so that it is there even if this run wrote no frame.
            series.write()?;
            let checkpoint = checkpoints.write_now(sim, &run_info(frames, next_frame));
            return Err(RunError::Interrupted { signal, step: sim.step, time: sim.time, checkpoint });
        }
        if opts.inject_nan_at_step == Some(sim.step) {
            if let Some(u) = sim.fluid.ux.first_mut() {
                *u = f32::NAN;
            }
        }
        let t = Instant::now();
        let previous_time = sim.time;
        let result = sim.step().copied();
        let st = match result {
            Ok(st) => st,
            Err(error) => {
                bar.abandon();
                // Keep the last state for diagnosis: as a frame to look at,
                // and as a checkpoint to inspect or load.
                let name = format!("frame_{:05}_failed.vtkhdf", frames);
                let _ = write_frame(&frames_dir.join(name), &sim.frame());
                let diagnostic = checkpoints.write_failed(sim, &run_info(frames, next_frame), &error.to_string());
                return Err(RunError::Step { error, diagnostic });
            }
        };
        let ms_step = t.elapsed().as_secs_f64() * 1e3;
        tally.step(&st);
        let mut row = vec![
            sim.step as f64,
            sim.time,
            st.dt as f64,
            st.iterations as f64,
            st.density_error as f64,
            st.max_speed as f64,
            st.max_drift_speed as f64,
            st.cg_iterations as f64,
            st.cg_residual as f64,
            st.granular_substeps as f64,
            st.viscosity_iterations as f64,
            st.largest_density_error as f64,
            n,
        ];
        let (outer, inner) = sim.phase_volumes_split();
        row.extend(sim.phase_volumes());
        row.extend(outer);
        row.extend(inner);
        row.extend(sim.phase_masses());
        let (absorbed, saturation) = porous_solids(sim);
        row.extend(absorbed);
        row.extend(saturation);
        row.extend(st.times.ms);
        row.push(ms_step);
        row.extend(GpuPasses::PASSES.iter().map(|&p| st.times.gpu(p)));
        stats.row(&row)?;
        if sim.time >= next_frame - 1e-9 {
            write(sim, &mut frames, &mut series)?;
            next_frame += frame_every;
        }
        if checkpoints.due(sim, previous_time) {
            if let Err(error) = checkpoints.write(sim, &run_info(frames, next_frame)) {
                bar.abandon();
                return Err(RunError::Checkpoint { error, last_good: checkpoints.last_good().map(Path::to_path_buf) });
            }
            tally.checkpoint();
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
    Ok(tally.finish(sim, frames - first_frame, start.elapsed().as_secs_f64()))
}
