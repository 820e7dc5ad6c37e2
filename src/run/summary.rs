//! The end of a run in a few lines a user can read: simulated time and
//! steps, the time step (mean, least, and which term of the rule held it),
//! the wall time per simulated second and the particle-steps per second
//! (fluid and solid), the pressure solve's mean iterations, how many of
//! its solves ran to the sweep cap and the largest row compression any
//! solve left (which a mean-error stop can hide), the process's
//! peak resident memory (what a cluster job must ask for), and with two or
//! more phases how much each phase's mass changed.

use crate::pipeline::{DtLimit, Simulation, StepStats};
use std::fmt;

/// What a finished run did.
#[derive(Clone, Debug, Default)]
pub struct RunSummary {
    /// Steps taken by this run.
    pub steps: u64,
    /// Frames written by this run.
    pub frames: u64,
    /// Checkpoints written by this run (on schedule).
    pub checkpoints: u64,
    pub wall_seconds: f64,
    /// Simulated time where the run started and where it stopped, s.
    pub start_time: f64,
    pub end_time: f64,
    pub fluid_particles: usize,
    pub solid_particles: usize,
    /// (fluid + solid particles) x steps / wall seconds.
    pub particle_steps_per_second: f64,
    /// Sum and least of the steps' dt, s (least: infinite without steps).
    pub dt_sum: f64,
    pub dt_min: f64,
    /// Steps whose dt each term of the rule set, in the order of
    /// [`DtLimit::ALL`].
    pub dt_held: [u64; DtLimit::ALL.len()],
    /// Steps whose dt was set before this run, so that its term is not
    /// known here: the first step of a resumed run (the checkpoint's dt).
    pub dt_held_before: u64,
    /// Pressure solve iterations, summed over the steps.
    pub iterations: u64,
    /// The solve's sweep cap (`max_iterations`), and the steps whose solve
    /// ran to it.
    pub max_iterations: u32,
    pub capped: u64,
    /// The largest predicted row compression a solve left
    /// (`StepStats::largest_density_error`; 0 where the GPU solved), the
    /// step that left it, and the solve's bound on the mean
    /// (`max_density_error`), fractions of rest density.
    pub largest_row: f32,
    pub largest_row_step: u64,
    pub mean_bound: f32,
    /// Per phase: its name and (mass at the end - mass at the start) /
    /// mass at the start (NaN if it had no mass).
    pub mass_change: Vec<(String, f64)>,
    /// The process's peak resident memory, bytes (`VmHWM` of
    /// /proc/self/status; `None` where the system has no such file).
    pub peak_memory: Option<u64>,
}

/// The process's peak resident set size so far, bytes (Linux `VmHWM`).
fn peak_resident_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// Tallies the steps of a run as it goes.
pub(super) struct Tally {
    summary: RunSummary,
    masses: Vec<f64>,
    /// The term that set the dt of the next step (`None`: set before the run).
    next: Option<DtLimit>,
    /// The simulation's step number before the run.
    first_step: u64,
}

impl Tally {
    pub fn start(sim: &Simulation) -> Tally {
        Tally {
            summary: RunSummary {
                start_time: sim.time,
                end_time: sim.time,
                dt_min: f64::INFINITY,
                fluid_particles: sim.fluid.len(),
                solid_particles: sim.solids.len(),
                max_iterations: sim.params.max_iterations,
                mean_bound: sim.params.max_density_error,
                ..RunSummary::default()
            },
            masses: sim.phase_masses(),
            next: sim.last.next_dt_limit,
            first_step: sim.step,
        }
    }

    /// Counts a step just taken, whose stats are `st`.
    pub fn step(&mut self, st: &StepStats) {
        let s = &mut self.summary;
        s.steps += 1;
        s.dt_sum += f64::from(st.dt);
        s.dt_min = s.dt_min.min(f64::from(st.dt));
        s.iterations += u64::from(st.iterations);
        s.capped += u64::from(st.iterations >= s.max_iterations);
        if st.largest_density_error > s.largest_row {
            (s.largest_row, s.largest_row_step) = (st.largest_density_error, self.first_step + s.steps);
        }
        match self.next {
            Some(l) => s.dt_held[l as usize] += 1,
            None => s.dt_held_before += 1,
        }
        self.next = st.next_dt_limit;
    }

