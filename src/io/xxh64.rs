//! XXH64 (Yann Collet's xxHash, 64-bit variant, seed 0), the checksum of
//! every checkpoint dataset.
//!
//! Implemented here from the published specification
//! (`doc/xxhash_spec.md` of the xxHash repository) rather than pulled in as a
//! dependency: about 100 lines, several GB/s, and the same value Python's
//! `xxhash.xxh64(data).intdigest()` gives for the dataset's little-endian
//! bytes, so h5py users can check a file without porosph.

const P1: u64 = 0x9E37_79B1_85EB_CA87;
const P2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const P3: u64 = 0x1656_67B1_9E37_79F9;
const P4: u64 = 0x85EB_CA77_C2B2_AE63;
const P5: u64 = 0x27D4_EB2F_1656_67C5;

#[inline(always)]
fn round(acc: u64, lane: u64) -> u64 {
    acc.wrapping_add(lane.wrapping_mul(P2)).rotate_left(31).wrapping_mul(P1)
}

#[inline(always)]
fn merge(acc: u64, v: u64) -> u64 {
    (acc ^ round(0, v)).wrapping_mul(P1).wrapping_add(P4)
}

/// A streaming XXH64 hasher: feeding the bytes in pieces gives the same
/// value as hashing them at once.
#[derive(Clone, Debug)]
pub struct Xxh64 {
    v: [u64; 4],
    /// Bytes of an incomplete 32-byte stripe.
    buf: [u8; 32],
    buf_len: usize,
    total: u64,
    seed: u64,
}

impl Default for Xxh64 {
    fn default() -> Self {
        Self::new(0)
    }
}

impl Xxh64 {
    /// A hasher with `seed` (porosph uses 0).
    pub fn new(seed: u64) -> Self {
        Self {
            v: [seed.wrapping_add(P1).wrapping_add(P2), seed.wrapping_add(P2), seed, seed.wrapping_sub(P1)],
            buf: [0; 32],
            buf_len: 0,
            total: 0,
            seed,
        }
    }

    #[inline(always)]
    fn stripe(&mut self, lanes: [u64; 4]) {
        for (v, l) in self.v.iter_mut().zip(lanes) {
            *v = round(*v, l);
        }
    }

    /// Feeds bytes.
    pub fn update(&mut self, mut bytes: &[u8]) {
        self.total += bytes.len() as u64;
        if self.buf_len > 0 {
            let take = (32 - self.buf_len).min(bytes.len());
            self.buf[self.buf_len..self.buf_len + take].copy_from_slice(&bytes[..take]);
            self.buf_len += take;
            bytes = &bytes[take..];
            if self.buf_len < 32 {
                return;
            }
            let lanes = lanes_of(&self.buf);
            self.stripe(lanes);
            self.buf_len = 0;
        }
        let mut stripes = bytes.chunks_exact(32);
        for s in &mut stripes {
            self.stripe(lanes_of(s));
        }
        let rest = stripes.remainder();
        self.buf[..rest.len()].copy_from_slice(rest);
        self.buf_len = rest.len();
    }

    /// Feeds `n` 32-bit words, `word(i)` for i in 0..n, as little-endian
    /// bytes (the bytes of an `f32` or `u32` array on disk), without
    /// building a byte buffer.
    pub fn update_words(&mut self, n: usize, word: impl Fn(usize) -> u32) {
        let mut i = 0;
        // Finish a partial stripe left by an earlier call (word-aligned).
        while self.buf_len != 0 && i < n {
            self.update(&word(i).to_le_bytes());
            i += 1;
        }
        let lane = |k: usize| u64::from(word(k)) | (u64::from(word(k + 1)) << 32);
        while i + 8 <= n {
            self.stripe([lane(i), lane(i + 2), lane(i + 4), lane(i + 6)]);
            i += 8;
            self.total += 32;
        }
        while i < n {
            self.update(&word(i).to_le_bytes());
            i += 1;
        }
    }

    /// Feeds the little-endian bytes of `v`.
    pub fn update_f32(&mut self, v: &[f32]) {
        self.update_words(v.len(), |i| v[i].to_bits());
    }

    /// Feeds the little-endian bytes of `v`.
    pub fn update_u32(&mut self, v: &[u32]) {
        self.update_words(v.len(), |i| v[i]);
    }

