//! The `porosph` command line (DESIGN.md, "Interfaces users rely on").

use clap::{Args, Parser, Subcommand};
use porosph::backend::gpu::GpuBackend;
use porosph::backend::{BackendKind, GpuPasses};
use porosph::builtin;
use porosph::io::checkpoint::{file_kind, inspect_checkpoint, read_checkpoint, FileKind};
use porosph::io::inspect_frame;
use porosph::io::read_stats;
use porosph::pipeline::Simulation;
use porosph::plot::{self, PlotOptions};
use porosph::render::{self, Clip, ColorMode, Hide, RenderOptions};
use porosph::run::output::{self, Claim};
use porosph::run::{interrupt, run, CheckpointEvery, Continuation, RunError, RunOptions, DEFAULT_KEEP};
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
    #[arg(long, conflicts_with = "steps", allow_negative_numbers = true)]
    until: Option<f64>,
    /// Stop after this many steps (resume: this many more steps).
    #[arg(long, allow_negative_numbers = true, value_parser = parse_steps)]
    steps: Option<u64>,
    /// Simulated time between frames, s (run: default the scene's
    /// frame_interval; resume: default the saved run's).
    #[arg(long, allow_negative_numbers = true)]
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
    /// Write into a --out that holds an earlier porosph run: first remove
    /// its frames, frame series index, checkpoints, rendered pictures,
    /// stats.csv, plots.png and scene.toml. Never removes anything else: a
    /// directory that holds other files is refused.
    #[arg(long)]
    overwrite: bool,
    /// Where the offloadable passes run: `cpu` (every pass on the CPU,
    /// bitwise deterministic) or `gpu` (through wgpu/Vulkan; the passes of
    /// --gpu-passes on the GPU, the rest on the CPU).
    #[arg(long, default_value = "cpu", value_name = "cpu|gpu")]
    backend: BackendKind,
    /// With --backend gpu: the passes to run on the GPU, by their stats.csv
    /// names, comma-separated (`neighbors`, `pressure_solve`, `drift`), or `all` (default).
    #[arg(long, value_name = "PASSES", default_value = "all")]
    gpu_passes: GpuPasses,
    /// Testing aid: set a fluid velocity to NaN before the step that starts
    /// at step N, to exercise the failure path (diagnostic checkpoint,
    /// non-zero exit).
    #[arg(long, value_name = "N", hide = true)]
    inject_nan_at_step: Option<u64>,
    /// Compress the frames (HDF5 deflate, level 4, after a byte shuffle;
    /// ParaView and h5py read them as they are): about a third of the
    /// bytes, a little more time per frame. Resume: a run that compressed
    /// goes on compressing.
    #[arg(long)]
    compress: bool,
}

