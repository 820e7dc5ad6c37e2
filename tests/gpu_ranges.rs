//! The cell-range tables built on the GPU (shaders/ranges.wgsl) are
//! bitwise those built on the CPU (src/backend/gpu/ranges.rs: fluid_rows,
//! wall_rows) on 100k random fluid particles and 30k random walls (a random
//! half of them active), and with no walls. Integer work (Morton keys,
//! binary search instead of the CPU's hash table) but for the walls'
//! cell_of, the same f32 operations: no tolerance.

mod gpu_common;

use porosph::backend::gpu::ranges::{fluid_rows, wall_rows};
use porosph::backend::gpu::RangesGpu;
use porosph_kernels::grid::CellGrid;
use porosph_kernels::neighbors::{compute_keys, sort_permutation, Points};

use gpu_common::Rng;

/// Random points in a box, sorted by Morton cell, and their grid.
fn sorted(n: usize, lo: f32, hi: f32, support: f32, rng: &mut Rng) -> ([Vec<f32>; 3], CellGrid) {
    let x: [Vec<f32>; 3] = std::array::from_fn(|_| (0..n).map(|_| rng.range(lo, hi)).collect());
    let mut keys = vec![0u64; n];
    compute_keys(&x[0], &x[1], &x[2], 1.0 / support, &mut keys);
    let (mut scratch, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut scratch, &mut perm);
    let x = std::array::from_fn(|c| perm.iter().map(|&i| x[c][i as usize]).collect());
    let keys: Vec<u64> = scratch.iter().map(|&(k, _)| k).collect();
    let mut grid = CellGrid::default();
    grid.build(&keys, support);
    (x, grid)
}

#[test]
fn gpu_cell_ranges_are_bitwise_the_cpu_tables_on_100k_particles() {
    let Some(ctx) = gpu_common::context() else { return };
    let mut gpu = RangesGpu::new(&ctx);
    let support = 0.02f32;
    let mut rng = Rng(11);
    // Fluid around the origin (negative cells too), walls overlapping it.
    let (_fx, fluid_grid) = sorted(100_000, -0.5, 0.5, support, &mut rng);
    let (wx, wall_grid) = sorted(30_000, -0.3, 0.7, support, &mut rng);
    let walls = Points { x: &wx[0], y: &wx[1], z: &wx[2] };
    let active: Vec<u32> = (0..30_000u32).filter(|_| rng.range(0.0, 1.0) < 0.5).collect();
    let no_walls = CellGrid::default();
    let no_points = Points { x: &[], y: &[], z: &[] };
    for (wall_grid, walls, active) in [(&wall_grid, walls, &active[..]), (&no_walls, no_points, &[][..])] {
        let (mut cell_row, mut ff, mut fb, mut bf) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        fluid_rows(&fluid_grid, wall_grid, &mut cell_row, &mut ff, &mut fb);
        wall_rows(walls, active, &fluid_grid, &mut bf);
        let (mut gff, mut gfb, mut gbf) = (Vec::new(), Vec::new(), Vec::new());
        gpu.build(&ctx, &fluid_grid, wall_grid, walls, active, &mut gff, &mut gfb, &mut gbf).expect("GPU ranges");
        let occupied = |t: &[[u32; 2]]| t.iter().filter(|r| r[1] > r[0]).count();
        eprintln!(
            "{} fluid cells, {} wall cells, {} active walls; non-empty ranges: ff {}, fb {}, bf {}",
            fluid_grid.len(),
            wall_grid.len(),
            active.len(),
            occupied(&ff),
            occupied(&fb),
            occupied(&bf)
        );
        assert!(occupied(&ff) > 0 && (wall_grid.is_empty() || occupied(&fb) > 0 && occupied(&bf) > 0));
        assert!(gff == ff, "fluid-fluid ranges differ");
        assert!(gfb == fb, "fluid-wall ranges differ");
        assert!(gbf == bf, "wall-fluid ranges differ");
    }
}
