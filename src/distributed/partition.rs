//! The partitioner: which rank owns which particles, and which particles
//! of other ranks each rank needs (its halo).
//!
//! The global order is the one the step already uses: each kind of
//! particle sorted by the Morton key of its cell of size H, ties by index
//! ([`sort_permutation`], as pass 0 sorts the fluid store, the walls once
//! at setup, and a copy of the solids every step).
//!
//! Ownership:
//! - The *primary* kind is the fluid (the solids in a scene without fluid;
//!   the walls in one with neither). Its sorted order is cut on whole
//!   cache blocks of [`BLOCK`] particles: rank r owns the blocks
//!   `floor(r nb / P) .. floor((r + 1) nb / P)` of the nb blocks, so every
//!   rank has `floor(nb / P)` or `ceil(nb / P)` blocks and owns fewer than
//!   [`BLOCK`] particles more than the mean (the cut balances by particle
//!   count: every fluid particle costs about the same in every pass).
//! - Rank r's first primary particle gives its first Morton key `lo_r`
//!   (`lo_0 = 0`). A wall or solid particle with a primary particle closer
//!   than H belongs to the owner of the nearest one (of equal distances the
//!   first in key order): a wall row or solid row is owned where the fluid
//!   it couples to is. Any other (far from every primary particle) belongs
//!   to the last rank with `lo_r <= k` for its key k, so a rank owns one
//!   run of cells along the curve of it. Not by key range alone: the
//!   keys put everything at a negative coordinate before everything at a
//!   positive one (the grid's origin offset), so the walls below and
//!   behind the fluid all went to rank 0, which then had the whole floor's
//!   fluid in its halo (the 8 M dam break at 1,024 ranks: 988,216 walls
//!   and a fluid halo of 128,373 for 8,192 owned, bench/RESULTS.md).
//! - The global order of a kind is rank by rank, key order within a rank
//!   (for the primary kind: its key order), so a rank owns a contiguous
//!   range of every kind's order. A solid body may span ranks.
//!
//! The halo of rank r: every particle (of any kind) owned by another rank
//! closer than H (`|x_i - x_j| < H`, the half-open support of the pair
//! search, in the same f32 arithmetic) to a particle (of any kind) that r
//! owns. It is found with the cell grid of each kind ([`CellGrid`]), the
//! 27 cells around each owned particle's cell.

use porosph_kernels::blocks::{nblocks, BLOCK};
use porosph_kernels::grid::{cell_of, CellGrid};
use porosph_kernels::neighbors::{compute_keys, sort_permutation};
use porosph_kernels::soa::Vel;
use rayon::prelude::*;
use std::fmt;
use std::ops::Range;

/// The most ranks a partition has (issue 19: "any P (1 to 4096)").
pub const MAX_RANKS: usize = 4096;

/// A kind of particle; indexes the per-kind arrays of a [`Partition`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    Fluid = 0,
    Wall = 1,
    Solid = 2,
}

impl Kind {
    /// Every kind, in index order.
    pub const ALL: [Kind; 3] = [Kind::Fluid, Kind::Wall, Kind::Solid];

    /// How messages and tables name it.
    pub fn name(self) -> &'static str {
        match self {
            Kind::Fluid => "fluid",
            Kind::Wall => "wall",
            Kind::Solid => "solid",
        }
    }
}

/// What a partition cannot be made of.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PartitionError {
    /// Zero ranks asked for.
    NoRanks,
    /// More than [`MAX_RANKS`].
    TooManyRanks { ranks: usize },
    /// More ranks than cache blocks of the primary kind: a rank would own
    /// nothing.
    MoreRanksThanBlocks { ranks: usize, blocks: usize, particles: usize, kind: Kind },
    /// The scene has no particles at all.
    NoParticles,
}

impl fmt::Display for PartitionError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PartitionError::NoRanks => write!(f, "--ranks must be at least 1 (1 to {MAX_RANKS})"),
            PartitionError::TooManyRanks { ranks } => {
                write!(f, "--ranks {ranks}: at most {MAX_RANKS} ranks (1 to {MAX_RANKS})")
            }
            PartitionError::MoreRanksThanBlocks { ranks, blocks, particles, kind } => write!(
                f,
                "--ranks {ranks}: the scene's {particles} {} particles make {blocks} cache block(s) of {BLOCK}, \
                 and a rank owns whole blocks: give 1 to {} ranks",
                kind.name(),
                blocks.min(&MAX_RANKS)
            ),
            PartitionError::NoParticles => write!(f, "the scene has no particles to partition"),
        }
    }
}

impl std::error::Error for PartitionError {}

/// One rank's share.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RankPart {
    /// The first Morton key the rank owns (0 for rank 0); it owns the keys
    /// up to the next rank's first.
    pub first_key: u64,
    /// The owned particles of each kind ([`Kind`] order), as a range of
    /// that kind's sorted order ([`Partition::order`]).
    pub owned: [Range<usize>; 3],
    /// The halo of each kind: indices into that kind's sorted order,
    /// ascending, none owned by this rank.
    pub halo: [Vec<u32>; 3],
}

