//! Pass 0, neighbour search (PHYSICS.md §6): Morton keys, the sort order, and
//! per-pair kernel data for every query particle within the support H of a
//! target set sorted by cell.
//!
//! Neighbour data is kept per cache block of [`BLOCK`] query particles, so a
//! pass runs block by block in parallel with each block's pairs contiguous,
//! and the result does not depend on the number of threads.

use crate::blocks::BLOCK;
use crate::grid::{cell_of, morton, CellGrid};
use crate::kernel::{Kernel, KernelShape};
use crate::lanes::{load, load_partial, store, F, LANES};
use crate::soa::Vel;
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

    /// Makes `self` the pairs of `src` with the gradients times `scale`,
    /// for the queries i where `active[i]`; every other query keeps no
    /// pairs. The kernel values W are not copied (`w` stays empty). A loop
    /// over the pairs of an inactive query then adds nothing, as it would
    /// over pairs whose terms are all 0.
    pub fn copy_scaled_where(&mut self, src: &PairLists, scale: f32, active: &[bool]) {
        let nb = src.used().len();
        if self.blocks.len() < nb {
            self.blocks.resize_with(nb, PairBlock::default);
        }
        self.n = src.n;
        self.blocks[..nb].par_iter_mut().zip(src.used().par_iter()).enumerate().for_each(|(b, (d, s))| {
            d.clear();
            d.start.push(0);
            for q in 0..s.start.len().saturating_sub(1) {
                if active[b * BLOCK + q] {
                    let r = s.range(q);
                    d.j.extend_from_slice(&s.j[r.clone()]);
                    d.gx.extend(s.gx[r.clone()].iter().map(|x| x * scale));
                    d.gy.extend(s.gy[r.clone()].iter().map(|x| x * scale));
                    d.gz.extend(s.gz[r].iter().map(|x| x * scale));
                }
                d.start.push(d.j.len() as u32);
            }
        });
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

/// Finds, for every query point, all target points with |x_q - x_t| < H
/// (H = `kernel.support`; the support is half-open, W(H) = 0), and stores
/// their kernel values and gradients. Targets must be sorted by the cells of
/// `grid`. Pairs of a query are in ascending target order.
///
/// Each query's pairs are padded to a whole number of SIMD vectors with
/// pairs of weight and gradient 0 (target index: the query's first real
/// neighbour, or 0), so that every pass loads whole vectors.
///
/// `near`, if given, is a set of cells outside which no query has a target
/// within reach (see [`CellGrid::dilated_keys`]); queries there are skipped
/// with one lookup instead of 27.
pub fn build_pairs(
    lists: &mut PairLists,
    query: Vel,
    target: Vel,
    grid: &CellGrid,
    near: Option<&CellGrid>,
    kernel: &Kernel,
) {
    let n = query.len();
    let nblocks = n.div_ceil(BLOCK);
    if lists.blocks.len() < nblocks {
        lists.blocks.resize_with(nblocks, PairBlock::default);
    }
    lists.n = n;
    let h2 = kernel.support * kernel.support;
    lists.blocks[..nblocks].par_iter_mut().enumerate().for_each(|(b, blk)| {
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
                nr = if near.is_some_and(|set| set.find(morton(c)).is_none()) {
                    0
                } else {
                    let found = grid.neighbor_ranges(c, &mut ranges);
                    merge_ranges(&mut ranges, found)
                };
                last_cell = c;
            }
            let first = blk.j.len();
            let (vx, vy, vz) = (F::splat(xi), F::splat(yi), F::splat(zi));
            // Pass 1: compress the candidates inside the support; keep their
            // offsets x_ij in the gradient slots.
            for &(s, e) in &ranges[..nr] {
                let (s, e) = (s as usize, e as usize);
                let mut k = s;
                while k < e {
                    let dx = vx - load_partial(target.x, k);
                    let dy = vy - load_partial(target.y, k);
                    let dz = vz - load_partial(target.z, k);
                    let r2 = dx * dx + dy * dy + dz * dz;
                    let lanes = (e - k).min(LANES);
                    let inside = r2.simd_lt(F::splat(h2)).to_bitmask() & ((1u32 << lanes) - 1);
                    if inside != 0 {
                        push_offsets(blk, inside, k as u32, dx, dy, dz);
                    }
                    k += LANES;
                }
            }
            // Pad to whole vectors with zero pairs.
            let real = blk.j.len() - first;
            let pad = blk.j.get(first).copied().unwrap_or(0);
            while (blk.j.len() - first) % LANES != 0 {
                blk.j.push(pad);
                blk.gx.push(0.0);
                blk.gy.push(0.0);
                blk.gz.push(0.0);
            }
            blk.w.resize(blk.j.len(), 0.0);
            // Pass 2, the shape chosen once per query, not per vector.
            match kernel.shape {
                KernelShape::CubicSpline => {
                    kernel_values(blk, first, real, |r| (kernel.cubic_spline_w(r), kernel.cubic_spline_grad_over_r(r)))
                }
                KernelShape::WendlandC2 => {
                    kernel_values(blk, first, real, |r| (kernel.wendland_w(r), kernel.wendland_grad_over_r(r)))
                }
            }
            blk.start.push(blk.j.len() as u32);
        }
    });
}

