//! Migration: after the particles move, each goes to the rank that owns it
//! now (issue 19: "migrates particles that leave its range each step"),
//! and the ranks' ranges are cut again on whole cache blocks. It is the
//! distributed form of pass 0's Morton sort of the fluid store.
//!
//! [`migrate`], on every rank together:
//! 1. Each owned particle's new Morton key; it goes to the last rank whose
//!    first key (from the last cut) is at most its key, with its index in
//!    the old global order. The ranks then hold disjoint key ranges in
//!    rank order.
//! 2. Each rank sorts what it holds by (key, old global index): the single
//!    process's sort (key, ties by store index), so the ranks' lists in
//!    rank order are the single process's sorted store.
//! 3. The new global order is cut on whole blocks as the partitioner cuts
//!    it (rank r owns blocks `floor(r nb / P) .. floor((r + 1) nb / P)`),
//!    and the particles on the wrong side of a cut go to the next or
//!    previous ranks. The first keys of the new cut are gathered for the
//!    next migration.
//!
//! A particle travels as its row of every registered column of the
//! [`FluidStore`] (`for_each_column`), copied bit for bit: a field added
//! to the store later migrates with no extra code, and every phase's mass
//! and volume are the sums of the same particles' values afterwards.
//!
//! Only the fluid moves ranks here; solids (which follow their nearest
//! fluid particle's owner) and walls (which never move, but are handed
//! over as the fluid reaches them) are later slices.

use super::comm::{from_bytes, Communicator};
use super::partition::{Kind, PartitionError};
use crate::store::{Column, ColumnMut, FluidStore, Scratch};
use porosph_kernels::blocks::{nblocks, BLOCK};
use porosph_kernels::neighbors::compute_keys;
use std::ops::Range;

/// Tags of the two message rounds (below the communicator's own).
const TAG_ROUTE: u32 = 0x4d00;
const TAG_CUT: u32 = 0x4d02;

/// What a migration did, and the cut it left.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Migration {
    /// This rank's particles sent to another rank by key (step 1).
    pub routed: usize,
    /// This rank's particles sent across a new cut (step 3).
    pub recut: usize,
    /// The first key of every rank in the new cut (0 for rank 0).
    pub first_keys: Vec<u64>,
    /// Every rank's range of the new global order.
    pub ranges: Vec<Range<usize>>,
}

