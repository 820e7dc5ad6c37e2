//! The GPU neighbour sort (shaders/neighbors.wgsl) against the CPU pass
//! (compute_keys + sort_permutation, kernels/src/neighbors.rs) on 100k
//! random particles. Tolerance: none. The keys are integers from the same
//! correctly rounded f32 product x / H, and (key, index) pairs are unique,
//! so the order must be bitwise the CPU's; and a run with the sort on the
//! GPU must be bitwise the CPU run.

mod common;
mod gpu_common;

use gpu_common::Rng;
use porosph::backend::GpuPasses;
use porosph::pipeline::Simulation;
use porosph_kernels::neighbors::{compute_keys, sort_permutation};
use porosph_kernels::soa::Vel;

#[test]
fn gpu_sort_is_bitwise_the_cpu_sort_on_100k_random_particles() {
    let Some(mut gpu) = gpu_common::backend(GpuPasses::ALL) else { return };
    let mut rng = Rng(3);
    let n = 100_000;
    // A box across the origin (negative cells), plus particles exactly on
    // cell faces, far away, and sharing cells (ties broken by index).
    let mut x: [Vec<f32>; 3] = std::array::from_fn(|_| (0..n).map(|_| rng.range(-0.7, 0.9)).collect());
    let [x0, x1, _] = &mut x;
    for (i, (a, b)) in x0.iter_mut().zip(x1.iter_mut()).take(100).enumerate() {
        *a = 0.02 * (i as f32 - 50.0);
        *b = 0.02 * i as f32;
    }
    x[2][100] = 1e6;
    x[0][101] = -1e6;
    x[1][102] = x[1][103];
    let inv_cell = 1.0 / 0.02f32;
    let pts = Vel { x: &x[0], y: &x[1], z: &x[2] };
    let mut keys = vec![0u64; n];
    compute_keys(pts.x, pts.y, pts.z, inv_cell, &mut keys);
    let (mut cpu_sort, mut cpu_perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut cpu_sort, &mut cpu_perm);
    let (mut sort, mut perm) = (Vec::new(), Vec::new());
    let t = std::time::Instant::now();
    let ms = gpu.sort_permutation(pts, inv_cell, &mut sort, &mut perm).unwrap_or_else(|e| panic!("{e}"));
    eprintln!("GPU keys + sort of 100k: {:.1} ms wall, device {ms:?} ms", t.elapsed().as_secs_f64() * 1e3);
    assert_eq!(perm, cpu_perm);
    assert_eq!(sort, cpu_sort);
}

fn state_bits(sim: &Simulation) -> Vec<u32> {
    let f = &sim.fluid;
    [&f.x, &f.y, &f.z, &f.ux, &f.uy, &f.uz, &f.pressure].iter().flat_map(|v| v.iter().map(|x| x.to_bits())).collect()
}

#[test]
fn run_with_the_sort_on_the_gpu_is_bitwise_the_cpu_run() {
    let passes = GpuPasses { neighbors: true, pressure_solve: false, drift: false };
    let Some(gpu) = gpu_common::backend(passes) else { return };
    let scene = || common::scene_file("two_phase_mixing.toml");
    let mut cpu = Simulation::new(scene());
    let mut sim = Simulation::new(scene());
    sim.use_gpu(gpu);
    for _ in 0..20 {
        cpu.step().unwrap_or_else(|e| panic!("{e}"));
        sim.step().unwrap_or_else(|e| panic!("{e}"));
    }
    assert!(sim.last.times.gpu_ms[0] >= 0.0);
    assert!(state_bits(&cpu) == state_bits(&sim), "states differ after 20 steps");
}
