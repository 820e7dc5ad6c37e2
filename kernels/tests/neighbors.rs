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
