//! SIMD lanes. Kernels are written once over the [`Real`] lane type and
//! serve both scalar (`f32`) and SIMD ([`F`] = `wide::f32x16`) code; a test
//! checks the SIMD form against the scalar form lane by lane.

use crate::soa::Vel;
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

/// Loads `s[k..k + LANES]` (all lanes must lie inside `s`; a pair list's
/// ranges are read with [`pair_vectors`] instead).
#[inline(always)]
pub fn load(s: &[f32], k: usize) -> F {
    let a: &[f32; LANES] = s[k..k + LANES].try_into().expect("a whole vector");
    F::from(*a)
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

/// Sum of the lanes, in a fixed order (so results do not depend on anything
/// but the input).
#[inline(always)]
pub fn sum(v: F) -> f32 {
    v.reduce_add()
}

/// The vectors of one query's pairs `r` in pair lists whose target indices
/// are `j` (`crate::neighbors`): LANES pairs a vector from `r.start`, the
/// last one partial. The lists are not padded: a partial vector's lanes
/// past `r.end` belong to the next query or lie past the lists' end, so
/// [`PairVec`] masks them (they load 0, gather at the query's first
/// target, which is a valid index, and are not stored). Lane l of vector
/// c is pair `r.start + c LANES + l`, so the lanes' sums come out in the
/// same order for any layout of the other queries' pairs.
#[inline(always)]
pub fn pair_vectors(j: &[u32], r: std::ops::Range<usize>) -> PairVectors<'_> {
    assert!(r.end <= j.len(), "pair range past the lists");
    let fill = if r.start < r.end { j[r.start] } else { 0 };
    PairVectors { j, k: r.start, end: r.end, fill }
}

/// A three-component field packed 16 bytes a particle, `[x, y, z, 0]`, for
/// passes that read all three components of every neighbour
/// ([`PairVec::gather3`]).
pub type Packed = [f32; 4];

/// A three-component field that a pass reads at its pairs' targets, as
/// three arrays ([`Vel`]: three gathers) or packed (`&[Packed]`: one load
/// a lane); both give the same values.
pub trait Field3: Copy + Send + Sync {
    /// The components at the vector's target indices.
    fn gather3(self, v: &PairVec) -> [F; 3];
    /// The components of entry `i`.
    fn at(self, i: usize) -> [f32; 3];
}

impl Field3 for Vel<'_> {
    #[inline(always)]
    fn gather3(self, v: &PairVec) -> [F; 3] {
        [v.gather(self.x), v.gather(self.y), v.gather(self.z)]
    }
    #[inline(always)]
    fn at(self, i: usize) -> [f32; 3] {
        [self.x[i], self.y[i], self.z[i]]
    }
}

impl Field3 for &[Packed] {
    #[inline(always)]
    fn gather3(self, v: &PairVec) -> [F; 3] {
        v.gather3(self)
    }
    #[inline(always)]
    fn at(self, i: usize) -> [f32; 3] {
        let [x, y, z, _] = self[i];
        [x, y, z]
    }
}

/// TAIL[n]: all bits set in the first n lanes, 0 in the others.
static TAIL: [F; LANES + 1] = {
    let mut t = [[0u32; LANES]; LANES + 1];
    let mut n = 0;
    while n <= LANES {
        let mut l = 0;
        while l < n {
            t[n][l] = u32::MAX;
            l += 1;
        }
        n += 1;
    }
    // SAFETY: F is LANES f32 (any bits), the same size as [u32; LANES].
    unsafe { std::mem::transmute::<[[u32; LANES]; LANES + 1], [F; LANES + 1]>(t) }
};

/// Iterator of [`pair_vectors`].
pub struct PairVectors<'a> {
    j: &'a [u32],
    k: usize,
    end: usize,
    fill: u32,
}

impl Iterator for PairVectors<'_> {
    type Item = PairVec;

    #[inline(always)]
    fn next(&mut self) -> Option<PairVec> {
        if self.k >= self.end {
            return None;
        }
        let v = PairVec::new(self.j, self.k, self.end, self.fill);
        self.k += LANES;
        Some(v)
    }
}

