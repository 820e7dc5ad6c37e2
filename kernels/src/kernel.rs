//! The smoothing kernel W, support radius H = 2 d (PHYSICS.md §1), in
//! scalar and SIMD form through [`Real`]. Two shapes, chosen per scene
//! (`[simulation] kernel`):
//!
//! - the cubic spline (the SPlisHSPlasH form; the default): on the start
//!   lattice d^3 sum_j W_ij = 0.99997 and the gradient's first moment
//!   -(1/3) sum_j d^3 x_ij . grad W_ij = 1.020, used as they are;
//! - Wendland C2 (Wendland 1995; Dehnen & Aly 2012 show it has no pairing
//!   instability): W = C (1 - q)^4 (1 + 4q). At H = 2 d its plain lattice
//!   sum is 1.0338 and its first moment 0.982, so both are calibrated on
//!   the cubic lattice at construction (PHYSICS.md §1 asks for the first):
//!   C is divided by the lattice sum, so a full fluid particle at the start
//!   is at rest density with V = d^3 as for the spline, and the gradient by
//!   the first moment, so a linear pressure field gives its exact gradient
//!   on the lattice (without it the tank at rest's slope of p is 6-10 % steep).
//!
//! Why the choice matters (tests/hydrostatic.rs `tank_at_rest_per_particle`,
//! `scripts/lattice_stability.py --kernel`): at positive pressure the
//! symmetric pressure force drives any lattice of the cubic spline at H = 2 d
//! to disorder (negative curvature on density-preserving modes), whose
//! zeroth-order force keeps the fluid moving; Wendland C2's cubic lattice
//! has none at H = 2 d (least curvature +1e-3), and a tank at rest moves
//! about three times less.

use crate::lanes::Real;
use std::f32::consts::PI;

/// The kernel's shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum KernelShape {
    /// The cubic spline, W = k (6q^3 - 6q^2 + 1) for q <= 1/2, 2k (1-q)^3
    /// for q <= 1, k = 8 / (pi H^3).
    CubicSpline,
    /// Wendland C2, W = C (1-q)^4 (1+4q), C = 21 / (2 pi H^3) calibrated on
    /// the lattice (module doc).
    WendlandC2,
}

/// A kernel of support radius `support` (H). W is in 1/m^3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Kernel {
    /// The shape.
    pub shape: KernelShape,
    /// Support radius H, m.
    pub support: f32,
    inv_h: f32,
    /// Cubic spline: 8 / (pi H^3). Wendland: C over the lattice sum.
    k: f32,
    /// Cubic spline: 48 / (pi H^4). Wendland: 20 C / (H^2 m1), with m1 the
    /// uncalibrated gradient's first moment on the lattice.
    l: f32,
}

impl Kernel {
    /// The cubic spline of support radius `support` = H.
    pub fn new(support: f32) -> Self {
        Self::with_shape(KernelShape::CubicSpline, support)
    }

    /// A kernel of the given shape and support radius H (spacing H / 2).
    pub fn with_shape(shape: KernelShape, support: f32) -> Self {
        let h = support;
        match shape {
            KernelShape::CubicSpline => {
                Self { shape, support: h, inv_h: 1.0 / h, k: 8.0 / (PI * h * h * h), l: 48.0 / (PI * h * h * h * h) }
            }
            KernelShape::WendlandC2 => {
                let (sum, moment) = wendland_lattice_moments();
                let k = 21.0 / (2.0 * std::f64::consts::PI * f64::from(h).powi(3)) / sum;
                let l = 20.0 * k * sum / (f64::from(h) * f64::from(h) * moment);
                Self { shape, support: h, inv_h: 1.0 / h, k: k as f32, l: l as f32 }
            }
        }
    }

    /// W(r), with q = r / H; 0 beyond the support.
    #[inline(always)]
    pub fn w<R: Real>(&self, r: R) -> R {
        match self.shape {
            KernelShape::CubicSpline => self.cubic_spline_w(r),
            KernelShape::WendlandC2 => self.wendland_w(r),
        }
    }

    /// W'(r) / r, in 1/m^5, so that grad W_ij = (W'(r)/r) x_ij with
    /// x_ij = x_i - x_j (PHYSICS.md §0). Finite at r = 0, so a particle's
    /// own term contributes a zero gradient; 0 beyond the support.
    #[inline(always)]
    pub fn grad_over_r<R: Real>(&self, r: R) -> R {
        match self.shape {
            KernelShape::CubicSpline => self.cubic_spline_grad_over_r(r),
            KernelShape::WendlandC2 => self.wendland_grad_over_r(r),
        }
    }

    /// q = r / H and max(1 - q, 0).
    #[inline(always)]
    fn q<R: Real>(&self, r: R) -> (R, R) {
        let q = r * R::splat(self.inv_h);
        (q, (R::splat(1.0) - q).max(R::splat(0.0)))
    }

    /// [`Self::w`] of the cubic spline, for loops that dispatch on the shape
    /// once outside (the neighbour pass).
    #[inline(always)]
    pub fn cubic_spline_w<R: Real>(&self, r: R) -> R {
        let (q, om) = self.q(r);
        let inner = R::splat(self.k) * (R::splat(6.0) * q * q * (q - R::splat(1.0)) + R::splat(1.0));
        let outer = R::splat(2.0 * self.k) * om * om * om;
        q.select_le(R::splat(0.5), inner, outer)
    }

