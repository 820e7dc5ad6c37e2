//! Chebyshev semi-iteration over the relaxed Jacobi sweeps of the pressure
//! solve (pass 5, P-Eqs. 27-28; Golub and Varga 1961, the form Wang 2015
//! uses for position-based dynamics). Opt-in: `chebyshev_radius` of the
//! scene's `[simulation]`. The CPU loop (src/backend/cpu.rs) calls these
//! functions; the GPU loop (shaders/iisph.wgsl, `chebyshev_fluid`,
//! `chebyshev_walls` and the weight in `mean_error`) is their twin.
//!
//! Relaxed Jacobi is a fixed-point iteration p <- G p + c. Its slowest
//! modes are the smooth pressure fields of a deep pool: their factor per
//! sweep approaches 1 as the column gets deeper in particles, which is why
//! a 0.3 m column at d = 2.4 mm needs tens to hundreds of sweeps. The
//! semi-iteration combines the last two iterates,
//!
//! p_{k+1} = w_{k+1} (J(p_k) - p_{k-1}) + p_{k-1},
//! w_1 = 2 / (2 - rho^2), w_{k+1} = 4 / (4 - rho^2 w_k),
//!
//! (J one Jacobi sweep) so that after k sweeps the error of a mode with
//! factor lambda is T_k(lambda / rho) / T_k(1 / rho) times its start, T_k
//! the Chebyshev polynomial: every mode with |lambda| <= rho falls as
//! ((1 - sqrt(1 - rho^2)) / rho)^k (0.72 per sweep at rho = 0.95), and a
//! mode with rho < |lambda| < 1 still falls, faster than under plain
//! Jacobi. So a radius below the true one never diverges in the linear,
//! symmetric case; it only accelerates the slowest modes less. The solve's
//! two departures from that case: the bound p >= 0 (only rows positive in
//! the last two iterates are extrapolated, and p >= 0 after, as after
//! each plain sweep), and a solve whose error grows
//! (`iisph::Divergence`), which restarts as plain Jacobi.

use rayon::prelude::*;

/// Plain sweeps before the semi-iteration starts (it then takes one more
/// before its first extrapolation): the warm start's first two sweeps
/// remove its largest local errors. The CPU and GPU loops both use it.
pub const PLAIN_SWEEPS: u32 = 1;

/// The weights w_k of the semi-iteration for a spectral radius estimate
/// `rho`: 1 for the first `plain + 1` sweeps, then w_1, w_2, ...
#[derive(Clone, Copy, Debug)]
pub struct Weights {
    rho: f32,
    plain: u32,
    sweeps: u32,
    w: f32,
}

impl Weights {
    /// `rho` in (0, 1): the estimate of the plain iteration's spectral
    /// radius; `plain`: sweeps before the semi-iteration starts, from
    /// whose result it then takes one plain sweep and extrapolates from
    /// the next on (sweep `plain + 2`).
    pub fn new(rho: f32, plain: u32) -> Self {
        debug_assert!(rho > 0.0 && rho < 1.0);
        Self { rho, plain, sweeps: 0, w: 1.0 }
    }

    /// The weight of the sweep just done (1 during the plain sweeps).
    pub fn after_sweep(&mut self) -> f32 {
        self.sweeps += 1;
        let r2 = self.rho * self.rho;
        self.w = match self.sweeps.cmp(&(self.plain + 2)) {
            std::cmp::Ordering::Less => 1.0,
            std::cmp::Ordering::Equal => 2.0 / (2.0 - r2),
            std::cmp::Ordering::Greater => 4.0 / (4.0 - r2 * self.w),
        };
        self.w
    }
}