impl RankPart {
    /// Owned particles of all kinds.
    pub fn owned_total(&self) -> usize {
        self.owned.iter().map(|r| r.len()).sum()
    }

    /// Halo particles of all kinds.
    pub fn halo_total(&self) -> usize {
        self.halo.iter().map(|h| h.len()).sum()
    }
}

/// The particles split among ranks.
#[derive(Clone, Debug)]
pub struct Partition {
    /// The support radius H the halo reaches, m.
    pub support: f32,
    /// The kind whose order is cut on whole blocks.
    pub primary: Kind,
    /// Each kind's global order (rank by rank, key order within a rank):
    /// `order[k][new] = old` (the index in the positions given to
    /// [`partition`]).
    pub order: [Vec<u32>; 3],
    /// Each kind's Morton keys in its global order.
    pub keys: [Vec<u64>; 3],
    /// One entry per rank.
    pub ranks: Vec<RankPart>,
}

impl Partition {
    /// Number of particles of kind `k`.
    pub fn len(&self, k: Kind) -> usize {
        self.order[k as usize].len()
    }

    /// Max over ranks / mean over ranks of the particles owned of the
    /// given kinds (1 = perfect balance; 1 with no such particles).
    pub fn imbalance(&self, kinds: &[Kind]) -> f64 {
        let owned: Vec<usize> =
            self.ranks.iter().map(|r| kinds.iter().map(|&k| r.owned[k as usize].len()).sum()).collect();
        let total: usize = owned.iter().sum();
        if total == 0 {
            return 1.0;
        }
        let mean = total as f64 / owned.len() as f64;
        *owned.iter().max().unwrap_or(&0) as f64 / mean
    }

    /// Halo particles of all ranks over all particles: the fraction of the
    /// particles a step keeps a second copy of.
    pub fn halo_fraction(&self) -> f64 {
        let halo: usize = self.ranks.iter().map(RankPart::halo_total).sum();
        let n: usize = Kind::ALL.iter().map(|&k| self.len(k)).sum();
        if n == 0 {
            0.0
        } else {
            halo as f64 / n as f64
        }
    }
}

/// One kind sorted along the Morton curve, with its cell grid (also the
/// halo's "is any owned particle within H", `halo::HaloPlan::discover`).
pub(super) struct Sorted {
    order: Vec<u32>,
    keys: Vec<u64>,
    pub(super) x: Vec<f32>,
    pub(super) y: Vec<f32>,
    pub(super) z: Vec<f32>,
    pub(super) grid: CellGrid,
}

pub(super) fn sort(p: Vel, support: f32) -> Sorted {
    let mut keys = vec![0u64; p.len()];
    compute_keys(p.x, p.y, p.z, 1.0 / support, &mut keys);
    let (mut scratch, mut order) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut scratch, &mut order);
    let keys: Vec<u64> = scratch.iter().map(|&(k, _)| k).collect();
    let gather = |v: &[f32]| order.iter().map(|&i| v[i as usize]).collect::<Vec<f32>>();
    let (x, y, z) = (gather(p.x), gather(p.y), gather(p.z));
    let mut grid = CellGrid::default();
    grid.build(&keys, support);
    Sorted { order, keys, x, y, z, grid }
}

