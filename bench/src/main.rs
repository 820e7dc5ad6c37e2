//! Dam-break benchmark of the whole step, per pass.
//!
//! The scene is SPlisHSPlasH's DamBreakModel geometry, as run by
//! `../shared/peers/splishsplash_dambreak.py`: a 1 m fluid cube at
//! x[-1.95,-0.95] y[0.05,1.05] z[-0.5,0.5] in a 4 x 3 x 1.5 m tank
//! (x[-2,2] y[0,3] z[-0.75,0.75]), water (1000 kg/m^3, 0.01 Pa s), dt fixed
//! at `--dt` like the peer's (CFL number 1, which binds only above
//! h / dt = 16 m/s at 250k particles and 1 ms; the run reports the smallest
//! dt taken).
//!
//! Prints particle-steps/s of the whole step (fluid particles x steps /
//! wall seconds), mean ms per pass, mean solver iterations, and bytes of
//! memory per fluid particle; `--json FILE` appends the result as JSON.
//!
//! `--phases K` (default 1) fills the column with an even mixture of K
//! phases (densities 1000, 1100, ... kg/m^3, all 0.01 Pa s, the default
//! drift weights), so the mixture passes (drift, drift momentum, transport,
//! correction) run on every particle; their cost is also printed in ns per
//! particle-step.
//!
//! `--backend gpu` runs the passes of `--gpu-passes` (default: all the GPU
//! backend has) on the GPU through wgpu and also prints their device time
//! (timestamp queries) per pass and per Jacobi iteration.
//!
//! ```sh
//! cargo run --release -p porosph-bench -- --spacing 0.015625 --steps 60 --warmup 10 --threads 2
//! cargo run --release -p porosph-bench -- --spacing 0.015625 --steps 4 --warmup 1 --backend gpu
//! cargo run --release -p porosph-bench -- --spacing 0.025 --steps 40 --warmup 10 --phases 3
//! cargo run --release -p porosph-bench -- --spacing 0.015625 --steps 60 --warmup 10 --solid
//! cargo run --release -p porosph-bench -- --spacing 0.01 --steps 30 --warmup 10 --dt 0.002 --porous
//! ```
//!
//! `--scene FILE` runs a scene file instead, with its own time-step rule
//! (`--spacing`, `--dt` as its max_dt and `--max-error` override the file
//! only when given), e.g. the paper's Example 1 at the paper's size (about
//! 400k fluid particles at d = 2.4 mm):
//!
//! ```sh
//! cargo run --release -p porosph-bench -- --scene scenes/example1_wave_block.toml --spacing 0.0024 --steps 50 --warmup 10
//! ```
//!
//! Every mode also prints the simulated time of the measured steps, their
//! mean dt and the wall seconds per simulated second.
//!
//! `--porous` replaces the dam break by the porous coupling (issue 5): a
//! closed 1.2 x 0.7 x 0.4 m tank filled to 0.6 m with an even mixture of
//! three phases (water 1000, oil 800, brine 1200 kg/m^3, all 1 Pa s) around
//! a porous elastic block (0.3 m cube on the floor, 600 kg/m^3, mu = 2e4 Pa,
//! lambda = 1e4 Pa, porosity 0.6, p0 = 5e4 Pa, B = 4.9e4 Pa, eta = 7.5e-4,
//! psi = 2, K = 1) that absorbs water (permeability 1e-7 m^2, p0k =
//! 2.5e4 Pa) and oil (3e-8 m^2, 2e4 Pa) but not brine. The whole block is
//! `fixed` (held in place: with only its bottom fixed, or free, this soft
//! block blew up within 20-50 steps, also without the porous terms), so the
//! elasticity pass computes strain and stress but its CG has nothing to
//! solve. Drift weights are the defaults (P Table 2). At spacing 0.01 m:
//! 261k fluid + 27k solid particles. Warm-up steps let it soak, so
//! the porous pass, the inner (beta) drift and transport have work when
//! timing starts; the inner volume per phase and the solid's saturation are
//! printed at the start and the end of the measured steps. The pool is 60
//! layers deep: its first five or so steps solve in two sweeps while the
//! column sags, then its solve takes 2-100 sweeps a step (10.6 a step on
//! average over steps 11-40, against 2.0 over steps 2-4; the same without
//! the block, bench/RESULTS.md, "The porous bench's first steps"), so
//! compare steps after at least 10 warm-up steps.

