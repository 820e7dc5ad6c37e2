//! The `porosph` command line (DESIGN.md, "Interfaces users rely on").

use clap::{Args, Parser, Subcommand};
use porosph::backend::gpu::GpuBackend;
use porosph::backend::{BackendKind, GpuPasses};
use porosph::builtin;
use porosph::io::checkpoint::{file_kind, inspect_checkpoint, read_checkpoint, FileKind};
use porosph::io::inspect_frame;
use porosph::pipeline::Simulation;
use porosph::render::{self, Camera, ColorMode, RenderOptions};
use porosph::run::{run, CheckpointEvery, Continuation, RunOptions, DEFAULT_KEEP};
use porosph::scene::Scene;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "porosph", version, about = "Multiple fluids through porous, deformable solids, one particle system")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// Options shared by `run` and `resume`.
#[derive(Args)]
struct RunArgs {
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Stop at this simulated time, s (run: default the scene's end_time;
    /// resume: default where the saved run was going to stop).
    #[arg(long, conflicts_with = "steps")]
    until: Option<f64>,
    /// Stop after this many steps (resume: this many more steps).
    #[arg(long)]
    steps: Option<u64>,
    /// Simulated time between frames, s (run: default the scene's
    /// frame_interval; resume: default the saved run's).
    #[arg(long)]
    frame_every: Option<f64>,
    /// Write a checkpoint (complete state, HDF5) to OUT/checkpoints/ckpt_<step>.h5
    /// every SECONDS of simulated time (`0.1` or `0.1s`) or every N steps
    /// (`500steps`). Resume: default the saved run's schedule. A step that
    /// fails (NaN, explosion) always writes OUT/checkpoints/ckpt_<step>_failed.h5.
    #[arg(long, value_name = "SECONDS|Nsteps", value_parser = parse_every)]
    checkpoint_every: Option<CheckpointEvery>,
    /// Keep the newest N checkpoints (default 3; resume: the saved run's).
    #[arg(long, value_name = "N")]
    keep: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
    /// Where the offloadable passes run: `cpu` (every pass on the CPU,
    /// bitwise deterministic) or `gpu` (through wgpu/Vulkan; the passes of
    /// --gpu-passes on the GPU, the rest on the CPU).
    #[arg(long, default_value = "cpu", value_name = "cpu|gpu")]
    backend: BackendKind,
    /// With --backend gpu: the passes to run on the GPU, by their stats.csv
    /// names, comma-separated (`pressure_solve`), or `all` (default).
    #[arg(long, value_name = "PASSES", default_value = "all")]
    gpu_passes: GpuPasses,
    /// Testing aid: set a fluid velocity to NaN before the step that starts
    /// at step N, to exercise the failure path (diagnostic checkpoint,
    /// non-zero exit).
    #[arg(long, value_name = "N", hide = true)]
    inject_nan_at_step: Option<u64>,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene (a TOML file or a built-in name; default: the built-in dam break).
    Run {
        /// Scene file or built-in scene name (see `porosph scenes`).
        scene: Option<String>,
        /// Output directory.
        #[arg(long, default_value = "out")]
        out: PathBuf,
        #[command(flatten)]
        args: RunArgs,
    },
    /// Continue a run from a checkpoint: the resumed run computes bitwise
    /// what the run would have computed without stopping (CPU).
    Resume {
        /// A checkpoint file (OUT/checkpoints/ckpt_<step>.h5).
        checkpoint: PathBuf,
        /// Output directory (default: the checkpoint's run directory, the
        /// parent of its checkpoints/ folder): frames continue their
        /// numbering, stats.csv is continued from the checkpoint's step.
        #[arg(long)]
        out: Option<PathBuf>,
        #[command(flatten)]
        args: RunArgs,
    },
    /// List the built-in scenes and the example scenes in ./scenes.
    Scenes,
    /// Print what a frame or checkpoint file holds; for a checkpoint, also
    /// check every dataset's checksum (exit status 1 if one fails).
    Inspect {
        /// A frame (.vtkhdf) or checkpoint (.h5) file; recognised by content.
        file: PathBuf,
    },
    /// Render a frame to a PNG picture (headless: shaded particle spheres),
    /// or with --movie every frame of a run directory to OUTDIR/render/.
    Render {
        /// A frame file (.vtkhdf), or with --movie a run directory (OUTDIR,
        /// holding frames/).
        input: PathBuf,
        /// Output picture (default: the frame's name with .png).
        #[arg(short, long, conflicts_with = "movie")]
        out: Option<PathBuf>,
        /// Image width, pixels.
        #[arg(long, default_value_t = 1280)]
        width: u32,
        /// Image height, pixels.
        #[arg(long, default_value_t = 720)]
        height: u32,
        /// Colour by: phase (the phase mixture), speed or pressure (colormap).
        #[arg(long, default_value = "phase", value_parser = parse_color)]
        color: ColorMode,
        /// Draw the wall particles (faintly).
        #[arg(long)]
        walls: bool,
        /// Orthographic camera (default: perspective).
        #[arg(long)]
        ortho: bool,
        /// Render every frame of OUTDIR/frames/ to OUTDIR/render/frame_NNNNN.png,
        /// with one camera and colour range for all.
        #[arg(long)]
        movie: bool,
    },
}

fn parse_color(s: &str) -> Result<ColorMode, String> {
    s.parse()
}

fn parse_every(s: &str) -> Result<CheckpointEvery, String> {
    s.parse()
}

fn load_scene(arg: Option<&str>) -> Result<Scene, String> {
    let name = arg.unwrap_or(builtin::DEFAULT);
    let path = Path::new(name);
    if path.exists() {
        return Scene::from_file(path).map_err(|e| e.to_string());
    }
    if let Some(b) = builtin::find(name) {
        return Scene::from_toml_str(b.text, &format!("<built-in {}>", b.name)).map_err(|e| e.to_string());
    }
    Err(format!("{name}: no such file, and not a built-in scene (see `porosph scenes`)"))
}

fn positive(name: &str, v: Option<f64>) -> Result<(), String> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => {
            Err(format!("--{name} must be a positive number of seconds, got {x}"))
        }
        _ => Ok(()),
    }
}

