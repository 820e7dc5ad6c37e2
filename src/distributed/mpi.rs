//! The [`Communicator`] over MPI (issue 19), with `--features mpi`:
//! [`MpiComm`], through rsmpi (the `mpi` crate) over the system's MPI
//! (MPICH from Debian: `scripts/setup.sh --mpi`). One process is one rank;
//! `mpirun -np P` starts P of them. A program built with the feature but
//! started without `mpirun` runs as one rank (MPI's singleton start).
//!
//! Each method is one MPI call, as [`super::comm`] lays out:
//! - [`Communicator::send_bytes`] is `MPI_Isend` of a copy of the data,
//!   which returns at once. The trait lets a rank post all its sends
//!   before its receives, and every exchange here does (a halo exchange:
//!   each rank sends to its neighbours, then receives from them); a
//!   blocking `MPI_Send` may wait for the matching receive (always, for a
//!   message above the eager limit), so two ranks that send to each other
//!   first would wait forever. The copy lives in [`MpiComm`] with its
//!   request until the request completes; every later call of the
//!   communicator first frees the sends that completed (`MPI_Test`), and
//!   dropping it waits for the rest. MPI progresses a send while its rank
//!   waits in any other call, so a rank blocked in a receive still
//!   delivers what it sent. (`MPI_Bsend` would need a buffer attached
//!   ahead of the largest round of sends, which a migration does not
//!   know, and a larger one cannot be attached without first detaching,
//!   which waits for every buffered message to be received.)
//! - [`Communicator::recv_bytes`] is `MPI_Mprobe` for the message from one
//!   source with one tag, which gives its size, then `MPI_Mrecv` of it
//!   into a vector of that size. MPI keeps messages of one sender and one
//!   tag in order (the trait's rule).
//! - [`Communicator::barrier`] is `MPI_Barrier`.
//! - [`Communicator::all_gather_bytes`] is `MPI_Allgather` of the lengths,
//!   then `MPI_Allgatherv` of the bytes.
//!
//! Tags: a pass's tag is the MPI tag, unchanged; the collectives need
//! none (MPI keeps them apart from point-to-point messages). MPI promises
//! tags up to `MPI_TAG_UB`, at least 32767 (MPICH 4: 2^31 - 1 with ch3,
//! less with ch4); the passes' tags are all below 2^15 (the largest,
//! migration's, 0x4d03), so they pass on any MPI. [`MpiComm::init`] reads
//! the bound and a send above it panics, saying so.
//!
//! Messages and gathers are counted in bytes as a C `int`: each at most
//! 2^31 - 1 bytes (a gather's total too), or the call panics.
//!
//! Threads: MPI is initialized *funneled*: every MPI call comes from the
//! thread that initialized it (the main thread), and rayon's threads work
//! inside a rank between the calls. [`MpiComm`] is neither `Send` nor
//! `Sync`, so it cannot reach another thread.
//!
//! A rank that panics while it holds the communicator ends the whole run
//! (`MPI_Abort`, when the communicator is dropped while unwinding), so
//! the other ranks do not wait for it forever.

use super::comm::{Communicator, RESERVED_TAGS};
use mpi::datatype::PartitionMut;
use mpi::environment::Universe;
use mpi::request::{Request, StaticScope};
use mpi::topology::SimpleCommunicator;
use mpi::traits::Communicator as _;
use mpi::traits::*;
use mpi::{Count, Threading};
use std::cell::RefCell;
use std::ffi::{c_int, c_void};
use std::marker::PhantomData;

/// An immediate send in flight: its request and the copy of the data it
/// reads, which is freed once the request completes.
struct Pending {
    request: Request<'static, [u8], StaticScope>,
    /// From `Box::leak`; only [`Pending::free`] turns it back into a box.
    buffer: *mut [u8],
}

impl Pending {
    /// Frees the copy of a completed send.
    fn free(buffer: *mut [u8]) {
        // SAFETY: `buffer` came from `Box::leak` in `send_bytes`, and its
        // request, the only other user, has completed and is gone.
        drop(unsafe { Box::from_raw(buffer) });
    }

    /// Frees the copy if the send completed, or gives the send back.
    fn test(self) -> Option<Self> {
        let Pending { request, buffer } = self;
        match request.test() {
            Ok(_) => {
                Self::free(buffer);
                None
            }
            Err(request) => Some(Pending { request, buffer }),
        }
    }

    /// Waits for the send and frees the copy.
    fn wait(self) {
        let Pending { request, buffer } = self;
        request.wait();
        Self::free(buffer);
    }
}

/// This process's rank of an MPI run (module doc). Dropping it finalizes
/// MPI; MPI cannot be initialized again in the same process.
pub struct MpiComm {
    world: SimpleCommunicator,
    rank: usize,
    size: usize,
    /// `MPI_TAG_UB`: the largest tag this MPI takes.
    tag_ub: u32,
    /// Immediate sends not yet known to have completed.
    pending: RefCell<Vec<Pending>>,
    /// Finalizes MPI when dropped, after [`MpiComm`]'s own `drop` waited
    /// for the pending sends (fields drop in order, this one last).
    _universe: Universe,
    /// Funneled: not `Send`, not `Sync` (module doc).
    _main_thread: PhantomData<*const ()>,
}

