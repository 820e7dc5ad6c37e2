//! Neighbour search against brute force.

use porosph_kernels::grid::CellGrid;
use porosph_kernels::kernel::Kernel;
use porosph_kernels::neighbors::{build_pairs, compute_keys, sort_permutation, PairLists};
use porosph_kernels::soa::Vel;

struct Lcg(u64);
impl Lcg {
    fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 40) as f32 / (1u64 << 24) as f32
    }
}

/// Sorts points by Morton key and returns (x, y, z, grid).
fn sorted(points: &[[f32; 3]], h: f32) -> (Vec<f32>, Vec<f32>, Vec<f32>, CellGrid) {
    let (x, y, z): (Vec<f32>, Vec<f32>, Vec<f32>) = (
        points.iter().map(|p| p[0]).collect(),
        points.iter().map(|p| p[1]).collect(),
        points.iter().map(|p| p[2]).collect(),
    );
    let mut keys = vec![0; x.len()];
    compute_keys(&x, &y, &z, 1.0 / h, &mut keys);
    let (mut s, mut perm) = (Vec::new(), Vec::new());
    sort_permutation(&keys, &mut s, &mut perm);
    let p = |v: &Vec<f32>| perm.iter().map(|&i| v[i as usize]).collect::<Vec<f32>>();
    let sk: Vec<u64> = s.iter().map(|&(k, _)| k).collect();
    let mut g = CellGrid::default();
    g.build(&sk, h);
    (p(&x), p(&y), p(&z), g)
}

fn pairs_of(l: &PairLists) -> Vec<Vec<u32>> {
    let mut out = Vec::new();
    for b in &l.blocks[..l.n.div_ceil(porosph_kernels::blocks::BLOCK)] {
        for q in 0..b.start.len() - 1 {
            let mut v: Vec<u32> = b.range(q).filter(|&p| b.w[p] > 0.0).map(|p| b.j[p]).collect();
            v.sort_unstable();
            out.push(v);
        }
    }
    out
}

#[test]
fn random_sets_match_brute_force() {
    let h = 0.05;
    let kernel = Kernel::new(h);
    let mut rng = Lcg(7);
    for (n, extent, offset) in [(3000usize, 0.5f32, 0.0f32), (2000, 0.3, -0.17), (1500, 2.0, -1.0)] {
        let pts: Vec<[f32; 3]> = (0..n)
            .map(|_| [offset + extent * rng.next(), offset + extent * rng.next(), offset + extent * rng.next()])
            .collect();
        let (x, y, z, g) = sorted(&pts, h);
        let p = Vel { x: &x, y: &y, z: &z };
        let mut l = PairLists::default();
        build_pairs(&mut l, p, p, &g, None, &kernel);
        let got = pairs_of(&l);
        // Skipping far cells with the dilated set changes nothing.
        let mut near = CellGrid::default();
        near.build(&g.dilated_keys(), h);
        let mut l2 = PairLists::default();
        build_pairs(&mut l2, p, p, &g, Some(&near), &kernel);
        assert_eq!(pairs_of(&l2), got);
        for i in 0..n {
            let want: Vec<u32> = (0..n as u32)
                .filter(|&j| {
                    let j = j as usize;
                    let (dx, dy, dz) = (x[i] - x[j], y[i] - y[j], z[i] - z[j]);
                    dx * dx + dy * dy + dz * dz < h * h
                })
                .collect();
            assert_eq!(got[i], want, "neighbours of particle {i} (n = {n})");
        }
        // Kernel values stored with the pairs are the kernel's.
        let b = &l.blocks[0];
        for q in 0..10 {
            for pidx in b.range(q).filter(|&p| b.w[p] > 0.0) {
                let j = b.j[pidx] as usize;
                let r = ((x[q] - x[j]).powi(2) + (y[q] - y[j]).powi(2) + (z[q] - z[j]).powi(2)).sqrt();
                assert!((b.w[pidx] - kernel.w(r)).abs() <= 1e-5 * kernel.w0());
            }
        }
    }
}

