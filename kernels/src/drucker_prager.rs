//! Granular solids (issue 18): the Drucker-Prager yield surface with its
//! tension cut-off, and the return mapping of an elastic trial stress onto
//! it, for one stress point. The SPH continuum that calls it (current
//! neighbours, the stress rate) is built on top of this.
//!
//! Conventions: Cauchy stress, tension positive, Pa; I1 = tr(sigma),
//! s = sigma - I1/3 I the deviator, J2 = s:s / 2.
//!
//! The surface (Bui et al. 2008, "Lagrangian meshfree particles method
//! (SPH) for large deformation and failure flows of geomaterial using
//! elastic-plastic soil constitutive model", Int. J. Numer. Anal. Meth.
//! Geomech. 32, Eqs. 18-22):
//!
//!   f(sigma) = alpha_phi I1 + sqrt(J2) - k_c <= 0,
//!
//! with phi the friction angle, c the cohesion and the plastic potential
//! g = alpha_psi I1 + sqrt(J2) of the dilatancy angle psi (psi = 0: no
//! plastic volume change, Bui's choice for sand; psi = phi: associated
//! flow). Perfect plasticity (no hardening). A cone meets the Mohr-Coulomb
//! pyramid only along some stress paths, so it is fitted to one:
//!
//! - [`DruckerPrager::compression_cone`], through the compression meridian
//!   (triaxial compression fails at the Mohr-Coulomb value):
//!   alpha_phi = 2 sin(phi) / (sqrt(3) (3 - sin(phi))),
//!   k_c = 6 c cos(phi) / (sqrt(3) (3 - sin(phi))), alpha_psi alike.
//! - [`DruckerPrager::plane_strain_cone`]: plastic flow in plane strain
//!   (no strain along one axis) fails at the Mohr-Coulomb value, as in Bui
//!   et al.'s Eqs. 21-22, here for any dilatancy. With
//!   alpha_psi = tan(psi) / sqrt(9 + 12 tan^2(psi)) and
//!   r = sqrt(1 - 3 alpha_psi^2): zero plastic strain out of the plane sets
//!   the out-of-plane deviator to s_zz = -2 alpha_psi sqrt(J2), hence
//!   sqrt(J2) = tau / r and I1 = 3 s_c - 3 alpha_psi tau / r for the Mohr
//!   circle of centre s_c and radius tau; f = 0 is then tau + s_c sin(phi)
//!   = c cos(phi) (Mohr-Coulomb) for
//!   alpha_phi = sin(phi) / (3 (r + alpha_psi sin(phi))),
//!   k_c = c cos(phi) (1 - 3 alpha_phi alpha_psi) / r.
//!   For psi = phi this is Bui's tan(phi) / sqrt(9 + 12 tan^2(phi)) and
//!   3 c / sqrt(9 + 12 tan^2(phi)); for psi = 0, sin(phi) / 3 and c cos(phi).
//!   At phi = 30 degrees its alpha_phi is 0.167 against the compression
//!   cone's 0.231, and in plane-strain compression at 100 kPa the
//!   compression cone flows at 1.84 times the Mohr-Coulomb axial stress
//!   (the test below).
//!
//! The return mapping (closed-form for this cone; e.g. de Souza Neto,
//! Peric and Owen 2008, "Computational Methods for Plasticity", §8.3.3,
//! in their notation eta = 3 alpha): with the elastic shear modulus G and
//! bulk modulus K, the plastic multiplier of a trial state with f > 0 is
//!
//!   d_lambda = f(trial) / (G + 9 K alpha_phi alpha_psi),
//!
//! the deviator shrinks radially, sqrt(J2) = sqrt(J2_trial) - G d_lambda,
//! and I1 = I1_trial - 9 K alpha_psi d_lambda. Where that would make
//! sqrt(J2) negative the state returns to the apex of the cone, s = 0 and
//! I1 = k_c / alpha_phi: the tension cut-off (Bui's "tension cracking"),
//! which for cohesionless sand is no tension at all.
//!
//! The stress of a granular particle evolves by the Jaumann rate (Bui et
//! al. 2008, Eqs. 11-13; objective under rotation), explicit in time, then
//! the return ([`DruckerPrager::stress_step`]): with the velocity gradient
//! L (L_ab = d v_a / d x_b), D = (L + L^T)/2 and W = (L - L^T)/2,
//!
//!   sigma_trial = sigma + dt (2 G dev(D) + K tr(D) I + W sigma - sigma W).

