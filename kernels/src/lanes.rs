//! SIMD lanes. Kernels are written once over the [`Real`] lane type and
//! serve both scalar (`f32`) and SIMD ([`F`] = `wide::f32x16`) code; a test
//! checks the SIMD form against the scalar form lane by lane.

use std::ops::{Add, Div, Mul, Neg, Sub};

/// Number of f32 lanes in [`F`]: 16 (one AVX-512 register where the build's
/// `target-cpu=native` has AVX-512; two AVX2 registers otherwise).
pub const LANES: usize = 16;

/// The SIMD lane type of the neighbour loops.
pub type F = wide::f32x16;

/// Arithmetic that both `f32` and [`F`] provide, so one kernel serves both.
pub trait Real:
    Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Div<Output = Self> + Neg<Output = Self>
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

/// Loads `s[k..k + LANES]` (all lanes must lie inside `s`: pair lists are
/// padded to whole vectors, see [`crate::neighbors`]).
#[inline(always)]
pub fn load(s: &[f32], k: usize) -> F {
    let a: &[f32; LANES] = s[k..k + LANES].try_into().expect("a whole vector");
    F::from(*a)
}

/// Stores `v` to `s[k..k + LANES]`.
#[inline(always)]
pub fn store(s: &mut [f32], k: usize, v: F) {
    let a: &mut [f32; LANES] = (&mut s[k..k + LANES]).try_into().expect("a whole vector");
    *a = v.to_array();
}

/// Loads `s[k..k + LANES]`, zero-filling lanes past the end of `s`.
#[inline(always)]
pub fn load_partial(s: &[f32], k: usize) -> F {
    if k + LANES <= s.len() {
        load(s, k)
    } else {
        let mut a = [0.0f32; LANES];
        let n = s.len().saturating_sub(k);
        a[..n].copy_from_slice(&s[k..k + n]);
        F::from(a)
    }
}

/// Gathers `src[idx[k + l]]` for the LANES lanes l (all of `idx[k..k + LANES]`
/// must exist and be valid indices of `src`). One AVX-512 gather where the
/// target has it.
#[inline(always)]
pub fn gather(src: &[f32], idx: &[u32], k: usize) -> F {
    let ix: &[u32; LANES] = idx[k..k + LANES].try_into().expect("a whole vector");
    #[cfg(target_feature = "avx512f")]
    {
        use std::arch::x86_64::{__m512, _mm512_i32gather_ps, _mm512_loadu_si512, _mm512_reduce_max_epu32};
        // SAFETY: the load reads the 16 u32 of `ix`; the gather reads
        // src[ix[l]] only after checking that the largest index is in
        // bounds; F and __m512 are both 16 f32 in 64 bytes.
        unsafe {
            let vi = _mm512_loadu_si512(ix.as_ptr() as *const _);
            assert!((_mm512_reduce_max_epu32(vi) as usize) < src.len(), "gather index out of bounds");
            let v = _mm512_i32gather_ps::<4>(vi, src.as_ptr());
            std::mem::transmute::<__m512, F>(v)
        }
    }
    #[cfg(all(target_feature = "avx2", not(target_feature = "avx512f")))]
    {
        use std::arch::x86_64::{
            __m256, __m256i, _mm256_extracti128_si256, _mm256_i32gather_ps, _mm256_loadu_si256, _mm256_max_epu32,
            _mm_cvtsi128_si32, _mm_max_epu32, _mm_shuffle_epi32,
        };
        // SAFETY: the two loads read the 16 u32 of `ix`; the gathers read
        // src[ix[l]] only after checking that the largest index is in
        // bounds (as u32, so also below 2^31 for the gathers' i32 indices
        // whenever src is shorter than that); F is 16 f32 in 64 bytes, two
        // __m256 in lane order.
        unsafe {
            let lo = _mm256_loadu_si256(ix.as_ptr() as *const __m256i);
            let hi = _mm256_loadu_si256(ix.as_ptr().add(8) as *const __m256i);
            let m = _mm256_max_epu32(lo, hi);
            let m = _mm_max_epu32(_mm256_extracti128_si256::<0>(m), _mm256_extracti128_si256::<1>(m));
            let m = _mm_max_epu32(m, _mm_shuffle_epi32::<0b01_00_11_10>(m));
            let m = _mm_max_epu32(m, _mm_shuffle_epi32::<0b10_11_00_01>(m));
            let largest = _mm_cvtsi128_si32(m) as u32 as usize;
            assert!(largest < src.len() && src.len() <= i32::MAX as usize, "gather index out of bounds");
            let a = _mm256_i32gather_ps::<4>(src.as_ptr(), lo);
            let b = _mm256_i32gather_ps::<4>(src.as_ptr(), hi);
            std::mem::transmute::<[__m256; 2], F>([a, b])
        }
    }
    #[cfg(not(any(target_feature = "avx512f", target_feature = "avx2")))]
    {
        F::from(std::array::from_fn::<f32, LANES, _>(|l| src[ix[l] as usize]))
    }
}

/// Sum of the lanes, in a fixed order (so results do not depend on anything
/// but the input).
#[inline(always)]
pub fn sum(v: F) -> f32 {
    v.reduce_add()
}
