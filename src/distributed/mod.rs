//! Distributed runs (issue 19): how the particles are split among ranks.
//!
//! Only the partitioner and its dry run (`porosph partition`) so far: a
//! rank owns a contiguous range of the global Morton order, cut on whole
//! cache blocks ([`partition`]), and keeps a halo of one support radius;
//! [`traffic`] is the model of the halo bytes a step exchanges, and
//! [`report`] the table `porosph partition` prints.

pub mod partition;
pub mod report;
pub mod traffic;

pub use partition::{partition, Kind, Partition, PartitionError, RankPart, MAX_RANKS};
