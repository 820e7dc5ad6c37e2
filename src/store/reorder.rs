//! Applying a permutation to registered columns with reused buffers.

use super::ColumnMut;
use porosph_kernels::blocks::BLOCK;
use rayon::prelude::*;

/// Buffers reused by every reorder, so a reorder in steady state allocates
/// nothing.
#[derive(Default, Debug)]
pub struct Scratch {
    f: Vec<f32>,
    u: Vec<u32>,
}

fn gather_into<T: Copy + Send + Sync>(src: &[T], perm: &[u32], dst: &mut Vec<T>, fill: T) {
    dst.clear();
    dst.resize(perm.len(), fill);
    dst.par_chunks_mut(BLOCK).enumerate().for_each(|(b, out)| {
        for (q, o) in out.iter_mut().enumerate() {
            *o = src[perm[b * BLOCK + q] as usize];
        }
    });
}

impl Scratch {
    /// `c[i] <- c[perm[i]]` for every component of `c`.
    pub fn permute(&mut self, c: ColumnMut, perm: &[u32]) {
        match c {
            ColumnMut::F32(v) => {
                assert_eq!(v.len(), perm.len(), "column length differs from the particle count");
                gather_into(v, perm, &mut self.f, 0.0);
                std::mem::swap(v, &mut self.f);
            }
            ColumnMut::U32(v) => {
                assert_eq!(v.len(), perm.len(), "column length differs from the particle count");
                gather_into(v, perm, &mut self.u, 0);
                std::mem::swap(v, &mut self.u);
            }
            ColumnMut::PerPhase(vs) => {
                for v in vs.iter_mut() {
                    assert_eq!(v.len(), perm.len(), "column length differs from the particle count");
                    gather_into(v, perm, &mut self.f, 0.0);
                    std::mem::swap(v, &mut self.f);
                }
            }
        }
    }
}