/// A pair at 0.9999 H is found; at exactly H and at 1.0001 H it is not
/// (the support is half-open, where W already vanishes). Checked along each
/// axis and across a cell boundary.
#[test]
fn pairs_at_the_support_radius() {
    let h = 0.25; // exactly representable
    let kernel = Kernel::new(h);
    for axis in 0..3 {
        for (dist, expect) in [(0.9999 * h, true), (h, false), (1.0001 * h, false)] {
            for base in [0.0f32, 0.1, -0.37] {
                let a = [base; 3];
                let mut b = a;
                b[axis] += dist;
                let (x, y, z, g) = sorted(&[a, b], h);
                let p = Vel { x: &x, y: &y, z: &z };
                let mut l = PairLists::default();
                build_pairs(&mut l, p, p, &g, None, &kernel);
                let found = pairs_of(&l)[0].len() == 2;
                assert_eq!(found, expect, "axis {axis}, distance {dist}/H = {}, base {base}", dist / h);
            }
        }
    }
}

/// The pair lists of `build_pairs`, as they are laid out (per query: the
/// targets within H in ascending order, the next query's right after, no
/// padding), against an O(n^2) scalar reference,
/// bit for bit: the same pairs in the same order, the same W and gradient
/// bits. Random clouds, a jittered lattice (H = 2 d), a clump much denser
/// than a cell, a NaN particle; query set = target set and a query set
/// against another target set; both kernel shapes; with and without the
/// dilated-cell skip.
#[test]
fn pair_lists_match_brute_force_bit_for_bit() {
    use porosph_kernels::kernel::KernelShape;
    let h = 0.05;
    let mut rng = Lcg(11);
    let mut clouds: Vec<Vec<[f32; 3]>> = Vec::new();
    clouds.push((0..2500).map(|_| [0.4 * rng.next(), 0.4 * rng.next() - 0.2, 0.4 * rng.next()]).collect());
    let mut lattice = Vec::new();
    for k in 0..14 {
        for j in 0..14 {
            for i in 0..14 {
                let d = h / 2.0;
                let jit = |r: f32| 0.3 * d * (r - 0.5);
                lattice.push([
                    -0.1 + i as f32 * d + jit(rng.next()),
                    j as f32 * d + jit(rng.next()),
                    0.3 + k as f32 * d + jit(rng.next()),
                ]);
            }
        }
    }
    clouds.push(lattice);
    let mut clump: Vec<[f32; 3]> =
        (0..600).map(|_| [0.02 * rng.next(), 0.02 * rng.next(), 0.02 * rng.next()]).collect();
    clump.extend((0..900).map(|_| [0.3 * rng.next() - 0.1, 0.3 * rng.next() - 0.1, 0.3 * rng.next() - 0.1]));
    clump.push([f32::NAN, 0.01, 0.01]);
    clouds.push(clump);
    let targets: Vec<[f32; 3]> =
        (0..1800).map(|_| [0.5 * rng.next() - 0.05, 0.5 * rng.next() - 0.2, 0.5 * rng.next()]).collect();
    let (tx, ty, tz, tg) = sorted(&targets, h);
    for shape in [KernelShape::CubicSpline, KernelShape::WendlandC2] {
        let kernel = Kernel::with_shape(shape, h);
        for cloud in &clouds {
            let (x, y, z, g) = sorted(cloud, h);
            let q = Vel { x: &x, y: &y, z: &z };
            let other = Vel { x: &tx, y: &ty, z: &tz };
            let mut near = CellGrid::default();
            near.build(&tg.dilated_keys(), h);
            for (t, grid, near) in [(q, &g, None), (other, &tg, None), (other, &tg, Some(&near))] {
                let mut l = PairLists::default();
                build_pairs(&mut l, q, t, grid, near, &kernel);
                let mut got = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
                for b in l.used() {
                    for qi in 0..b.start.len() - 1 {
                        let r = b.range(qi);
                        got.0.push(r.len());
                        got.1.extend_from_slice(&b.j[r.clone()]);
                        got.2.extend(b.w[r.clone()].iter().map(|v| v.to_bits()));
                        got.3.extend(b.gx[r.clone()].iter().map(|v| v.to_bits()));
                        got.4.extend(b.gy[r.clone()].iter().map(|v| v.to_bits()));
                        got.5.extend(b.gz[r].iter().map(|v| v.to_bits()));
                    }
                }
                let mut want = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
                for i in 0..q.len() {
                    let first = want.1.len();
                    for j in 0..t.len() {
                        let (dx, dy, dz) = (q.x[i] - t.x[j], q.y[i] - t.y[j], q.z[i] - t.z[j]);
                        let r2 = dx * dx + dy * dy + dz * dz;
                        if r2 < h * h {
                            let r = r2.sqrt();
                            let (w, gr) = match shape {
                                KernelShape::CubicSpline => {
                                    (kernel.cubic_spline_w(r), kernel.cubic_spline_grad_over_r(r))
                                }
                                KernelShape::WendlandC2 => (kernel.wendland_w(r), kernel.wendland_grad_over_r(r)),
                            };
                            want.1.push(j as u32);
                            want.2.push(w.to_bits());
                            want.3.push((gr * dx).to_bits());
                            want.4.push((gr * dy).to_bits());
                            want.5.push((gr * dz).to_bits());
                        }
                    }
                    want.0.push(want.1.len() - first);
                }
                assert_eq!(got.0, want.0, "pairs per query ({shape:?}, {} queries)", q.len());
                assert_eq!(got.1, want.1, "targets ({shape:?})");
                assert_eq!(got.2, want.2, "W bits ({shape:?})");
                assert_eq!(got.3, want.3, "grad x bits ({shape:?})");
                assert_eq!(got.4, want.4, "grad y bits ({shape:?})");
                assert_eq!(got.5, want.5, "grad z bits ({shape:?})");
                assert!(got.1.len() > q.len(), "the cloud has pairs: {} for {} queries", got.1.len(), q.len());
            }
        }
    }
}

