//! The cell-range tables built on the GPU (shaders/ranges.wgsl) are
//! bitwise those built on the CPU (src/backend/gpu/ranges.rs: fluid_rows,
//! wall_rows) on 100k random fluid particles and 30k random walls (a random
//! half of them active), and with no walls, with each particle's cell_row.
//! Integer work (Morton keys, binary search instead of the CPU's hash
//! table) but for the walls' cell_of, the same f32 operations: no
//! tolerance. And the tables on the device are rebuilt exactly when what
//! they are built from changes.

mod gpu_common;

use porosph::backend::gpu::ranges::{fluid_rows, wall_rows};
use porosph::backend::gpu::{GpuContext, RangesGpu, WallInput};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::neighbors::{compute_keys, sort_permutation};

use gpu_common::Rng;
use porosph_kernels::soa::Vel;

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

/// The CPU tables (cell_row, ff, fb, bf).
type Tables = (Vec<u32>, Vec<[u32; 2]>, Vec<[u32; 2]>, Vec<[u32; 2]>);

fn cpu_tables(fluid_grid: &CellGrid, walls: Option<WallInput>) -> Tables {
    let no_walls = CellGrid::default();
    let (wall_grid, pts, active) = match walls {
        Some(w) => (w.grid, w.walls, w.active),
        None => (&no_walls, Vel { x: &[], y: &[], z: &[] }, &[][..]),
    };
    let (mut cell_row, mut ff, mut fb, mut bf) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    fluid_rows(fluid_grid, wall_grid, &mut cell_row, &mut ff, &mut fb);
    wall_rows(pts, active, fluid_grid, &mut bf);
    (cell_row, ff, fb, bf)
}

fn gpu_tables(gpu: &RangesGpu, ctx: &GpuContext) -> Tables {
    let (mut cell_row, mut ff, mut fb, mut bf) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    gpu.read_tables(ctx, &mut cell_row, &mut ff, &mut fb, &mut bf).expect("read back");
    (cell_row, ff, fb, bf)
}

fn assert_same(gpu: &Tables, cpu: &Tables) {
    assert!(gpu.0 == cpu.0, "cell rows differ");
    assert!(gpu.1 == cpu.1, "fluid-fluid ranges differ");
    assert!(gpu.2 == cpu.2, "fluid-wall ranges differ");
    assert!(gpu.3 == cpu.3, "wall-fluid ranges differ");
}

#[test]
fn gpu_cell_ranges_are_bitwise_the_cpu_tables_on_100k_particles() {
    let Some(ctx) = gpu_common::context() else { return };
    let support = 0.02f32;
    let mut rng = Rng(11);
    // Fluid around the origin (negative cells too), walls overlapping it.
    let (_fx, fluid_grid) = sorted(100_000, -0.5, 0.5, support, &mut rng);
    let (wx, wall_grid) = sorted(30_000, -0.3, 0.7, support, &mut rng);
    let walls = Vel { x: &wx[0], y: &wx[1], z: &wx[2] };
    let active: Vec<u32> = (0..30_000u32).filter(|_| rng.range(0.0, 1.0) < 0.5).collect();
    for input in [Some(WallInput { grid: &wall_grid, walls, active: &active }), None] {
        let t = std::time::Instant::now();
        let cpu = cpu_tables(&fluid_grid, input);
        let cpu_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut gpu = RangesGpu::new(&ctx);
        let t = std::time::Instant::now();
        let device_ms = gpu.ensure(&ctx, &fluid_grid, input).expect("GPU ranges");
        let gpu_ms = t.elapsed().as_secs_f64() * 1e3;
        eprintln!(
            "build: CPU {cpu_ms:.1} ms ({} threads); GPU {gpu_ms:.1} ms wall (first, with uploads), device {device_ms:.1} ms",
            rayon::current_num_threads()
        );
        let g = gpu_tables(&gpu, &ctx);
        let occupied = |t: &[[u32; 2]]| t.iter().filter(|r| r[1] > r[0]).count();
        eprintln!(
            "{} fluid cells, {} wall cells, {} active walls; non-empty ranges: ff {}, fb {}, bf {}",
            fluid_grid.len(),
            input.map_or(0, |w| w.grid.len()),
            input.map_or(0, |w| w.active.len()),
            occupied(&cpu.1),
            occupied(&cpu.2),
            occupied(&cpu.3)
        );
        assert!(occupied(&cpu.1) > 0 && (input.is_none() || occupied(&cpu.2) > 0 && occupied(&cpu.3) > 0));
        assert_eq!(cpu.0.len(), 100_000);
        assert_same(&g, &cpu);
    }
}

#[test]
fn gpu_cell_ranges_are_rebuilt_when_their_input_changes() {
    let Some(ctx) = gpu_common::context() else { return };
    let support = 0.05f32;
    let mut rng = Rng(5);
    let (_a, grid_a) = sorted(20_000, -0.5, 0.5, support, &mut rng);
    let (_b, grid_b) = sorted(12_000, -0.4, 0.6, support, &mut rng);
    let (wx, wall_grid) = sorted(5_000, -0.3, 0.7, support, &mut rng);
    let walls = Vel { x: &wx[0], y: &wx[1], z: &wx[2] };
    let active: Vec<u32> = (0..5_000u32).filter(|_| rng.range(0.0, 1.0) < 0.5).collect();
    let fewer: Vec<u32> = active.iter().copied().filter(|b| b % 3 == 0).collect();
    let w = |active| Some(WallInput { grid: &wall_grid, walls, active });
    let mut gpu = RangesGpu::new(&ctx);
    // (fluid grid, walls, whether it builds, the tables it must hold).
    let steps: [(&CellGrid, Option<WallInput>, bool, Option<WallInput>); 7] = [
        (&grid_a, w(&active), true, w(&active)),
        // The same input, or fewer needs: the step's second pass reuses them.
        (&grid_a, w(&active), false, w(&active)),
        (&grid_a, None, false, w(&active)),
        // A new fluid grid (the next step), first asked for without walls.
        (&grid_b, None, true, None),
        (&grid_b, w(&active), true, w(&active)),
        // Other active walls, then a larger fluid grid again.
        (&grid_b, w(&fewer), true, w(&fewer)),
        (&grid_a, w(&fewer), true, w(&fewer)),
    ];
    for (k, (grid, input, builds, holds)) in steps.into_iter().enumerate() {
        let before = gpu.builds();
        gpu.ensure(&ctx, grid, input).expect("GPU ranges");
        assert_eq!(gpu.builds() - before, u64::from(builds), "step {k}: built {}", gpu.builds() - before);
        assert_eq!(gpu.n_fluid(), grid.starts.last().copied().unwrap_or(0) as usize);
        assert_same(&gpu_tables(&gpu, &ctx), &cpu_tables(grid, holds));
    }
}