#[derive(Subcommand)]
enum Command {
    /// Run a scene (a TOML file or a built-in name; default: the built-in
    /// wave_block, the paper's Example 1 small).
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
    /// Dry run of a distributed run (issue 19), no MPI needed: set up the
    /// scene (as `run` does, without stepping), split its particles among
    /// P ranks as the distributed run will (contiguous ranges of the Morton
    /// order, cut on whole cache blocks) and print per rank the owned and
    /// halo particles and the halo bytes per step, and the imbalance.
    Partition {
        /// Scene file or built-in scene name (default: the built-in wave_block).
        scene: Option<String>,
        /// Number of ranks, 1 to 4096 (at most the scene's cache blocks of fluid).
        #[arg(long, value_name = "P")]
        ranks: usize,
        /// Jacobi sweeps per step for the halo bytes (a run's stats.csv
        /// `iterations` column gives its own).
        #[arg(long, value_name = "N", default_value_t = 10)]
        sweeps: u32,
        /// Particle spacing to sample the scene at instead of its own, m
        /// (the same scene at another resolution; the scene is validated
        /// again at it).
        #[arg(long, value_name = "METRES")]
        spacing: Option<f32>,
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
    },
    /// List the built-in scenes and the example scenes in ./scenes.
    Scenes,
    /// Print the JSON Schema of scene files (the scene reference, for
    /// editors: docs/scene.schema.json holds the same).
    Schema,
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
        /// Render every frame of OUTDIR/frames/ to OUTDIR/render/frame_NNNNN.png,
        /// with one camera and colour range for all.
        #[arg(long)]
        movie: bool,
        #[command(flatten)]
        args: RenderArgs,
    },
    /// Plot a run's statistics (OUTDIR/stats.csv) to a PNG, over simulated
    /// time: the time step, the pressure solve (iterations, density error),
    /// the change of each phase's volume and mass, the liquid in each
    /// porous solid, the solid solver (elastic CG iterations, granular
    /// sub-steps) and the time per pass, stacked. Phases in their colours
    /// of the run's scene.toml (beside stats.csv).
    Plot {
        /// A run directory (holding stats.csv), or a stats file.
        input: PathBuf,
        /// Output picture (default: plots.png beside stats.csv).
        #[arg(short, long)]
        out: Option<PathBuf>,
        /// Image width, pixels.
        #[arg(long, default_value_t = 1600)]
        width: u32,
        /// Image height, pixels.
        #[arg(long, default_value_t = 1400)]
        height: u32,
    },
}

/// Options of `render`.
#[derive(Args)]
struct RenderArgs {
    /// Image width, pixels.
    #[arg(long, default_value_t = 1280)]
    width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 720)]
    height: u32,
    #[arg(long, default_value = "phase", value_parser = parse_color, help = color_help())]
    color: ColorMode,
    /// Draw the wall particles (faintly).
    #[arg(long)]
    walls: bool,
    /// Colour range of speed, pressure or saturation, in the field's unit
    /// (default: the 1st to 99th percentile of the drawn particles' values,
    /// from 0 for speed and saturation; with --movie over all frames).
    #[arg(long, value_name = "MIN,MAX", value_parser = parse_range, allow_hyphen_values = true)]
    range: Option<[f32; 2]>,
    /// Leave out a kind of particle: fluid, solids or walls (repeat the
    /// option or give a comma list).
    #[arg(long, value_name = "KINDS", value_parser = parse_hide)]
    hide: Vec<Hide>,
    /// Draw only the particles on one side of a plane normal to an axis:
    /// 'x<0.15' keeps those with x below 0.15 m (axes x, y, z; < or >).
    /// Repeat for several planes. The camera stays where it was without it.
    #[arg(long, value_name = "PLANE", value_parser = parse_clip, allow_hyphen_values = true)]
    clip: Vec<Clip>,
    /// Opacity of the fluid, 0 to 1 (below 1 the solids show through it).
    #[arg(long, value_name = "0..1", default_value_t = 1.0, value_parser = parse_opacity)]
    fluid_opacity: f32,
    /// Leave out the time stamp and the colour bar.
    #[arg(long)]
    no_annotations: bool,
    /// Orthographic camera (default: perspective).
    #[arg(long, help_heading = "Camera")]
    ortho: bool,
    /// Camera position, m (default: in front of the scene, a little above
    /// and to the right, just far enough to show it all).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true, help_heading = "Camera")]
    eye: Option<[f32; 3]>,
    /// The point the camera looks at, drawn at the image centre, m
    /// (default: the centre of the fluid and solid particles' bounding box).
    /// Image up is +y (looking down within 8 degrees of the vertical: -z).
    #[arg(long, value_name = "X,Y,Z", value_parser = parse_point, allow_hyphen_values = true, help_heading = "Camera")]
    target: Option<[f32; 3]>,
    /// Vertical field of view of the perspective camera, degrees (default 34.4).
    #[arg(long, value_name = "DEGREES", value_parser = parse_fov, conflicts_with = "ortho", help_heading = "Camera")]
    fov: Option<f32>,
}