use glam::{Mat3, Vec3};

/// a I.
fn iso(a: f32) -> Mat3 {
    Mat3::from_diagonal(Vec3::splat(a))
}

/// The Drucker-Prager cone of a granular material, fitted to Mohr-Coulomb
/// along one stress path (module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DruckerPrager {
    /// alpha_phi (dimensionless).
    pub alpha_phi: f32,
    /// alpha_psi of the plastic potential (dimensionless).
    pub alpha_psi: f32,
    /// k_c, Pa.
    pub k_c: f32,
}

/// The cone's slope coefficient 2 sin(a) / (sqrt(3) (3 - sin(a))).
fn cone_alpha(angle: f64) -> f64 {
    2.0 * angle.sin() / (3f64.sqrt() * (3.0 - angle.sin()))
}

/// What [`DruckerPrager::return_map`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Yield {
    /// The trial state was inside the cone (f <= 0) and is kept.
    Elastic,
    /// Returned onto the cone's surface.
    Surface,
    /// Returned to the apex (the tension cut-off).
    Apex,
}

impl DruckerPrager {
    /// The cone of friction angle `phi`, dilatancy angle `psi` (radians,
    /// 0 <= psi <= phi < pi/2) and cohesion `c` (Pa, >= 0).
    pub fn compression_cone(phi: f32, psi: f32, c: f32) -> Self {
        let (phi, psi, c) = (f64::from(phi), f64::from(psi), f64::from(c));
        Self {
            alpha_phi: cone_alpha(phi) as f32,
            alpha_psi: cone_alpha(psi) as f32,
            k_c: (6.0 * c * phi.cos() / (3f64.sqrt() * (3.0 - phi.sin()))) as f32,
        }
    }

    /// The cone that fails at the Mohr-Coulomb value in plane-strain flow
    /// (module doc), for friction angle `phi`, dilatancy angle `psi`
    /// (radians, 0 <= psi <= phi < pi/2) and cohesion `c` (Pa, >= 0).
    pub fn plane_strain_cone(phi: f32, psi: f32, c: f32) -> Self {
        let (phi, psi, c) = (f64::from(phi), f64::from(psi), f64::from(c));
        let t = psi.tan();
        let a_psi = t / (9.0 + 12.0 * t * t).sqrt();
        let r = (1.0 - 3.0 * a_psi * a_psi).sqrt();
        let a_phi = phi.sin() / (3.0 * (r + a_psi * phi.sin()));
        Self {
            alpha_phi: a_phi as f32,
            alpha_psi: a_psi as f32,
            k_c: (c * phi.cos() * (1.0 - 3.0 * a_phi * a_psi) / r) as f32,
        }
    }

    /// f(sigma) = alpha_phi I1 + sqrt(J2) - k_c, Pa (> 0: outside the cone).
    pub fn yield_function(&self, sigma: Mat3) -> f32 {
        let (i1, _, sqrt_j2) = invariants(sigma);
        self.alpha_phi * i1 + sqrt_j2 - self.k_c
    }

    /// The mean stress I1/3 of the apex, the largest a state can carry, Pa
    /// (infinite for a cone of zero friction, which has no apex).
    pub fn apex_mean_stress(&self) -> f32 {
        if self.alpha_phi > 0.0 {
            self.k_c / (3.0 * self.alpha_phi)
        } else {
            f32::INFINITY
        }
    }