    /// [`Self::grad_over_r`] of the cubic spline: W'(r) = l q (3q - 2) for
    /// q <= 1/2, -l (1-q)^2 for q <= 1.
    #[inline(always)]
    pub fn cubic_spline_grad_over_r<R: Real>(&self, r: R) -> R {
        let (q, om) = self.q(r);
        // inner: l q (3q-2) / r = l (3q - 2) / H
        let inner = R::splat(self.l) * (R::splat(3.0) * q - R::splat(2.0)) * R::splat(self.inv_h);
        // outer: -l (1-q)^2 / r; r >= H/2 > 0 on this branch
        let outer = -R::splat(self.l) * om * om / r.max(R::splat(0.5 * self.support));
        q.select_le(R::splat(0.5), inner, outer)
    }

    /// [`Self::w`] of Wendland C2.
    #[inline(always)]
    pub fn wendland_w<R: Real>(&self, r: R) -> R {
        let (q, om) = self.q(r);
        let om2 = om * om;
        R::splat(self.k) * om2 * om2 * (R::splat(1.0) + R::splat(4.0) * q)
    }

    /// [`Self::grad_over_r`] of Wendland C2: -l (1-q)^3.
    #[inline(always)]
    pub fn wendland_grad_over_r<R: Real>(&self, r: R) -> R {
        let (_, om) = self.q(r);
        -R::splat(self.l) * om * om * om
    }

    /// W(0).
    pub fn w0(&self) -> f32 {
        self.k
    }

    /// 1 / H, 1/m.
    pub fn inv_support(&self) -> f32 {
        self.inv_h
    }

    /// The gradient's constant l, 1/m^4 (cubic spline: 48 / (pi H^4);
    /// Wendland C2: calibrated, see the field): what a copy of
    /// [`Self::grad_over_r`] elsewhere (the GPU's WGSL) needs besides the
    /// shape and H, so that it reads the constants from here.
    pub fn grad_scale(&self) -> f32 {
        self.l
    }

    /// d^3 sum_j W_ij for a particle i in the inner layer of a flat wall of
    /// two lattice layers (its own layer and the one behind it), spacing
    /// d = `h`. About 0.850 for the cubic spline with H = 2d.
    pub fn flat_wall_gamma(&self, h: f32) -> f32 {
        let mut s = 0.0f64;
        for c in [0i32, -1] {
            for a in -3i32..=3 {
                for b in -3i32..=3 {
                    let r = h * ((a * a + b * b + c * c) as f32).sqrt();
                    s += self.w(r) as f64;
                }
            }
        }
        (s * (h as f64).powi(3)) as f32
    }
}

/// Wendland C2 at H = 2 d on the cubic lattice of spacing d: d^3 sum_j W_ij
/// and -(1/3) sum_j d^3 x_ij . grad W_ij, both with C = 21 / (2 pi H^3).
fn wendland_lattice_moments() -> (f64, f64) {
    let (h, c) = (2.0f64, 21.0 / (2.0 * std::f64::consts::PI * 8.0));
    let (mut sum, mut moment) = (0.0, 0.0);
    for i in -2i32..=2 {
        for j in -2i32..=2 {
            for k in -2i32..=2 {
                let r = f64::from(i * i + j * j + k * k).sqrt();
                let q = r / h;
                if q < 1.0 {
                    sum += c * (1.0 - q).powi(4) * (1.0 + 4.0 * q);
                    // -(1/3) r W'(r), W'(r) = -20 C q (1-q)^3 / H
                    moment += r * 20.0 * c * q * (1.0 - q).powi(3) / h / 3.0;
                }
            }
        }
    }
    (sum, moment)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// d^3 sum W and the gradient's first moment over the start lattice of
    /// spacing d = H / 2 (reference: the continuum values 1 and 1 that the
    /// calibration restores for Wendland; the spline's are PHYSICS.md §1's).
    fn lattice(kernel: &Kernel) -> (f64, f64) {
        let d = f64::from(kernel.support) / 2.0;
        let (mut sum, mut moment) = (0.0, 0.0);
        for i in -3i32..=3 {
            for j in -3i32..=3 {
                for k in -3i32..=3 {
                    let r = (f64::from(i * i + j * j + k * k)).sqrt() * d;
                    sum += d.powi(3) * f64::from(kernel.w(r as f32));
                    moment -= d.powi(3) * r * r * f64::from(kernel.grad_over_r(r as f32)) / 3.0;
                }
            }
        }
        (sum, moment)
    }

    #[test]
    fn the_lattice_is_at_rest_density_and_its_gradient_is_consistent() {
        let (sum, moment) = lattice(&Kernel::with_shape(KernelShape::WendlandC2, 0.02));
        assert!((sum - 1.0).abs() < 1e-5 && (moment - 1.0).abs() < 1e-5, "Wendland: {sum} {moment}");
        let (sum, moment) = lattice(&Kernel::new(0.02));
        assert!((sum - 0.99997).abs() < 1e-4 && (moment - 1.020).abs() < 1e-3, "cubic spline: {sum} {moment}");
    }

    #[test]
    fn wendland_gradient_is_the_derivative_up_to_the_calibration() {
        // W'(r) by central differences against r grad_over_r(r) times the
        // two calibration factors' ratio, over the support.
        let kernel = Kernel::with_shape(KernelShape::WendlandC2, 1.0);
        let (sum, moment) = wendland_lattice_moments();
        for s in 1..20 {
            let r = s as f64 / 20.0;
            let e = 1e-3;
            let dw = (f64::from(kernel.w((r + e) as f32)) - f64::from(kernel.w((r - e) as f32))) / (2.0 * e);
            let g = r * f64::from(kernel.grad_over_r(r as f32)) * moment / sum;
            assert!((dw - g).abs() <= 2e-3 * kernel.w0() as f64, "r = {r}: W' {dw}, gradient {g}");
        }
    }
}
