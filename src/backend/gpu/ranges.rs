//! Cell-range tables: how a GPU pass finds the neighbours of a particle
//! without pair lists. A query row (a fluid cell, or one active wall) has
//! 27 (start, end) particle ranges of a target set sorted by cell: the
//! occupied cells among the 27 around the row's cell, in the fixed order of
//! [`CellGrid::neighbor_ranges`], then empty (0, 0) slots. A pass scans these
//! ranges and keeps the targets closer than the support H, the same set the
//! CPU neighbour search stores as pairs.

use porosph_kernels::grid::{cell_of, unmorton, CellGrid};
use porosph_kernels::neighbors::Points;
use rayon::prelude::*;

/// Ranges per query row.
pub const RANGES: usize = 27;

fn fill(target: &CellGrid, cell: [u32; 3], out: &mut [[u32; 2]]) {
    let mut r = [(0u32, 0u32); RANGES];
    let n = if target.is_empty() { 0 } else { target.neighbor_ranges(cell, &mut r) };
    for (o, &(s, e)) in out.iter_mut().zip(&r[..n]) {
        *o = [s, e];
    }
    out[n..].fill([0, 0]);
}

/// Rows of the fluid particles, one per occupied fluid cell: `cell_row[i]`
/// is the cell of fluid particle i (the fluid is sorted by cell), and row c
/// of `ff` / `fb` holds the fluid / wall ranges around cell c.
pub fn fluid_rows(
    fluid_grid: &CellGrid,
    wall_grid: &CellGrid,
    cell_row: &mut Vec<u32>,
    ff: &mut Vec<[u32; 2]>,
    fb: &mut Vec<[u32; 2]>,
) {
    let cells = fluid_grid.len();
    let n = fluid_grid.starts.last().copied().unwrap_or(0) as usize;
    cell_row.resize(n, 0);
    for (c, w) in fluid_grid.starts.windows(2).enumerate() {
        cell_row[w[0] as usize..w[1] as usize].fill(c as u32);
    }
    ff.resize(cells * RANGES, [0, 0]);
    fb.resize(cells * RANGES, [0, 0]);
    ff.par_chunks_mut(RANGES).zip(fb.par_chunks_mut(RANGES)).zip(fluid_grid.cells.par_iter()).for_each(
        |((f, b), &key)| {
            let c = unmorton(key);
            fill(fluid_grid, c, f);
            fill(wall_grid, c, b);
        },
    );
}

/// Rows of the active walls, one per wall: row k of `bf` holds the fluid
/// ranges around the cell of wall `active[k]`.
pub fn wall_rows(walls: Points, active: &[u32], fluid_grid: &CellGrid, bf: &mut Vec<[u32; 2]>) {
    bf.resize(active.len() * RANGES, [0, 0]);
    bf.par_chunks_mut(RANGES).zip(active.par_iter()).for_each(|(out, &b)| {
        let b = b as usize;
        fill(fluid_grid, cell_of(walls.x[b], walls.y[b], walls.z[b], fluid_grid.inv_cell), out);
    });
}