/// Pass 2 of [`build_pairs`] for one query: kernel values and gradients
/// (`wg` gives W and W'/r) of its `real` pairs from `first`, a whole
/// vector at a time (padding lanes stay 0).
#[inline(always)]
fn kernel_values(blk: &mut PairBlock, first: usize, real: usize, wg: impl Fn(F) -> (F, F)) {
    let mut k = first;
    while k < blk.j.len() {
        let (dx, dy, dz) = (load(&blk.gx, k), load(&blk.gy, k), load(&blk.gz, k));
        let r = (dx * dx + dy * dy + dz * dz).sqrt();
        let valid = (real + first).saturating_sub(k).min(LANES);
        let keep = F::from(std::array::from_fn::<f32, LANES, _>(|l| if l < valid { 1.0 } else { 0.0 }));
        let (w, g) = wg(r);
        let g = g * keep;
        store(&mut blk.w, k, w * keep);
        store(&mut blk.gx, k, g * dx);
        store(&mut blk.gy, k, g * dy);
        store(&mut blk.gz, k, g * dz);
        k += LANES;
    }
}

/// Sorts the ranges by start and joins ranges that touch (in Morton order,
/// cells that differ only in their lowest bits are contiguous), so a query
/// scans fewer, longer runs. Returns the new count.
fn merge_ranges(r: &mut [(u32, u32); 27], n: usize) -> usize {
    r[..n].sort_unstable();
    let mut m = 0;
    for k in 0..n {
        if m > 0 && r[m - 1].1 == r[k].0 {
            r[m - 1].1 = r[k].1;
        } else {
            r[m] = r[k];
            m += 1;
        }
    }
    m
}

/// Appends the lanes of `mask`: target index `base + lane` to `j`, the
/// offset x_ij to the gradient slots (`w` is filled later).
#[inline(always)]
fn push_offsets(blk: &mut PairBlock, mask: u32, base: u32, gx: F, gy: F, gz: F) {
    #[cfg(target_feature = "avx512f")]
    {
        use std::arch::x86_64::*;
        let cnt = mask.count_ones() as usize;
        let len = blk.j.len();
        for v in [&mut blk.gx, &mut blk.gy, &mut blk.gz] {
            v.reserve(LANES);
        }
        blk.j.reserve(LANES);
        let m = mask as __mmask16;
        // SAFETY: each vector has room for LANES more elements (reserved
        // above); each store writes LANES elements at its pointer, of which
        // set_len covers the popcount(mask) <= LANES that the compress put
        // first (the rest is spare capacity, written but not exposed);
        // j, gx, gy, gz have the same length `len` (they grow together).
        // Compress into a register, then a plain store: the compress with
        // a memory operand (vcompressps m512{k}) is microcoded on AMD Zen 4,
        // where these four stores took 31 % of the 250k dam break's CPU
        // time (perf, bench/RESULTS.md).
        unsafe {
            let idx = _mm512_add_epi32(
                _mm512_set1_epi32(base as i32),
                _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15),
            );
            _mm512_storeu_si512(blk.j.as_mut_ptr().add(len) as *mut _, _mm512_maskz_compress_epi32(m, idx));
            let f = |v: F| std::mem::transmute::<F, __m512>(v);
            _mm512_storeu_ps(blk.gx.as_mut_ptr().add(len), _mm512_maskz_compress_ps(m, f(gx)));
            _mm512_storeu_ps(blk.gy.as_mut_ptr().add(len), _mm512_maskz_compress_ps(m, f(gy)));
            _mm512_storeu_ps(blk.gz.as_mut_ptr().add(len), _mm512_maskz_compress_ps(m, f(gz)));
            blk.j.set_len(len + cnt);
            blk.gx.set_len(len + cnt);
            blk.gy.set_len(len + cnt);
            blk.gz.set_len(len + cnt);
        }
    }
    #[cfg(not(target_feature = "avx512f"))]
    {
        let (gx, gy, gz) = (gx.to_array(), gy.to_array(), gz.to_array());
        let mut m = mask;
        while m != 0 {
            let l = m.trailing_zeros() as usize;
            m &= m - 1;
            blk.j.push(base + l as u32);
            blk.gx.push(gx[l]);
            blk.gy.push(gy[l]);
            blk.gz.push(gz[l]);
        }
    }
}