/// Splits the fluid, wall and solid particles at `points` ([`Kind`]
/// order; positions in any order, m) among `ranks` ranks with halos of
/// `support` = H (module doc). Runs once: correctness before speed, but
/// O(n x neighbours) in all, in parallel.
pub fn partition(points: [Vel; 3], support: f32, ranks: usize) -> Result<Partition, PartitionError> {
    if ranks == 0 {
        return Err(PartitionError::NoRanks);
    }
    if ranks > MAX_RANKS {
        return Err(PartitionError::TooManyRanks { ranks });
    }
    let primary = [Kind::Fluid, Kind::Solid, Kind::Wall]
        .into_iter()
        .find(|&k| !points[k as usize].is_empty())
        .ok_or(PartitionError::NoParticles)?;
    let n = points[primary as usize].len();
    let nb = nblocks(n);
    if ranks > nb {
        return Err(PartitionError::MoreRanksThanBlocks { ranks, blocks: nb, particles: n, kind: primary });
    }
    let sorted = points.map(|p| sort(p, support));

    // The cuts of the primary order on whole blocks, and the first key of
    // every rank.
    let start = |r: usize| if r == ranks { n } else { (r * nb / ranks * BLOCK).min(n) };
    let pk = &sorted[primary as usize].keys;
    let first_key: Vec<u64> = (0..ranks).map(|r| if r == 0 { 0 } else { pk[start(r)] }).collect();
    // The owner of every particle, in each kind's key order.
    let mut owner: [Vec<u32>; 3] = Kind::ALL.map(|k| vec![0u32; sorted[k as usize].keys.len()]);
    for r in 0..ranks {
        owner[primary as usize][start(r)..start(r + 1)].fill(r as u32);
    }
    let (po, rest) = {
        let [a, b, c] = &mut owner;
        match primary {
            Kind::Fluid => (&*a, [(Kind::Wall, b), (Kind::Solid, c)]),
            Kind::Wall => (&*b, [(Kind::Fluid, a), (Kind::Solid, c)]),
            Kind::Solid => (&*c, [(Kind::Fluid, a), (Kind::Wall, b)]),
        }
    };
    for (k, own) in rest {
        let p = &sorted[primary as usize];
        let q = &sorted[k as usize];
        own.par_iter_mut().enumerate().for_each(|(i, o)| {
            *o = match nearest(p, q.x[i], q.y[i], q.z[i], support) {
                Some(j) => po[j],
                None => (first_key.partition_point(|&f| f <= q.keys[i]) - 1) as u32,
            };
        });
    }
    // Each rank's members of each kind, in key order.
    let members: [Vec<Vec<u32>>; 3] = owner.each_ref().map(|own| {
        let mut m = vec![Vec::new(); ranks];
        for (i, &o) in own.iter().enumerate() {
            m[o as usize].push(i as u32);
        }
        m
    });
    let halos: Vec<[Vec<u32>; 3]> = (0..ranks)
        .into_par_iter()
        .map(|r| {
            if ranks == 1 {
                return Default::default();
            }
            let mine = [&members[0][r][..], &members[1][r][..], &members[2][r][..]];
            halo(r as u32, mine, &sorted, &owner, support)
        })
        .collect();
    // The global order of each kind: rank by rank, key order within a
    // rank (the primary's key order itself).
    let mut order: [Vec<u32>; 3] = Default::default();
    let mut keys: [Vec<u64>; 3] = Default::default();
    let mut new_index: [Vec<u32>; 3] = Default::default();
    let mut owned: Vec<[Range<usize>; 3]> = vec![Default::default(); ranks];
    for k in Kind::ALL {
        let (ki, s) = (k as usize, &sorted[k as usize]);
        new_index[ki] = vec![0; s.keys.len()];
        for (r, m) in members[ki].iter().enumerate() {
            let lo = order[ki].len();
            for &i in m {
                new_index[ki][i as usize] = order[ki].len() as u32;
                order[ki].push(s.order[i as usize]);
                keys[ki].push(s.keys[i as usize]);
            }
            owned[r][ki] = lo..order[ki].len();
        }
    }
    let parts = halos
        .into_iter()
        .zip(owned)
        .zip(first_key)
        .map(|((h, owned), first_key)| {
            let halo = Kind::ALL.map(|k| {
                let mut v: Vec<u32> = h[k as usize].iter().map(|&i| new_index[k as usize][i as usize]).collect();
                v.sort_unstable();
                v
            });
            RankPart { first_key, owned, halo }
        })
        .collect();
    Ok(Partition { support, primary, order, keys, ranks: parts })
}

/// The particle of `p` nearest to (x, y, z) closer than H, if any (of
/// equal distances the first in key order).
fn nearest(p: &Sorted, x: f32, y: f32, z: f32, support: f32) -> Option<usize> {
    let mut ranges = [(0u32, 0u32); 27];
    let nr = p.grid.neighbor_ranges(cell_of(x, y, z, p.grid.inv_cell), &mut ranges);
    ranges[..nr].sort_unstable();
    let mut best: Option<(f32, usize)> = None;
    for &(s, e) in &ranges[..nr] {
        for j in s as usize..e as usize {
            let (dx, dy, dz) = (x - p.x[j], y - p.y[j], z - p.z[j]);
            let d2 = dx * dx + dy * dy + dz * dz;
            if d2 < support * support && best.is_none_or(|(b, _)| d2 < b) {
                best = Some((d2, j));
            }
        }
    }
    best.map(|(_, j)| j)
}

/// The halo of rank `r` that owns `owned` (module doc).
fn halo(r: u32, owned: [&[u32]; 3], sorted: &[Sorted; 3], owner: &[Vec<u32>; 3], support: f32) -> [Vec<u32>; 3] {
    let h2 = support * support;
    let mut found: [Vec<u32>; 3] = Default::default();
    let mut ranges = [(0u32, 0u32); 27];
    for (q, mine) in sorted.iter().zip(owned) {
        for &i in mine {
            let i = i as usize;
            let (xi, yi, zi) = (q.x[i], q.y[i], q.z[i]);
            let c = cell_of(xi, yi, zi, q.grid.inv_cell);
            for ((t, own), out) in sorted.iter().zip(owner).zip(found.iter_mut()) {
                let nr = t.grid.neighbor_ranges(c, &mut ranges);
                for &(s, e) in &ranges[..nr] {
                    let (s, e) = (s as usize, e as usize);
                    for (j, &o) in (s..e).zip(&own[s..e]) {
                        if o == r {
                            continue;
                        }
                        // As the pair search: query minus target, < H^2.
                        let (dx, dy, dz) = (xi - t.x[j], yi - t.y[j], zi - t.z[j]);
                        if dx * dx + dy * dy + dz * dz < h2 {
                            out.push(j as u32);
                        }
                    }
                }
            }
        }
    }
    for f in &mut found {
        f.sort_unstable();
        f.dedup();
    }
    found
}