/// `build_gradient_pairs` lays out the same pairs and gradients as
/// `build_pairs` without the kernel values, and its sums are the density
/// sums of `iisph::fluid_volumes` over the stored values, bit for bit:
/// random clouds and a lattice, both kernel shapes, non-uniform values.
#[test]
fn gradient_pairs_sum_what_stored_values_sum() {
    use porosph_kernels::iisph::FluidSums;
    use porosph_kernels::kernel::KernelShape;
    use porosph_kernels::neighbors::build_gradient_pairs;
    let h = 0.05;
    let mut rng = Lcg(11);
    let cloud: Vec<[f32; 3]> = (0..3000).map(|_| [0.4 * rng.next(), 0.4 * rng.next(), 0.4 * rng.next()]).collect();
    let lattice: Vec<[f32; 3]> =
        (0..4096).map(|i| [(i % 16) as f32 * 0.025, (i / 16 % 16) as f32 * 0.025, (i / 256) as f32 * 0.025]).collect();
    for shape in [KernelShape::CubicSpline, KernelShape::WendlandC2] {
        let kernel = Kernel::with_shape(shape, h);
        for pts in [&cloud, &lattice] {
            let n = pts.len();
            let (x, y, z, g) = sorted(pts, h);
            let p = Vel { x: &x, y: &y, z: &z };
            let val: Vec<f32> = (0..n).map(|_| 1e-6 * (0.5 + rng.next())).collect();
            let mut with_w = PairLists::default();
            build_pairs(&mut with_w, p, p, &g, None, &kernel);
            let (mut without, mut sums) = (PairLists::default(), vec![0.0f32; n]);
            build_gradient_pairs(&mut without, p, p, &g, None, &kernel, &val, &mut sums);
            for (a, b) in with_w.used().iter().zip(without.used()) {
                assert!(b.w.is_empty());
                assert_eq!((&a.start, &a.j), (&b.start, &b.j));
                let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!((bits(&a.gx), bits(&a.gy), bits(&a.gz)), (bits(&b.gx), bits(&b.gy), bits(&b.gz)));
            }
            let bits = |sigma: Vec<f32>| sigma.iter().map(|s| s.to_bits()).collect::<Vec<_>>();
            let (done, pairs) = (FluidSums::Done(&sums), FluidSums::Pairs(&with_w));
            let run = |ff| bits(fluid_sigma(ff, p, &val, &kernel));
            assert_eq!(run(done), run(pairs), "{shape:?}, {n} points");
        }
    }
}