impl RunArgs {
    fn check(&self) -> Result<(), String> {
        positive("until", self.until)?;
        positive("frame-every", self.frame_every)?;
        if self.threads == Some(0) {
            return Err("--threads must be at least 1".to_string());
        }
        if self.keep == Some(0) {
            return Err("--keep must be at least 1".to_string());
        }
        Ok(())
    }

    /// Puts `sim` on the backend of `--backend` (an error if it has no GPU).
    fn attach_backend(&self, sim: &mut Simulation) -> Result<(), String> {
        if self.backend == BackendKind::Gpu {
            let gpu = GpuBackend::new(self.gpu_passes).map_err(|e| e.to_string())?;
            if !self.quiet {
                eprintln!("porosph: GPU backend on {}", gpu.ctx.describe());
            }
            sim.use_gpu(gpu);
        }
        Ok(())
    }

    /// A thread pool of `--threads` threads (default: all cores).
    fn pool(&self) -> Result<rayon::ThreadPool, String> {
        let mut b = rayon::ThreadPoolBuilder::new();
        if let Some(t) = self.threads {
            b = b.num_threads(t);
        }
        b.build().map_err(|e| format!("cannot start {:?} threads: {e}", self.threads))
    }
}

/// Runs `sim` and reports how it went.
fn execute(sim: &mut Simulation, opts: &RunOptions) -> Result<(), String> {
    match run(sim, opts) {
        Ok(s) => {
            if !opts.quiet {
                eprintln!(
                    "porosph: {} steps, {} frames, {:.1} s wall, {:.3} M particle-steps/s",
                    s.steps,
                    s.frames,
                    s.wall_seconds,
                    s.particle_steps_per_second / 1e6
                );
            }
            Ok(())
        }
        Err(e) => Err(e.to_string()),
    }
}

fn run_command(scene: Option<String>, out: PathBuf, a: RunArgs) -> Result<(), String> {
    a.check()?;
    let scene = load_scene(scene.as_deref())?;
    a.pool()?.install(|| {
        let origin = scene.origin.clone();
        let mut sim = Simulation::new(scene);
        a.attach_backend(&mut sim)?;
        if !a.quiet {
            eprintln!(
                "porosph: {origin}: {} fluid + {} wall particles, {} threads, output in {}",
                sim.fluid.len(),
                sim.walls.len(),
                rayon::current_num_threads(),
                out.display()
            );
        }
        let opts = RunOptions {
            out: out.clone(),
            until: a.until,
            steps: a.steps,
            frame_every: a.frame_every,
            quiet: a.quiet,
            checkpoint_every: a.checkpoint_every,
            keep: a.keep.unwrap_or(DEFAULT_KEEP),
            resume: None,
            inject_nan_at_step: a.inject_nan_at_step,
        };
        execute(&mut sim, &opts)
    })
}

