//! Distributed runs (issue 19): how the particles are split among ranks,
//! and how the ranks talk.
//!
//! So far, without changing the single-process step (there is no
//! distributed step yet):
//! - [`partition`](mod@partition): a rank owns a contiguous range of the
//!   global Morton order, cut on whole cache blocks, and keeps a halo of
//!   one support radius; [`traffic`] is the model of the halo bytes a
//!   step exchanges, and [`report`] the table `porosph partition` prints
//!   (the dry run).
//! - [`comm`]: the [`Communicator`] trait and [`run_ranks`], P virtual
//!   ranks as threads of one process.
//! - [`halo`]: a rank's owned and halo particles in the single process's
//!   order (from the partitioner, or found by the ranks after a
//!   migration), and the exchange of halo values.
//! - [`migrate`](mod@migrate): particles that moved go to their new
//!   owners, and the ranges are cut again on whole blocks.
//! - [`reduce`]: sums combined in global block order, bitwise the single
//!   process's for any number of ranks.
//! - [`check`]: the cases of the tests of all the above as functions of a
//!   communicator, run over the virtual ranks (`tests/distributed.rs`) and
//!   under `mpirun` (`examples/mpi_check.rs`).
//! - `mpi` (with `--features mpi`): `MpiComm`, the [`Communicator`] over
//!   MPI.

pub mod check;
pub mod comm;
pub mod halo;
pub mod migrate;
#[cfg(feature = "mpi")]
pub mod mpi;
pub mod partition;
pub mod reduce;
pub mod report;
pub mod traffic;

pub use comm::{run_ranks, Communicator};
pub use halo::HaloPlan;
pub use migrate::{migrate, Migration};
#[cfg(feature = "mpi")]
pub use mpi::MpiComm;
pub use partition::{partition, Kind, Partition, PartitionError, RankPart, MAX_RANKS};
