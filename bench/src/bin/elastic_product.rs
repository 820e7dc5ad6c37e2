//! The elastic product (M A) v of the implicit elastic solve
//! (`porosph_kernels::elasticity::System::apply`, PHYSICS.md §3.3) alone,
//! on a lattice block: the kernel the prediction's conjugate gradients call
//! once an iteration and the bodies' response twice a Jacobi sweep, about a
//! third of Example 1's step (bench/RESULTS.md). Prints the least and the
//! median time a call over `--repeat` calls, and a checksum of the result
//! (the same for two builds whose products agree bit for bit). Then the
//! Jacobi-preconditioned conjugate gradients of the prediction
//! (`conjugate_gradients`) run `--cg-iterations` iterations (tolerance 0),
//! a tenth of `--repeat` times: the least time an iteration, and what of it
//! is not the product (the CG's vector passes and reductions). Last, the
//! bodies' response as the pressure solve's sweeps call it
//! (`conjugate_gradients_from`: one iteration from the last answer and its
//! carried residual, the right-hand side changed a little each time),
//! `--repeat` solves: the least and the median time a solve.
//!
//! ```sh
//! cargo build --release -p porosph-bench --bin elastic_product
//! target/release/elastic_product --threads 2 --size 37,37,25 --repeat 300
//! ```
//!
//! The default block is Example 1's at d = 4 mm (about 33k particles, 26
//! rest neighbours each inside, support 2 d); `--size 62,62,40` is about the
//! paper's size (155k).

use glam::{Mat3, Quat, Vec3};
use porosph_kernels::elasticity::{
    conjugate_gradients, conjugate_gradients_from, deform, CarriedResidual, CgBuffers, Deformation, Lame,
    ProductScratch, RestState, System,
};
use porosph_kernels::kernel::Kernel;
use std::time::Instant;

