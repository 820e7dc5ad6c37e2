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
use crate::lanes::{load_partial, pair_vectors, sum, F, LANES};
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

    /// Multiplies the gradients of query q's pairs by `scale(q, j)` and
    /// keeps the pairs whose scaled gradient is nonzero, in their order
    /// (W, where the block stores it, goes with them); the ranges stay
    /// contiguous. For lists whose pairs are only ever summed one by one:
    /// the ranges are no longer whole SIMD vectors.
    pub fn scale_retain_nonzero(&mut self, scale: impl Fn(usize, usize) -> f32) {
        let with_w = self.w.len() == self.j.len();
        let mut to = 0;
        let mut from = self.start.first().map_or(0, |&s| s as usize);
        for q in 0..self.start.len().saturating_sub(1) {
            let end = self.start[q + 1] as usize;
            self.start[q] = to as u32;
            for k in from..end {
                let s = scale(q, self.j[k] as usize);
                let (x, y, z) = (self.gx[k] * s, self.gy[k] * s, self.gz[k] * s);
                if x != 0.0 || y != 0.0 || z != 0.0 {
                    self.j[to] = self.j[k];
                    if with_w {
                        self.w[to] = self.w[k];
                    }
                    (self.gx[to], self.gy[to], self.gz[to]) = (x, y, z);
                    to += 1;
                }
            }
            from = end;
        }
        if let Some(last) = self.start.last_mut() {
            *last = to as u32;
        }
        self.j.truncate(to);
        if with_w {
            self.w.truncate(to);
        }
        self.gx.truncate(to);
        self.gy.truncate(to);
        self.gz.truncate(to);
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

    /// Makes `self` lists of `n` queries without pairs (the vectors keep
    /// their capacity).
    pub fn clear_to(&mut self, n: usize) {
        let nb = n.div_ceil(BLOCK);
        if self.blocks.len() < nb {
            self.blocks.resize_with(nb, PairBlock::default);
        }
        self.n = n;
        for (b, blk) in self.blocks[..nb].iter_mut().enumerate() {
            blk.clear();
            blk.start.resize(BLOCK.min(n - b * BLOCK) + 1, 0);
        }
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
    scratch.resize(keys.len(), (0, 0));
    perm.resize(keys.len(), 0);
    sort_permutation_into(keys, scratch, perm);
}

/// [`sort_permutation`] into slices of the keys' length: `sorted` gets the
/// (key, index) pairs in ascending order, `perm` the indices.
pub fn sort_permutation_into(keys: &[u64], sorted: &mut [(u64, u32)], perm: &mut [u32]) {
    assert!(sorted.len() == keys.len() && perm.len() == keys.len(), "sort buffers of the keys' length");
    sorted.par_iter_mut().zip(keys.par_iter()).enumerate().for_each(|(i, (s, &k))| *s = (k, i as u32));
    sorted.par_sort_unstable();
    perm.par_iter_mut().zip(sorted.par_iter()).for_each(|(p, &(_, i))| *p = i);
}

/// Finds, for every query point, all target points with |x_q - x_t| < H
/// (H = `kernel.support`; the support is half-open, W(H) = 0), and stores
/// their kernel values and gradients. Targets must be sorted by the cells of
/// `grid`. Pairs of a query are in ascending target order.
///
/// The queries' pairs follow each other without padding; a pass reads
/// them a vector at a time with [`crate::lanes::pair_vectors`], whose last
/// vector of a query masks the lanes past its pairs (bench/RESULTS.md,
/// "Pair lists without padding": the padding to whole vectors was 7 % of
/// the fluid-fluid slots of the 1 M dam break, 14 % at 250k, and most of
/// the short wall and solid lists' slots).
///
/// `near`, if given, is a set of cells outside which no query has a target
/// within reach (see [`CellGrid::dilated_keys`]); queries there are skipped
/// with one lookup instead of 27.
///
/// Consecutive queries in one cell share their candidates: the targets of
/// the 27 cells around it, less those at H or more from the bounding box of
/// these queries, packed once into a scratch list which each query then
/// tests. (Geometry: on the start lattice at H = 2 d a cell's 8 queries
/// span about d per axis, and the volume within H of that box is 10.5 H^3
/// of the 27 cells' 27 H^3.)
pub fn build_pairs(
    lists: &mut PairLists,
    query: Vel,
    target: Vel,
    grid: &CellGrid,
    near: Option<&CellGrid>,
    kernel: &Kernel,
) {
    build::<true>(lists, query, target, grid, near, kernel, None)
}

/// [`build_pairs`] without storing the kernel values (`w` stays empty: 16
/// bytes a pair slot instead of 20), which only the density sum reads:
/// instead, `sums[i]` = sum_j `val[j]` W_ij for every query i, the sum of
/// [`crate::iisph::fluid_volumes`] over stored values, bit for bit (the
/// same W_ij, products and lane-wise accumulation in the same order). For
/// the fluid-fluid pairs, with `val` = V0 of the fluid.
#[allow(clippy::too_many_arguments)]
pub fn build_gradient_pairs(
    lists: &mut PairLists,
    query: Vel,
    target: Vel,
    grid: &CellGrid,
    near: Option<&CellGrid>,
    kernel: &Kernel,
    val: &[f32],
    sums: &mut [f32],
) {
    assert_eq!(sums.len(), query.len(), "one sum per query");
    build::<false>(lists, query, target, grid, near, kernel, Some((val, sums)))
}

/// The sums of [`build_gradient_pairs`] after some values changed:
/// `sums[i]` += (`new[j]` - `old[j]`) W_ij for every pair of the
/// fluid-fluid lists `ff` (query and target the same points `x`) whose
/// `j` changed (its bits differ). The lists are symmetric (i is in j's
/// list exactly when j is in i's, the same |x_i - x_j|^2 bits), so each
/// changed j walks its own list; W_ij is recomputed from the positions as
/// the neighbour pass computes it. Sequential in j order: the same result
/// for any thread count. For the porous partition, which changes a few
/// particles' rest volumes after the pairs were built (P Alg. 4's release,
/// beta back to alpha where no porous solid is near).
pub fn update_sums(ff: &PairLists, x: Vel, kernel: &Kernel, old: &[f32], new: &[f32], sums: &mut [f32]) {
    for (b, blk) in ff.used().iter().enumerate() {
        for q in 0..blk.start.len().saturating_sub(1) {
            let j = b * BLOCK + q;
            if old[j].to_bits() == new[j].to_bits() {
                continue;
            }
            let dv = new[j] - old[j];
            for p in blk.range(q) {
                let i = blk.j[p] as usize;
                let (dx, dy, dz) = (x.x[i] - x.x[j], x.y[i] - x.y[j], x.z[i] - x.z[j]);
                sums[i] += dv * kernel.w((dx * dx + dy * dy + dz * dz).sqrt());
            }
        }
    }
}

/// [`build_pairs`] (`W`: with the kernel values) or
/// [`build_gradient_pairs`] (with `sums`).
fn build<const W: bool>(
    lists: &mut PairLists,
    query: Vel,
    target: Vel,
    grid: &CellGrid,
    near: Option<&CellGrid>,
    kernel: &Kernel,
    sums: Option<(&[f32], &mut [f32])>,
) {
    let n = query.len();
    let nblocks = n.div_ceil(BLOCK);
    if lists.blocks.len() < nblocks {
        lists.blocks.resize_with(nblocks, PairBlock::default);
    }
    lists.n = n;
    let (val, out) = match sums {
        Some((v, s)) => (v, s),
        None => (&[][..], &mut [][..]),
    };
    let with_sums = !out.is_empty();
    let room = Candidates::room(grid, target.len());
    let blocks = lists.blocks[..nblocks].par_iter_mut();
    let out = if with_sums {
        rayon::iter::Either::Left(out.par_chunks_mut(BLOCK).map(Some))
    } else {
        rayon::iter::Either::Right((0..nblocks).into_par_iter().map(|_| None))
    };
    blocks.zip(out).enumerate().for_each(|(b, (blk, out))| {
        CANDIDATES.with_borrow_mut(|cand| {
            cand.reserve_room(room);
            let lo = b * BLOCK;
            let sums = out.map(|o| (val, o));
            let caps = blk.capacities();
            block_pairs::<W>(blk, cand, query, lo..(lo + BLOCK).min(n), target, grid, near, kernel, sums);
            if blk.capacities() != caps {
                blk.keep_headroom(W);
                blk.release_tails();
            }
        })
    });
}

impl PairBlock {
    /// The capacities of the pair lists.
    fn capacities(&self) -> [usize; 5] {
        [self.j.capacity(), self.w.capacity(), self.gx.capacity(), self.gy.capacity(), self.gz.capacity()]
    }

    /// After the lists grew: their capacity to a quarter above their
    /// length, so that the slow drift of the pair counts in a settling pool
    /// does not make a later step grow them again (a steady-state step
    /// allocates nothing, tests/no_alloc.rs). Growing by doubling alone
    /// left that to chance: without the padding, which rounded every
    /// query's count up to 16, one block of the hydrostatic tank's lists
    /// grew from 2,048 to 4,096 slots within steps 101-150, its count having
    /// crept past the capacity its first step's doubling ended at. The
    /// capacity past the length is not written, so it costs no resident
    /// memory ([`Self::release_tails`]).
    fn keep_headroom(&mut self, with_w: bool) {
        let len = self.j.len();
        let want = len + len / 4 + LANES;
        if self.j.capacity() < want {
            let more = want - len;
            self.j.reserve_exact(more);
            self.gx.reserve_exact(more);
            self.gy.reserve_exact(more);
            self.gz.reserve_exact(more);
            if with_w {
                self.w.reserve_exact(more);
            }
        }
    }

    /// Hands the whole pages of the lists' unused capacity back to the
    /// system (their memory stays allocated; a later write gets fresh
    /// pages). Called when a list has grown: the allocator may have placed
    /// it in memory written before (buffers freed earlier, the lists'
    /// own smaller predecessors), whose pages beyond the pairs would
    /// otherwise stay resident (bench/RESULTS.md, memory per fluid
    /// particle). A list grows only where a block has more pairs than
    /// ever before, so a step in steady state does not get here.
    fn release_tails(&self) {
        release_tail(&self.j);
        release_tail(&self.w);
        release_tail(&self.gx);
        release_tail(&self.gy);
        release_tail(&self.gz);
    }
}

/// [`PairBlock::release_tails`] for one list: `madvise(MADV_DONTNEED)` over
/// the whole pages between its length and its capacity (Linux; elsewhere
/// nothing).
fn release_tail<T>(v: &Vec<T>) {
    #[cfg(not(target_os = "linux"))]
    let _ = v;
    #[cfg(target_os = "linux")]
    {
        // Where pages are larger, an unaligned range makes the call fail
        // (EINVAL), which only leaves the pages resident.
        const PAGE: usize = 4096;
        let base = v.as_ptr() as usize;
        let (lo, hi) = (base + v.len() * size_of::<T>(), base + v.capacity() * size_of::<T>());
        // One vector past the length: the compressed stores write whole
        // vectors (query_pairs).
        let lo = (lo + LANES * size_of::<T>()).next_multiple_of(PAGE);
        let hi = hi / PAGE * PAGE;
        if lo < hi {
            // SAFETY: lo..hi lies inside the vector's allocation, past its
            // initialised elements (and past the whole vector that a
            // compressed store may write after them), in whole pages; with
            // MADV_DONTNEED those pages read as zeros afterwards, and the
            // vector reads nothing there before writing it.
            unsafe {
                libc::madvise(lo as *mut libc::c_void, hi - lo, libc::MADV_DONTNEED);
            }
        }
    }
}

/// Makes the C library serve every allocation of 64 KiB or more from its
/// own mapping, returned to the system when freed (glibc: a fixed
/// `M_MMAP_THRESHOLD`; elsewhere nothing). For the binaries, at start.
///
/// The pair lists are per-block vectors of 30-60 KiB each (512 queries,
/// about 30 pairs a query, 4 bytes a slot) that grow while the pairs are
/// built. glibc's default threshold starts at 128 KiB and rises to the
/// size of any mapped block that is freed, so these vectors are carved
/// from the worker threads' heaps, where the pages of the ones they
/// outgrew stay resident. Measured (bench/RESULTS.md, "Pair lists without
/// padding"): peak RSS of the 1 M dam break 882 -> 741-752 MB, Example 1
/// at the paper's size 675 -> 629 MB, the same step times.
pub fn large_allocations_from_mmap() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes the allocator's threshold; called before
    // any thread allocates (at the start of main).
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 * 1024);
    }
}

