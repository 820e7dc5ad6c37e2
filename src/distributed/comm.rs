//! The communication layer of distributed runs (issue 19): the
//! [`Communicator`] trait, and [`run_ranks`], which runs P virtual ranks as
//! threads of one process ("an in-process communicator that runs P virtual
//! ranks as threads, so the partitioner, migration, halos and reductions
//! are tested without MPI").
//!
//! The trait holds what the distributed passes need and no more: the rank
//! and the number of ranks, point-to-point messages of bytes (and of
//! `f32`/`u32` through [`bytemuck`]), a barrier, and an all-gather of
//! variable length (the per-block partial sums of a reproducible
//! reduction, [`super::reduce`]). Each maps onto one MPI call, as the
//! implementation over rsmpi behind the `mpi` feature does
//! (`super::mpi`): `send_bytes` an immediate (non-blocking) send,
//! `recv_bytes` a receive from one source with one tag, `barrier`
//! `MPI_Barrier`, `all_gather_bytes` `MPI_Allgather` of the lengths then
//! `MPI_Allgatherv`.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{channel, Receiver, RecvTimeoutError, Sender};
use std::time::Duration;

/// Tags from here up are the communicator's own (its collectives); the
/// passes use tags below it.
pub const RESERVED_TAGS: u32 = 1 << 30;
const TAG_GATHER: u32 = RESERVED_TAGS;

/// P ranks that exchange messages (module doc).
///
/// Message order: of the messages one rank sends to another with one tag,
/// the receiver gets them in the order sent (MPI's non-overtaking rule);
/// messages with other tags or from other ranks may be received in any
/// order. A send returns without waiting for its receive, so an exchange
/// may post all its sends before its receives.
pub trait Communicator {
    /// This rank, 0 to `size() - 1`.
    fn rank(&self) -> usize;

    /// The number of ranks P.
    fn size(&self) -> usize;

    /// Sends `data` to rank `to` (another rank) with `tag` (below
    /// [`RESERVED_TAGS`]).
    fn send_bytes(&self, to: usize, tag: u32, data: &[u8]);

    /// The next message from rank `from` with `tag`; waits for it.
    fn recv_bytes(&self, from: usize, tag: u32) -> Vec<u8>;

    /// Returns once every rank has called it.
    fn barrier(&self);

    /// Every rank's `local` (any length, rank by rank), on every rank.
    fn all_gather_bytes(&self, local: &[u8]) -> Vec<Vec<u8>>;

    /// [`Communicator::send_bytes`] of `f32` values.
    fn send_f32(&self, to: usize, tag: u32, data: &[f32]) {
        self.send_bytes(to, tag, bytemuck::cast_slice(data));
    }

    /// [`Communicator::recv_bytes`] of `f32` values.
    fn recv_f32(&self, from: usize, tag: u32) -> Vec<f32> {
        from_bytes(&self.recv_bytes(from, tag))
    }

    /// [`Communicator::send_bytes`] of `u32` values.
    fn send_u32(&self, to: usize, tag: u32, data: &[u32]) {
        self.send_bytes(to, tag, bytemuck::cast_slice(data));
    }

    /// [`Communicator::recv_bytes`] of `u32` values.
    fn recv_u32(&self, from: usize, tag: u32) -> Vec<u32> {
        from_bytes(&self.recv_bytes(from, tag))
    }

    /// Every rank's `local` concatenated in rank order, on every rank: with
    /// each rank's per-block partial sums, all blocks in global order.
    fn all_gather_f64(&self, local: &[f64]) -> Vec<f64> {
        self.all_gather_bytes(bytemuck::cast_slice(local)).iter().flat_map(|b| from_bytes(b)).collect()
    }

    /// Every rank's `local` concatenated in rank order (counts, keys).
    fn all_gather_u64(&self, local: &[u64]) -> Vec<u64> {
        self.all_gather_bytes(bytemuck::cast_slice(local)).iter().flat_map(|b| from_bytes(b)).collect()
    }
}

/// Values of type `T` out of the bytes a message carried (which need not
/// be aligned for `T`).
pub fn from_bytes<T: bytemuck::Pod>(bytes: &[u8]) -> Vec<T> {
    let size = std::mem::size_of::<T>();
    assert_eq!(bytes.len() % size, 0, "a message of {} bytes is not a whole number of {size}-byte values", bytes.len());
    let mut v = vec![T::zeroed(); bytes.len() / size];
    bytemuck::cast_slice_mut::<T, u8>(&mut v).copy_from_slice(bytes);
    v
}

/// A message between virtual ranks.
struct Msg {
    from: usize,
    tag: u32,
    data: Vec<u8>,
}

/// What the virtual ranks of one [`run_ranks`] share: which rank failed
/// first, so that the others stop waiting for it.
struct Shared {
    failed: AtomicBool,
    first_failed: AtomicUsize,
}