    /// The hash of everything fed so far.
    pub fn finish(&self) -> u64 {
        let mut h = if self.total >= 32 {
            let [v1, v2, v3, v4] = self.v;
            let mut h = v1
                .rotate_left(1)
                .wrapping_add(v2.rotate_left(7))
                .wrapping_add(v3.rotate_left(12))
                .wrapping_add(v4.rotate_left(18));
            for v in self.v {
                h = merge(h, v);
            }
            h
        } else {
            self.seed.wrapping_add(P5)
        };
        h = h.wrapping_add(self.total);
        let mut rest = &self.buf[..self.buf_len];
        while rest.len() >= 8 {
            let (lane, tail) = rest.split_at(8);
            h ^= round(0, u64::from_le_bytes(lane.try_into().unwrap_or([0; 8])));
            h = h.rotate_left(27).wrapping_mul(P1).wrapping_add(P4);
            rest = tail;
        }
        if rest.len() >= 4 {
            let (word, tail) = rest.split_at(4);
            h ^= u64::from(u32::from_le_bytes(word.try_into().unwrap_or([0; 4]))).wrapping_mul(P1);
            h = h.rotate_left(23).wrapping_mul(P2).wrapping_add(P3);
            rest = tail;
        }
        for &b in rest {
            h ^= u64::from(b).wrapping_mul(P5);
            h = h.rotate_left(11).wrapping_mul(P1);
        }
        h ^= h >> 33;
        h = h.wrapping_mul(P2);
        h ^= h >> 29;
        h = h.wrapping_mul(P3);
        h ^ (h >> 32)
    }
}

/// The four little-endian 64-bit lanes of a 32-byte stripe.
#[inline(always)]
fn lanes_of(s: &[u8]) -> [u64; 4] {
    let lane = |k: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&s[8 * k..8 * k + 8]);
        u64::from_le_bytes(b)
    };
    [lane(0), lane(1), lane(2), lane(3)]
}

/// XXH64 of `bytes`, seed 0.
pub fn xxh64(bytes: &[u8]) -> u64 {
    let mut h = Xxh64::new(0);
    h.update(bytes);
    h.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Test input of the xxHash repository's sanity check: a byte stream
    /// from a fixed LCG (`tests/sanity_test_vectors.h` generator).
    fn sanity_buffer(len: usize) -> Vec<u8> {
        const PRIME32: u64 = 2_654_435_761;
        let mut byte_gen: u64 = PRIME32;
        (0..len)
            .map(|_| {
                let b = (byte_gen >> 56) as u8;
                byte_gen = byte_gen.wrapping_mul(PRIME64);
                b
            })
            .collect()
    }
    const PRIME64: u64 = 11_400_714_785_074_694_797;

    /// Reference values computed with the system's libxxhash 0.8.1
    /// (`XXH64(buf, len, 0)` through Python ctypes) for the inputs below.
    #[test]
    fn matches_reference_xxh64() {
        assert_eq!(xxh64(b""), 0xEF46_DB37_51D8_E999);
        assert_eq!(xxh64(b"a"), 0xD24E_C4F1_A98C_6E5B);
        assert_eq!(xxh64(b"abc"), 0x44BC_2CF5_AD77_0999);
        let buf = sanity_buffer(1000);
        for (len, want) in REFERENCE {
            assert_eq!(xxh64(&buf[..*len]), *want, "length {len}");
        }
    }

    const REFERENCE: &[(usize, u64)] = &[
        (0, 0xEF46_DB37_51D8_E999),
        (1, 0xE934_A84A_DB05_2768),
        (3, 0xFF7E_1959_CB50_794A),
        (4, 0x9136_A0DC_A574_57EE),
        (7, 0x6C83_909A_9F01_ED25),
        (8, 0xCDBC_F538_E71D_1348),
        (15, 0x1807_1931_6D62_2D84),
        (16, 0x98C9_0B57_FDFC_B55C),
        (31, 0x299B_39A2_90E6_D783),
        (32, 0x18B2_1649_2BB4_4B70),
        (33, 0x55C8_DC3E_578F_5B59),
        (63, 0xA9EF_BE0F_A0F3_F4E7),
        (64, 0xEF55_8F8A_CAC2_B5CD),
        (100, 0x4BFE_019C_D91D_9EA4),
        (255, 0xA80F_35BB_0DC8_E3A7),
        (999, 0x22EA_C650_671B_0AA7),
        (1000, 0x52BD_1358_F22E_9EF7),
    ];

    #[test]
    fn streaming_in_pieces_equals_one_shot() {
        let buf = sanity_buffer(1000);
        let whole = xxh64(&buf);
        for split in [1usize, 3, 4, 7, 8, 31, 32, 33, 64, 100, 999] {
            let mut h = Xxh64::new(0);
            for piece in buf.chunks(split) {
                h.update(piece);
            }
            assert_eq!(h.finish(), whole, "pieces of {split}");
        }
    }

    #[test]
    fn words_hash_as_their_little_endian_bytes() {
        let words: Vec<u32> = (0..257u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
        let bytes: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
        // Several arrays fed one after the other, with lengths that leave
        // partial stripes, hash like their concatenated bytes.
        for cut in [0usize, 1, 5, 8, 13, 100, 257] {
            let mut h = Xxh64::new(0);
            h.update_u32(&words[..cut]);
            h.update_u32(&words[cut..]);
            assert_eq!(h.finish(), xxh64(&bytes), "cut at {cut}");
        }
        let floats: Vec<f32> = words.iter().map(|&w| f32::from_bits(w)).collect();
        let mut h = Xxh64::new(0);
        h.update_f32(&floats);
        assert_eq!(h.finish(), xxh64(&bytes));
    }
}
