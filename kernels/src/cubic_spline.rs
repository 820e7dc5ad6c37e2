//! The cubic spline kernel (PHYSICS.md §1, the SPlisHSPlasH form) with support
//! radius H = 2 d, in scalar and SIMD form through [`Real`].

use crate::lanes::Real;
use std::f32::consts::PI;

/// Cubic spline of support radius `support` (H). W is in 1/m^3.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CubicSpline {
    /// Support radius H, m.
    pub support: f32,
    inv_h: f32,
    /// 8 / (pi H^3)
    k: f32,
    /// 48 / (pi H^4)
    l: f32,
}

impl CubicSpline {
    /// The kernel of support radius `support` = H.
    pub fn new(support: f32) -> Self {
        let h = support;
        Self { support: h, inv_h: 1.0 / h, k: 8.0 / (PI * h * h * h), l: 48.0 / (PI * h * h * h * h) }
    }

    /// W(r) = k (6q^3 - 6q^2 + 1) for q <= 1/2, 2k (1-q)^3 for q <= 1, 0
    /// beyond, with q = r / H.
    #[inline(always)]
    pub fn w<R: Real>(&self, r: R) -> R {
        let q = r * R::splat(self.inv_h);
        let one = R::splat(1.0);
        let inner = R::splat(self.k) * (R::splat(6.0) * q * q * (q - one) + one);
        let om = (one - q).max(R::splat(0.0));
        let outer = R::splat(2.0 * self.k) * om * om * om;
        q.select_le(R::splat(0.5), inner, outer)
    }

    /// W'(r) / r, in 1/m^5, so that grad W_ij = (W'(r)/r) x_ij with
    /// x_ij = x_i - x_j (PHYSICS.md §0). W'(r) = l q (3q - 2) for q <= 1/2,
    /// -l (1-q)^2 for q <= 1, 0 beyond. Finite at r = 0 (the limit of the
    /// inner branch), so a particle's own term contributes a zero gradient.
    #[inline(always)]
    pub fn grad_over_r<R: Real>(&self, r: R) -> R {
        let q = r * R::splat(self.inv_h);
        let one = R::splat(1.0);
        let ih = R::splat(self.inv_h);
        // inner: l q (3q-2) / r = l (3q - 2) / H
        let inner = R::splat(self.l) * (R::splat(3.0) * q - R::splat(2.0)) * ih;
        let om = (one - q).max(R::splat(0.0));
        // outer: -l (1-q)^2 / r; r >= H/2 > 0 on this branch
        let outer = -R::splat(self.l) * om * om / r.max(R::splat(0.5 * self.support));
        q.select_le(R::splat(0.5), inner, outer)
    }

    /// W(0) = k.
    pub fn w0(&self) -> f32 {
        self.k
    }
}