fn main() {
    let (mut threads, mut size, mut repeat, mut cg_iterations) = (2usize, [37usize, 37, 25], 300usize, 20u32);
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let v = it.next().unwrap_or_else(|| panic!("{k} needs a value"));
        match k.as_str() {
            "--threads" => threads = v.parse().expect("--threads: a number"),
            "--repeat" => repeat = v.parse().expect("--repeat: a number"),
            "--cg-iterations" => cg_iterations = v.parse().expect("--cg-iterations: a number"),
            "--size" => {
                let n: Vec<usize> = v.split(',').map(|s| s.parse().expect("--size: NX,NY,NZ")).collect();
                size = [n[0], n[1], n[2]];
            }
            _ => panic!("unknown argument {k} (--threads, --size NX,NY,NZ, --repeat, --cg-iterations)"),
        }
    }
    let d = 0.004f32;
    let mut x0 = Vec::new();
    for k in 0..size[2] {
        for j in 0..size[1] {
            for i in 0..size[0] {
                x0.push(Vec3::new(i as f32, j as f32, k as f32) * d);
            }
        }
    }
    let n = x0.len();
    let mass = vec![500.0 * d * d * d; n];
    let rest = RestState::new(&x0, &vec![0; n], &mass, &Kernel::new(2.0 * d));
    // A rotated, slightly sheared state, so that RL_i is a full matrix.
    let r = Mat3::from_quat(Quat::from_axis_angle(Vec3::new(0.3, 1.0, -0.4).normalize(), 0.7));
    let shear = Mat3::from_cols(Vec3::new(1.02, 0.01, 0.0), Vec3::new(0.03, 0.98, 0.0), Vec3::new(0.0, -0.01, 1.01));
    let x: Vec<Vec3> = x0.iter().map(|&p| r * (shear * p)).collect();
    let (mut rot, mut def) = (vec![Quat::IDENTITY; n], vec![Deformation::default(); n]);
    let lame = vec![Lame { mu: 1e5, lambda: 1e5 }; n];
    let fixed = vec![0u32; n];
    let v: Vec<Vec3> =
        (0..n).map(|i| Vec3::new((i as f32 * 0.37).sin(), (i as f32 * 0.11).cos(), 0.01 * (i % 13) as f32)).collect();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().expect("thread pool");
    pool.install(|| {
        deform(&rest, &x, &mut rot, &mut def);
        let sys = System { rest: &rest, def: &def, lame: &lame, mass: &mass, fixed: &fixed, dt: 0.002, jacobi: None, coarse: None };
        let (mut scratch, mut out) = (ProductScratch::default(), vec![Vec3::ZERO; n]);
        // The pair list's product beside the lattice's, alternated.
        let pairs = rest.clone().without_lattice();
        let sys_pairs = System { rest: &pairs, ..sys };
        let (mut scratch_pairs, mut out_pairs) = (ProductScratch::default(), vec![Vec3::ZERO; n]);
        let (mut ms, mut ms_pairs) = (Vec::with_capacity(repeat), Vec::with_capacity(repeat));
        for _ in 0..repeat.max(1) {
            let t = Instant::now();
            sys.apply(&v, &mut scratch, &mut out);
            ms.push(t.elapsed().as_secs_f64() * 1e3);
            let t = Instant::now();
            sys_pairs.apply(&v, &mut scratch_pairs, &mut out_pairs);
            ms_pairs.push(t.elapsed().as_secs_f64() * 1e3);
        }
        ms.sort_by(f64::total_cmp);
        ms_pairs.sort_by(f64::total_cmp);
        let sum_pairs: f64 = out_pairs.iter().map(|o| f64::from(o.x) + f64::from(o.y) + f64::from(o.z)).sum();
        println!(
            "the pair list's product (lattice {}): least {:.3} ms, median {:.3} ms; checksum {sum_pairs:.9e}",
            if rest.has_lattice() { "used below" } else { "none: the same product below" },
            ms_pairs[0],
            ms_pairs[ms_pairs.len() / 2]
        );
        let sum: f64 = out.iter().map(|o| f64::from(o.x) + f64::from(o.y) + f64::from(o.z)).sum();
        let pairs = rest.start[n] as usize;
        println!(
            "{n} particles, {pairs} rest pairs ({:.1} a particle), {threads} threads: least {:.3} ms, median {:.3} ms a product ({:.2} ns a pair, least); checksum {sum:.9e}",
            pairs as f64 / n as f64,
            ms[0],
            ms[ms.len() / 2],
            ms[0] * 1e6 / pairs as f64
        );
        let mut jacobi = Vec::new();
        sys.inverse_diagonal(&mut jacobi);
        let sys = System { jacobi: Some(&jacobi), ..sys };
        let mut buf = CgBuffers::default();
        let rhs: Vec<Vec3> = v.iter().map(|&v| mass[0] * v + Vec3::new(0.0, -1e-5, 0.0)).collect();
        let (mut cg_ms, mut iterations, mut sol) = (f64::INFINITY, 0, Vec::new());
        for _ in 0..(repeat / 10).max(1) {
            sol.clear();
            sol.resize(n, Vec3::ZERO);
            let t = Instant::now();
            let stats = conjugate_gradients(&sys, &rhs, &mut sol, 0.0, cg_iterations, &mut buf);
            cg_ms = cg_ms.min(t.elapsed().as_secs_f64() * 1e3);
            iterations = stats.iterations;
        }
        let sum: f64 = sol.iter().map(|o| f64::from(o.x) + f64::from(o.y) + f64::from(o.z)).sum();
        let per = cg_ms / f64::from(iterations.max(1));
        println!(
            "conjugate gradients, {iterations} iterations: least {cg_ms:.3} ms, {per:.3} ms an iteration, {:.3} ms of it besides the product; checksum {sum:.9e}",
            per - ms[0]
        );
        let mut carry = CarriedResidual::default();
        let mut ms = Vec::with_capacity(repeat);
        let mut force: Vec<Vec3> = rhs.iter().map(|&f| 1e-3 * f).collect();
        for k in 0..repeat.max(1) {
            force.iter_mut().for_each(|f| f.y -= 1e-9 * (k % 7) as f32);
            let t = Instant::now();
            conjugate_gradients_from(&sys, &force, &mut sol, 1e-4, 1, &mut buf, &mut carry);
            ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        ms.sort_by(f64::total_cmp);
        let sum: f64 = sol.iter().map(|o| f64::from(o.x) + f64::from(o.y) + f64::from(o.z)).sum();
        println!(
            "response (one iteration from the carried residual): least {:.3} ms, median {:.3} ms a solve; checksum {sum:.9e}",
            ms[0],
            ms[ms.len() / 2]
        );
    });
}
