//! Cache blocks and deterministic reductions.
//!
//! Every parallel loop runs over fixed blocks of [`BLOCK`] particles; a
//! reduction combines one partial result per block in block order. The
//! result is therefore bitwise the same for any number of threads.

use rayon::prelude::*;

/// Particles per cache block. 512 particles x ~40 pairs x 20 bytes ~ 400 KiB
/// of pair data per block.
pub const BLOCK: usize = 512;

/// Number of blocks for `n` particles.
pub fn nblocks(n: usize) -> usize {
    n.div_ceil(BLOCK)
}

/// Sum over `0..n` of `f(i)`, in f64, blocked: partial sums per block in
/// index order (written to `parts`, which needs [`nblocks`]`(n)` entries and
/// comes from the step's arena), then the block sums in block order.
pub fn sum_f64(n: usize, parts: &mut [f64], f: impl Fn(usize) -> f64 + Sync) -> f64 {
    block_sums(n, parts, f);
    combine(&parts[..nblocks(n)])
}

/// The partial sums of [`sum_f64`]: `parts[b]` = the sum of `f(i)` over
/// block b, in index order from 0.0, for the [`nblocks`]`(n)` blocks.
/// A distributed run's rank computes these for its own whole blocks.
pub fn block_sums(n: usize, parts: &mut [f64], f: impl Fn(usize) -> f64 + Sync) {
    parts[..nblocks(n)].par_iter_mut().enumerate().for_each(|(b, s)| {
        let mut acc = 0.0;
        for i in b * BLOCK..((b + 1) * BLOCK).min(n) {
            acc += f(i);
        }
        *s = acc;
    });
}

/// The block sums combined in block order: the one place that fixes the
/// order of [`sum_f64`]'s last step, so a distributed run that gathers
/// every rank's [`block_sums`] in global block order gets the same bits.
pub fn combine(parts: &[f64]) -> f64 {
    parts.iter().sum()
}

/// Maximum over `0..n` of `f(i)` (0 for n = 0; NaN propagates).
pub fn max_f32(n: usize, f: impl Fn(usize) -> f32 + Sync) -> f32 {
    (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut m = 0.0f32;
            for i in b * BLOCK..((b + 1) * BLOCK).min(n) {
                keep_largest(&mut m, f(i));
                if m.is_nan() {
                    break;
                }
            }
            m
        })
        .reduce(|| 0.0f32, larger)
}

/// [`max_f32`]'s step: `m` becomes `v` where `v` is larger or NaN.
#[inline(always)]
pub fn keep_largest(m: &mut f32, v: f32) {
    if v.is_nan() || v > *m {
        *m = v;
    }
}

/// [`max_f32`]'s combination of two maxima: NaN if either is.
pub fn larger(a: f32, b: f32) -> f32 {
    if a.is_nan() || b.is_nan() {
        f32::NAN
    } else {
        a.max(b)
    }
}
