//! XXH64 (Yann Collet's xxHash, 64-bit variant, seed 0), the checksum of
//! every checkpoint dataset, through the `twox-hash` crate.
//!
//! The value is the one Python's `xxhash.xxh64(data).intdigest()` gives for
//! a dataset's little-endian bytes, so h5py users can check a file without
//! porosph; checkpoints written by porosph's earlier, hand-written XXH64
//! carry the same digests (the known-answer tests below are the ones that
//! implementation passed).

use std::hash::Hasher as _;
use twox_hash::XxHash64;

/// A streaming XXH64 hasher: feeding the bytes in pieces gives the same
/// value as hashing them at once.
#[derive(Clone)]
pub struct Xxh64(XxHash64);

impl Default for Xxh64 {
    fn default() -> Self {
        Self::new(0)
    }
}

impl std::fmt::Debug for Xxh64 {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_tuple("Xxh64").field(&self.finish()).finish()
    }
}

/// Words converted to little-endian bytes per block of this many, so that
/// hashing an array needs no buffer of its size.
const WORD_BLOCK: usize = 1024;

impl Xxh64 {
    /// A hasher with `seed` (porosph uses 0).
    pub fn new(seed: u64) -> Self {
        Self(XxHash64::with_seed(seed))
    }

    /// Feeds bytes.
    pub fn update(&mut self, bytes: &[u8]) {
        self.0.write(bytes);
    }

    /// Feeds `n` 32-bit words, `word(i)` for i in 0..n, as little-endian
    /// bytes (the bytes of an `f32` or `u32` array on disk).
    pub fn update_words(&mut self, n: usize, word: impl Fn(usize) -> u32) {
        let mut buf = [0u8; 4 * WORD_BLOCK];
        for start in (0..n).step_by(WORD_BLOCK) {
            let len = WORD_BLOCK.min(n - start);
            for (i, b) in buf.chunks_exact_mut(4).take(len).enumerate() {
                b.copy_from_slice(&word(start + i).to_le_bytes());
            }
            self.0.write(&buf[..4 * len]);
        }
    }

    /// Feeds the little-endian bytes of `v`.
    pub fn update_f32(&mut self, v: &[f32]) {
        if cfg!(target_endian = "little") {
            self.0.write(bytemuck::cast_slice(v));
        } else {
            self.update_words(v.len(), |i| v[i].to_bits());
        }
    }

    /// Feeds the little-endian bytes of `v`.
    pub fn update_u32(&mut self, v: &[u32]) {
        if cfg!(target_endian = "little") {
            self.0.write(bytemuck::cast_slice(v));
        } else {
            self.update_words(v.len(), |i| v[i]);
        }
    }

    /// The hash of everything fed so far.
    pub fn finish(&self) -> u64 {
        self.0.finish()
    }
}

/// XXH64 of `bytes`, seed 0.
pub fn xxh64(bytes: &[u8]) -> u64 {
    XxHash64::oneshot(0, bytes)
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

    #[test]
    fn words_fed_by_function_hash_as_their_bytes_across_blocks() {
        // More than two blocks of words, after a partial stripe of bytes.
        let n = 2 * WORD_BLOCK + 37;
        let word = |i: usize| (i as u32).wrapping_mul(2_654_435_761) ^ 0x5bd1_e995;
        let mut bytes = b"abc".to_vec();
        bytes.extend((0..n).flat_map(|i| word(i).to_le_bytes()));
        let mut h = Xxh64::new(0);
        h.update(b"abc");
        h.update_words(n, word);
        assert_eq!(h.finish(), xxh64(&bytes));
    }
}
