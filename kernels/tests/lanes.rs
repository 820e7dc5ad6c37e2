//! The lane helpers against plain indexing: `gather` (one AVX-512 gather,
//! two AVX2 gathers, or sixteen loads, by the build's target features) must
//! read exactly `src[idx[k + l]]`, and must refuse an index past the end of
//! `src` as the plain indexing does.

use porosph_kernels::lanes::{gather, LANES};

/// Indices from a fixed linear congruential sequence, every one below `n`,
/// with the largest index `n - 1` in the last lane of one vector (the
/// bound the gathers check).
fn indices(n: u32, count: usize) -> Vec<u32> {
    let mut s = 0x9e37_79b9u32;
    let mut v: Vec<u32> = (0..count)
        .map(|_| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            s % n
        })
        .collect();
    v[2 * LANES - 1] = n - 1;
    v
}

#[test]
fn gather_reads_the_indexed_values_bit_for_bit() {
    let n = 100_003u32;
    // Values with every kind of bit pattern a kernel meets: negative,
    // subnormal, zero of both signs, large.
    let src: Vec<f32> = (0..n)
        .map(|i| match i % 5 {
            0 => -(i as f32) * 1.5e-3,
            1 => f32::from_bits(i),
            2 => -0.0,
            3 => 3.0e38 / (i as f32 + 1.0),
            _ => i as f32,
        })
        .collect();
    let idx = indices(n, 64 * LANES);
    for k in (0..idx.len()).step_by(LANES) {
        let v = gather(&src, &idx, k).to_array();
        for l in 0..LANES {
            assert_eq!(v[l].to_bits(), src[idx[k + l] as usize].to_bits(), "vector at {k}, lane {l}");
        }
    }
    // Unaligned starts read the same lanes.
    for k in 1..LANES {
        let v = gather(&src, &idx, k).to_array();
        for l in 0..LANES {
            assert_eq!(v[l].to_bits(), src[idx[k + l] as usize].to_bits());
        }
    }
}

#[test]
#[should_panic]
fn gather_refuses_an_index_past_the_end() {
    let src = vec![1.0f32; 40];
    let mut idx = vec![3u32; LANES];
    idx[LANES / 2] = 40;
    let _ = gather(&src, &idx, 0);
}