fn color_help() -> String {
    let modes: Vec<String> = ColorMode::ALL.iter().map(|(_, name, what)| format!("{name} ({what})")).collect();
    format!("Colour by: {}", modes.join(", "))
}

/// `X,Y,Z`: three finite numbers.
fn parse_point(s: &str) -> Result<[f32; 3], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: expected three numbers X,Y,Z in metres, e.g. 0.5,0.3,1.2"))?;
    match v[..] {
        [x, y, z] if [x, y, z].iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("{s:?}: expected three finite numbers X,Y,Z in metres, e.g. 0.5,0.3,1.2")),
    }
}

fn parse_fov(s: &str) -> Result<f32, String> {
    let (lo, hi) = render::FOV_RANGE_DEG;
    match s.trim().parse::<f32>() {
        Ok(f) if f >= lo && f <= hi => Ok(f),
        _ => Err(format!("{s:?}: expected a field of view of {lo} to {hi} degrees")),
    }
}

fn parse_color(s: &str) -> Result<ColorMode, String> {
    s.parse()
}

/// `MIN,MAX`: two finite numbers, MIN < MAX.
fn parse_range(s: &str) -> Result<[f32; 2], String> {
    let v: Vec<f32> = s
        .split(',')
        .map(|c| c.trim().parse::<f32>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("{s:?}: expected two numbers MIN,MAX in the field's unit, e.g. 0,2000"))?;
    let [lo, hi] = v[..] else {
        return Err(format!("{s:?}: expected two numbers MIN,MAX in the field's unit, e.g. 0,2000"));
    };
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(format!("{s:?}: MIN and MAX must be finite numbers"));
    }
    if lo >= hi {
        return Err(format!("{s:?}: MIN must be less than MAX"));
    }
    Ok([lo, hi])
}

fn parse_hide(s: &str) -> Result<Hide, String> {
    let mut h = Hide::default();
    h.add(s)?;
    Ok(h)
}

fn parse_clip(s: &str) -> Result<Clip, String> {
    s.parse()
}