    pub fn checkpoint(&mut self) {
        self.summary.checkpoints += 1;
    }

    pub fn finish(mut self, sim: &Simulation, frames: u64, wall_seconds: f64) -> RunSummary {
        let s = &mut self.summary;
        s.frames = frames;
        s.wall_seconds = wall_seconds;
        s.end_time = sim.time;
        let particles = (s.fluid_particles + s.solid_particles) as f64;
        s.particle_steps_per_second = particles * s.steps as f64 / wall_seconds.max(1e-9);
        s.mass_change = sim
            .scene
            .phases
            .iter()
            .zip(self.masses.iter().zip(sim.phase_masses()))
            .map(|(p, (&m0, m1))| (p.name.clone(), if m0 > 0.0 { (m1 - m0) / m0 } else { f64::NAN }))
            .collect();
        s.peak_memory = peak_resident_bytes();
        self.summary
    }
}

/// Seconds in the unit that reads best: s, ms or us.
fn seconds(t: f64) -> String {
    if t >= 1.0 {
        format!("{t:.3} s")
    } else if t >= 1e-4 {
        format!("{:.3} ms", t * 1e3)
    } else {
        format!("{:.3} us", t * 1e6)
    }
}

fn plural(n: u64, one: &str, many: &str) -> String {
    format!("{n} {}", if n == 1 { one } else { many })
}

impl fmt::Display for RunSummary {
    /// Lines of the form `porosph: ...`, without a final newline.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let simulated = self.end_time - self.start_time;
        write!(
            f,
            "porosph: done: t = {:.4} to {:.4} s ({simulated:.4} s simulated) in {}, {}, {}, {:.1} s wall",
            self.start_time,
            self.end_time,
            plural(self.steps, "step", "steps"),
            plural(self.frames, "frame", "frames"),
            plural(self.checkpoints, "checkpoint", "checkpoints"),
            self.wall_seconds
        )?;
        if self.steps == 0 {
            return Ok(());
        }
        let mut held: Vec<String> = DtLimit::ALL
            .iter()
            .zip(&self.dt_held)
            .filter(|(_, &n)| n > 0)
            .map(|(l, &n)| format!("{} {n}", l.name()))
            .collect();
        if self.dt_held_before > 0 {
            held.push(format!("the checkpoint's dt {}", self.dt_held_before));
        }
        write!(
            f,
            "\nporosph:   dt: mean {}, least {}; steps held by {}",
            seconds(self.dt_sum / self.steps as f64),
            seconds(self.dt_min),
            held.join(", ")
        )?;
        write!(
            f,
            "\nporosph:   speed: {:.1} s wall per simulated s, {:.3} M particle-steps/s ({} fluid + {} solid particles)",
            self.wall_seconds / simulated.max(1e-300),
            self.particle_steps_per_second / 1e6,
            self.fluid_particles,
            self.solid_particles
        )?;
        write!(
            f,
            "\nporosph:   pressure solve: {:.1} iterations per step (mean), {} at the cap of {}",
            self.iterations as f64 / self.steps as f64,
            match self.capped {
                0 => "no step".to_string(),
                n => plural(n, "step", "steps"),
            },
            self.max_iterations
        )?;
        if self.largest_row > 0.0 {
            write!(
                f,
                "; largest row compression left {:.2} % (step {}; the mean's bound {:.2} %)",
                100.0 * self.largest_row,
                self.largest_row_step,
                100.0 * self.mean_bound
            )?;
        }
        if let Some(b) = self.peak_memory {
            let particles = (self.fluid_particles + self.solid_particles).max(1);
            write!(
                f,
                "\nporosph:   memory: peak {:.1} MB resident ({:.0} B per fluid + solid particle)",
                b as f64 / 1e6,
                b as f64 / particles as f64
            )?;
        }
        if self.mass_change.len() > 1 {
            let m: Vec<String> = self.mass_change.iter().map(|(n, c)| format!("{n} {c:+.2e}")).collect();
            write!(f, "\nporosph:   mass change over the run (relative): {}", m.join(", "))?;
        }
        Ok(())
    }
}
