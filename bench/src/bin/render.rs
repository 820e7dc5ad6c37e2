//! Time to render a large frame to a PNG (the issue's target: a 1M-particle
//! frame in under 5 s on 2 cores).
//!
//! The frame is synthetic, with every array a simulation frame has: a block
//! of fluid (two phases, mixed left to right) on a porous solid slab, in a
//! cubic lattice with a little deterministic jitter, `--particles` points in
//! all (fluid and solid), plus a floor of wall particles (hidden, as by
//! default). Timed, `--repeat` times (median and range): `render` (the
//! default camera, particle size estimate, projection, rasterisation,
//! shading) and PNG encoding.
//!
//! ```sh
//! cargo run --release -p porosph-bench --bin render -- --particles 1000000 --threads 2
//! ```

use clap::Parser;
use porosph::io::{ArrayData, Frame, PointArray};
use porosph::render::{render, ColorMode, RenderOptions};
use porosph::run::kind;
use std::time::Instant;

/// Time to render a large synthetic frame to a PNG.
#[derive(Parser)]
#[command(name = "render", about)]
struct Cli {
    /// Points of the frame, fluid and solid (`1e6` is accepted).
    #[arg(long, value_name = "N", default_value_t = 1e6)]
    particles: f64,
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Timed runs.
    #[arg(long, value_name = "N", default_value_t = 5)]
    repeat: usize,
    /// Image size, pixels.
    #[arg(long, value_name = "W", default_value_t = 1920)]
    width: u32,
    #[arg(long, value_name = "H", default_value_t = 1080)]
    height: u32,
    /// Also write the image to this PNG file.
    #[arg(long, value_name = "PNG")]
    out: Option<String>,
}

struct Args {
    particles: usize,
    threads: usize,
    repeat: usize,
    width: u32,
    height: u32,
    out: Option<String>,
}

fn parse() -> Result<Args, String> {
    let c = Cli::parse();
    let a = Args {
        particles: c.particles as usize,
        threads: c.threads,
        repeat: c.repeat,
        width: c.width,
        height: c.height,
        out: c.out,
    };
    if a.repeat == 0 || a.threads == 0 {
        return Err("--repeat and --threads must be at least 1".into());
    }
    Ok(a)
}

/// A deterministic hash to 0..1.
fn hash(i: u64) -> f32 {
    let mut x = i.wrapping_mul(0x9e37_79b9_7f4a_7c15);
    x ^= x >> 31;
    x = x.wrapping_mul(0xbf58_476d_1ce4_e5b9);
    x ^= x >> 29;
    (x >> 40) as f32 / (1u64 << 24) as f32
}

/// The synthetic frame: `n` fluid and solid points and a wall floor.
fn frame(n: usize) -> Frame {
    // Block nx x ny x nz with nx = 2 ny = 2 nz: 4 s^3 = n.
    let s = ((n as f64 / 4.0).cbrt().ceil()) as usize;
    let (nx, ny, nz) = (2 * s, s, 2 * s);
    let d = 0.01f32;
    let (water, oil) = ([0.15f32, 0.45, 0.9], [0.9f32, 0.6, 0.1]);
    let mut points = Vec::with_capacity(n + nx * nz);
    let mut kinds = Vec::with_capacity(n + nx * nz);
    let mut alpha = Vec::with_capacity(2 * (n + nx * nz));
    let mut color = Vec::with_capacity(3 * (n + nx * nz));
    'fill: for j in 0..ny {
        for k in 0..nz {
            for i in 0..nx {
                if points.len() == n {
                    break 'fill;
                }
                let id = points.len() as u64;
                let jit = |a: u64| 0.1 * d * (hash(3 * id + a) - 0.5);
                points.push([i as f32 * d + jit(0), j as f32 * d + jit(1), k as f32 * d + jit(2)]);
                if j < ny / 5 {
                    kinds.push(kind::SOLID);
                    alpha.extend([0.0, 0.0]);
                    color.extend([0.55, 0.4, 0.25]);
                } else {
                    let t = i as f32 / nx as f32;
                    kinds.push(kind::FLUID);
                    alpha.extend([1.0 - t, t]);
                    color.extend([0, 1, 2].map(|c| (1.0 - t) * water[c] + t * oil[c]));
                }
            }
        }
    }
    for k in 0..nz {
        for i in 0..nx {
            points.push([i as f32 * d, -d, k as f32 * d]);
            kinds.push(kind::WALL);
            alpha.extend([0.0, 0.0]);
            color.extend([0.6, 0.6, 0.6]);
        }
    }
    let m = points.len();
    let velocity: Vec<f32> = (0..m).flat_map(|i| [hash(7 * i as u64), 0.5 * hash(7 * i as u64 + 1), 0.0]).collect();
    let pressure: Vec<f32> = points.iter().map(|p| 1000.0 * 9.81 * (ny as f32 * d - p[1])).collect();
    let density = vec![1000.0f32; m];
    let a = |name: &str, c: usize, data: ArrayData| PointArray {
        name: name.into(),
        unit: String::new(),
        components: c,
        data,
    };
    Frame {
        time: 1.0,
        step: 1000,
        points,
        arrays: vec![
            a("velocity", 3, ArrayData::F32(velocity)),
            a("pressure", 1, ArrayData::F32(pressure)),
            a("density", 1, ArrayData::F32(density)),
            a("alpha", 2, ArrayData::F32(alpha)),
            a("color", 3, ArrayData::F32(color)),
            a("kind", 1, ArrayData::U8(kinds)),
            a("id", 1, ArrayData::U32((0..m as u32).collect())),
        ],
    }
}

fn stats(mut v: Vec<f64>) -> String {
    v.sort_by(f64::total_cmp);
    format!("{:.3} s (range {:.3}-{:.3})", v[v.len() / 2], v[0], v[v.len() - 1])
}

fn main() {
    let a = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    let f = frame(a.particles);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(a.threads).build().expect("thread pool");
    println!(
        "frame: {} fluid+solid points + {} wall points (hidden); image {} x {}; {} threads; median of {}",
        a.particles,
        f.points.len() - a.particles,
        a.width,
        a.height,
        a.threads,
        a.repeat
    );
    for mode in [ColorMode::Phase, ColorMode::Speed] {
        let opts = RenderOptions { width: a.width, height: a.height, color: mode, ..RenderOptions::default() };
        let (mut tr, mut te, mut tt) = (Vec::new(), Vec::new(), Vec::new());
        let mut png = Vec::new();
        for _ in 0..a.repeat {
            let t0 = Instant::now();
            let img = pool.install(|| render(&f, &opts)).expect("render");
            let t1 = Instant::now();
            png = img.encode_png().expect("encode");
            let t2 = Instant::now();
            tr.push((t1 - t0).as_secs_f64());
            te.push((t2 - t1).as_secs_f64());
            tt.push((t2 - t0).as_secs_f64());
        }
        println!(
            "{mode:?}: render {}, PNG encode {}, total {}; PNG {} KB",
            stats(tr),
            stats(te),
            stats(tt),
            png.len() / 1024
        );
        if let (Some(out), ColorMode::Phase) = (&a.out, mode) {
            std::fs::write(out, &png).expect("write PNG");
        }
    }
}
