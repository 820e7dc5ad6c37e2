//! The smoothing kernels against their defining properties (PHYSICS.md §1;
//! the lattice calibration of Wendland C2 is tested in kernels/src/kernel.rs).

use porosph_kernels::kernel::{Kernel, KernelShape};
use porosph_kernels::lanes::{F, LANES};

const H: f32 = 0.02;

/// Both shapes, with the integral of W each must have: 1 for the spline;
/// 1 / 1.033843 for Wendland C2, whose C is divided by its lattice sum at
/// H = 2d (the sum of 21/(2 pi H^3) (1-q)^4 (1+4q) over the cubic lattice,
/// evaluated independently in scripts: 1.033843).
fn shapes() -> [(Kernel, f64); 2] {
    [(Kernel::new(H), 1.0), (Kernel::with_shape(KernelShape::WendlandC2, H), 1.0 / 1.033843)]
}

/// Reference: a kernel is a normalised weight: the integral of W over R^3 is
/// 1 (module doc for Wendland's). Midpoint rule on a fine grid; tolerance
/// 1e-3 covers the quadrature.
#[test]
fn integrates_to_one() {
    for (k, integral) in shapes() {
        integrates_to(&k, integral);
    }
}

fn integrates_to(k: &Kernel, integral: f64) {
    let m = 80;
    let dx = 2.0 * H as f64 / m as f64;
    let mut s = 0.0f64;
    for a in 0..m {
        for b in 0..m {
            for c in 0..m {
                let p = |i: usize| -H as f64 + (i as f64 + 0.5) * dx;
                let r = (p(a).powi(2) + p(b).powi(2) + p(c).powi(2)).sqrt();
                s += k.w(r as f32) as f64 * dx * dx * dx;
            }
        }
    }
    assert!((s - integral).abs() < 1e-3, "{:?}: integral of W = {s}", k.shape);
}

#[test]
fn compact_support() {
    for (k, _) in shapes() {
        compact(&k);
    }
}

fn compact(k: &Kernel) {
    for r in [H, 1.0001 * H, 1.5 * H, 10.0 * H] {
        assert_eq!(k.w(r), 0.0, "W({r}) must vanish at and beyond H");
        assert_eq!(k.grad_over_r(r), 0.0);
    }
    assert!(k.w(0.9999 * H) > 0.0);
    assert!(k.grad_over_r(0.9999 * H) < 0.0);
}

/// On a full cubic lattice of spacing d = H/2, sum_j grad W_ij = 0 by
/// symmetry (to round-off), and d^3 sum_j W_ij = 0.99997 (PHYSICS.md §1).
#[test]
fn lattice_gradient_sums_to_zero_and_volume_sums_to_one() {
    let k = Kernel::new(H);
    let d = H / 2.0;
    let (mut g, mut w) = ([0.0f64; 3], 0.0f64);
    let mut gmag = 0.0f64;
    for a in -3i32..=3 {
        for b in -3i32..=3 {
            for c in -3i32..=3 {
                // x_ij = x_i - x_j with x_i at the origin
                let x = [-(a as f32) * d, -(b as f32) * d, -(c as f32) * d];
                let r = (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt();
                let f = k.grad_over_r(r);
                for (gc, xc) in g.iter_mut().zip(x) {
                    *gc += (f * xc) as f64;
                }
                gmag += (f * r) as f64;
                w += k.w(r) as f64;
            }
        }
    }
    for gc in g {
        assert!(gc.abs() < 1e-6 * gmag.abs(), "sum of gradients {gc} vs scale {gmag}");
    }
    let vol_sum = w * (d as f64).powi(3);
    assert!((vol_sum - 0.99997).abs() < 1e-4, "d^3 sum W = {vol_sum}");
}

/// Gradient against a central difference of W (the spline's; Wendland's
/// gradient carries its own calibration, tested in kernels/src/kernel.rs).
#[test]
fn gradient_matches_finite_difference() {
    let k = Kernel::new(H);
    for i in 1..100 {
        let r = i as f64 / 100.0 * H as f64;
        let e = 1e-4 * H as f64;
        let fd = (k.w((r + e) as f32) as f64 - k.w((r - e) as f32) as f64) / (2.0 * e);
        let an = k.grad_over_r(r as f32) as f64 * r;
        let scale = k.w0() as f64 / H as f64;
        assert!((fd - an).abs() < 2e-3 * scale, "r = {r}: fd {fd} vs analytic {an}");
    }
}

/// The SIMD form equals the scalar form lane by lane, bit for bit.
#[test]
fn simd_equals_scalar_lane_by_lane() {
    for (k, _) in shapes() {
        simd_equals_scalar(&k);
    }
}

fn simd_equals_scalar(k: &Kernel) {
    for start in 0..200 {
        let rs: [f32; LANES] = std::array::from_fn(|l| (start * LANES + l) as f32 * 1.3e-3 * H);
        let w = k.w(F::from(rs)).to_array();
        let g = k.grad_over_r(F::from(rs)).to_array();
        for l in 0..LANES {
            assert_eq!(w[l].to_bits(), k.w(rs[l]).to_bits(), "W at r = {}", rs[l]);
            assert_eq!(g[l].to_bits(), k.grad_over_r(rs[l]).to_bits(), "W'/r at r = {}", rs[l]);
        }
    }
}
