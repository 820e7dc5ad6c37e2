//! The lane helpers against plain indexing: a pair vector's `gather` (one
//! AVX-512 gather, two AVX2 gathers, or sixteen loads, by the build's
//! target features) must read exactly `src[j[k + l]]`, and must refuse an
//! index past the end of `src` as the plain indexing does.

use porosph_kernels::lanes::{pair_vectors, Packed, F, LANES};

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
    // Aligned starts, then unaligned ones: the same lanes.
    for start in 0..LANES {
        for v in pair_vectors(&idx, start..idx.len()) {
            let g = v.gather(&src).to_array();
            for l in 0..v.n {
                assert_eq!(g[l].to_bits(), src[idx[v.k + l] as usize].to_bits(), "vector at {}, lane {l}", v.k);
            }
        }
    }
}

/// `gather3` of a packed field (one 16-byte load a lane and a transpose,
/// by the build's target features) gives what three `gather`s of the
/// component arrays give, bit for bit, in every lane: whole vectors and
/// partial ones of every length (lanes past the range at the first
/// target), at aligned and unaligned starts.
#[test]
fn gather3_of_a_packed_field_is_three_gathers() {
    let n = 20_011u32;
    let comp = |c: u32| -> Vec<f32> { (0..n).map(|i| f32::from_bits(0x3f80_0000 ^ (i * 2_654_435_761 + c))).collect() };
    let (x, y, z) = (comp(0), comp(1), comp(2));
    let packed: Vec<Packed> = (0..n as usize).map(|i| [x[i], y[i], z[i], f32::NAN]).collect();
    let idx = indices(n, 8 * LANES);
    for start in 0..LANES {
        for len in [0, 1, 5, LANES - 1, LANES, LANES + 3, 3 * LANES, idx.len() - start] {
            for v in pair_vectors(&idx, start..start + len) {
                let [a, b, c] = v.gather3(&packed);
                for (got, arr) in [(a, &x), (b, &y), (c, &z)] {
                    let want = v.gather(arr).to_array();
                    let got = got.to_array();
                    for l in 0..LANES {
                        assert_eq!(got[l].to_bits(), want[l].to_bits(), "start {start}, len {len}, lane {l}");
                    }
                }
            }
        }
    }
}

#[test]
#[should_panic]
fn gather3_refuses_an_index_past_the_end() {
    let src = vec![[1.0f32; 4]; 40];
    let mut idx = vec![3u32; LANES];
    idx[LANES / 2] = 40;
    for v in pair_vectors(&idx, 0..LANES) {
        let _ = v.gather3(&src);
    }
}

#[test]
#[should_panic]
fn gather_refuses_an_index_past_the_end() {
    let src = vec![1.0f32; 40];
    let mut idx = vec![3u32; LANES];
    idx[LANES / 2] = 40;
    for v in pair_vectors(&idx, 0..LANES) {
        let _ = v.gather(&src);
    }
}

/// `pair_vectors` over unpadded pair ranges: every range length from 0 to
/// 3 vectors, starting anywhere in the lists, also where the range ends at
/// the lists' end (the masked path) and where other pairs follow (the
/// whole-vector path). Each vector's lanes below `n` load, gather and
/// store exactly the range's slots; the lanes past the range load 0,
/// gather at the range's first target and leave the slots after the range
/// untouched.
#[test]
fn pair_vectors_cover_the_range_and_mask_the_rest() {
    let n = 5_000u32;
    let src: Vec<f32> = (0..n).map(|i| 1.0 + i as f32).collect();
    let total = 4 * LANES + 7;
    let j = indices(n, total);
    let vals: Vec<f32> = (0..total).map(|k| -(k as f32) - 0.5).collect();
    for start in [0, 1, LANES - 1, LANES, 2 * LANES + 3] {
        for len in 0..=(total - start).min(3 * LANES) {
            let r = start..start + len;
            let mut seen = Vec::new();
            let mut out = vec![7.0f32; total];
            for v in pair_vectors(&j, r.clone()) {
                assert_eq!(v.k, r.start + seen.len(), "vectors in order, LANES apart");
                assert!(v.n >= 1 && v.n <= LANES && v.k + v.n <= r.end);
                let (ld, g, idx) = (v.load(&vals).to_array(), v.gather(&src).to_array(), v.indices());
                for l in 0..LANES {
                    if l < v.n {
                        assert_eq!(ld[l].to_bits(), vals[v.k + l].to_bits());
                        assert_eq!(idx[l], j[v.k + l]);
                        assert_eq!(g[l].to_bits(), src[j[v.k + l] as usize].to_bits());
                    } else {
                        assert_eq!(ld[l].to_bits(), 0.0f32.to_bits(), "lane {l} past the range loads +0");
                        assert_eq!(idx[l], j[r.start], "lane {l} past the range gathers at the first target");
                        assert_eq!(g[l].to_bits(), src[j[r.start] as usize].to_bits());
                    }
                }
                v.store(&mut out, F::from(std::array::from_fn::<f32, LANES, _>(|l| l as f32)));
                seen.extend(v.k..v.k + v.n);
            }
            assert_eq!(seen, r.clone().collect::<Vec<_>>(), "start {start}, len {len}");
            for (k, &o) in out.iter().enumerate() {
                let want = if r.contains(&k) { ((k - r.start) % LANES) as f32 } else { 7.0 };
                assert_eq!(o, want, "slot {k} after the stores (start {start}, len {len})");
            }
        }
    }
}