fn parse_opacity(s: &str) -> Result<f32, String> {
    match s.trim().parse::<f32>() {
        Ok(a) if (0.0..=1.0).contains(&a) => Ok(a),
        _ => Err(format!("{s:?}: expected an opacity from 0 (invisible) to 1 (opaque)")),
    }
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

/// A number of seconds that must be > 0 (clap reads negative numbers, so
/// that `--until -1` is this error rather than an unknown argument).
fn positive(name: &str, v: Option<f64>) -> Result<(), String> {
    match v {
        Some(x) if !(x.is_finite() && x > 0.0) => Err(format!("--{name} must be > 0 s, got {x}")),
        _ => Ok(()),
    }
}

/// `--steps N`: a whole number of steps, 0 or more.
fn parse_steps(s: &str) -> Result<u64, String> {
    s.trim().parse().map_err(|_| format!("expected a whole number of steps (0 or more), got {s:?}"))
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

/// Runs `sim` and reports how it went. SIGINT and SIGTERM stop the run
/// after the current step with a checkpoint, the command that resumes it,
/// and exit status 130 or 143 (a second signal exits at once).
fn execute(sim: &mut Simulation, opts: &RunOptions) -> Result<(), String> {
    interrupt::install()?;
    match run(sim, opts) {
        Ok(s) => {
            if !opts.quiet {
                eprintln!("{s}");
            }
            Ok(())
        }
        Err(RunError::Interrupted { signal, step, time, checkpoint }) => {
            let how = interrupt::name(signal);
            match checkpoint {
                Ok(c) => eprintln!(
                    "porosph: stopped by {how} after step {step} (t = {time} s); checkpoint written, \
                     frames and stats.csv are complete. To continue:\n  porosph resume {}",
                    output::shell_quote(&c)
                ),
                Err(e) => {
                    eprintln!("porosph: error: stopped by {how} after step {step}: cannot write a checkpoint: {e}")
                }
            }
            // Every writer of the run is closed (flushed) by now.
            std::process::exit(128 + signal);
        }
        Err(e) => Err(e.to_string()),
    }
}

/// Takes the output directory as `claim` allows: removes an earlier run's
/// files (`--overwrite`) and says what went.
fn take_output(claim: Claim) -> Result<(), String> {
    if let Claim::Replace(s) = claim {
        s.remove().map_err(|e| format!("--overwrite: {e}"))?;
        eprintln!("porosph: --overwrite: removed the earlier run in {}: {}", s.dir.display(), s.describe());
    }
    Ok(())
}

fn run_command(scene: Option<String>, out: PathBuf, a: RunArgs) -> Result<(), String> {
    a.check()?;
    let claim = output::claim(&out, a.overwrite).map_err(|e| e.to_string())?;
    let scene = load_scene(scene.as_deref())?;
    a.pool()?.install(|| {
        let origin = scene.origin.clone();
        let mut sim = Simulation::new(scene);
        a.attach_backend(&mut sim)?;
        if !a.quiet {
            eprintln!(
                "porosph: {origin}: {} fluid + {} solid + {} wall particles, {} threads, output in {}",
                sim.fluid.len(),
                sim.solids.len(),
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
            compress: a.compress,
        };
        take_output(claim)?;
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

/// Whether `a` and `b` are the same existing directory.
fn same_dir(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => false,
    }
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
    // The checkpoint's own run directory is continued; any other --out is
    // a new directory for this run, as for `porosph run`.
    let own = run_dir_of(&path);
    let out = out.unwrap_or_else(|| own.clone());
    let claim = if same_dir(&out, &own) {
        if a.overwrite {
            return Err(format!(
                "--overwrite: {} is the run this checkpoint belongs to, and resume continues it \
                 (stats.csv and the frames after the checkpoint are replaced); leave out --overwrite, \
                 or give another --out",
                out.display()
            ));
        }
        Claim::Fresh
    } else {
        output::claim(&out, a.overwrite).map_err(|e| e.to_string())?
    };
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
        compress: a.compress || r.compress,
    };
    a.pool()?.install(|| {
        let mut sim = Simulation::from_saved_state(ckpt.state).map_err(|e| format!("{}: {e}", path.display()))?;
        a.attach_backend(&mut sim)?;
        take_output(claim)?;
        if !a.quiet {
            eprintln!(
                "porosph: resuming {} at step {step} (t = {time} s): {} fluid + {} solid + {} wall particles, \
                 {} threads, output in {}",
                path.display(),
                sim.fluid.len(),
                sim.solids.len(),
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

/// Renders one frame file to `out`; the PNG's text chunks say what it
/// shows (`porosph:time`, and for a colormap `porosph:field`,
/// `porosph:unit`, `porosph:range`). Returns the colour scale used.
fn render_file(input: &Path, out: &Path, opts: &RenderOptions) -> Result<Option<render::ColorScale>, String> {
    let frame = porosph::io::read_frame(input).map_err(|e| match file_kind(input) {
        Ok(FileKind::Checkpoint) => not_a_frame(input),
        _ => e.to_string(),
    })?;
    let at = |e: render::RenderError| format!("{}: {e}", input.display());
    let scale = render::color_scale(&frame, opts).map_err(at)?;
    let image = render::render(&frame, opts).map_err(at)?;
    let mut text = vec![("porosph:time".to_string(), format!("{}", frame.time))];
    if let Some(s) = &scale {
        text.push(("porosph:field".into(), s.field.clone()));
        text.push(("porosph:unit".into(), s.unit.clone()));
        text.push(("porosph:range".into(), format!("{},{}", s.range[0], s.range[1])));
    }
    image.write_png_with_text(out, &text).map_err(|e| e.to_string())?;
    Ok(scale)
}

/// What `render` says of a checkpoint: what it is, and where the frames are.
fn not_a_frame(checkpoint: &Path) -> String {
    let frames = run_dir_of(checkpoint).join("frames");
    let c = output::shell_quote(checkpoint);
    format!(
        "{}: a porosph checkpoint, not a frame: render draws frames (.vtkhdf). See what it holds with \
         `porosph inspect {c}`; render a frame of its run, from {} (`porosph render {}`), or \
         `porosph resume {c}` to write more frames",
        checkpoint.display(),
        frames.display(),
        output::shell_quote(&frames.join("frame_NNNNN.vtkhdf"))
    )
}

/// The frame files of a run directory, in name order.
fn frame_files(dir: &Path) -> Result<Vec<PathBuf>, String> {
    let frames = dir.join("frames");
    let rd = std::fs::read_dir(&frames).map_err(|e| format!("{}: cannot list frames: {e}", frames.display()))?;
    let mut files: Vec<PathBuf> = rd
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && p.extension().is_some_and(|x| x == "vtkhdf"))
        // Not the run's walls file (frames/walls.vtkhdf): the frames hold the walls.
        .filter(|p| p.file_name().is_some_and(|n| n.to_string_lossy().starts_with("frame_")))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(format!("{}: no frames (*.vtkhdf)", frames.display()));
    }
    Ok(files)
}

/// Values kept per frame for a movie's colour range: at most this many,
/// evenly strided, so that the percentiles of a long movie stay cheap.
const RANGE_SAMPLES_PER_FRAME: usize = 200_000;

fn movie_command(dir: &Path, mut opts: RenderOptions) -> Result<(), String> {
    let files = frame_files(dir)?;
    // One camera, particle size and colour range for the whole movie: from
    // all frames' shown points, the range's percentiles over all frames'
    // values together.
    let mut lo_hi: Option<render::Bounds> = None;
    let mut values: Vec<f32> = Vec::new();
    let mut spacing = None;
    for (n, f) in files.iter().enumerate() {
        eprint!("\rporosph: scanning frame {}/{}", n + 1, files.len());
        let frame = porosph::io::read_frame(f).map_err(|e| format!("\n{e}"))?;
        let err = |e: render::RenderError| format!("\n{}: {e}", f.display());
        if let Some((a, b)) = render::shown_bounds(&frame, &opts).map_err(err)? {
            lo_hi = Some(match lo_hi {
                None => (a, b),
                Some((lo, hi)) => ([0, 1, 2].map(|c| lo[c].min(a[c])), [0, 1, 2].map(|c| hi[c].max(b[c]))),
            });
        }
        if opts.range.is_none() {
            if let Some(v) = render::field_values(&frame, &opts).map_err(err)? {
                let stride = v.len().div_ceil(RANGE_SAMPLES_PER_FRAME).max(1);
                values.extend(v.iter().step_by(stride));
            }
        }
        if spacing.is_none() {
            spacing = render::estimate_spacing(&frame).map_err(err)?;
        }
    }
    eprintln!();
    opts.framing = lo_hi;
    let shared = if opts.range.is_none() { render::robust_range(opts.color, &mut values) } else { None };
    opts.range = opts.range.or(shared);
    opts.radius = spacing.map(|s| 0.5 * s);
    let out = dir.join("render");
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: cannot create: {e}", out.display()))?;
    let mut scale = None;
    for (n, f) in files.iter().enumerate() {
        let stem = f.file_stem().unwrap_or_default();
        let png = out.join(stem).with_extension("png");
        eprint!("\rporosph: rendering frame {}/{} -> {}", n + 1, files.len(), png.display());
        scale = render_file(f, &png, &opts).map_err(|e| format!("\n{e}"))?;
    }
    eprintln!("\nporosph: {} pictures in {}", files.len(), out.display());
    if let Some(s) = scale {
        let how = if shared.is_some() { " (1st-99th percentile over all frames)" } else { " (--range)" };
        let unit = if s.unit.is_empty() { String::new() } else { format!(" {}", s.unit) };
        eprintln!("porosph: colour range: {} {} to {}{unit}{how}", s.field, s.range[0], s.range[1]);
    }
    Ok(())
}

fn render_command(input: &Path, out: Option<PathBuf>, movie: bool, a: RenderArgs) -> Result<(), String> {
    let (width, height) = (a.width, a.height);
    if width == 0 || height == 0 || width > render::MAX_SIDE || height > render::MAX_SIDE {
        return Err(format!("--width and --height must be 1 to {} pixels", render::MAX_SIDE));
    }
    let view = render::CameraSpec { eye: a.eye, target: a.target, fov_deg: a.fov };
    view.check().map_err(|e| format!("--eye/--target/--fov: {e}"))?;
    if a.range.is_some() && a.color == ColorMode::Phase {
        return Err("--range sets the colour range of --color speed, pressure or saturation; \
                    --color phase has none"
            .to_string());
    }
    let hide = a.hide.iter().fold(Hide::default(), |h, k| Hide {
        fluid: h.fluid || k.fluid,
        solids: h.solids || k.solids,
        walls: h.walls || k.walls,
    });
    let opts = RenderOptions {
        width,
        height,
        color: a.color,
        walls: a.walls,
        hide,
        clip: a.clip,
        fluid_opacity: a.fluid_opacity,
        annotate: !a.no_annotations,
        orthographic: a.ortho,
        view,
        range: a.range,
        ..RenderOptions::default()
    };
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
    let scale = render_file(input, &out, &opts)?;
    eprintln!("porosph: wrote {}", out.display());
    if let Some(s) = scale {
        eprintln!("porosph: colour range: {}", s.describe());
    }
    Ok(())
}

/// Plots the stats of a run directory (or a stats file) to `out`
/// (default: plots.png beside the stats file).
fn plot_command(input: &Path, out: Option<PathBuf>, width: u32, height: u32) -> Result<(), String> {
    let ((w0, h0), max) = (plot::MIN_SIZE, plot::MAX_SIDE);
    if !((w0..=max).contains(&width) && (h0..=max).contains(&height)) {
        return Err(format!("--width must be {w0} to {max} pixels and --height {h0} to {max}"));
    }
    let csv = if input.is_dir() {
        input.join("stats.csv")
    } else if input.exists() {
        input.to_path_buf()
    } else {
        return Err(format!("{}: no such run directory or stats file", input.display()));
    };
    let table = read_stats(&csv).map_err(|e| e.to_string())?;
    if table.torn_last_line {
        eprintln!(
            "porosph: note: {}: the last line has no newline yet (is the run writing it?): left out",
            csv.display()
        );
    }
    let span = |name: &str| table.column(name).map(|c| (c[0], c[c.len() - 1]));
    let title = match (span("step"), span("time")) {
        (Some((s0, s1)), Some((t0, t1))) => {
            format!("{}: steps {s0} to {s1}, t = {t0:.4} to {t1:.4} s", csv.display())
        }
        _ => csv.display().to_string(),
    };
    // The phases' colours from the run's scene, if it is there.
    let phase_colors = std::fs::read_to_string(csv.with_file_name("scene.toml"))
        .map(|text| plot::phase_colors(&text))
        .unwrap_or_default();
    let image = plot::plot(&table, &title, &PlotOptions { width, height, phase_colors })
        .map_err(|e| format!("{}: {e}", csv.display()))?;
    let out = out.unwrap_or_else(|| csv.with_file_name("plots.png"));
    image.write_png(&out).map_err(|e| e.to_string())?;
    let rows = table.rows();
    eprintln!("porosph: wrote {} ({rows} row{})", out.display(), if rows == 1 { "" } else { "s" });
    Ok(())
}

/// `scene` sampled at particle spacing `d` instead of its own: its text
/// with `simulation.particle_spacing` replaced, parsed and validated again.
fn with_spacing(scene: &Scene, d: f32) -> Result<Scene, String> {
    if !(d.is_finite() && d > 0.0) {
        return Err(format!("--spacing must be > 0 m, got {d}"));
    }
    let mut table: toml::Table = scene.text.parse().map_err(|e| format!("{}: {e}", scene.origin))?;
    if let Some(toml::Value::Table(sim)) = table.get_mut("simulation") {
        sim.insert("particle_spacing".into(), toml::Value::Float(f64::from(d)));
    }
    let text = toml::to_string(&table).map_err(|e| format!("{}: {e}", scene.origin))?;
    let origin = format!("{} at --spacing {d}", scene.origin);
    Scene::from_toml_str(&text, &origin).map_err(|e| e.to_string())
}

/// `porosph partition`: the partitioner's table for `scene` on `ranks` ranks.
fn partition_command(
    scene: Option<String>,
    ranks: usize,
    sweeps: u32,
    spacing: Option<f32>,
    threads: Option<usize>,
) -> Result<(), String> {
    use porosph::distributed::{partition, report, traffic::HaloModel, MAX_RANKS};
    if ranks == 0 || ranks > MAX_RANKS {
        return Err(format!("--ranks must be 1 to {MAX_RANKS}, got {ranks}"));
    }
    if threads == Some(0) {
        return Err("--threads must be at least 1".to_string());
    }
    let mut scene = load_scene(scene.as_deref())?;
    if let Some(d) = spacing {
        scene = with_spacing(&scene, d)?;
    }
    let mut b = rayon::ThreadPoolBuilder::new();
    if let Some(t) = threads {
        b = b.num_threads(t);
    }
    let pool = b.build().map_err(|e| format!("cannot start {threads:?} threads: {e}"))?;
    pool.install(|| {
        let origin = scene.origin.clone();
        let sim = Simulation::new(scene);
        let (f, w, s) = (&sim.fluid, &sim.walls, &sim.solids);
        let points = [
            porosph_kernels::soa::Vel { x: &f.x, y: &f.y, z: &f.z },
            porosph_kernels::soa::Vel { x: &w.x, y: &w.y, z: &w.z },
            porosph_kernels::soa::Vel { x: &s.x, y: &s.y, z: &s.z },
        ];
        let part = partition(points, sim.params.kernel.support, ranks).map_err(|e| format!("{origin}: {e}"))?;
        let model = HaloModel::new(sim.params.phases(), sim.params.porous());
        println!("porosph partition: {origin}: {} fluid + {} wall + {} solid particles", f.len(), w.len(), s.len());
        print!("{}", report::table(&part, &model, sweeps));
        Ok(())
    })
}

fn main() -> ExitCode {
    porosph_kernels::neighbors::large_allocations_from_mmap();
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, out, args } => run_command(scene, out, args),
        Command::Resume { checkpoint, out, args } => resume_command(checkpoint, out, args),
        Command::Partition { scene, ranks, sweeps, spacing, threads } => {
            partition_command(scene, ranks, sweeps, spacing, threads)
        }
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
                    println!("scene files in ./scenes (porosph run FILE):");
                    for f in files {
                        // The file's first comment line says what it is.
                        let text = std::fs::read_to_string(&f).unwrap_or_default();
                        let what = text.lines().next().and_then(|l| l.strip_prefix('#')).unwrap_or("").trim();
                        println!("  {:<40} {}", f.display().to_string(), what);
                    }
                }
            }
            Ok(())
        }
        Command::Schema => {
            print!("{}", porosph::scene::schema_text());
            Ok(())
        }
        Command::Inspect { file } => inspect_command(&file),
        Command::Render { input, out, movie, args } => render_command(&input, out, movie, args),
        Command::Plot { input, out, width, height } => plot_command(&input, out, width, height),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("porosph: error: {e}");
            ExitCode::FAILURE
        }
    }
}
