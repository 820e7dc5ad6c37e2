//! Time to fill a closed triangle mesh with particles (issue 16's target: a
//! mesh of 100k triangles at 1 cm in under 5 s on 2 cores).
//!
//! The mesh is generated: a bumpy torus (major radius 0.35 m, tube radius
//! 0.12 m with +-15 % ripples, so the surface is not convex and the rays
//! cross it four times), `--triangles` triangles in all, written as a
//! binary STL to a temporary directory. Timed, `--repeat` times (median and
//! range): parsing the scene with the mesh as a `[[fluid]]` (reading the
//! STL, merging vertices, the closed-surface check, building the search
//! structures), filling it on the lattice (`sample_fluid`, one thread), and the same
//! mesh as a `[[wall]]` (the two-layer shell, with distances). The
//! particle count is compared with the torus's volume / d^3.
//!
//! ```sh
//! cargo run --release -p porosph-bench --bin mesh_fill -- --triangles 100000 --spacing 0.01
//! ```

use clap::Parser;
use porosph::scene::{sample_fluid, sample_walls, Scene};
use std::f64::consts::PI;
use std::time::Instant;

/// Time to fill a closed triangle mesh with particles.
#[derive(Parser)]
#[command(name = "mesh_fill", about)]
struct Cli {
    /// Triangles of the mesh (at least 8; `1e5` is accepted).
    #[arg(long, value_name = "N", default_value_t = 100_000.0)]
    triangles: f64,
    /// Particle spacing, m.
    #[arg(long, value_name = "M", default_value_t = 0.01)]
    spacing: f64,
    /// Timed runs.
    #[arg(long, value_name = "N", default_value_t = 5)]
    repeat: usize,
}

struct Args {
    triangles: usize,
    spacing: f64,
    repeat: usize,
}

fn parse() -> Result<Args, String> {
    let c = Cli::parse();
    let a = Args { triangles: c.triangles as usize, spacing: c.spacing, repeat: c.repeat };
    if a.repeat == 0 || a.triangles < 8 || a.spacing.is_nan() || a.spacing <= 0.0 {
        return Err("--repeat >= 1, --triangles >= 8 and --spacing > 0".into());
    }
    Ok(a)
}

/// Major and tube radius of the torus, m, and the ripple amplitude.
const R: f64 = 0.35;
const TUBE: f64 = 0.12;
const RIPPLE: f64 = 0.15;

/// The tube radius at angles (u around the axis, v around the tube).
fn tube(u: f64, v: f64) -> f64 {
    TUBE * (1.0 + RIPPLE * (5.0 * u).sin() * (3.0 * v).cos())
}

/// The bumpy torus as binary STL bytes: `nu` x `nv` quads, two triangles
/// each, outward, centred at (0.5, 0.5, 0.5) with its axis along y.
fn torus_stl(nu: usize, nv: usize) -> Vec<u8> {
    let point = |i: usize, j: usize| -> [f32; 3] {
        let (u, v) = (2.0 * PI * (i % nu) as f64 / nu as f64, 2.0 * PI * (j % nv) as f64 / nv as f64);
        let r = R + tube(u, v) * v.cos();
        [(0.5 + r * u.cos()) as f32, (0.5 + tube(u, v) * v.sin()) as f32, (0.5 + r * u.sin()) as f32]
    };
    let mut b = vec![b' '; 80];
    b[..13].copy_from_slice(b"bumpy torus  ");
    b.extend(((2 * nu * nv) as u32).to_le_bytes());
    let mut tri = |p: [[f32; 3]; 3]| {
        b.extend([0f32; 3].iter().flat_map(|x| x.to_le_bytes()));
        for c in p {
            b.extend(c.iter().flat_map(|x| x.to_le_bytes()));
        }
        b.extend(0u16.to_le_bytes());
    };
    for i in 0..nu {
        for j in 0..nv {
            let (a, bb, c, d) = (point(i, j), point(i + 1, j), point(i + 1, j + 1), point(i, j + 1));
            // Counter-clockwise seen from outside: normal along the tube's
            // outward direction for u around +y and v around the tube.
            tri([a, d, c]);
            tri([a, c, bb]);
        }
    }
    b
}