/// One virtual rank of [`run_ranks`]: a thread with an inbox and a sender
/// to every rank's inbox.
struct ThreadComm<'s> {
    rank: usize,
    senders: Vec<Sender<Msg>>,
    inbox: Receiver<Msg>,
    /// Messages received while waiting for another one, in arrival order.
    pending: RefCell<VecDeque<Msg>>,
    shared: &'s Shared,
}

/// How often a waiting rank looks whether another has failed.
const POLL: Duration = Duration::from_millis(50);

impl Communicator for ThreadComm<'_> {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.senders.len()
    }

    fn send_bytes(&self, to: usize, tag: u32, data: &[u8]) {
        assert!(to != self.rank && to < self.size(), "rank {}: send to rank {to} of {}", self.rank, self.size());
        let msg = Msg { from: self.rank, tag, data: data.to_vec() };
        if self.senders[to].send(msg).is_err() {
            panic!("rank {}: rank {to} has ended and cannot receive (tag {tag})", self.rank);
        }
    }

    fn recv_bytes(&self, from: usize, tag: u32) -> Vec<u8> {
        assert!(from != self.rank && from < self.size(), "rank {}: receive from rank {from}", self.rank);
        let mut pending = self.pending.borrow_mut();
        if let Some(k) = pending.iter().position(|m| m.from == from && m.tag == tag) {
            return pending.remove(k).map(|m| m.data).unwrap_or_default();
        }
        loop {
            match self.inbox.recv_timeout(POLL) {
                Ok(m) if m.from == from && m.tag == tag => return m.data,
                Ok(m) => pending.push_back(m),
                Err(RecvTimeoutError::Timeout) => {
                    if self.shared.failed.load(Ordering::Acquire) {
                        panic!("rank {}: stopped, another rank failed", self.rank);
                    }
                }
                Err(RecvTimeoutError::Disconnected) => unreachable!("a rank holds a sender to itself"),
            }
        }
    }

    fn barrier(&self) {
        self.all_gather_bytes(&[]);
    }

    fn all_gather_bytes(&self, local: &[u8]) -> Vec<Vec<u8>> {
        for to in (0..self.size()).filter(|&r| r != self.rank) {
            self.send_bytes(to, TAG_GATHER, local);
        }
        (0..self.size()).map(|r| if r == self.rank { local.to_vec() } else { self.recv_bytes(r, TAG_GATHER) }).collect()
    }
}

/// Marks the run failed when its rank's thread unwinds.
struct FailGuard<'s> {
    rank: usize,
    shared: &'s Shared,
}

impl Drop for FailGuard<'_> {
    fn drop(&mut self) {
        if std::thread::panicking() {
            let _ =
                self.shared.first_failed.compare_exchange(usize::MAX, self.rank, Ordering::AcqRel, Ordering::Acquire);
            self.shared.failed.store(true, Ordering::Release);
        }
    }
}

/// Runs `f` on `size` virtual ranks, each a thread with its own
/// [`Communicator`], and returns their results in rank order. The passes
/// inside `f` may use rayon (the ranks share its pool). If a rank panics,
/// the others stop at their next wait and the first rank's panic is
/// resumed here.
pub fn run_ranks<R: Send>(size: usize, f: impl Fn(&dyn Communicator) -> R + Sync) -> Vec<R> {
    assert!(size >= 1, "run_ranks: at least one rank");
    let shared = Shared { failed: AtomicBool::new(false), first_failed: AtomicUsize::new(usize::MAX) };
    let (senders, inboxes): (Vec<_>, Vec<_>) = (0..size).map(|_| channel::<Msg>()).unzip();
    let results: Vec<std::thread::Result<R>> = std::thread::scope(|s| {
        let handles: Vec<_> = inboxes
            .into_iter()
            .enumerate()
            .map(|(rank, inbox)| {
                let comm =
                    ThreadComm { rank, senders: senders.clone(), inbox, pending: RefCell::default(), shared: &shared };
                let (f, shared) = (&f, &shared);
                std::thread::Builder::new()
                    .name(format!("rank {rank}"))
                    .spawn_scoped(s, move || {
                        let _guard = FailGuard { rank, shared };
                        f(&comm)
                    })
                    .expect("spawn a virtual rank")
            })
            .collect();
        handles.into_iter().map(|h| h.join()).collect()
    });
    let first = shared.first_failed.load(Ordering::Acquire);
    let mut out = Vec::with_capacity(size);
    let mut failure = None;
    for (rank, r) in results.into_iter().enumerate() {
        match r {
            Ok(v) => out.push(v),
            Err(e) if rank == first || failure.is_none() => failure = Some(e),
            Err(_) => {}
        }
    }
    if let Some(e) = failure {
        std::panic::resume_unwind(e);
    }
    out
}
