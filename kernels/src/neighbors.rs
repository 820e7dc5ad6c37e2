//! Pass 0, neighbour search (PHYSICS.md §6): Morton keys, the sort order, and
//! per-pair kernel data for every query particle within the support H of a
//! target set sorted by cell.
//!
//! Neighbour data is kept per cache block of [`BLOCK`] query particles, so a
//! pass runs block by block in parallel with each block's pairs contiguous,
//! and the result does not depend on the number of threads.

use crate::blocks::BLOCK;
use crate::cubic_spline::CubicSpline;
use crate::grid::{cell_of, morton, CellGrid};
use crate::lanes::{load, F, LANES};
use rayon::prelude::*;

/// The pairs of one block of query particles (local CSR).
///
/// For query `q` of the block, its pairs are `start[q]..start[q + 1]`; pair
/// `p` has target index `j[p]`, kernel value `w[p]` = W(|x_ij|) (1/m^3) and
/// gradient `g[p]` = grad_i W(x_i - x_j) (1/m^4), which the pressure solve
/// later scales in place by the harmonic pair volume (PHYSICS.md §2.4).
#[derive(Clone, Debug, Default)]
pub struct PairBlock {
    pub start: Vec<u32>,
    pub j: Vec<u32>,
    pub w: Vec<f32>,
    pub gx: Vec<f32>,
    pub gy: Vec<f32>,
    pub gz: Vec<f32>,
}

impl PairBlock {
    fn clear(&mut self) {
        self.start.clear();
        self.j.clear();
        self.w.clear();
        self.gx.clear();
        self.gy.clear();
        self.gz.clear();
    }

    /// Number of pairs.
    pub fn len(&self) -> usize {
        self.j.len()
    }

    /// Whether the block has no pairs.
    pub fn is_empty(&self) -> bool {
        self.j.is_empty()
    }

    /// The pair range of local query `q`.
    #[inline(always)]
    pub fn range(&self, q: usize) -> std::ops::Range<usize> {
        self.start[q] as usize..self.start[q + 1] as usize
    }
}

/// Neighbour pairs of a query set against a target set, block by block.
#[derive(Clone, Debug, Default)]
pub struct PairLists {
    pub blocks: Vec<PairBlock>,
    /// Number of query particles.
    pub n: usize,
}

impl PairLists {
    /// The blocks in use (the vector keeps more when the query set shrank).
    #[inline]
    pub fn used(&self) -> &[PairBlock] {
        &self.blocks[..self.n.div_ceil(BLOCK)]
    }

    /// The blocks in use, mutably.
    #[inline]
    pub fn used_mut(&mut self) -> &mut [PairBlock] {
        let nb = self.n.div_ceil(BLOCK);
        &mut self.blocks[..nb]
    }

    /// Total number of pairs.
    pub fn pairs(&self) -> usize {
        self.used().iter().map(|b| b.len()).sum()
    }

    /// Bytes held (capacity) by the lists.
    pub fn bytes(&self) -> usize {
        self.blocks
            .iter()
            .map(|b| {
                4 * (b.start.capacity()
                    + b.j.capacity()
                    + b.w.capacity()
                    + b.gx.capacity()
                    + b.gy.capacity()
                    + b.gz.capacity())
            })
            .sum()
    }
}

/// Morton key of each particle's cell (cell size `1/inv_cell`), in parallel.
pub fn compute_keys(x: &[f32], y: &[f32], z: &[f32], inv_cell: f32, keys: &mut [u64]) {
    keys.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
        let o = b * BLOCK;
        for (k, key) in out.iter_mut().enumerate() {
            let i = o + k;
            *key = morton(cell_of(x[i], y[i], z[i], inv_cell));
        }
    });
}

/// The permutation that sorts `keys` ascending, ties by index (so it is
/// unique): `perm[new] = old`. `scratch` is reused between calls.
pub fn sort_permutation(keys: &[u64], scratch: &mut Vec<(u64, u32)>, perm: &mut Vec<u32>) {
    scratch.clear();
    scratch.extend(keys.iter().enumerate().map(|(i, &k)| (k, i as u32)));
    scratch.par_sort_unstable();
    perm.clear();
    perm.extend(scratch.iter().map(|&(_, i)| i));
}

/// Positions as three coordinate slices.
#[derive(Clone, Copy)]
pub struct Points<'a> {
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub z: &'a [f32],
}

impl Points<'_> {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Whether there are no points.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }
}

/// Finds, for every query point, all target points with |x_q - x_t| < H
/// (H = `kernel.support`; the support is half-open, W(H) = 0), and stores
/// their kernel values and gradients. Targets must be sorted by the cells of
/// `grid`. Pairs of a query are in target-cell order, then target order.
pub fn build_pairs(
    lists: &mut PairLists,
    query: Points,
    target: Points,
    grid: &CellGrid,
    kernel: &CubicSpline,
) {
    let n = query.len();
    let nblocks = n.div_ceil(BLOCK);
    if lists.blocks.len() < nblocks {
        lists.blocks.resize_with(nblocks, PairBlock::default);
    }
    lists.n = n;
    let h2 = kernel.support * kernel.support;
    lists.blocks[..nblocks]
        .par_iter_mut()
        .enumerate()
        .for_each(|(b, blk)| {
            blk.clear();
            let lo = b * BLOCK;
            let hi = (lo + BLOCK).min(n);
            let mut ranges = [(0u32, 0u32); 27];
            let mut nr = 0;
            let mut last_cell = [u32::MAX; 3];
            blk.start.push(0);
            for i in lo..hi {
                let (xi, yi, zi) = (query.x[i], query.y[i], query.z[i]);
                let c = cell_of(xi, yi, zi, grid.inv_cell);
                if c != last_cell {
                    nr = grid.neighbor_ranges(c, &mut ranges);
                    last_cell = c;
                }
                let (vx, vy, vz) = (F::splat(xi), F::splat(yi), F::splat(zi));
                for &(s, e) in &ranges[..nr] {
                    let (s, e) = (s as usize, e as usize);
                    let mut k = s;
                    while k < e {
                        let dx = vx - load(&target.x[..e], k);
                        let dy = vy - load(&target.y[..e], k);
                        let dz = vz - load(&target.z[..e], k);
                        let r2 = dx * dx + dy * dy + dz * dz;
                        let lanes = (e - k).min(LANES);
                        let inside = r2.simd_lt(F::splat(h2)).to_bitmask() & ((1u32 << lanes) - 1);
                        if inside != 0 {
                            let r = r2.sqrt();
                            let w = kernel.w(r).to_array();
                            let g = kernel.grad_over_r(r);
                            let (gx, gy, gz) = (
                                (g * dx).to_array(),
                                (g * dy).to_array(),
                                (g * dz).to_array(),
                            );
                            let mut m = inside;
                            while m != 0 {
                                let l = m.trailing_zeros() as usize;
                                m &= m - 1;
                                blk.j.push((k + l) as u32);
                                blk.w.push(w[l]);
                                blk.gx.push(gx[l]);
                                blk.gy.push(gy[l]);
                                blk.gz.push(gz[l]);
                            }
                        }
                        k += LANES;
                    }
                }
                blk.start.push(blk.j.len() as u32);
            }
        });
}