impl MpiComm {
    /// Initializes MPI, funneled, on the calling thread (the main thread,
    /// which makes every later MPI call). Fails if MPI was initialized
    /// before in this process or grants no threads.
    pub fn init() -> Result<Self, String> {
        let (universe, threading) =
            mpi::initialize_with_threading(Threading::Funneled).ok_or("MPI was initialized before in this process")?;
        if threading == Threading::Single {
            return Err("this MPI grants no threads (MPI_THREAD_SINGLE); rayon needs MPI_THREAD_FUNNELED".into());
        }
        let world = universe.world();
        let (rank, size) = (world.rank() as usize, world.size() as usize);
        let tag_ub = tag_upper_bound(&world);
        Ok(MpiComm {
            world,
            rank,
            size,
            tag_ub,
            pending: RefCell::default(),
            _universe: universe,
            _main_thread: PhantomData,
        })
    }

    /// `MPI_TAG_UB` of this MPI.
    pub fn tag_upper_bound(&self) -> u32 {
        self.tag_ub
    }

    /// The MPI library's own name and version (`MPI_Get_library_version`).
    pub fn library_version() -> String {
        mpi::environment::library_version().unwrap_or_else(|_| "(not UTF-8)".into()).trim().to_string()
    }

    /// Frees the copies of the sends that completed.
    fn free_completed_sends(&self) {
        let mut pending = self.pending.borrow_mut();
        if !pending.is_empty() {
            *pending = pending.drain(..).filter_map(Pending::test).collect();
        }
    }
}

/// `MPI_TAG_UB` of `world` (32767, the least MPI promises, if the
/// attribute is missing).
fn tag_upper_bound(world: &SimpleCommunicator) -> u32 {
    let mut value: *mut c_int = std::ptr::null_mut();
    let mut flag: c_int = 0;
    // SAFETY: MPI_Comm_get_attr stores a pointer to the attribute's int in
    // `value` (for a predefined attribute, MPI's own storage) and sets
    // `flag` where the attribute exists.
    unsafe {
        mpi::ffi::MPI_Comm_get_attr(
            world.as_raw(),
            mpi::ffi::MPI_TAG_UB as c_int,
            (&mut value as *mut *mut c_int).cast::<c_void>(),
            &mut flag,
        );
        if flag != 0 && !value.is_null() {
            return (*value).max(32767) as u32;
        }
    }
    32767
}

impl Communicator for MpiComm {
    fn rank(&self) -> usize {
        self.rank
    }

    fn size(&self) -> usize {
        self.size
    }

    fn send_bytes(&self, to: usize, tag: u32, data: &[u8]) {
        assert!(to != self.rank && to < self.size, "rank {}: send to rank {to} of {}", self.rank, self.size);
        assert!(tag < RESERVED_TAGS, "rank {}: tag {tag} is the communicator's own", self.rank);
        assert!(tag <= self.tag_ub, "rank {}: tag {tag} is above this MPI's MPI_TAG_UB {}", self.rank, self.tag_ub);
        assert!(
            data.len() <= i32::MAX as usize,
            "rank {}: a message of {} bytes (MPI counts in int)",
            self.rank,
            data.len()
        );
        self.free_completed_sends();
        let buffer: &'static [u8] = Box::leak(data.to_vec().into_boxed_slice());
        let request = self.world.process_at_rank(to as i32).immediate_send_with_tag(StaticScope, buffer, tag as i32);
        self.pending.borrow_mut().push(Pending { request, buffer: std::ptr::from_ref(buffer).cast_mut() });
    }

    fn recv_bytes(&self, from: usize, tag: u32) -> Vec<u8> {
        assert!(from != self.rank && from < self.size, "rank {}: receive from rank {from}", self.rank);
        self.free_completed_sends();
        self.world.process_at_rank(from as i32).matched_probe_with_tag(tag as i32).matched_receive_vec::<u8>().0
    }

    fn barrier(&self) {
        self.free_completed_sends();
        self.world.barrier();
    }

    fn all_gather_bytes(&self, local: &[u8]) -> Vec<Vec<u8>> {
        self.free_completed_sends();
        let len = Count::try_from(local.len()).expect("an all-gather of at most 2^31 - 1 bytes a rank");
        let mut counts: Vec<Count> = vec![0; self.size];
        self.world.all_gather_into(&len, &mut counts[..]);
        let mut displs: Vec<Count> = Vec::with_capacity(self.size);
        let mut total: Count = 0;
        for &c in &counts {
            displs.push(total);
            total = total.checked_add(c).expect("an all-gather of at most 2^31 - 1 bytes in all");
        }
        let mut all = vec![0u8; total as usize];
        {
            let mut parts = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
            self.world.all_gather_varcount_into(local, &mut parts);
        }
        counts.iter().zip(&displs).map(|(&c, &d)| all[d as usize..(d + c) as usize].to_vec()).collect()
    }
}

impl Drop for MpiComm {
    fn drop(&mut self) {
        if std::thread::panicking() {
            // The others may wait for this rank: end the run.
            eprintln!("rank {}: panicked; aborting the MPI run", self.rank);
            self.world.abort(101);
        }
        for p in self.pending.get_mut().drain(..) {
            p.wait();
        }
    }
}