/// The candidate targets shared by a run of queries in one cell (see
/// [`build_pairs`]): positions and target indices, padded to whole vectors
/// with NaN positions (never within reach).
#[derive(Default)]
struct Candidates {
    x: Vec<f32>,
    y: Vec<f32>,
    z: Vec<f32>,
    j: Vec<u32>,
}

thread_local! {
    /// Each worker's candidate list, kept between calls so that a step in
    /// steady state allocates nothing (tests/no_alloc.rs).
    static CANDIDATES: std::cell::RefCell<Candidates> = std::cell::RefCell::default();
}

impl Candidates {
    /// Room for the candidates of any query cell of `grid`'s targets: the
    /// particles of 27 cells, at most 27 times its fullest cell and at
    /// most all `targets`, and the padding, rounded up to a power of two.
    fn room(grid: &CellGrid, targets: usize) -> usize {
        ((27 * grid.fullest as usize).min(targets) + LANES).next_power_of_two()
    }

    /// Makes room for `room` candidates. Every block takes it before its
    /// queries, so a worker's list has the room of every search it worked
    /// on, whichever blocks it got. Grown instead by what its blocks
    /// happened to need, a worker's list grew at a step that depended on
    /// rayon's schedule, not on the particles (tests/no_alloc.rs counts a
    /// step's allocations).
    fn reserve_room(&mut self, room: usize) {
        for v in [&mut self.x, &mut self.y, &mut self.z] {
            v.reserve(room.saturating_sub(v.len()));
        }
        self.j.reserve(room.saturating_sub(self.j.len()));
    }
}