    /// Returns the elastic `trial` stress (symmetric, Pa) onto the cone for
    /// an elastic material of shear modulus `mu` and bulk modulus `bulk`
    /// (Pa), with the plastic multiplier d_lambda (0 when elastic).
    pub fn return_map(&self, trial: Mat3, mu: f32, bulk: f32) -> (Mat3, f32, Yield) {
        let f = self.yield_function(trial);
        if f <= 0.0 {
            return (trial, 0.0, Yield::Elastic);
        }
        let (i1, s, sqrt_j2) = invariants(trial);
        // f64 for the scalar algebra: sqrt(J2) - G d_lambda cancels near
        // the apex.
        let (mu, bulk) = (f64::from(mu), f64::from(bulk));
        let (a_phi, a_psi) = (f64::from(self.alpha_phi), f64::from(self.alpha_psi));
        let d_lambda = f64::from(f) / (mu + 9.0 * bulk * a_phi * a_psi);
        let sqrt_j2_new = f64::from(sqrt_j2) - mu * d_lambda;
        if sqrt_j2_new > 0.0 {
            let i1_new = f64::from(i1) - 9.0 * bulk * a_psi * d_lambda;
            let scale = (sqrt_j2_new / f64::from(sqrt_j2)) as f32;
            let sigma = s * scale + iso((i1_new / 3.0) as f32);
            (sigma, d_lambda as f32, Yield::Surface)
        } else {
            let p = self.apex_mean_stress();
            (iso(p), d_lambda as f32, Yield::Apex)
        }
    }

    /// One explicit step `dt` of the stress `sigma` (Pa) of a particle whose
    /// velocity gradient is `grad_v` (L_ab = d v_a / d x_b, 1/s): the
    /// Jaumann-rate elastic trial (module doc), symmetrised against
    /// round-off, returned onto the cone.
    pub fn stress_step(&self, sigma: Mat3, grad_v: Mat3, dt: f32, mu: f32, bulk: f32) -> (Mat3, f32, Yield) {
        let d = 0.5 * (grad_v + grad_v.transpose());
        let w = 0.5 * (grad_v - grad_v.transpose());
        let tr = d.x_axis.x + d.y_axis.y + d.z_axis.z;
        let dev = d - iso(tr / 3.0);
        let rate = 2.0 * mu * dev + iso(bulk * tr) + w * sigma - sigma * w;
        let trial = sigma + dt * rate;
        self.return_map(0.5 * (trial + trial.transpose()), mu, bulk)
    }
}

