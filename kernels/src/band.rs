//! Fields kept only for the fluid particles within reach of a solid: the
//! band. The fluid side of the porous terms (P-Eqs. 16-18, 20, 22) is a sum
//! over a fluid particle's solid neighbours, so it is 0 wherever a particle
//! has none, which is most of a pool. Stored per band slot instead of per
//! fluid particle, those fields cost memory only where they are nonzero
//! (bench/RESULTS.md, "The porous terms on the band").
//!
//! A field read at a particle outside the band reads 0.0, exactly what the
//! sum over no pairs gives, so a pass that reads it computes the same
//! values bit for bit as over a full-length field.

use bumpalo::Bump;

/// The slot of a particle outside the band.
pub const NONE: u32 = u32::MAX;

/// Which fluid particles the band holds: `idx[s]` is slot s's particle
/// (ascending), `at[i]` particle i's slot or [`NONE`].
#[derive(Clone, Copy)]
pub struct Band<'a> {
    pub idx: &'a [u32],
    pub at: &'a [u32],
}

impl<'a> Band<'a> {
    /// The band of the particles `i < n` for which `inside(i)` holds, in
    /// `arena`.
    pub fn new(arena: &'a Bump, n: usize, inside: impl Fn(usize) -> bool) -> Band<'a> {
        let at = arena.alloc_slice_fill_copy(n, NONE);
        let mut m = 0u32;
        for (i, a) in at.iter_mut().enumerate() {
            if inside(i) {
                *a = m;
                m += 1;
            }
        }
        let idx = arena.alloc_slice_fill_copy(m as usize, 0u32);
        for (i, &a) in at.iter().enumerate() {
            if a != NONE {
                idx[a as usize] = i as u32;
            }
        }
        Band { idx, at }
    }

    /// Number of slots.
    pub fn len(&self) -> usize {
        self.idx.len()
    }

    /// Whether the band holds no particle.
    pub fn is_empty(&self) -> bool {
        self.idx.is_empty()
    }

    /// Particle i's slot.
    #[inline(always)]
    pub fn slot(&self, i: usize) -> Option<usize> {
        let s = self.at[i];
        (s != NONE).then_some(s as usize)
    }
}

/// A scalar field per phase on the band: phase k of slot s at `k m + s`, m
/// the band's length.
#[derive(Clone, Copy)]
pub struct BandField<'a> {
    pub band: Band<'a>,
    pub v: &'a [f32],
}

impl BandField<'_> {
    /// Phase k's value at fluid particle i (0.0 outside the band).
    #[inline(always)]
    pub fn get(&self, k: usize, i: usize) -> f32 {
        self.band.slot(i).map_or(0.0, |s| self.v[k * self.band.len() + s])
    }
}

/// A vector field per phase on the band, its components as [`BandField`].
#[derive(Clone, Copy)]
pub struct BandVel<'a> {
    pub band: Band<'a>,
    pub x: &'a [f32],
    pub y: &'a [f32],
    pub z: &'a [f32],
}

impl BandVel<'_> {
    /// Phase k's vector at fluid particle i (0.0 outside the band).
    #[inline(always)]
    pub fn get(&self, k: usize, i: usize) -> [f32; 3] {
        match self.band.slot(i) {
            Some(s) => {
                let r = k * self.band.len() + s;
                [self.x[r], self.y[r], self.z[r]]
            }
            None => [0.0; 3],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_fields_read_their_slots_and_zero_elsewhere() {
        let n = 7;
        let arena = Bump::new();
        let band = Band::new(&arena, n, |i| i % 3 == 1);
        assert_eq!(band.idx, &[1, 4]);
        assert_eq!(band.slot(4), Some(1));
        assert_eq!(band.slot(0), None);
        // Two phases: phase k of slot s at k m + s.
        let v = [10.0, 11.0, 20.0, 21.0];
        let f = BandField { band, v: &v };
        assert_eq!((f.get(0, 1), f.get(1, 4), f.get(1, 5)), (10.0, 21.0, 0.0));
        let g = BandVel { band, x: &v, y: &v, z: &v };
        assert_eq!(g.get(1, 1), [20.0; 3]);
        assert_eq!(g.get(0, 6).map(f32::to_bits), [0.0f32.to_bits(); 3]);
    }
}