/// The pairs of the queries `rows` (one cache block) into `blk`.
#[allow(clippy::too_many_arguments)]
fn block_pairs<const W: bool>(
    blk: &mut PairBlock,
    cand: &mut Candidates,
    query: Vel,
    rows: std::ops::Range<usize>,
    target: Vel,
    grid: &CellGrid,
    near: Option<&CellGrid>,
    kernel: &Kernel,
    mut sums: Option<(&[f32], &mut [f32])>,
) {
    let h2 = kernel.support * kernel.support;
    blk.clear();
    blk.start.push(0);
    let mut ranges = [(0u32, 0u32); 27];
    let mut i = rows.start;
    while i < rows.end {
        // The run i..e of queries in the cell of query i, and their box.
        let c = cell_of(query.x[i], query.y[i], query.z[i], grid.inv_cell);
        let (mut bmin, mut bmax) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        let mut e = i;
        while e < rows.end {
            let q = [query.x[e], query.y[e], query.z[e]];
            if e > i && cell_of(q[0], q[1], q[2], grid.inv_cell) != c {
                break;
            }
            // f32::min/max skip NaN: a NaN query has no pairs anyway.
            for a in 0..3 {
                bmin[a] = bmin[a].min(q[a]);
                bmax[a] = bmax[a].max(q[a]);
            }
            e += 1;
        }
        let nr = if near.is_some_and(|set| set.find(morton(c)).is_none()) {
            0
        } else {
            let found = grid.neighbor_ranges(c, &mut ranges);
            merge_ranges(&mut ranges, found)
        };
        gather_candidates(cand, target, &ranges[..nr], bmin, bmax, h2);
        if cand.j.is_empty() {
            // No target near the run (most of a pool, for walls and
            // solids): empty lists, and sums of nothing.
            let len = blk.j.len() as u32;
            for i in i..e {
                blk.start.push(len);
                if let Some((_, out)) = sums.as_mut() {
                    out[i - rows.start] = 0.0;
                }
            }
            i = e;
            continue;
        }
        for i in i..e {
            let first = blk.j.len();
            query_pairs(blk, cand, [query.x[i], query.y[i], query.z[i]], h2);
            let real = blk.j.len() - first;
            if W {
                blk.w.resize(first + real, 0.0);
            }
            // Pass 2, the shape chosen once per query, not per vector.
            let val = sums.as_ref().map(|s| s.0);
            let sum = match kernel.shape {
                KernelShape::CubicSpline => kernel_values::<W>(blk, first, real, val, |r| {
                    (kernel.cubic_spline_w(r), kernel.cubic_spline_grad_over_r(r))
                }),
                KernelShape::WendlandC2 => kernel_values::<W>(blk, first, real, val, |r| {
                    (kernel.wendland_w(r), kernel.wendland_grad_over_r(r))
                }),
            };
            if let Some((_, out)) = sums.as_mut() {
                out[i - rows.start] = sum;
            }
            blk.start.push(blk.j.len() as u32);
        }
        i = e;
    }
}