/// (I1, the deviator s, sqrt(J2)) of a symmetric stress.
fn invariants(sigma: Mat3) -> (f32, Mat3, f32) {
    let i1 = sigma.x_axis.x + sigma.y_axis.y + sigma.z_axis.z;
    let s = sigma - iso(i1 / 3.0);
    let ss = s.x_axis.length_squared() + s.y_axis.length_squared() + s.z_axis.length_squared();
    (i1, s, (0.5 * ss).sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    const DEG: f32 = std::f32::consts::PI / 180.0;

    #[test]
    fn inside_the_cone_is_kept() {
        let dp = DruckerPrager::compression_cone(30.0 * DEG, 0.0, 0.0);
        let sigma = Mat3::from_diagonal(Vec3::new(-1.5e5, -1.0e5, -1.0e5));
        assert!(dp.yield_function(sigma) < 0.0);
        assert_eq!(dp.return_map(sigma, 1e6, 2e6), (sigma, 0.0, Yield::Elastic));
    }

    #[test]
    fn tension_returns_to_the_apex() {
        // Cohesionless: the apex is at zero stress.
        let dp = DruckerPrager::compression_cone(30.0 * DEG, 0.0, 0.0);
        let (sigma, _, y) = dp.return_map(Mat3::from_diagonal(Vec3::new(1e3, -2e2, 5e2)), 1e6, 2e6);
        assert_eq!(y, Yield::Apex);
        assert_eq!(sigma, Mat3::ZERO);
        // With cohesion c the apex carries k_c / alpha_phi in I1.
        let dp = DruckerPrager::compression_cone(30.0 * DEG, 0.0, 1e4);
        let (sigma, _, y) = dp.return_map(Mat3::from_diagonal(Vec3::splat(1e5)), 1e6, 2e6);
        assert_eq!(y, Yield::Apex);
        let p = dp.apex_mean_stress();
        assert!((sigma.x_axis.x - p).abs() <= 1e-6 * p && dp.yield_function(sigma).abs() <= 1e-6 * dp.k_c);
    }

    #[test]
    fn a_returned_state_is_on_the_surface_and_stays_there() {
        let dp = DruckerPrager::compression_cone(35.0 * DEG, 10.0 * DEG, 5e3);
        let mut trial =
            Mat3::from_cols(Vec3::new(-4e5, 6e4, -2e4), Vec3::new(6e4, -1e5, 3e4), Vec3::new(-2e4, 3e4, -5e4));
        trial = 0.5 * (trial + trial.transpose());
        let (sigma, d_lambda, y) = dp.return_map(trial, 4e6, 6e6);
        assert_eq!(y, Yield::Surface);
        assert!(d_lambda > 0.0);
        let scale = trial.x_axis.x.abs();
        assert!(dp.yield_function(sigma).abs() <= 1e-6 * scale, "f = {}", dp.yield_function(sigma));
        let (again, _, _) = dp.return_map(sigma, 4e6, 6e6);
        assert!((again - sigma).abs_diff_eq(Mat3::ZERO, 1e-6 * scale));
        // The deviator keeps its direction (radial return).
        let (_, s0, r0) = invariants(trial);
        let (_, s1, r1) = invariants(sigma);
        assert!((s0 / r0 - s1 / r1).abs_diff_eq(Mat3::ZERO, 1e-6));
    }

    /// A rigid rotation leaves the stress co-rotating, sigma(t) = R sigma_0
    /// R^T (the Jaumann rate's objectivity), for a state inside the cone.
    /// Reference: the rotated tensor. Explicit Euler grows the rotating part
    /// by (1 + (Omega dt)^2)^(N/2) - 1 ~ N (Omega dt)^2 / 2 = 7.7e-6 here
    /// (45 degrees in 40,000 steps; 45, not 90: a diagonal stress turned
    /// by +-90 degrees is the same tensor, so the sense would not show),
    /// so the bound is 1e-4 of |sigma_0|.
    #[test]
    fn a_rigid_rotation_rotates_the_stress() {
        let dp = DruckerPrager::compression_cone(30.0 * DEG, 0.0, 0.0);
        let sigma0 = Mat3::from_diagonal(Vec3::new(-1.2e5, -1.0e5, -0.9e5));
        assert!(dp.yield_function(sigma0) < 0.0);
        let omega = 2.0f32; // rad/s about z
        let grad_v = Mat3::from_cols(Vec3::new(0.0, omega, 0.0), Vec3::new(-omega, 0.0, 0.0), Vec3::ZERO);
        let (n, angle) = (40_000, std::f32::consts::FRAC_PI_4);
        let dt = angle / omega / n as f32;
        let mut sigma = sigma0;
        for _ in 0..n {
            let (s, _, y) = dp.stress_step(sigma, grad_v, dt, 3.85e6, 8.3e6);
            assert_eq!(y, Yield::Elastic);
            sigma = s;
        }
        let r = Mat3::from_rotation_z(angle);
        let expect = r * sigma0 * r.transpose();
        let err = (sigma - expect).to_cols_array().iter().fold(0.0f32, |m, x| m.max(x.abs()));
        assert!(err <= 1e-4 * 1.2e5, "largest component off by {err} Pa: {sigma:?} vs {expect:?}");
    }

    /// Simple shear (v_x = gamma_dot y) from an isotropic confinement: the
    /// shear stress rises at G gamma_dot and then holds on the cone, where
    /// sqrt(J2) = k_c - alpha_phi I1 with I1 unchanged for psi = 0
    /// (reference: the cone's equation). Within 1e-5 of sqrt(J2).
    #[test]
    fn simple_shear_holds_on_the_cone() {
        let dp = DruckerPrager::compression_cone(30.0 * DEG, 0.0, 2e3);
        let (mu, bulk) = (3.85e6f32, 8.3e6f32);
        let gamma_dot = 1.0f32;
        let grad_v = Mat3::from_cols(Vec3::ZERO, Vec3::new(gamma_dot, 0.0, 0.0), Vec3::ZERO);
        let mut sigma = Mat3::from_diagonal(Vec3::splat(-5e4));
        let dt = 1e-5;
        let (mut first_plastic, mut tau_elastic) = (None, 0.0);
        for k in 0..3000 {
            let (s, _, y) = dp.stress_step(sigma, grad_v, dt, mu, bulk);
            if y == Yield::Elastic {
                tau_elastic = s.y_axis.x;
            } else if first_plastic.is_none() {
                first_plastic = Some(k);
            }
            sigma = s;
        }
        let k0 = first_plastic.expect("the shear must reach the cone");
        // Elastic branch: tau = G gamma_dot t (the Jaumann terms are second
        // order in the small shear strain).
        let tau_hooke = mu * gamma_dot * dt * k0 as f32;
        assert!((tau_elastic - tau_hooke).abs() <= 1e-3 * tau_hooke, "{tau_elastic} vs {tau_hooke}");
        let (i1, _, sqrt_j2) = invariants(sigma);
        assert!((i1 + 1.5e5).abs() <= 1e-5 * 1.5e5, "I1 {i1}");
        let expect = dp.k_c - dp.alpha_phi * i1;
        assert!((sqrt_j2 - expect).abs() <= 1e-5 * expect, "sqrt(J2) {sqrt_j2} vs {expect}");
    }

    /// Triaxial compression, strain-driven in the axial direction with the
    /// lateral stress held at the confining stress: the axial stress rises
    /// elastically and fails at the Mohr-Coulomb compression value,
    /// sigma_1 = N sigma_3 + 2 c sqrt(N), N = (1 + sin phi) / (1 - sin phi)
    /// (compressions as magnitudes), which the compression cone matches by
    /// construction. The stress-point test: 100 kPa confinement,
    /// phi = 30 degrees; within 1e-4 relative; every returned state on the
    /// surface.
    #[test]
    fn triaxial_compression_fails_at_the_mohr_coulomb_value() {
        for (c, psi) in [(0.0f32, 0.0f32), (1e4, 0.0), (0.0, 30.0 * DEG), (1e4, 10.0 * DEG)] {
            let phi = 30.0 * DEG;
            let dp = DruckerPrager::compression_cone(phi, psi, c);
            let (mu, lambda) = (3.85e6f32, 5.77e6f32); // E = 10 MPa, nu = 0.3
            let bulk = lambda + 2.0 * mu / 3.0;
            let confining = 1e5f32;
            let n = (1.0 + phi.sin()) / (1.0 - phi.sin());
            let sigma1_ref = n * confining + 2.0 * c * n.sqrt();
            // Hooke's law for a diagonal strain increment.
            let hooke = |e: Vec3| Vec3::splat(lambda * (e.x + e.y + e.z)) + 2.0 * mu * e;
            let mut sigma = Vec3::splat(-confining);
            let mut peak = 0.0f32;
            let mut plastic = 0;
            for _ in 0..400 {
                let d_axial = -2e-4f32;
                // The lateral strain increment that keeps the lateral stress
                // at -confining after the return (secant iteration).
                let lateral_stress = |e_lat: f32| {
                    let trial = sigma + hooke(Vec3::new(d_axial, e_lat, e_lat));
                    let (s, _, y) = dp.return_map(Mat3::from_diagonal(trial), mu, bulk);
                    (s.y_axis.y + confining, s, y)
                };
                let (mut x0, mut x1) = (0.0f32, -d_axial * lambda / (2.0 * (lambda + mu)));
                let (mut g0, _, _) = lateral_stress(x0);
                let mut out = lateral_stress(x1);
                for _ in 0..50 {
                    if out.0.abs() <= 1e-6 * confining || out.0 == g0 {
                        break;
                    }
                    let x2 = x1 - out.0 * (x1 - x0) / (out.0 - g0);
                    (x0, g0, x1) = (x1, out.0, x2);
                    out = lateral_stress(x1);
                }
                let (res, s, y) = out;
                assert!(res.abs() <= 1e-5 * confining, "lateral stress off by {res} Pa");
                if y != Yield::Elastic {
                    plastic += 1;
                    assert!(dp.yield_function(s).abs() <= 2e-6 * sigma1_ref, "f = {}", dp.yield_function(s));
                }
                sigma = Vec3::new(s.x_axis.x, s.y_axis.y, s.z_axis.z);
                peak = peak.max(-sigma.x);
            }
            assert!(plastic > 100, "the test must reach the yield surface ({plastic} plastic increments)");
            let rel = (peak - sigma1_ref).abs() / sigma1_ref;
            assert!(rel <= 1e-4, "c {c} psi {psi}: sigma_1 at failure {peak} Pa vs {sigma1_ref} Pa ({rel:.2e})");
            assert!((-sigma.x - sigma1_ref).abs() <= 1e-4 * sigma1_ref, "perfect plasticity: a plateau");
        }
    }

    /// Plane-strain compression (a biaxial test), strain-driven along x with
    /// the stress along y held at the confining stress and no strain along
    /// z: once the flow is steady (the out-of-plane stress has settled) the
    /// axial stress is the Mohr-Coulomb value sigma_1 = N sigma_3 + 2 c
    /// sqrt(N), N = (1 + sin phi) / (1 - sin phi), which the plane-strain
    /// cone matches for any dilatancy (module doc). Reference: Mohr-Coulomb;
    /// within 1e-4 relative (f32 stress increments); the compression cone
    /// on the same path fails well above it.
    #[test]
    fn plane_strain_compression_flows_at_the_mohr_coulomb_value() {
        let phi = 30.0 * DEG;
        for (c, psi) in [(0.0f32, 0.0f32), (1e4, 0.0), (0.0, 30.0 * DEG), (1e4, 10.0 * DEG)] {
            let (mu, lambda) = (3.85e6f32, 5.77e6f32);
            let bulk = lambda + 2.0 * mu / 3.0;
            let confining = 1e5f32;
            let n = (1.0 + phi.sin()) / (1.0 - phi.sin());
            let sigma1_ref = n * confining + 2.0 * c * n.sqrt();
            let hooke = |e: Vec3| Vec3::splat(lambda * (e.x + e.y + e.z)) + 2.0 * mu * e;
            let axial = |dp: DruckerPrager| {
                let mut sigma = Vec3::splat(-confining);
                for _ in 0..3000 {
                    let d_axial = -1e-4f32;
                    let lateral_stress = |e_lat: f32| {
                        let trial = sigma + hooke(Vec3::new(d_axial, e_lat, 0.0));
                        let (s, _, _) = dp.return_map(Mat3::from_diagonal(trial), mu, bulk);
                        (s.y_axis.y + confining, s)
                    };
                    let (mut x0, mut x1) = (0.0f32, -d_axial * lambda / (lambda + 2.0 * mu));
                    let (mut g0, _) = lateral_stress(x0);
                    let mut out = lateral_stress(x1);
                    for _ in 0..50 {
                        if out.0.abs() <= 1e-6 * confining || out.0 == g0 {
                            break;
                        }
                        let x2 = x1 - out.0 * (x1 - x0) / (out.0 - g0);
                        (x0, g0, x1) = (x1, out.0, x2);
                        out = lateral_stress(x1);
                    }
                    assert!(out.0.abs() <= 1e-5 * confining, "lateral stress off by {} Pa", out.0);
                    sigma = Vec3::new(out.1.x_axis.x, out.1.y_axis.y, out.1.z_axis.z);
                }
                -sigma.x
            };
            let got = axial(DruckerPrager::plane_strain_cone(phi, psi, c));
            let rel = (got - sigma1_ref).abs() / sigma1_ref;
            assert!(rel <= 1e-4, "c {c} psi {psi}: sigma_1 {got} Pa vs Mohr-Coulomb {sigma1_ref} Pa ({rel:.2e})");
            let stronger = axial(DruckerPrager::compression_cone(phi, psi, c)) / sigma1_ref;
            assert!(stronger > 1.2, "the compression cone in plane strain: {stronger} x Mohr-Coulomb");
        }
    }

    /// For associated flow the plane-strain cone is Bui et al.'s Eqs. 21-22.
    #[test]
    fn associated_plane_strain_cone_is_buis() {
        let (phi, c) = (30.0 * DEG, 1e4f32);
        let dp = DruckerPrager::plane_strain_cone(phi, phi, c);
        let q = (9.0 + 12.0 * phi.tan().powi(2)).sqrt();
        assert!((dp.alpha_phi - phi.tan() / q).abs() <= 1e-6, "{} vs {}", dp.alpha_phi, phi.tan() / q);
        assert!((dp.k_c - 3.0 * c / q).abs() <= 1e-6 * c, "{} vs {}", dp.k_c, 3.0 * c / q);
        let dp = DruckerPrager::plane_strain_cone(phi, 0.0, c);
        assert!((dp.alpha_phi - phi.sin() / 3.0).abs() <= 1e-7 && (dp.k_c - c * phi.cos()).abs() <= 1e-6 * c);
    }
}