use clap::Parser;
use porosph::backend::gpu::GpuBackend;
use porosph::backend::{BackendKind, GpuPasses};
use porosph::pipeline::{Pass, Simulation};
use porosph::scene::Scene;
use std::io::Write;
use std::time::Instant;

/// Dam-break (or porous, or scene-file) benchmark of the whole step, per
/// pass.
#[derive(Parser)]
#[command(name = "porosph-bench", about)]
struct Cli {
    /// Particle spacing, m (default 0.015625; a scene file's own unless given).
    #[arg(long, value_name = "M", conflicts_with = "particles")]
    spacing: Option<f32>,
    /// Particles per m^3 instead of a spacing: spacing = 1 / cbrt(N).
    #[arg(long, value_name = "N")]
    particles: Option<f64>,
    /// Steps in all, warm-up included.
    #[arg(long, default_value_t = 60)]
    steps: u64,
    /// Steps before the measurement starts.
    #[arg(long, default_value_t = 10)]
    warmup: u64,
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Mean density error of the pressure solve, fraction (default 0.001;
    /// a scene file's own unless given).
    #[arg(long, value_name = "FRACTION")]
    max_error: Option<f32>,
    /// Time step, s (default 0.001; a scene file's max_dt unless given).
    #[arg(long, value_name = "S")]
    dt: Option<f32>,
    /// Phases of the dam break's even mixture.
    #[arg(long, value_name = "K", default_value_t = 1)]
    phases: usize,
    /// Add an elastic block (0.5 m cube, Peer 2018) in the dam's path.
    #[arg(long)]
    solid: bool,
    /// The porous three-phase scene instead of the dam break.
    #[arg(long)]
    porous: bool,
    /// A scene file instead of the built-in scenes.
    #[arg(long, value_name = "FILE")]
    scene: Option<String>,
    /// Append the result as one JSON line to FILE.
    #[arg(long, value_name = "FILE")]
    json: Option<String>,
    #[arg(long, value_name = "cpu|gpu", default_value = "cpu")]
    backend: BackendKind,
    /// The passes `--backend gpu` runs on the GPU (comma-separated, or `all`).
    #[arg(long, value_name = "PASSES", default_value = "all")]
    gpu_passes: GpuPasses,
    /// The pressure solve's Chebyshev semi-iteration (`chebyshev_radius`
    /// in [0, 1); 0 = plain Jacobi; default: the scene's, 0 for the
    /// built-in scenes).
    #[arg(long, value_name = "RHO")]
    chebyshev_radius: Option<f32>,
}

struct Args {
    spacing: f32,
    steps: u64,
    warmup: u64,
    threads: usize,
    max_error: f32,
    dt: f32,
    phases: usize,
    solid: bool,
    porous: bool,
    /// A scene file instead of the built-in scenes; `--spacing`, `--dt`
    /// (its max_dt) and `--max-error` override its values only when given.
    scene: Option<String>,
    /// Which of --spacing, --dt, --max-error were given.
    given: Given,
    json: Option<String>,
    backend: BackendKind,
    gpu_passes: GpuPasses,
    chebyshev_radius: Option<f32>,
}

#[derive(Default)]
struct Given {
    spacing: bool,
    dt: bool,
    max_error: bool,
}

fn parse() -> Result<Args, String> {
    let c = Cli::parse();
    let spacing = c.spacing.or(c.particles.map(|n| (1.0 / n.cbrt()) as f32));
    let mut a = Args {
        spacing: spacing.unwrap_or(0.015625),
        steps: c.steps,
        warmup: c.warmup,
        threads: c.threads,
        max_error: c.max_error.unwrap_or(0.001),
        dt: c.dt.unwrap_or(0.001),
        phases: c.phases,
        solid: c.solid,
        porous: c.porous,
        scene: c.scene,
        given: Given { spacing: spacing.is_some(), dt: c.dt.is_some(), max_error: c.max_error.is_some() },
        json: c.json,
        backend: c.backend,
        gpu_passes: c.gpu_passes,
        chebyshev_radius: c.chebyshev_radius,
    };
    if a.chebyshev_radius.is_some_and(|r| !(0.0..1.0).contains(&r)) {
        return Err("--chebyshev-radius must be in [0, 1)".into());
    }
    if a.steps <= a.warmup {
        return Err("--steps must exceed --warmup".into());
    }
    if a.phases == 0 {
        return Err("--phases must be at least 1".into());
    }
    if a.scene.is_some() && (a.porous || a.solid || a.phases != 1) {
        return Err("--scene runs the scene file as it is: leave out --porous, --solid and --phases".into());
    }
    if a.porous {
        if a.solid {
            return Err("--porous and --solid are different scenes: give one".into());
        }
        if a.phases != 1 && a.phases != 3 {
            return Err("--porous runs three phases (water, oil, brine); leave out --phases".into());
        }
        a.phases = 3;
    }
    Ok(a)
}

/// The `--porous` scene.
fn porous_scene(a: &Args) -> Result<Scene, String> {
    let text = format!(
        r#"[simulation]
particle_spacing = {sp}
end_time = 100.0
max_dt = {dt}
max_density_error = {err}
frame_interval = 100.0
cfl_number = 1.0
[[phase]]
name = "water"
density = 1000.0
viscosity = 1.0
[[phase]]
name = "oil"
density = 800.0
viscosity = 1.0
[[phase]]
name = "brine"
density = 1200.0
viscosity = 1.0
[[fluid]]
box = {{ min = [0.0, 0.0, 0.0], max = [1.2, 0.6, 0.4] }}
fractions = {{ water = 0.3333333, oil = 0.3333334, brine = 0.3333333 }}
[[wall]]
box = {{ min = [0.0, 0.0, 0.0], max = [1.2, 0.7, 0.4] }}
container = true
[[solid]]
name = "sponge"
box = {{ min = [0.45, 0.0, 0.05], max = [0.75, 0.3, 0.35] }}
density = 600.0
shear_modulus = 2e4
lame_lambda = 1e4
fixed = {{ box = {{ min = [0.45, 0.0, 0.05], max = [0.75, 0.3, 0.35] }} }}
[solid.porous]
porosity = 0.6
rest_pore_pressure = 5e4
biot_modulus = 4.9e4
swelling = 7.5e-4
capillarity = 2.0
absorption = 1.0
[solid.porous.phase.water]
permeability = 1e-7
outer_pore_pressure = 2.5e4
[solid.porous.phase.oil]
permeability = 3e-8
outer_pore_pressure = 2.0e4
"#,
        sp = a.spacing,
        dt = a.dt,
        err = a.max_error,
    );
    Scene::from_toml_str(&text, "<bench porous>").map_err(|e| e.to_string())
}

/// The `--scene` file with the overrides that were given.
fn scene_file(a: &Args, path: &str) -> Result<Scene, String> {
    let mut scene = Scene::from_file(std::path::Path::new(path)).map_err(|e| e.to_string())?;
    if a.given.spacing {
        scene.simulation.particle_spacing = a.spacing;
    }
    if a.given.dt {
        scene.simulation.max_dt = a.dt;
    }
    if a.given.max_error {
        scene.simulation.max_density_error = a.max_error;
    }
    Ok(scene)
}

fn scene(a: &Args) -> Result<Scene, String> {
    if let Some(path) = &a.scene {
        return scene_file(a, path);
    }
    if a.porous {
        return porous_scene(a);
    }
    let mut phases = String::new();
    let mut fractions = Vec::new();
    for k in 0..a.phases {
        let rho = 1000.0 + 100.0 * k as f64;
        phases.push_str(&format!("[[phase]]\nname = \"p{k}\"\ndensity = {rho:.1}\nviscosity = 0.01\n"));
        fractions.push(format!("p{k} = {}", 1.0 / a.phases as f64));
    }
    let text = format!(
        r#"[simulation]
particle_spacing = {sp}
end_time = 100.0
max_dt = {dt}
max_density_error = {err}
frame_interval = 100.0
cfl_number = 1.0
{phases}
[[fluid]]
box = {{ min = [-1.95, 0.05, -0.5], max = [-0.95, 1.05, 0.5] }}
fractions = {{ {fr} }}
[[wall]]
box = {{ min = [-2.0, 0.0, -0.75], max = [2.0, 3.0, 0.75] }}
container = true
"#,
        sp = a.spacing,
        dt = a.dt,
        err = a.max_error,
        fr = fractions.join(", ")
    );
    let text = if a.solid {
        text + r#"
[[solid]]
name = "block"
box = { min = [0.0, 0.0, -0.25], max = [0.5, 0.5, 0.25] }
density = 800.0
shear_modulus = 1e5
lame_lambda = 5e4
"#
    } else {
        text
    };
    Scene::from_toml_str(&text, "<bench dam break>").map_err(|e| e.to_string())
}

/// What the porous solid holds: the inner volume sum h^3 beta_k per phase
/// (m^3), the mean and largest saturation sum_k phi_sk and the largest pore
/// pressure of the solid particles, and the number of fluid particles with
/// an inner part.
struct Soak {
    inner: Vec<f64>,
    mean_saturation: f64,
    max_saturation: f32,
    max_pore_pressure: f32,
    wet_fluid: usize,
}

fn soak(sim: &Simulation) -> Soak {
    let (_, inner) = sim.phase_volumes_split();
    let sat = &sim.solids.saturation;
    let n = sim.fluid.len();
    Soak {
        inner,
        mean_saturation: sat.iter().map(|&x| f64::from(x)).sum::<f64>() / sat.len().max(1) as f64,
        max_saturation: sat.iter().copied().fold(0.0, f32::max),
        max_pore_pressure: sim.solids.pore_pressure.iter().copied().fold(0.0, f32::max),
        wet_fluid: (0..n).filter(|&i| sim.fluid.beta.iter().any(|b| b[i] > 0.0)).count(),
    }
}

fn print_soak(what: &str, s: &Soak) {
    let inner: Vec<String> = s.inner.iter().map(|v| format!("{:.3e}", v)).collect();
    println!(
        "{what}: inner volume per phase [{}] m^3, saturation mean {:.4} max {:.4}, max pore pressure {:.0} Pa, \
         {} fluid particles with beta > 0",
        inner.join(", "),
        s.mean_saturation,
        s.max_saturation,
        s.max_pore_pressure,
        s.wet_fluid
    );
}

/// CPU time of the whole machine that is not idle, of this process, and of
/// niced processes, in clock ticks (from /proc): to tell steps disturbed by
/// other processes.
fn cpu_snapshot() -> Option<(u64, u64, u64)> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let v: Vec<u64> = stat.lines().next()?.split_whitespace().skip(1).filter_map(|x| x.parse().ok()).collect();
    // busy = all - nice - idle - iowait (niced background jobs do not count)
    let busy = v.iter().sum::<u64>() - v.get(1)? - v.get(3)? - v.get(4)?;
    let own = std::fs::read_to_string("/proc/self/stat").ok()?;
    let w: Vec<&str> = own.rsplit_once(')')?.1.split_whitespace().collect();
    Some((busy, w.get(11)?.parse::<u64>().ok()? + w.get(12)?.parse::<u64>().ok()?, *v.get(1)?))
}