/// One vector of a query's pairs: `n` (1 to LANES) pairs from slot `k`,
/// their target indices (lanes past `n`: the query's first target), and
/// the lane mask.
#[derive(Clone, Copy)]
pub struct PairVec {
    /// First pair slot.
    pub k: usize,
    /// Pairs in this vector.
    pub n: usize,
    /// The largest target index (the gathers' bound check).
    max: u32,
    imp: imp::Lanes,
}

impl PairVec {
    #[inline(always)]
    fn new(j: &[u32], k: usize, end: usize, fill: u32) -> Self {
        let n = (end - k).min(LANES);
        // SAFETY: k + n <= end <= j.len() (pair_vectors).
        let (imp, max) = unsafe { imp::Lanes::new(j.as_ptr().add(k), n, j.len() - k, fill) };
        PairVec { k, n, max, imp }
    }

    /// `s[k..k + n]`, lanes past `n` 0.
    #[inline(always)]
    pub fn load(&self, s: &[f32]) -> F {
        if self.n == LANES {
            load(s, self.k)
        } else if self.k + LANES <= s.len() {
            // The next query's pairs follow: a whole vector, the lanes past
            // n cleared by a bit mask.
            load(s, self.k) & TAIL[self.n]
        } else {
            assert!(self.k + self.n <= s.len(), "pair vector past the list");
            // SAFETY: the n lanes read lie inside `s` (checked).
            unsafe { self.imp.load(s.as_ptr().add(self.k)) }
        }
    }

    /// `src[j]` for the vector's target indices (lanes past `n`: at the
    /// query's first target).
    #[inline(always)]
    pub fn gather(&self, src: &[f32]) -> F {
        assert!((self.max as usize) < src.len(), "gather index out of bounds");
        // SAFETY: every lane's index is at most `max` (checked).
        unsafe { self.imp.gather(src.as_ptr()) }
    }

    /// `src[j]` of a packed three-component field ([`Packed`]) for the
    /// vector's target indices: the three components, each as
    /// [`PairVec::gather`] of its own array would give them (lanes past
    /// `n`: at the query's first target), from one 16-byte load a lane
    /// instead of three gathered elements (bench/RESULTS.md, "The Jacobi
    /// sweep's a^p packed").
    #[inline(always)]
    pub fn gather3(&self, src: &[Packed]) -> [F; 3] {
        let [x, y, z, _] = self.gather4(src);
        [x, y, z]
    }

    /// [`PairVec::gather3`] with the fourth entry of each [`Packed`] as well.
    #[inline(always)]
    pub fn gather4(&self, src: &[Packed]) -> [F; 4] {
        assert!((self.max as usize) < src.len(), "gather index out of bounds");
        // SAFETY: every lane's index is at most `max` (checked); an entry
        // is 4 f32.
        unsafe { self.imp.gather4(src.as_ptr() as *const f32) }
    }

    /// Stores the first `n` lanes of `v` to `s[k..k + n]`. (A whole-vector
    /// read-modify-write where the next query's slots follow was slower:
    /// the 1 M dam break's neighbour pass 88-92 -> 93-96 ms, its loads
    /// waiting on the previous vector's stores.)
    #[inline(always)]
    pub fn store(&self, s: &mut [f32], v: F) {
        assert!(self.k + self.n <= s.len(), "pair vector past the list");
        // SAFETY: the n lanes written lie inside `s` (checked).
        unsafe { self.imp.store(s.as_mut_ptr().add(self.k), v) }
    }