/// `iisph::fluid_volumes`' sigma of the points `p` from the fluid sums `ff`
/// with the values `val`, and no wall pairs (one wall particle out of
/// reach): the fluid sum alone.
fn fluid_sigma(ff: porosph_kernels::iisph::FluidSums, p: Vel, val: &[f32], kernel: &Kernel) -> Vec<f32> {
    let h = kernel.support;
    let mut none = PairLists::default();
    let far = [1e3f32; 1];
    let mut wg = CellGrid::default();
    wg.build(&[porosph_kernels::grid::morton(porosph_kernels::grid::cell_of(1e3, 1e3, 1e3, 1.0 / h))], h);
    build_pairs(&mut none, p, Vel { x: &far, y: &far, z: &far }, &wg, None, kernel);
    let n = p.len();
    let (mut sigma, mut vol) = (vec![0.0f32; n], vec![0.0f32; n]);
    porosph_kernels::iisph::fluid_volumes(ff, &none, None, val, &[1.0], &mut sigma, &mut vol);
    sigma
}

/// `update_sums`: the sums of `build_gradient_pairs` taken with old values,
/// updated where a few values changed (one in 20, as the porous
/// partition's release changes a few rest volumes), equal the sums over
/// stored kernel values with the new ones. Reference: the stored-W sum of
/// `iisph::fluid_volumes`; the update adds in another order, so equal to
/// rounding (1e-6 relative; the sums are about 1, their terms 1e-2 to 1);
/// unchanged rows stay bit for bit.
#[test]
fn updated_gradient_pair_sums_follow_changed_values() {
    use porosph_kernels::iisph::FluidSums;
    use porosph_kernels::kernel::KernelShape;
    use porosph_kernels::neighbors::{build_gradient_pairs, update_sums};
    let h = 0.05;
    let mut rng = Lcg(23);
    let cloud: Vec<[f32; 3]> = (0..3000).map(|_| [0.4 * rng.next(), 0.4 * rng.next(), 0.4 * rng.next()]).collect();
    for shape in [KernelShape::CubicSpline, KernelShape::WendlandC2] {
        let kernel = Kernel::with_shape(shape, h);
        let n = cloud.len();
        let (x, y, z, g) = sorted(&cloud, h);
        let p = Vel { x: &x, y: &y, z: &z };
        let old: Vec<f32> = (0..n).map(|_| 1e-3 * (0.5 + rng.next())).collect();
        let changed: Vec<bool> = (0..n).map(|_| rng.next() < 0.05).collect();
        let new: Vec<f32> =
            old.iter().zip(&changed).map(|(&v, &c)| if c { v * (0.2 + rng.next()) } else { v }).collect();
        let mut with_w = PairLists::default();
        build_pairs(&mut with_w, p, p, &g, None, &kernel);
        let (mut without, mut sums) = (PairLists::default(), vec![0.0f32; n]);
        build_gradient_pairs(&mut without, p, p, &g, None, &kernel, &old, &mut sums);
        let before = sums.clone();
        update_sums(&without, p, &kernel, &old, &new, &mut sums);
        let got = fluid_sigma(FluidSums::Done(&sums), p, &new, &kernel);
        let want = fluid_sigma(FluidSums::Pairs(&with_w), p, &new, &kernel);
        let near_changed = pairs_of(&with_w).iter().map(|r| r.iter().any(|&j| changed[j as usize])).collect::<Vec<_>>();
        let (mut touched, mut worst) = (0, 0.0f32);
        for i in 0..n {
            worst = worst.max((got[i] - want[i]).abs() / want[i]);
            if near_changed[i] {
                touched += 1;
            } else {
                assert_eq!(sums[i].to_bits(), before[i].to_bits(), "{shape:?}: row {i} without a changed neighbour");
                assert_eq!(got[i].to_bits(), want[i].to_bits(), "{shape:?}: row {i} without a changed neighbour");
            }
        }
        assert!(worst <= 1e-6, "{shape:?}: relative difference {worst}");
        assert!(touched > n / 10, "{shape:?}: only {touched} rows saw a changed neighbour");
    }
}

