//! SIMD lanes. Kernels are written once over the [`Real`] lane type and
//! serve both scalar (`f32`) and SIMD ([`F`] = `wide::f32x16`) code; a test
//! checks the SIMD form against the scalar form lane by lane.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Number of f32 lanes in [`F`]: 16 (one AVX-512 register with the project's
/// `target-cpu=x86-64-v4`; two AVX2 registers otherwise).
pub const LANES: usize = 16;

/// The SIMD lane type of the neighbour loops.
pub type F = wide::f32x16;

/// Arithmetic that both `f32` and [`F`] provide, so one kernel serves both.
pub trait Real:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
{
    fn splat(v: f32) -> Self;
    fn sqrt(self) -> Self;
    fn min(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    /// `self * a + b` (one FMA where the target has it).
    fn mul_add(self, a: Self, b: Self) -> Self;
    /// Per lane: `if self <= limit { if_le } else { if_gt }`.
    fn select_le(self, limit: Self, if_le: Self, if_gt: Self) -> Self;
}

impl Real for f32 {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        v
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        f32::sqrt(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        f32::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        f32::max(self, o)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        // Plain multiply-add: must round like the SIMD form, which is an FMA
        // only where the target has FMA. Both paths use the same expression.
        f32::mul_add(self, a, b)
    }
    #[inline(always)]
    fn select_le(self, limit: Self, if_le: Self, if_gt: Self) -> Self {
        if self <= limit {
            if_le
        } else {
            if_gt
        }
    }
}

impl Real for F {
    #[inline(always)]
    fn splat(v: f32) -> Self {
        F::splat(v)
    }
    #[inline(always)]
    fn sqrt(self) -> Self {
        F::sqrt(self)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        F::min(self, o)
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        F::max(self, o)
    }
    #[inline(always)]
    fn mul_add(self, a: Self, b: Self) -> Self {
        F::mul_add(self, a, b)
    }
    #[inline(always)]
    fn select_le(self, limit: Self, if_le: Self, if_gt: Self) -> Self {
        wide::Select::select(self.simd_le(limit), if_le, if_gt)
    }
}

/// Loads `s[k..k + LANES]`, zero-filling lanes past the end of `s`.
#[inline(always)]
pub fn load(s: &[f32], k: usize) -> F {
    if k + LANES <= s.len() {
        let a: [f32; LANES] = s[k..k + LANES].try_into().unwrap_or([0.0; LANES]);
        F::from(a)
    } else {
        let mut a = [0.0f32; LANES];
        let n = s.len().saturating_sub(k);
        a[..n].copy_from_slice(&s[k..k + n]);
        F::from(a)
    }
}

/// Gathers `src[idx[k + l]]` for each lane l; lanes past the end of `idx`
/// read 0.
#[inline(always)]
pub fn gather(src: &[f32], idx: &[u32], k: usize) -> F {
    let mut a = [0.0f32; LANES];
    let n = (idx.len().saturating_sub(k)).min(LANES);
    for l in 0..n {
        a[l] = src[idx[k + l] as usize];
    }
    F::from(a)
}

/// Sum of the lanes, in a fixed order (so results do not depend on anything
/// but the input).
#[inline(always)]
pub fn sum(v: F) -> f32 {
    v.reduce_add()
}