/// Moves rank `comm.rank()`'s fluid `store` (its owned range `offset..`
/// of the global order, moved since the cut that gave `first_keys`)
/// to the owners of its particles now (module doc). Fails, on every rank
/// alike, if the fluid makes fewer cache blocks than there are ranks.
pub fn migrate(
    comm: &dyn Communicator,
    store: &mut FluidStore,
    offset: usize,
    first_keys: &[u64],
    support: f32,
) -> Result<Migration, PartitionError> {
    let (me, size) = (comm.rank(), comm.size());
    assert_eq!(first_keys.len(), size, "one first key per rank");
    // 1. Route by key.
    let keys = keys_of(store, support);
    let dest: Vec<usize> = keys.iter().map(|&k| first_keys.partition_point(|&f| f <= k).saturating_sub(1)).collect();
    let mut routed = 0;
    for to in (0..size).filter(|&r| r != me) {
        let rows: Vec<u32> = (0..dest.len() as u32).filter(|&i| dest[i as usize] == to).collect();
        routed += rows.len();
        let old: Vec<u32> = rows.iter().map(|&i| (offset + i as usize) as u32).collect();
        send_rows(comm, to, TAG_ROUTE, store, &rows, &old);
    }
    let mine: Vec<u32> = (0..dest.len() as u32).filter(|&i| dest[i as usize] == me).collect();
    let mut old: Vec<u32> = mine.iter().map(|&i| (offset + i as usize) as u32).collect();
    let mut held = rows_of(store, &mine);
    for from in (0..size).filter(|&r| r != me) {
        old.extend(recv_rows(comm, from, TAG_ROUTE, &mut held));
    }
    // 2. Sort by (key, old global index).
    let keys = keys_of(&held, support);
    let mut perm: Vec<u32> = (0..keys.len() as u32).collect();
    perm.sort_unstable_by_key(|&i| (keys[i as usize], old[i as usize]));
    held.reorder(&perm, &mut Scratch::default());
    // 3. Cut on whole blocks.
    let counts = comm.all_gather_u64(&[held.len() as u64]);
    let n: usize = counts.iter().map(|&c| c as usize).sum();
    let nb = nblocks(n);
    if size > nb {
        return Err(PartitionError::MoreRanksThanBlocks { ranks: size, blocks: nb, particles: n, kind: Kind::Fluid });
    }
    let start = |r: usize| if r == size { n } else { (r * nb / size * BLOCK).min(n) };
    let target: Vec<Range<usize>> = (0..size).map(|r| start(r)..start(r + 1)).collect();
    let mut at = 0;
    let current: Vec<Range<usize>> = counts
        .iter()
        .map(|&c| {
            at += c as usize;
            at - c as usize..at
        })
        .collect();
    let overlap = |a: &Range<usize>, b: &Range<usize>| a.start.max(b.start)..a.end.min(b.end).max(a.start.max(b.start));
    let mut recut = 0;
    for to in (0..size).filter(|&r| r != me) {
        let o = overlap(&current[me], &target[to]);
        if !o.is_empty() {
            let rows: Vec<u32> = (o.start - current[me].start..o.end - current[me].start).map(|i| i as u32).collect();
            recut += rows.len();
            send_rows(comm, to, TAG_CUT, &held, &rows, &[]);
        }
    }
    let mut cut = empty_like(&held);
    for from in 0..size {
        let o = overlap(&current[from], &target[me]);
        if from == me {
            let rows: Vec<u32> = (o.start - current[me].start..o.end - current[me].start).map(|i| i as u32).collect();
            append_rows(&mut cut, &held, &rows);
        } else if !o.is_empty() {
            recv_rows(comm, from, TAG_CUT, &mut cut);
        }
    }
    assert_eq!(cut.len(), target[me].len(), "rank {me}: the new cut");
    *store = cut;
    let first = if me == 0 { 0 } else { keys_of(store, support)[0] };
    let first_keys = comm.all_gather_u64(&[first]);
    Ok(Migration { routed, recut, first_keys, ranges: target })
}

/// The Morton keys of a store's particles (cell size H, as pass 0).
fn keys_of(store: &FluidStore, support: f32) -> Vec<u64> {
    let mut keys = vec![0u64; store.len()];
    compute_keys(&store.x, &store.y, &store.z, 1.0 / support, &mut keys);
    keys
}

/// A store with the same columns (and phases) as `like` and no particles.
pub fn empty_like(like: &FluidStore) -> FluidStore {
    let mut phases = Vec::new();
    like.for_each_column(|_, _, c| {
        if let Column::PerPhase(v) = c {
            phases.push(v.len());
        }
    });
    let mut s = FluidStore::default();
    let mut phases = phases.into_iter();
    s.for_each_column_mut(|_, _, c| {
        if let ColumnMut::PerPhase(v) = c {
            *v = vec![Vec::new(); phases.next().unwrap_or(0)];
        }
    });
    s
}

/// The rows `rows` of `store`, in that order.
pub fn rows_of(store: &FluidStore, rows: &[u32]) -> FluidStore {
    let mut s = empty_like(store);
    append_rows(&mut s, store, rows);
    s
}

/// The rows `range` of a global store: a rank's share of it.
pub fn range_of(store: &FluidStore, range: Range<usize>) -> FluidStore {
    rows_of(store, &range.map(|i| i as u32).collect::<Vec<_>>())
}