    /// The target indices (lanes past `n`: the query's first target).
    #[inline(always)]
    pub fn indices(&self) -> [u32; LANES] {
        self.imp.indices()
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx512f"))]
mod imp {
    use super::{F, LANES};
    use std::arch::x86_64::*;

    /// AVX-512: the mask register and the 16 indices in one register.
    #[derive(Clone, Copy)]
    pub struct Lanes {
        mask: __mmask16,
        idx: __m512i,
    }

    impl Lanes {
        /// # Safety
        /// `j` is valid for reads of `avail` u32; `n` <= `avail`, LANES.
        #[inline(always)]
        pub unsafe fn new(j: *const u32, n: usize, avail: usize, fill: u32) -> (Self, u32) {
            let mask = if n >= LANES { 0xffff } else { ((1u32 << n) - 1) as __mmask16 };
            // SAFETY: a whole vector is read where `avail` has it; else the
            // masked load reads only the n lanes (no fault past them).
            unsafe {
                let idx = if n >= LANES {
                    _mm512_loadu_si512(j as *const _)
                } else if avail >= LANES {
                    let v = _mm512_loadu_si512(j as *const _);
                    let m = std::mem::transmute::<F, __m512i>(super::TAIL[n]);
                    _mm512_or_si512(_mm512_and_si512(m, v), _mm512_andnot_si512(m, _mm512_set1_epi32(fill as i32)))
                } else {
                    _mm512_mask_loadu_epi32(_mm512_set1_epi32(fill as i32), mask, j as *const _)
                };
                (Lanes { mask, idx }, _mm512_reduce_max_epu32(idx))
            }
        }

        /// # Safety
        /// `p` is valid for reads of the mask's lanes.
        #[inline(always)]
        pub unsafe fn load(&self, p: *const f32) -> F {
            // Only for a partial vector at a list's end (`PairVec::load`):
            // with every load masked (or every load followed by a masked
            // move), the 250k dam break's pressure solve took twice as long
            // on AMD Zen 5.
            unsafe { std::mem::transmute::<__m512, F>(_mm512_maskz_loadu_ps(self.mask, p)) }
        }

        /// # Safety
        /// `src` is valid for reads at every index.
        #[inline(always)]
        pub unsafe fn gather(&self, src: *const f32) -> F {
            unsafe { std::mem::transmute::<__m512, F>(_mm512_i32gather_ps::<4>(self.idx, src)) }
        }

        /// # Safety
        /// `p` is valid for writes of the mask's lanes.
        #[inline(always)]
        pub unsafe fn store(&self, p: *mut f32, v: F) {
            unsafe {
                let v = std::mem::transmute::<F, __m512>(v);
                if self.mask == 0xffff {
                    _mm512_storeu_ps(p, v)
                } else {
                    _mm512_mask_storeu_ps(p, self.mask, v)
                }
            }
        }

        /// # Safety
        /// `src` is valid for reads of 4 f32 at 4 times every index.
        #[inline(always)]
        pub unsafe fn gather4(&self, src: *const f32) -> [F; 4] {
            let j = self.indices();
            // SAFETY: the caller's; register operations otherwise.
            unsafe {
                let at = |l: usize| _mm_loadu_ps(src.add(4 * j[l] as usize));
                // Row m holds lanes m, m + 4, m + 8, m + 12, one a 128-bit
                // quarter, so that the 4x4 transposes below put lane l's
                // components at lane l.
                let row = |m: usize| {
                    let r = _mm512_castps128_ps512(at(m));
                    let r = _mm512_insertf32x4::<1>(r, at(m + 4));
                    let r = _mm512_insertf32x4::<2>(r, at(m + 8));
                    _mm512_insertf32x4::<3>(r, at(m + 12))
                };
                let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
                let (t0, t1) = (_mm512_unpacklo_ps(r0, r1), _mm512_unpackhi_ps(r0, r1));
                let (t2, t3) = (_mm512_unpacklo_ps(r2, r3), _mm512_unpackhi_ps(r2, r3));
                [
                    _mm512_shuffle_ps::<0x44>(t0, t2),
                    _mm512_shuffle_ps::<0xEE>(t0, t2),
                    _mm512_shuffle_ps::<0x44>(t1, t3),
                    _mm512_shuffle_ps::<0xEE>(t1, t3),
                ]
                .map(|v| std::mem::transmute::<__m512, F>(v))
            }
        }

        #[inline(always)]
        pub fn indices(&self) -> [u32; LANES] {
            // SAFETY: 16 u32 in 64 bytes either way.
            unsafe { std::mem::transmute::<__m512i, [u32; LANES]>(self.idx) }
        }
    }
}

#[cfg(all(target_arch = "x86_64", target_feature = "avx2", not(target_feature = "avx512f")))]
mod imp {
    use super::{F, LANES};
    use std::arch::x86_64::*;

    /// The largest of the 16 u32 in `a` and `b`.
    #[inline(always)]
    fn largest(a: __m256i, b: __m256i) -> u32 {
        // SAFETY: register operations only (AVX2, which this module needs).
        unsafe {
            let m = _mm256_max_epu32(a, b);
            let m = _mm_max_epu32(_mm256_extracti128_si256::<0>(m), _mm256_extracti128_si256::<1>(m));
            let m = _mm_max_epu32(m, _mm_shuffle_epi32::<0b01_00_11_10>(m));
            let m = _mm_max_epu32(m, _mm_shuffle_epi32::<0b10_11_00_01>(m));
            _mm_cvtsi128_si32(m) as u32
        }
    }

    /// AVX2: two halves of 8 lanes, each with an all-ones lane mask where
    /// the lane holds a pair.
    #[derive(Clone, Copy)]
    pub struct Lanes {
        full: bool,
        mask: [__m256i; 2],
        idx: [__m256i; 2],
    }

    impl Lanes {
        /// # Safety
        /// `j` is valid for reads of `n` <= LANES u32.
        #[inline(always)]
        pub unsafe fn new(j: *const u32, n: usize, _avail: usize, fill: u32) -> (Self, u32) {
            // SAFETY: the masked loads read only the lanes below n (no
            // fault past them); the second pointer is only formed, with
            // wrapping arithmetic, and read through an all-zero mask when
            // n <= 8.
            unsafe {
                if n >= LANES {
                    let ones = _mm256_set1_epi32(-1);
                    let a = _mm256_loadu_si256(j as *const __m256i);
                    let b = _mm256_loadu_si256(j.add(8) as *const __m256i);
                    return (Lanes { full: true, mask: [ones, ones], idx: [a, b] }, largest(a, b));
                }
                let iota = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
                let nn = _mm256_set1_epi32(n as i32);
                let lo = _mm256_cmpgt_epi32(nn, iota);
                let hi = _mm256_cmpgt_epi32(nn, _mm256_add_epi32(iota, _mm256_set1_epi32(8)));
                let f = _mm256_set1_epi32(fill as i32);
                let a = _mm256_blendv_epi8(f, _mm256_maskload_epi32(j as *const i32, lo), lo);
                let b = _mm256_blendv_epi8(f, _mm256_maskload_epi32(j.wrapping_add(8) as *const i32, hi), hi);
                (Lanes { full: false, mask: [lo, hi], idx: [a, b] }, largest(a, b))
            }
        }

        /// # Safety
        /// `p` is valid for reads of the mask's lanes.
        #[inline(always)]
        pub unsafe fn load(&self, p: *const f32) -> F {
            unsafe {
                if self.full {
                    return std::mem::transmute::<[__m256; 2], F>([_mm256_loadu_ps(p), _mm256_loadu_ps(p.add(8))]);
                }
                let a = _mm256_maskload_ps(p, self.mask[0]);
                let b = _mm256_maskload_ps(p.wrapping_add(8), self.mask[1]);
                std::mem::transmute::<[__m256; 2], F>([a, b])
            }
        }

        /// # Safety
        /// `src` is valid for reads at every index (below 2^31).
        #[inline(always)]
        pub unsafe fn gather(&self, src: *const f32) -> F {
            unsafe {
                let a = _mm256_i32gather_ps::<4>(src, self.idx[0]);
                let b = _mm256_i32gather_ps::<4>(src, self.idx[1]);
                std::mem::transmute::<[__m256; 2], F>([a, b])
            }
        }

        /// # Safety
        /// `p` is valid for writes of the mask's lanes.
        #[inline(always)]
        pub unsafe fn store(&self, p: *mut f32, v: F) {
            unsafe {
                let [a, b] = std::mem::transmute::<F, [__m256; 2]>(v);
                if self.full {
                    _mm256_storeu_ps(p, a);
                    _mm256_storeu_ps(p.add(8), b);
                    return;
                }
                _mm256_maskstore_ps(p, self.mask[0], a);
                _mm256_maskstore_ps(p.wrapping_add(8), self.mask[1], b);
            }
        }

        /// # Safety
        /// `src` is valid for reads of 4 f32 at 4 times every index.
        #[inline(always)]
        pub unsafe fn gather4(&self, src: *const f32) -> [F; 4] {
            let j = self.indices();
            // SAFETY: the caller's; register operations otherwise.
            unsafe {
                let at = |l: usize| _mm_loadu_ps(src.add(4 * j[l] as usize));
                // Per half of 8 lanes, row m holds lanes m and m + 4 (one a
                // 128-bit half), so that the 4x4 transposes put lane l's
                // components at lane l.
                let half = |h: usize| {
                    let row = |m: usize| _mm256_set_m128(at(8 * h + m + 4), at(8 * h + m));
                    let (r0, r1, r2, r3) = (row(0), row(1), row(2), row(3));
                    let (t0, t1) = (_mm256_unpacklo_ps(r0, r1), _mm256_unpackhi_ps(r0, r1));
                    let (t2, t3) = (_mm256_unpacklo_ps(r2, r3), _mm256_unpackhi_ps(r2, r3));
                    [
                        _mm256_shuffle_ps::<0x44>(t0, t2),
                        _mm256_shuffle_ps::<0xEE>(t0, t2),
                        _mm256_shuffle_ps::<0x44>(t1, t3),
                        _mm256_shuffle_ps::<0xEE>(t1, t3),
                    ]
                };
                let (a, b) = (half(0), half(1));
                [0, 1, 2, 3].map(|c| std::mem::transmute::<[__m256; 2], F>([a[c], b[c]]))
            }
        }

        #[inline(always)]
        pub fn indices(&self) -> [u32; LANES] {
            // SAFETY: 16 u32 in 64 bytes either way.
            unsafe { std::mem::transmute::<[__m256i; 2], [u32; LANES]>(self.idx) }
        }
    }
}

#[cfg(not(all(target_arch = "x86_64", target_feature = "avx2")))]
mod imp {
    use super::{F, LANES};

    /// Elsewhere: the indices in an array, lane by lane.
    #[derive(Clone, Copy)]
    pub struct Lanes {
        n: usize,
        idx: [u32; LANES],
    }

    impl Lanes {
        /// # Safety
        /// `j` is valid for reads of `n` <= LANES u32.
        #[inline(always)]
        pub unsafe fn new(j: *const u32, n: usize, _avail: usize, fill: u32) -> (Self, u32) {
            let idx = std::array::from_fn(|l| if l < n { unsafe { j.add(l).read() } } else { fill });
            (Lanes { n, idx }, idx.iter().copied().max().unwrap_or(0))
        }

        /// # Safety
        /// `p` is valid for reads of `n` f32.
        #[inline(always)]
        pub unsafe fn load(&self, p: *const f32) -> F {
            F::from(std::array::from_fn::<f32, LANES, _>(|l| if l < self.n { unsafe { p.add(l).read() } } else { 0.0 }))
        }

        /// # Safety
        /// `src` is valid for reads at every index.
        #[inline(always)]
        pub unsafe fn gather(&self, src: *const f32) -> F {
            F::from(self.idx.map(|i| unsafe { src.add(i as usize).read() }))
        }

        /// # Safety
        /// `p` is valid for writes of `n` f32.
        #[inline(always)]
        pub unsafe fn store(&self, p: *mut f32, v: F) {
            let a = v.to_array();
            for (l, x) in a.iter().enumerate().take(self.n) {
                unsafe { p.add(l).write(*x) };
            }
        }

        /// # Safety
        /// `src` is valid for reads of 4 f32 at 4 times every index.
        #[inline(always)]
        pub unsafe fn gather4(&self, src: *const f32) -> [F; 4] {
            [0, 1, 2, 3].map(|c| F::from(self.idx.map(|i| unsafe { src.add(4 * i as usize + c).read() })))
        }

        #[inline(always)]
        pub fn indices(&self) -> [u32; LANES] {
            self.idx
        }
    }
}
