//! Reductions whose bits do not depend on the number of ranks (issue 19:
//! "reductions are combined in a fixed order independent of P (e.g. gather
//! the per-block partial sums ...)").
//!
//! The single process sums over its particles with
//! [`porosph_kernels::blocks::sum_f64`]: one f64 partial sum per cache
//! block of [`BLOCK`](porosph_kernels::blocks::BLOCK) particles, in index
//! order, then the block sums in block order ([`blocks::combine`]); the
//! pressure solve's mean density error is such a sum (`backend/cpu.rs`,
//! over the fluid rows). A rank owns whole blocks of the fluid's global
//! order ([`super::partition::partition`] cuts on whole blocks, and
//! [`super::migrate::migrate`] keeps them whole after the particles move),
//! so its [`block_sums`] are the single process's partial sums of those
//! blocks; [`global_sum`] gathers every rank's in rank order, which is
//! global block order, and combines them as the single process does. The
//! result is bitwise the single process's, for any P. (Maxima, such as
//! the time step rule's largest speed, are exact in any order.)
//!
//! Not yet so: the solid rows' error, which the single process sums over
//! the solids' own Morton order, whose blocks are not cut with the ranks
//! (a solid's owner follows the fluid). It needs the solids' order cut on
//! blocks too, or an exact accumulator.

use super::comm::Communicator;
use porosph_kernels::blocks::{self, nblocks};

/// The per-block partial sums of `f` over a rank's `n` owned particles of
/// the primary kind, whose first is the first of a global block.
pub fn block_sums(n: usize, f: impl Fn(usize) -> f64 + Sync) -> Vec<f64> {
    let mut parts = vec![0.0; nblocks(n)];
    blocks::block_sums(n, &mut parts, f);
    parts
}

/// The sum of every rank's [`block_sums`], combined in global block order:
/// the same bits on every rank and for every P, and the same as the single
/// process's `sum_f64` over all particles.
pub fn global_sum(comm: &dyn Communicator, parts: &[f64]) -> f64 {
    blocks::combine(&comm.all_gather_f64(parts))
}