/// Packs into `cand` the targets of `ranges` (ascending, disjoint) that are
/// not at H or more from the box `bmin..bmax`, in target order. The box
/// test is conservative in floating point: for a query inside the box,
/// rounding is monotone, so its |x_q - x_t|^2, computed as in
/// [`query_pairs`], is at least the box distance squared; a dropped target
/// would therefore have failed the query's own test.
fn gather_candidates(
    cand: &mut Candidates,
    target: Vel,
    ranges: &[(u32, u32)],
    bmin: [f32; 3],
    bmax: [f32; 3],
    h2: f32,
) {
    let total: usize = ranges.iter().map(|&(s, e)| (e - s) as usize).sum();
    for v in [&mut cand.x, &mut cand.y, &mut cand.z] {
        v.clear();
        v.reserve(total + LANES);
    }
    cand.j.clear();
    cand.j.reserve(total + LANES);
    let (lx, ly, lz) = (F::splat(bmin[0]), F::splat(bmin[1]), F::splat(bmin[2]));
    let (hx, hy, hz) = (F::splat(bmax[0]), F::splat(bmax[1]), F::splat(bmax[2]));
    let zero = F::splat(0.0);
    let mut len = 0;
    for &(s, e) in ranges {
        let (s, e) = (s as usize, e as usize);
        let mut k = s;
        while k < e {
            let x = load_partial(target.x, k);
            let y = load_partial(target.y, k);
            let z = load_partial(target.z, k);
            // Per axis the distance to the box, 0 inside it (NaN: either
            // way, a NaN target has no pairs).
            let dx = (lx - x).fast_max(x - hx).fast_max(zero);
            let dy = (ly - y).fast_max(y - hy).fast_max(zero);
            let dz = (lz - z).fast_max(z - hz).fast_max(zero);
            let d2 = dx * dx + dy * dy + dz * dz;
            let lanes = (e - k).min(LANES);
            let keep = d2.simd_lt(F::splat(h2)).to_bitmask() & ((1u32 << lanes) - 1);
            if keep != 0 {
                let idx: [u32; LANES] = std::array::from_fn(|l| (k + l) as u32);
                let sel = pack::Sel::new(keep);
                // SAFETY: each vector has room for `total + LANES` elements
                // (reserved above) and `len + popcount(keep) <= total`; each
                // put writes LANES elements from `len`.
                unsafe {
                    sel.put(cand.x.as_mut_ptr().add(len), x);
                    sel.put(cand.y.as_mut_ptr().add(len), y);
                    sel.put(cand.z.as_mut_ptr().add(len), z);
                    sel.put_u32(cand.j.as_mut_ptr().add(len), &idx);
                }
                len += keep.count_ones() as usize;
            }
            k += LANES;
        }
    }
    // SAFETY: the first `len` elements of each were written above.
    unsafe {
        cand.x.set_len(len);
        cand.y.set_len(len);
        cand.z.set_len(len);
        cand.j.set_len(len);
    }
    let whole = len.next_multiple_of(LANES);
    cand.x.resize(whole, f32::NAN);
    cand.y.resize(whole, f32::NAN);
    cand.z.resize(whole, f32::NAN);
    cand.j.resize(whole, 0);
}