/// The run directory of a checkpoint: the parent of its `checkpoints/`
/// folder, or the folder it is in.
fn run_dir_of(checkpoint: &Path) -> PathBuf {
    let dir = match checkpoint.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    if dir.file_name().is_some_and(|n| n == "checkpoints") {
        if let Some(p) = dir.parent() {
            return if p.as_os_str().is_empty() { PathBuf::from(".") } else { p.to_path_buf() };
        }
    }
    dir
}

fn resume_command(path: PathBuf, out: Option<PathBuf>, a: RunArgs) -> Result<(), String> {
    a.check()?;
    let ckpt = read_checkpoint(&path).map_err(|e| e.to_string())?;
    if let Some(f) = &ckpt.failure {
        return Err(format!(
            "{}: a diagnostic checkpoint, written when the run failed ({f}); \
             resume from an earlier checkpoint",
            path.display()
        ));
    }
    let r = ckpt.run.clone();
    let out = out.unwrap_or_else(|| run_dir_of(&path));
    let (time, step) = (ckpt.state.time, ckpt.state.step);
    // Where to stop: as asked, else where the saved run was going to stop.
    let (until, steps) = match (a.until, a.steps, r.stop_time, r.stop_step) {
        (None, None, _, Some(s)) => (None, Some(s.saturating_sub(step))),
        (None, None, t, None) => (t, None),
        (u, s, _, _) => (u, s),
    };
    let checkpoint_every = match (a.checkpoint_every, r.checkpoint_every.as_str()) {
        (Some(c), _) => Some(c),
        (None, "") => None,
        (None, saved) => Some(saved.parse().map_err(|e| format!("{}: /run@checkpoint_every: {e}", path.display()))?),
    };
    let frame_every = a.frame_every.unwrap_or(r.frame_every);
    let next_frame =
        if frame_every.to_bits() == r.frame_every.to_bits() { r.next_frame_time } else { time + frame_every };
    let opts = RunOptions {
        out: out.clone(),
        until,
        steps,
        frame_every: Some(frame_every),
        quiet: a.quiet,
        checkpoint_every,
        keep: a.keep.unwrap_or_else(|| usize::try_from(r.keep).unwrap_or(DEFAULT_KEEP)),
        resume: Some(Continuation { frames: r.frames_written, next_frame }),
        inject_nan_at_step: a.inject_nan_at_step,
    };
    a.pool()?.install(|| {
        let mut sim = Simulation::from_saved_state(ckpt.state).map_err(|e| format!("{}: {e}", path.display()))?;
        a.attach_backend(&mut sim)?;
        if !a.quiet {
            eprintln!(
                "porosph: resuming {} at step {step} (t = {time} s): {} fluid + {} wall particles, \
                 {} threads, output in {}",
                path.display(),
                sim.fluid.len(),
                sim.walls.len(),
                rayon::current_num_threads(),
                out.display()
            );
        }
        execute(&mut sim, &opts)
    })
}

fn inspect_command(file: &Path) -> Result<(), String> {
    match file_kind(file).map_err(|e| e.to_string())? {
        FileKind::Frame => inspect_frame(file).map(|s| print!("{s}")).map_err(|e| e.to_string()),
        FileKind::Checkpoint => {
            let i = inspect_checkpoint(file).map_err(|e| e.to_string())?;
            print!("{}", i.text);
            if i.checksums_hold {
                Ok(())
            } else {
                Err(format!("{}: checksums do not hold: the file is damaged", file.display()))
            }
        }
    }
}

/// Renders one frame file to `out`.
fn render_file(input: &Path, out: &Path, opts: &RenderOptions) -> Result<(), String> {
    let frame = porosph::io::read_frame(input).map_err(|e| e.to_string())?;
    let image = render::render(&frame, opts).map_err(|e| format!("{}: {e}", input.display()))?;
    image.write_png(out).map_err(|e| e.to_string())
}

/// The frame files of a run directory, in name order.
fn frame_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let frames = dir.join("frames");
    let rd = std::fs::read_dir(&frames).map_err(|e| format!("{}: cannot list frames: {e}", frames.display()))?;
    let mut files: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "vtkhdf"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(format!("{}: no frames (*.vtkhdf)", frames.display()));
    }
    Ok(files)
}