fn main() {
    porosph_kernels::neighbors::large_allocations_from_mmap();
    let a = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build().expect("thread pool");
    pool.install(|| bench(&a));
}

fn bench(a: &Args) {
    let scene = match scene(a) {
        Ok(mut s) => {
            if let Some(r) = a.chebyshev_radius {
                s.simulation.chebyshev_radius = r;
            }
            s
        }
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    // What the run uses (a `--scene` file has its own values).
    let phases = scene.phases.len();
    let (spacing, max_dt, max_error) =
        (scene.simulation.particle_spacing, scene.simulation.max_dt, scene.simulation.max_density_error);
    let t0 = Instant::now();
    let mut sim = Simulation::new(scene);
    let setup_s = t0.elapsed().as_secs_f64();
    if a.backend == BackendKind::Gpu {
        match GpuBackend::new(a.gpu_passes) {
            Ok(g) => {
                eprintln!("GPU backend on {}", g.ctx.describe());
                sim.use_gpu(g);
            }
            Err(e) => {
                eprintln!("{e}");
                std::process::exit(2);
            }
        }
    }
    let n = sim.fluid.len();
    eprintln!(
        "{} fluid + {} wall + {} solid particles, {} phase(s), setup {:.2} s, {} threads",
        n,
        sim.walls.len(),
        sim.solids.len(),
        phases,
        setup_s,
        a.threads
    );
    let mut pass_ms = [0.0f64; Pass::COUNT];
    // The same over the clean steps only (< 5 % foreign load).
    let mut clean_ms = [0.0f64; Pass::COUNT];
    let mut gpu_ms = [0.0f64; Pass::COUNT];
    let (mut iters, mut wall_s, mut measured, mut min_dt) = (0u64, 0.0f64, 0u64, f32::MAX);
    let mut cg_iters = 0u64;
    let mut visc_iters = 0u64;
    let mut step_s = Vec::new();
    let mut clean_s = Vec::new();
    let tick = 100.0; // USER_HZ on Linux
    let cpus = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1) as f64;
    let mut soak_start = None;
    let mut t_start = sim.time;
    let (mut foreign_sum, mut niced_sum) = (0.0f64, 0.0f64);
    for s in 0..a.steps {
        if s == a.warmup {
            t_start = sim.time;
            if a.porous {
                soak_start = Some(soak(&sim));
            }
        }
        let c0 = cpu_snapshot();
        let t = Instant::now();
        let st = *sim.step().unwrap_or_else(|e| panic!("{e}"));
        let el = t.elapsed().as_secs_f64();
        if let (Some((b0, o0, n0)), Some((b1, o1, n1))) = (c0, cpu_snapshot()) {
            // Share of the machine used by other processes during this step.
            let foreign = ((b1 - b0) as f64 - (o1 - o0) as f64) / tick / (el * cpus);
            if s >= a.warmup {
                niced_sum += (n1 - n0) as f64 / tick / (el * cpus);
            }
            if s >= a.warmup && foreign < 0.05 {
                clean_s.push(el);
                for (acc, v) in clean_ms.iter_mut().zip(st.times.ms) {
                    *acc += v;
                }
            }
            if s >= a.warmup {
                foreign_sum += foreign.max(0.0);
            }
        }
        if s >= a.warmup {
            measured += 1;
            wall_s += el;
            step_s.push(el);
            iters += st.iterations as u64;
            cg_iters += u64::from(st.cg_iterations);
            visc_iters += u64::from(st.viscosity_iterations);
            min_dt = min_dt.min(st.dt);
            for (acc, v) in pass_ms.iter_mut().zip(st.times.ms) {
                *acc += v;
            }
            for (acc, v) in gpu_ms.iter_mut().zip(st.times.gpu_ms) {
                *acc += v;
            }
        }
    }
    step_s.sort_by(f64::total_cmp);
    let median = step_s[step_s.len() / 2];
    clean_s.sort_by(f64::total_cmp);
    let median_clean = clean_s.get(clean_s.len() / 2).copied();
    let m = measured as f64;
    let pps = n as f64 * m / wall_s;
    let (ff, fb) = sim.pair_counts();
    println!("fluid particles      {n}");
    println!("phases               {}", phases);
    if !sim.solids.is_empty() {
        println!(
            "solid particles      {} (model {}); mean CG iterations {:.1}, elasticity {:.1} ns per solid particle-step",
            sim.solids.len(),
            sim.solid_model.name(),
            cg_iters as f64 / m,
            pass_ms[Pass::Elasticity.index()] / m * 1e6 / sim.solids.len() as f64
        );
    }
    println!(
        "steps measured       {measured} (after {} warm-up), t = {:.3} s, min dt {:.2e} s",
        a.warmup, sim.time, min_dt
    );
    println!("mean s/step          {:.4}  (median {:.4})", wall_s / m, median);
    // What a user of a long run feels: wall time per simulated second over
    // the measured window (the time step is the scene's rule: CFL, max_dt).
    let simulated = sim.time - t_start;
    println!(
        "simulated            {:.4} s in the measured steps, mean dt {:.3e} s: {:.0} wall s per simulated s",
        simulated,
        simulated / m,
        wall_s / simulated
    );
    match median_clean {
        Some(mc) => println!("median of clean steps {:.4}  ({} steps with < 5 % foreign CPU load)", mc, clean_s.len()),
        None => println!("median of clean steps: none (other processes loaded the machine in every step)"),
    }
    println!(
        "foreign CPU load     {:.2} of {} cores on average in the measured steps (other processes; \
         niced ones, not counted against clean steps: {:.2} more)",
        foreign_sum / m * cpus,
        cpus,
        niced_sum / m * cpus
    );
    println!("particle-steps/s     {:.3} M  (median step: {:.3} M)", pps / 1e6, n as f64 / median / 1e6);
    if !sim.solids.is_empty() {
        let ns = sim.solids.len();
        println!(
            "particle-steps/s, fluid + solid {:.3} M  (median step: {:.3} M)",
            (n + ns) as f64 * m / wall_s / 1e6,
            (n + ns) as f64 / median / 1e6
        );
    }
    if a.porous {
        let ms = |p: Pass| pass_ms[p.index()] / m;
        println!(
            "porous pass          {:.2} ms = {:.1} ns per fluid particle-step; elasticity {:.2} ms, \
             drift {:.2} ms, phase_transport {:.2} ms",
            ms(Pass::Porous),
            ms(Pass::Porous) * 1e6 / n as f64,
            ms(Pass::Elasticity),
            ms(Pass::Drift),
            ms(Pass::PhaseTransport)
        );
        if let Some(s0) = &soak_start {
            print_soak("soak at first timed step", s0);
        }
        print_soak("soak at the end", &soak(&sim));
    }
    println!("mean iterations      {:.2}", iters as f64 / m);
    if sim.params.implicit_viscosity {
        println!("implicit viscosity   {:.1} CG iterations per step", visc_iters as f64 / m);
    }
    println!("pairs/particle       {:.1} fluid, {:.1} wall", ff as f64 / n as f64, fb as f64 / n as f64);
    println!("bytes/particle       {:.0}", sim.bytes_per_particle());
    let per = |b: usize| b as f64 / n as f64;
    let parts: Vec<String> =
        sim.memory().iter().filter(|(_, b)| *b > 0).map(|(k, b)| format!("{k} {:.0}", per(*b))).collect();
    println!("  of which, per fluid particle: {}", parts.join(", "));
    println!("  step arena used     {:.0} per fluid particle (its high-water mark)", per(sim.arena_used()));
    println!("  pass scratch used   {:.0} per fluid particle (its high-water mark)", per(sim.scratch_used()));
    println!("backend              {}", a.backend);
    let nc = clean_s.len();
    println!(
        "ms per pass (mean; wall, and device time of passes on the GPU{}):",
        if nc > 0 { format!("; then the mean over the {nc} clean steps") } else { String::new() }
    );
    for (((p, v), g), c) in Pass::ALL.iter().zip(pass_ms).zip(gpu_ms).zip(clean_ms) {
        let clean = if nc > 0 { format!("  (clean {:.2})", c / nc as f64) } else { String::new() };
        if g > 0.0 {
            println!("  {:<16} {:8.2}  (GPU device {:.2}){clean}", p, v / m, g / m);
        } else {
            println!("  {:<16} {:8.2}{clean}", p, v / m);
        }
    }
    let k = Pass::PressureSolve.index();
    println!("pressure_solve ms per Jacobi iteration {:.3}", pass_ms[k] / iters.max(1) as f64);
    if phases > 1 {
        println!("mixture passes, ns per particle-step:");
        for p in [Pass::Drift, Pass::DriftMomentum, Pass::PhaseTransport, Pass::PhaseCorrection] {
            println!("  {:<16} {:8.1}", p.name(), pass_ms[p.index()] / m * 1e6 / n as f64);
        }
    }
    if let Some(path) = &a.json {
        let passes: Vec<String> =
            Pass::ALL.iter().zip(pass_ms).map(|(p, v)| format!("\"{p}\": {:.3}", v / m)).collect();
        let line = format!(
            "{{\"fluid_particles\": {n}, \"phases\": {}, \"spacing\": {}, \"threads\": {}, \"dt\": {}, \"max_error\": {}, \
             \"steps\": {measured}, \"warmup\": {}, \"mean_s_per_step\": {:.5}, \"median_s_per_step\": {:.5}, \
             \"particle_steps_per_s\": {:.0}, \"mean_iterations\": {:.2}, \"bytes_per_particle\": {:.0}, \
             \"median_s_clean\": {}, \"clean_steps\": {}, \"backend\": \"{}\", \"solid_particles\": {}, \
             \"porous\": {}, \"scene\": {}, \"simulated_s\": {:.6}, \"wall_s_per_simulated_s\": {:.1}, \
             \"ms_per_pass\": {{{}}}}}",
            phases,
            spacing,
            a.threads,
            max_dt,
            max_error,
            a.warmup,
            wall_s / m,
            median,
            pps,
            iters as f64 / m,
            sim.bytes_per_particle(),
            median_clean.map_or("null".to_string(), |v| format!("{v:.5}")),
            clean_s.len(),
            a.backend,
            sim.solids.len(),
            a.porous,
            a.scene.as_ref().map_or("null".to_string(), |p| format!("{p:?}")),
            simulated,
            wall_s / simulated,
            passes.join(", ")
        );
        match std::fs::OpenOptions::new().create(true).append(true).open(path) {
            Ok(mut f) => {
                let _ = writeln!(f, "{line}");
            }
            Err(e) => eprintln!("{path}: {e}"),
        }
    }
}