/// The torus's volume, m^3: the integral of (R + t cos v) t^2 / 2 over u, v
/// (Pappus with a varying tube radius), by the midpoint rule.
fn torus_volume() -> f64 {
    let n = 2000;
    let h = 2.0 * PI / n as f64;
    let mut sum = 0.0;
    for i in 0..n {
        for j in 0..n {
            let (u, v) = ((i as f64 + 0.5) * h, (j as f64 + 0.5) * h);
            let t = tube(u, v);
            // Area element of the tube cross-section in polar coordinates,
            // times the circumference R + rho cos v, integrated over rho.
            sum += (R * t * t / 2.0 + t * t * t * v.cos() / 3.0) * h * h;
        }
    }
    sum
}

fn stats(mut v: Vec<f64>) -> String {
    v.sort_by(f64::total_cmp);
    format!("{:.3} s ({:.3}-{:.3})", v[v.len() / 2], v[0], v[v.len() - 1])
}

fn main() {
    let a = match parse() {
        Ok(a) => a,
        Err(e) => {
            eprintln!("{e}");
            std::process::exit(2);
        }
    };
    // nu = 3 nv: quads about square on the tube.
    let nv = ((a.triangles as f64 / 6.0).sqrt().round() as usize).max(2);
    let nu = (a.triangles / (2 * nv)).max(3);
    let dir = std::env::temp_dir().join(format!("porosph-mesh-fill-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let stl = dir.join("torus.stl");
    std::fs::write(&stl, torus_stl(nu, nv)).expect("write STL");
    let header = format!(
        "[simulation]\nparticle_spacing = {}\nend_time = 1.0\nmax_dt = 0.001\n\
         [[phase]]\nname = \"water\"\ndensity = 1000.0\nviscosity = 0.001\n",
        a.spacing
    );
    let fluid = format!("{header}[[fluid]]\nmesh = {{ path = {:?} }}\nfractions = {{ water = 1.0 }}\n", stl.display());
    let wall = format!("{header}[[wall]]\nmesh = {{ path = {:?} }}\n", stl.display());
    println!(
        "bumpy torus: {} triangles ({nu} x {nv} quads), {:.1} MB binary STL; d = {} m; one thread; median of {}",
        2 * nu * nv,
        std::fs::metadata(&stl).map(|m| m.len() as f64 / 1e6).unwrap_or(0.0),
        a.spacing,
        a.repeat
    );
    let (mut parse_t, mut fill_t, mut wall_t, mut total_t) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let (mut n_fluid, mut n_wall) = (0, 0);
    for _ in 0..a.repeat {
        let t0 = Instant::now();
        let scene = Scene::from_toml_str(&fluid, "bench.toml").unwrap_or_else(|e| panic!("{e}"));
        let t1 = Instant::now();
        n_fluid = sample_fluid(&scene, &sample_walls(&scene)).positions.len();
        let t2 = Instant::now();
        parse_t.push((t1 - t0).as_secs_f64());
        fill_t.push((t2 - t1).as_secs_f64());
        total_t.push((t2 - t0).as_secs_f64());
        let t3 = Instant::now();
        let scene = Scene::from_toml_str(&wall, "bench.toml").unwrap_or_else(|e| panic!("{e}"));
        n_wall = sample_walls(&scene).positions.len();
        wall_t.push(t3.elapsed().as_secs_f64());
    }
    let _ = std::fs::remove_dir_all(&dir);
    let expected = torus_volume() / a.spacing.powi(3);
    println!("| step | time |\n|---|---|");
    println!("| parse (read STL, merge, check, build search structures) | {} |", stats(parse_t));
    println!("| fill (sample_fluid) | {} |", stats(fill_t));
    println!("| **parse + fill** | **{}** |", stats(total_t));
    println!("| wall shell (parse + sample_walls) | {} |", stats(wall_t));
    println!(
        "fluid particles: {n_fluid} (volume / d^3 = {expected:.0}, {:+.2} %); wall particles: {n_wall}",
        100.0 * (n_fluid as f64 - expected) / expected
    );
}