/// `PairBlock::scale_retain_nonzero` (the solid rows scale the SS pairs
/// and drop those they scaled to 0): every query keeps exactly its pairs
/// with a nonzero scaled gradient, in their order, with their j and W bits
/// and the scaled gradient's bits, and the ranges stay contiguous; a query
/// left without pairs gets an empty range.
#[test]
fn dropping_zero_gradients_keeps_the_rest_in_order() {
    use porosph_kernels::neighbors::PairBlock;
    // Four queries with 3, 0, 5 and 2 pairs; gradients zero where k % 3 == 1
    // and in every component of query 3's pairs; scaled by 0 where j % 4 ==
    // 0, else by 2 (exact).
    let scale = |_q: usize, j: usize| if j.is_multiple_of(4) { 0.0f32 } else { 2.0 };
    let counts = [3usize, 0, 5, 2];
    let mut b = PairBlock::default();
    b.start.push(0);
    let mut want: Vec<Vec<(u32, u32, [u32; 3])>> = Vec::new();
    let mut k = 0u32;
    for (q, &c) in counts.iter().enumerate() {
        let mut keep = Vec::new();
        for _ in 0..c {
            let zero = k % 3 == 1 || q == 3;
            let g = if zero { [0.0f32, -0.0, 0.0] } else { [0.5 + k as f32, -(k as f32), 0.0] };
            let s = scale(q, 100 + k as usize);
            let w = 10.0 + k as f32;
            b.j.push(100 + k);
            b.w.push(w);
            b.gx.push(g[0]);
            b.gy.push(g[1]);
            b.gz.push(g[2]);
            if !zero && s != 0.0 {
                keep.push((100 + k, w.to_bits(), g.map(|g| (g * s).to_bits())));
            }
            k += 1;
        }
        b.start.push(b.j.len() as u32);
        want.push(keep);
    }
    b.scale_retain_nonzero(scale);
    assert_eq!(b.start.len(), counts.len() + 1);
    assert_eq!(b.start[0], 0);
    for (q, keep) in want.iter().enumerate() {
        let got: Vec<_> = b
            .range(q)
            .map(|p| (b.j[p], b.w[p].to_bits(), [b.gx[p].to_bits(), b.gy[p].to_bits(), b.gz[p].to_bits()]))
            .collect();
        assert_eq!(&got, keep, "query {q}");
    }
    let total: usize = want.iter().map(Vec::len).sum();
    assert_eq!((b.j.len(), b.w.len(), b.gx.len(), b.gy.len(), b.gz.len()), (total, total, total, total, total));
}

/// `clear_to` leaves lists of n queries, each without pairs, where a build
/// had found some (the solid-solid lists of a scene that reads none), also
/// when the lists shrink or grow between calls; the vectors keep their
/// capacity. Reference: every range empty and `pairs()` = 0.
#[test]
fn cleared_lists_have_every_query_and_no_pair() {
    let h = 0.05;
    let kernel = Kernel::new(h);
    let mut rng = Lcg(11);
    let pts: Vec<[f32; 3]> = (0..1500).map(|_| [0.3 * rng.next(), 0.3 * rng.next(), 0.3 * rng.next()]).collect();
    let (x, y, z, g) = sorted(&pts, h);
    let p = Vel { x: &x, y: &y, z: &z };
    let mut l = PairLists::default();
    build_pairs(&mut l, p, p, &g, None, &kernel);
    assert!(l.pairs() > 0);
    let cap = l.blocks[0].j.capacity();
    for n in [1500, 700, 1, 0, 2100] {
        l.clear_to(n);
        assert_eq!(l.n, n);
        assert_eq!(l.pairs(), 0);
        assert_eq!(pairs_of(&l).len(), n, "one (empty) range per query");
        assert!(pairs_of(&l).iter().all(Vec::is_empty));
    }
    assert_eq!(l.blocks[0].j.capacity(), cap, "capacity kept");
}