fn movie_command(dir: &Path, mut opts: RenderOptions) -> Result<(), String> {
    let files = frame_files(dir)?;
    // One camera, particle size and colour range for the whole movie: from
    // all frames' fluid and solid points.
    let mut lo_hi: Option<([f32; 3], [f32; 3])> = None;
    let mut range: Option<[f32; 2]> = None;
    let mut spacing = None;
    for (n, f) in files.iter().enumerate() {
        eprint!("\rporosph: scanning frame {}/{}", n + 1, files.len());
        let frame = porosph::io::read_frame(f).map_err(|e| format!("\n{e}"))?;
        let err = |e: render::RenderError| format!("\n{}: {e}", f.display());
        if let Some((a, b)) = render::bounds(&frame, opts.walls).map_err(err)? {
            lo_hi = Some(match lo_hi {
                None => (a, b),
                Some((lo, hi)) => ([0, 1, 2].map(|c| lo[c].min(a[c])), [0, 1, 2].map(|c| hi[c].max(b[c]))),
            });
        }
        if let Some([a, b]) = render::value_range(&frame, opts.color).map_err(err)? {
            range = Some(range.map_or([a, b], |[lo, hi]| [lo.min(a), hi.max(b)]));
        }
        if spacing.is_none() {
            spacing = render::estimate_spacing(&frame).map_err(err)?;
        }
    }
    eprintln!();
    if let Some((lo, hi)) = lo_hi {
        opts.camera = Some(Camera::framing(lo, hi, opts.width, opts.height, opts.orthographic));
    }
    opts.range = range;
    opts.radius = spacing.map(|s| 0.5 * s);
    let out = dir.join("render");
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: cannot create: {e}", out.display()))?;
    for (n, f) in files.iter().enumerate() {
        let stem = f.file_stem().unwrap_or_default();
        let png = out.join(stem).with_extension("png");
        eprint!("\rporosph: rendering frame {}/{} -> {}", n + 1, files.len(), png.display());
        render_file(f, &png, &opts).map_err(|e| format!("\n{e}"))?;
    }
    eprintln!("\nporosph: {} pictures in {}", files.len(), out.display());
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn render_command(
    input: &Path,
    out: Option<PathBuf>,
    width: u32,
    height: u32,
    color: ColorMode,
    walls: bool,
    ortho: bool,
    movie: bool,
) -> Result<(), String> {
    let opts = RenderOptions { width, height, color, walls, orthographic: ortho, ..RenderOptions::default() };
    if width == 0 || height == 0 || width > render::MAX_SIDE || height > render::MAX_SIDE {
        return Err(format!("--width and --height must be 1 to {} pixels", render::MAX_SIDE));
    }
    if movie {
        if !input.is_dir() {
            return Err(format!("{}: --movie needs a run directory (holding frames/)", input.display()));
        }
        return movie_command(input, opts);
    }
    if input.is_dir() {
        return Err(format!(
            "{}: a directory; give a frame file, or --movie to render every frame of a run",
            input.display()
        ));
    }
    let out = out.unwrap_or_else(|| input.with_extension("png"));
    render_file(input, &out, &opts)?;
    eprintln!("porosph: wrote {}", out.display());
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, out, args } => run_command(scene, out, args),
        Command::Resume { checkpoint, out, args } => resume_command(checkpoint, out, args),
        Command::Scenes => {
            println!("built-in scenes (porosph run NAME):");
            for b in builtin::SCENES {
                let mark = if b.name == builtin::DEFAULT { " (default)" } else { "" };
                println!("  {:<16} {}{}", b.name, b.description, mark);
            }
            if let Ok(rd) = std::fs::read_dir("scenes") {
                let mut files: Vec<PathBuf> = rd
                    .filter_map(|e| e.ok().map(|e| e.path()))
                    .filter(|p| p.extension().is_some_and(|x| x == "toml"))
                    .collect();
                files.sort();
                if !files.is_empty() {
                    println!("example scenes in ./scenes (porosph run FILE):");
                    for f in files {
                        println!("  {}", f.display());
                    }
                }
            }
            Ok(())
        }
        Command::Inspect { file } => inspect_command(&file),
        Command::Render { input, out, width, height, color, walls, ortho, movie } => {
            render_command(&input, out, width, height, color, walls, ortho, movie)
        }
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("porosph: error: {e}");
            ExitCode::FAILURE
        }
    }
}