/// The whole vectors of `v`.
#[inline(always)]
fn vectors(v: &[f32]) -> impl Iterator<Item = F> + '_ {
    v.chunks_exact(LANES).map(|c| F::from(<[f32; LANES]>::try_from(c).expect("a whole vector")))
}

/// Appends to `blk` the candidates within H of `q`, in candidate order:
/// target index to `j`, the offset x_ij to the gradient slots (`w` and the
/// gradients are filled later).
///
/// The lists grow only as pairs are found (a vector whose compressed store
/// would pass the capacity is appended lane by lane, growing as a push
/// does), so their capacity is what the pairs need, as with plain pushes,
/// not that plus the candidates' count.
#[inline(always)]
fn query_pairs(blk: &mut PairBlock, cand: &Candidates, q: [f32; 3], h2: f32) {
    let room = |b: &PairBlock| b.j.capacity().min(b.gx.capacity()).min(b.gy.capacity()).min(b.gz.capacity());
    let mut cap = room(blk);
    let (vx, vy, vz) = (F::splat(q[0]), F::splat(q[1]), F::splat(q[2]));
    let mut n = blk.j.len();
    let idx = cand.j.chunks_exact(LANES).map(|c| <&[u32; LANES]>::try_from(c).expect("a whole vector"));
    for (((cx, cy), cz), idx) in vectors(&cand.x).zip(vectors(&cand.y)).zip(vectors(&cand.z)).zip(idx) {
        let (dx, dy, dz) = (vx - cx, vy - cy, vz - cz);
        let r2 = dx * dx + dy * dy + dz * dz;
        let inside = r2.simd_lt(F::splat(h2)).to_bitmask();
        if inside == 0 {
            continue;
        }
        if n + LANES <= cap {
            let sel = pack::Sel::new(inside);
            // SAFETY: each vector has capacity for `n + LANES` elements
            // (checked above); each put writes LANES elements from `n`.
            unsafe {
                sel.put_u32(blk.j.as_mut_ptr().add(n), idx);
                sel.put(blk.gx.as_mut_ptr().add(n), dx);
                sel.put(blk.gy.as_mut_ptr().add(n), dy);
                sel.put(blk.gz.as_mut_ptr().add(n), dz);
            }
            n += inside.count_ones() as usize;
        } else {
            // SAFETY: the elements up to `n` were written (before, or by
            // the puts above).
            unsafe {
                blk.j.set_len(n);
                blk.gx.set_len(n);
                blk.gy.set_len(n);
                blk.gz.set_len(n);
            }
            let (dx, dy, dz) = (dx.to_array(), dy.to_array(), dz.to_array());
            let mut m = inside;
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                blk.j.push(idx[l]);
                blk.gx.push(dx[l]);
                blk.gy.push(dy[l]);
                blk.gz.push(dz[l]);
            }
            n = blk.j.len();
            cap = room(blk);
        }
    }
    // SAFETY: the elements up to `n` were written (before, or above).
    unsafe {
        blk.j.set_len(n);
        blk.gx.set_len(n);
        blk.gy.set_len(n);
        blk.gz.set_len(n);
    }
}