/// p <- max(0, w (p - prev) + prev) where the row's pressure was positive
/// in both earlier iterates; elsewhere p stays the plain sweep's. `p`
/// holds the plain sweep's result J(p_k), `cur` p_k and `prev` the
/// iterate before p_k. A row at the bound p = 0 (a free-surface particle
/// in expansion) is not a linear row there: extrapolating across the
/// bound would push on it with a pressure the linear recurrence made up.
/// Measured in `tests/hydrostatic.rs`'s column at radius 0.9: the same
/// sweeps (5,261 against 5,262 extrapolating every row), the deep mean
/// pressure's range over single steps -5.7 / +8.6 % against -7.2 / +8.7 %,
/// and 15.9 % per particle against 16.2 %.
pub fn extrapolate(w: f32, p: &mut [f32], cur: &[f32], prev: &[f32]) {
    if w == 1.0 {
        return;
    }
    p.par_iter_mut().zip(prev.par_iter().zip(cur.par_iter())).for_each(|(p, (&q, &c))| {
        if q > 0.0 && c > 0.0 {
            *p = (w * (*p - q) + q).max(0.0);
        }
    });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference: the Chebyshev recurrence's closed form. After k >= 1
    /// accelerated sweeps on a scalar mode lambda (p <- lambda p), the
    /// iterate is T_k(lambda / rho) / T_k(1 / rho) of the start; at
    /// lambda = rho it is 1 / T_k(1 / rho) (Golub and Varga 1961). The
    /// loop below is the solver's, on one unknown without the p >= 0
    /// bound (negative modes) and with it never active (positive start).
    fn run(lambda: f64, rho: f32, sweeps: u32) -> f64 {
        let mut wts = Weights::new(rho, 0);
        let (mut p, mut prev) = (1.0f32, 1.0f32);
        for _ in 0..sweeps {
            let w = wts.after_sweep();
            let cur = p;
            let jac = (lambda * f64::from(p)) as f32;
            p = if w == 1.0 { jac } else { w * (jac - prev) + prev };
            prev = cur;
        }
        f64::from(p)
    }

    /// T_k(x): cos(k acos x) inside [-1, 1], sign(x)^k cosh(k acosh |x|) outside.
    fn cheb_t(k: u32, x: f64) -> f64 {
        if x.abs() <= 1.0 {
            (f64::from(k) * x.acos()).cos()
        } else {
            x.signum().powi(k as i32) * (f64::from(k) * x.abs().acosh()).cosh()
        }
    }

    #[test]
    fn error_of_a_mode_is_the_chebyshev_polynomial() {
        let rho = 0.95f32;
        for &lambda in &[0.95, 0.5, 0.0, -0.7, -0.95, 0.99] {
            for k in [1, 2, 5, 10, 20] {
                let got = run(lambda, rho, k);
                let want = cheb_t(k, lambda / f64::from(rho)) / cheb_t(k, 1.0 / f64::from(rho));
                assert!((got - want).abs() < 1e-4, "lambda {lambda}, k {k}: {got} against {want}");
            }
        }
    }

    #[test]
    fn rows_at_the_bound_are_not_extrapolated() {
        // Row 0 positive in both iterates: extrapolated; row 1 was at 0
        // before: keeps the plain sweep's value; row 2 lands below 0: 0.
        let mut p = [2.0f32, 2.0, 1.0];
        extrapolate(1.5, &mut p, &[1.0, 1.0, 3.0], &[1.0, 0.0, 4.0]);
        assert_eq!(p, [2.5, 2.0, 0.0]);
    }

    #[test]
    fn slow_modes_fall_faster_than_plain_jacobi() {
        // lambda = 0.99, a deep pool's smooth mode: after 30 sweeps plain
        // Jacobi keeps 0.99^30 = 0.74 of it.
        let plain = 0.99f64.powi(30);
        let cheb = run(0.99, 0.95, 30).abs();
        assert!(cheb < 0.5 * plain, "{cheb} against {plain}");
        // And a mode at the radius falls as the theory's rate.
        let at = run(0.95, 0.95, 30).abs();
        let rate = (1.0 - (1.0 - 0.95f64 * 0.95).sqrt()) / 0.95;
        assert!(at <= 2.0 * rate.powi(30) * 1.01, "{at} against {}", rate.powi(30));
    }
}
