//! The `porosph` command line (DESIGN.md, "Interfaces users rely on").

use clap::{Parser, Subcommand};
use porosph::builtin;
use porosph::io::inspect_frame;
use porosph::pipeline::Simulation;
use porosph::run::{run, RunError, RunOptions};
use porosph::scene::Scene;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(Parser)]
#[command(name = "porosph", version, about = "Multiple fluids through porous, deformable solids, one particle system")]
struct Cli {
    #[command(subcommand)]
    command: Command,
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
        /// Worker threads (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// Stop at this simulated time, s (default: the scene's end_time).
        #[arg(long, conflicts_with = "steps")]
        until: Option<f64>,
        /// Stop after this many steps.
        #[arg(long)]
        steps: Option<u64>,
        /// Simulated time between frames, s (default: the scene's frame_interval).
        #[arg(long)]
        frame_every: Option<f64>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// List the built-in scenes and the example scenes in ./scenes.
    Scenes,
    /// Print what a frame file holds.
    Inspect {
        /// A frame (.vtkhdf) file.
        file: PathBuf,
    },
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

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Run { scene, out, threads, until, steps, frame_every, quiet } => (|| {
            positive("until", until)?;
            positive("frame-every", frame_every)?;
            if threads == Some(0) {
                return Err("--threads must be at least 1".to_string());
            }
            let scene = load_scene(scene.as_deref())?;
            let mut b = rayon::ThreadPoolBuilder::new();
            if let Some(t) = threads {
                b = b.num_threads(t);
            }
            let pool = b.build().map_err(|e| format!("cannot start {threads:?} threads: {e}"))?;
            pool.install(|| {
                let origin = scene.origin.clone();
                let mut sim = Simulation::new(scene);
                if !quiet {
                    eprintln!(
                        "porosph: {origin}: {} fluid + {} wall particles, {} threads, output in {}",
                        sim.fluid.len(),
                        sim.walls.len(),
                        rayon::current_num_threads(),
                        out.display()
                    );
                }
                let opts = RunOptions { out: out.clone(), until, steps, frame_every, quiet };
                match run(&mut sim, &opts) {
                    Ok(s) => {
                        if !quiet {
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
                    Err(RunError::Step(e)) => Err(format!("simulation stopped: {e}")),
                    Err(e) => Err(e.to_string()),
                }
            })
        })(),
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
        Command::Inspect { file } => inspect_frame(&file).map(|s| print!("{s}")).map_err(|e| e.to_string()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("porosph: error: {e}");
            ExitCode::FAILURE
        }
    }
}