/// Pass 2 of [`build_pairs`] for one query: kernel values and gradients
/// (`wg` gives W and W'/r) of its `real` pairs from `first`, a vector at a
/// time ([`pair_vectors`]: the last one partial, its other lanes neither
/// read nor written). Stores W if `W`; returns sum_j val_j W_ij where
/// `val` is given (as `iisph::weighted_sum` sums the stored values), else 0.
#[inline(always)]
fn kernel_values<const W: bool>(
    blk: &mut PairBlock,
    first: usize,
    real: usize,
    val: Option<&[f32]>,
    wg: impl Fn(F) -> (F, F),
) -> f32 {
    let mut acc = F::ZERO;
    for v in pair_vectors(&blk.j, first..first + real) {
        let (dx, dy, dz) = (v.load(&blk.gx), v.load(&blk.gy), v.load(&blk.gz));
        let r = (dx * dx + dy * dy + dz * dz).sqrt();
        let keep = F::from(std::array::from_fn::<f32, LANES, _>(|l| if l < v.n { 1.0 } else { 0.0 }));
        let (w, g) = wg(r);
        let w = w * keep;
        if W {
            v.store(&mut blk.w, w);
        }
        if let Some(val) = val {
            acc += v.gather(val) * w;
        }
        v.store(&mut blk.gx, g * dx);
        v.store(&mut blk.gy, g * dy);
        v.store(&mut blk.gz, g * dz);
    }
    sum(acc)
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

/// Stream compaction of SIMD lanes: [`Sel`] selects the lanes of a 16-bit
/// mask and writes them, in lane order, to the start of a buffer with room
/// for LANES elements (the lanes past the count are written but not part
/// of the result).
mod pack {
    use crate::lanes::{F, LANES};

    /// AVX-512: one compress into a register, then a plain store (the
    /// compress with a memory operand is microcoded on AMD Zen 4, where
    /// those stores took 31 % of the 250k dam break's CPU time; perf,
    /// bench/RESULTS.md).
    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    pub struct Sel(core::arch::x86_64::__mmask16);

    #[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
    impl Sel {
        #[inline(always)]
        pub fn new(mask: u32) -> Self {
            Sel(mask as u16)
        }

        /// # Safety
        /// `dst` is valid for writes of LANES f32.
        #[inline(always)]
        pub unsafe fn put(&self, dst: *mut f32, v: F) {
            use std::arch::x86_64::*;
            unsafe {
                let v = std::mem::transmute::<F, __m512>(v);
                _mm512_storeu_ps(dst, _mm512_maskz_compress_ps(self.0, v));
            }
        }

        /// # Safety
        /// `dst` is valid for writes of LANES u32.
        #[inline(always)]
        pub unsafe fn put_u32(&self, dst: *mut u32, v: &[u32; LANES]) {
            use std::arch::x86_64::*;
            unsafe {
                let v = _mm512_loadu_si512(v.as_ptr() as *const _);
                _mm512_storeu_si512(dst as *mut _, _mm512_maskz_compress_epi32(self.0, v));
            }
        }
    }

    /// AVX2: each 8-lane half through a permutation from a table of the
    /// 256 byte masks, stored at the count of the halves before it.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2", not(target_feature = "avx512f")))]
    pub struct Sel {
        lo: core::arch::x86_64::__m256i,
        hi: core::arch::x86_64::__m256i,
        n_lo: usize,
    }

    /// For each byte mask, the indices of its set bits, in order.
    #[cfg(all(target_arch = "x86_64", target_feature = "avx2", not(target_feature = "avx512f")))]
    static PERM: [[u32; 8]; 256] = {
        let mut t = [[0u32; 8]; 256];
        let mut m = 0;
        while m < 256 {
            let (mut n, mut l) = (0, 0);
            while l < 8 {
                if m & (1 << l) != 0 {
                    t[m][n] = l as u32;
                    n += 1;
                }
                l += 1;
            }
            m += 1;
        }
        t
    };

    #[cfg(all(target_arch = "x86_64", target_feature = "avx2", not(target_feature = "avx512f")))]
    impl Sel {
        #[inline(always)]
        pub fn new(mask: u32) -> Self {
            use std::arch::x86_64::*;
            let (a, b) = ((mask & 0xff) as usize, ((mask >> 8) & 0xff) as usize);
            // SAFETY: each row of PERM is 8 u32 (32 bytes); loadu has no
            // alignment requirement.
            unsafe {
                Sel {
                    lo: _mm256_loadu_si256(PERM[a].as_ptr() as *const __m256i),
                    hi: _mm256_loadu_si256(PERM[b].as_ptr() as *const __m256i),
                    n_lo: a.count_ones() as usize,
                }
            }
        }

        /// # Safety
        /// `dst` is valid for writes of LANES f32.
        #[inline(always)]
        pub unsafe fn put(&self, dst: *mut f32, v: F) {
            use std::arch::x86_64::*;
            // F is two __m256 (lanes 0-7, then 8-15) without AVX-512.
            unsafe {
                let [a, b] = std::mem::transmute::<F, [__m256; 2]>(v);
                _mm256_storeu_ps(dst, _mm256_permutevar8x32_ps(a, self.lo));
                _mm256_storeu_ps(dst.add(self.n_lo), _mm256_permutevar8x32_ps(b, self.hi));
            }
        }

        /// # Safety
        /// `dst` is valid for writes of LANES u32.
        #[inline(always)]
        pub unsafe fn put_u32(&self, dst: *mut u32, v: &[u32; LANES]) {
            use std::arch::x86_64::*;
            unsafe {
                let a = _mm256_loadu_si256(v.as_ptr() as *const __m256i);
                let b = _mm256_loadu_si256(v.as_ptr().add(8) as *const __m256i);
                _mm256_storeu_si256(dst as *mut __m256i, _mm256_permutevar8x32_epi32(a, self.lo));
                _mm256_storeu_si256(dst.add(self.n_lo) as *mut __m256i, _mm256_permutevar8x32_epi32(b, self.hi));
            }
        }
    }

    /// Elsewhere: lane by lane.
    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    pub struct Sel(u32);

    #[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
    impl Sel {
        #[inline(always)]
        pub fn new(mask: u32) -> Self {
            Sel(mask)
        }

        /// # Safety
        /// `dst` is valid for writes of LANES f32.
        #[inline(always)]
        pub unsafe fn put(&self, dst: *mut f32, v: F) {
            self.put_u32(dst as *mut u32, &v.to_array().map(f32::to_bits));
        }

        /// # Safety
        /// `dst` is valid for writes of LANES u32.
        #[inline(always)]
        pub unsafe fn put_u32(&self, dst: *mut u32, v: &[u32; LANES]) {
            let (mut m, mut n) = (self.0, 0);
            while m != 0 {
                let l = m.trailing_zeros() as usize;
                m &= m - 1;
                unsafe { dst.add(n).write(v[l]) };
                n += 1;
            }
        }
    }
}
