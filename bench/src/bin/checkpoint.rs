//! Checkpoint write and read time for a large state, against the time of one
//! simulation step (the issue's target: a write takes less than 10 steps).
//!
//! The state is the step benchmark's dam break (`src/main.rs`: a 1 m fluid
//! cube in a 4 x 3 x 1.5 m tank) at the spacing that gives `--particles`
//! fluid particles, after a few steps. Timed, each `--repeat` times (median):
//! - one step;
//! - `write_checkpoint` (temporary file, HDF5 write, close, fsync, rename);
//! - `read_checkpoint_with` through HDF5 (`H5Dread`) and through a memory
//!   map (HDF5 reads only the metadata), with the file in the page cache
//!   ("warm") and evicted from it with `posix_fadvise(DONTNEED)` ("cold");
//! - `load_checkpoint`: read + rebuilding the simulation (wall grid).
//!
//! Every read is checked bit for bit against the written state.
//!
//! ```sh
//! cargo run --release -p porosph-bench --bin checkpoint -- --particles 1000000 --threads 2
//! ```

use clap::Parser;
use porosph::io::checkpoint::{load_checkpoint, read_checkpoint_with, write_checkpoint, ReadMethod, RunInfo};
use porosph::pipeline::Simulation;
use porosph::scene::Scene;
use porosph::store::Column;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Checkpoint write and read times of a dam-break state.
#[derive(Parser)]
#[command(name = "checkpoint", about)]
struct Args {
    /// Fluid particles per m^3 (spacing 1 / cbrt(N)).
    #[arg(long, value_name = "N", default_value_t = 1e6)]
    particles: f64,
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Timed runs of each operation.
    #[arg(long, value_name = "N", default_value_t = 3)]
    repeat: usize,
    /// Where the checkpoints go (default: the system's temporary directory).
    #[arg(long, default_value_os_t = std::env::temp_dir())]
    dir: PathBuf,
}

fn parse() -> Result<Args, String> {
    let a = Args::parse();
    if a.repeat == 0 {
        return Err("--repeat must be at least 1".into());
    }
    Ok(a)
}

fn scene(particles: f64) -> Result<Scene, String> {
    let sp = (1.0 / particles.cbrt()) as f32;
    let text = format!(
        r#"[simulation]
particle_spacing = {sp}
end_time = 100.0
max_dt = 0.001
frame_interval = 100.0
[[phase]]
name = "water"
density = 1000.0
viscosity = 0.01
[[fluid]]
box = {{ min = [-1.95, 0.05, -0.5], max = [-0.95, 1.05, 0.5] }}
fractions = {{ water = 1.0 }}
[[wall]]
box = {{ min = [-2.0, 0.0, -0.75], max = [2.0, 3.0, 0.75] }}
container = true
"#
    );
    Scene::from_toml_str(&text, "<checkpoint bench dam break>").map_err(|e| e.to_string())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Seconds of `f`, `n` times.
fn time_n(n: usize, mut f: impl FnMut()) -> Vec<f64> {
    (0..n)
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .collect()
}

/// Drops the file's pages from the page cache (they are clean: the writer
/// synced them), so the next read comes from the disk.
fn evict(path: &Path) {
    use std::os::fd::AsRawFd;
    let f = std::fs::File::open(path).expect("open for eviction");
    // SAFETY: a plain system call on a file descriptor we own.
    let rc = unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
    assert_eq!(rc, 0, "posix_fadvise failed");
}

/// Every registered array's bits, to check reads against the written state.
fn bits(fluid: &porosph::store::FluidStore, walls: &porosph::store::WallStore) -> u64 {
    let mut h = porosph::io::xxh64::Xxh64::new(0);
    let mut add = |c: Column<'_>| match c {
        Column::F32(v) => h.update_f32(v),
        Column::U32(v) => h.update_u32(v),
        Column::PerPhase(vs) => vs.iter().for_each(|v| h.update_f32(v)),
    };
    fluid.for_each_column(|_, _, c| add(c));
    walls.for_each_column(|_, _, c| add(c));
    h.finish()
}

fn main() {
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
    let scene = scene(a.particles).unwrap_or_else(|e| panic!("{e}"));
    let t = Instant::now();
    let mut sim = Simulation::new(scene);
    let setup = t.elapsed().as_secs_f64();
    let (nf, nw) = (sim.fluid.len(), sim.walls.len());
    eprintln!("{nf} fluid + {nw} wall particles, setup {setup:.1} s, {} threads", a.threads);
    for _ in 0..2 {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
    }
    let step = median(time_n(a.repeat, || {
        sim.step().unwrap_or_else(|e| panic!("{e}"));
    }));
    eprintln!("step {step:.3} s");

    let path = a.dir.join(format!("porosph-bench-ckpt-{}.h5", std::process::id()));
    let run = RunInfo {
        frames_written: 0,
        next_frame_time: 100.0,
        frame_every: 100.0,
        stop_time: Some(100.0),
        stop_step: None,
        checkpoint_every: "100steps".into(),
        keep: 3,
        compress: false,
    };
    let write = median(time_n(a.repeat, || {
        write_checkpoint(&path, &sim, &run, None).unwrap_or_else(|e| panic!("{e}"));
    }));
    let bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    let want = bits(&sim.fluid, &sim.walls);
    let mb = bytes as f64 / 1e6;
    eprintln!("write {write:.3} s");

    let read = |method: ReadMethod, cold: bool| {
        let mut v = Vec::new();
        for _ in 0..a.repeat {
            if cold {
                evict(&path);
            }
            let t = Instant::now();
            let c = read_checkpoint_with(&path, method).unwrap_or_else(|e| panic!("{e}"));
            v.push(t.elapsed().as_secs_f64());
            assert_eq!(bits(&c.state.fluid, &c.state.walls), want, "read differs");
        }
        median(v)
    };
    let hdf5_warm = read(ReadMethod::Hdf5, false);
    let mmap_warm = read(ReadMethod::Mmap, false);
    let hdf5_cold = read(ReadMethod::Hdf5, true);
    let mmap_cold = read(ReadMethod::Mmap, true);
    let load = median(time_n(a.repeat, || {
        let (s, _) = load_checkpoint(&path).unwrap_or_else(|e| panic!("{e}"));
        std::hint::black_box(s.fluid.len());
    }));
    let _ = std::fs::remove_file(&path);

    let row = |what: &str, s: f64| {
        println!("| {what:<34} | {:>8.3} | {:>7.2} | {:>7.0} |", s, s / step, mb / s);
    };
    println!(
        "fluid particles {nf}, wall particles {nw}, file {mb:.1} MB, {} threads, median of {}",
        a.threads, a.repeat
    );
    println!("| {:<34} | {:>8} | {:>7} | {:>7} |", "what", "s", "steps", "MB/s");
    println!("|{:-<36}|{:->10}|{:->9}|{:->9}|", "", "", "", "");
    println!("| {:<34} | {:>8.3} | {:>7.2} | {:>7} |", "one simulation step", step, 1.0, "");
    row("write (HDF5, fsync, rename)", write);
    row("read, HDF5, warm cache", hdf5_warm);
    row("read, memory map, warm cache", mmap_warm);
    row("read, HDF5, cold cache", hdf5_cold);
    row("read, memory map, cold cache", mmap_cold);
    row("load (read + rebuild), warm cache", load);
}