/// The ranks' stores one after the other: the global store.
pub fn concat(parts: &[FluidStore]) -> FluidStore {
    let mut s = empty_like(&parts[0]);
    for p in parts {
        append_rows(&mut s, p, &(0..p.len() as u32).collect::<Vec<_>>());
    }
    s
}

/// Every rank's store in rank order, on every rank: after [`migrate`],
/// the global store (for checks; it sends every particle everywhere).
pub fn gather(comm: &dyn Communicator, store: &FluidStore) -> FluidStore {
    let (f, u) = pack(store, &(0..store.len() as u32).collect::<Vec<_>>());
    let counts = comm.all_gather_u64(&[store.len() as u64]);
    let (fs, us) = (comm.all_gather_bytes(bytemuck::cast_slice(&f)), comm.all_gather_bytes(bytemuck::cast_slice(&u)));
    let mut s = empty_like(store);
    for ((n, f), u) in counts.iter().zip(&fs).zip(&us) {
        unpack(&mut s, &from_bytes(f), &from_bytes(u), *n as usize);
    }
    s
}

/// Appends the rows `rows` of `src` to `dst` (same columns).
fn append_rows(dst: &mut FluidStore, src: &FluidStore, rows: &[u32]) {
    let (f, u) = pack(src, rows);
    unpack(dst, &f, &u, rows.len());
}

/// The rows `rows` of every column, column by column (phases in order):
/// the `f32` columns' values and the `u32` columns'.
fn pack(store: &FluidStore, rows: &[u32]) -> (Vec<f32>, Vec<u32>) {
    let (mut f, mut u) = (Vec::new(), Vec::new());
    store.for_each_column(|_, _, c| match c {
        Column::F32(v) => f.extend(rows.iter().map(|&i| v[i as usize])),
        Column::U32(v) => u.extend(rows.iter().map(|&i| v[i as usize])),
        Column::PerPhase(v) => v.iter().for_each(|v| f.extend(rows.iter().map(|&i| v[i as usize]))),
    });
    (f, u)
}

/// Appends `n` rows packed by [`pack`] to every column of `store`.
fn unpack(store: &mut FluidStore, f: &[f32], u: &[u32], n: usize) {
    let (mut fi, mut ui) = (0, 0);
    let mut take_f = |v: &mut Vec<f32>| {
        v.extend_from_slice(&f[fi..fi + n]);
        fi += n;
    };
    store.for_each_column_mut(|_, _, c| match c {
        ColumnMut::F32(v) => take_f(v),
        ColumnMut::U32(v) => {
            v.extend_from_slice(&u[ui..ui + n]);
            ui += n;
        }
        ColumnMut::PerPhase(v) => v.iter_mut().for_each(&mut take_f),
    });
    assert!(fi == f.len() && ui == u.len(), "a message of {n} particle rows with other columns");
}

/// Sends the rows `rows` of `store` and, after the `u32` columns, `extra`
/// (one `u32` per row, or none).
fn send_rows(comm: &dyn Communicator, to: usize, tag: u32, store: &FluidStore, rows: &[u32], extra: &[u32]) {
    let (f, mut u) = pack(store, rows);
    u.extend_from_slice(extra);
    comm.send_u32(to, tag, &[rows.len() as u32]);
    comm.send_f32(to, tag + 1, &f);
    comm.send_u32(to, tag, &u);
}

/// Receives rows sent by [`send_rows`], appends them to `store`, and
/// returns what came after the `u32` columns.
fn recv_rows(comm: &dyn Communicator, from: usize, tag: u32, store: &mut FluidStore) -> Vec<u32> {
    let n = comm.recv_u32(from, tag)[0] as usize;
    let f = comm.recv_f32(from, tag + 1);
    let u = comm.recv_u32(from, tag);
    let per_row_u = {
        let mut c = 0;
        store.for_each_column(|_, _, col| c += usize::from(matches!(col, Column::U32(_))));
        c
    };
    let extra = u[per_row_u * n..].to_vec();
    unpack(store, &f, &u[..per_row_u * n], n);
    extra
}
