//! The rigid motions of each free elastic body: the coarse space of the
//! elastic conjugate gradients' two-level preconditioner
//! ([`crate::elasticity::System`]).
//!
//! The implicit system (M + dt^2 K) v = b (PHYSICS.md §3.3) has K Phi = 0
//! for a rigid motion Phi of a body (translation; rotation about its centre
//! of mass to first order in the strain): the rigid motions are its
//! smallest eigenvectors, and a stiff body's (dt^2 K against M large) the
//! ones Jacobi-preconditioned CG finds last. A force on a few particles of
//! a stiff, light body moves it as a whole, but one CG iteration moves
//! only those particles: issue 34's placement 432 (a 120 kg/m^3 box, mu
//! 2.6e5 Pa, 87 times its mass in dt^2 k per particle at dt = 2 ms) took
//! 85 iterations to answer the ceiling's push, and the pressure solve's
//! sweeps, which see one iteration of the response each, balanced its rows
//! against accelerations 50 times too small.
//!
//! The preconditioner z = P r is the symmetric two-level one,
//! P = R + (I - R M) D (I - M R), with D the Jacobi preconditioner and
//! R = Phi (Phi^T M Phi)^-1 Phi^T the response of a rigid body of the same
//! mass and inertia: for body b, R r = t + w x (x_i - c_b) with
//! t = sum r_i / M_b and w = I_b^-1 sum (x_i - c_b) x r_i. P is symmetric
//! positive definite for any symmetric positive D, so CG converges to the
//! same solution; on a rigid motion P (M + dt^2 K) = I, so the first
//! iteration answers a force with the whole body's motion (the test
//! `two_level_cg_moves_a_stiff_light_body_as_a_whole`: 0.79 of the push's
//! momentum after one iteration, 0.002 with D alone).
//!
//! The pressure solve's rows around a body are then coupled through its
//! rigid motion, and their Jacobi diagonals must count it
//! ([`RigidModes::couple_mobility`]).
//!
//! A body with a fixed particle has no rigid motion (the clamp holds it),
//! and one of fewer than four particles or with a singular inertia is left
//! to D alone. Sums over a body are blocked f64 sums in index order, so the
//! result does not depend on the number of threads.

use crate::blocks::{nblocks, BLOCK};
use glam::{DMat3, DVec3, Vec3};
use rayon::prelude::*;

/// Not in a coarse body.
const NONE: u32 = u32::MAX;

/// The rigid motions of the free bodies at the current positions.
#[derive(Clone, Debug, Default)]
pub struct RigidModes {
    /// Coarse body of each particle, or [`NONE`].
    body: Vec<u32>,
    /// x_i - c_b, m.
    xi: Vec<Vec3>,
    /// The torque arm of a push along the surface normal, |(x_i - c_b) x n_i|
    /// (|x_i - c_b| where there is no normal), m.
    lever: Vec<f32>,
    /// 1 / M_b, 1/kg.
    inv_mass: Vec<f64>,
    /// I_b^-1 (about c_b), 1/(kg m^2).
    inv_inertia: Vec<DMat3>,
}

/// A block's sums: per coarse body present in it, (body, sum f, sum xi x f).
type Part = Vec<(u32, DVec3, DVec3)>;

/// Scratch of [`RigidModes::precondition`], kept by the caller across
/// calls so that the conjugate gradients' iterations allocate nothing.
#[derive(Clone, Debug, Default)]
pub struct CoarseScratch {
    /// Per block of particles, its bodies' sums.
    parts: Vec<Part>,
    /// Per coarse body, (sum f, sum xi x f).
    sums: Vec<(DVec3, DVec3)>,
    /// Per coarse body, the rigid response (t, w) to r and to M y.
    u: Vec<(Vec3, Vec3)>,
    my: Vec<(Vec3, Vec3)>,
}

impl CoarseScratch {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.parts.iter().map(|p| 56 * p.capacity()).sum::<usize>()
            + 24 * self.parts.capacity()
            + 48 * self.sums.capacity()
            + 24 * (self.u.capacity() + self.my.capacity())
    }
}

impl RigidModes {
    /// The coarse space of the groups `group` (an elastic body each; a
    /// granular particle a group of its own), `fixed`, masses `mass` (kg),
    /// positions `x` (m) and the direction `normal` of a push on each
    /// particle from outside its body (any length; 0 where unknown), all
    /// in store order.
    ///
    /// Where no body is free (every body clamped, as in the paper's
    /// Examples 1, 2 and 6), one pass over `fixed` and `group` and nothing
    /// is kept.
    pub fn update(&mut self, group: &[u32], fixed: &[u32], mass: &[f32], x: &[Vec3], normal: &[Vec3]) {
        let n = group.len();
        self.inv_mass.clear();
        self.inv_inertia.clear();
        self.body.clear();
        self.xi.clear();
        self.lever.clear();
        let groups = group.iter().map(|&g| g as usize + 1).max().unwrap_or(0);
        // Per group: particles, whether one is fixed, mass, first moment.
        let mut count = vec![0usize; groups];
        let mut clamped = vec![false; groups];
        for i in 0..n {
            let g = group[i] as usize;
            count[g] += 1;
            clamped[g] |= fixed[i] != 0;
        }
        let free = |g: usize| !clamped[g] && count[g] >= 4;
        if !(0..groups).any(free) {
            return;
        }
        let mut m = vec![0.0f64; groups];
        let mut mx = vec![DVec3::ZERO; groups];
        for i in 0..n {
            let g = group[i] as usize;
            if free(g) {
                m[g] += f64::from(mass[i]);
                mx[g] += f64::from(mass[i]) * x[i].as_dvec3();
            }
        }
        let centre: Vec<DVec3> = (0..groups).map(|g| if m[g] > 0.0 { mx[g] / m[g] } else { DVec3::ZERO }).collect();
        let mut inertia = vec![DMat3::ZERO; groups];
        for i in 0..n {
            let g = group[i] as usize;
            if !free(g) {
                continue;
            }
            let r = x[i].as_dvec3() - centre[g];
            inertia[g] += f64::from(mass[i]) * (DMat3::from_diagonal(DVec3::splat(r.dot(r))) - outer(r, r));
        }
        // The coarse bodies: free, at least four particles, an inertia
        // that is well conditioned enough to invert.
        let mut coarse = vec![NONE; groups];
        for g in 0..groups {
            let det = inertia[g].determinant();
            let scale = inertia[g].x_axis.x + inertia[g].y_axis.y + inertia[g].z_axis.z;
            let invertible = det.is_finite() && det > 1e-9 * scale.powi(3);
            if !free(g) || m[g] <= 0.0 || !invertible {
                continue;
            }
            coarse[g] = self.inv_mass.len() as u32;
            self.inv_mass.push(1.0 / m[g]);
            self.inv_inertia.push(inertia[g].inverse());
        }
        if self.is_empty() {
            return;
        }
        self.body.extend(group.iter().map(|&g| coarse[g as usize]));
        self.xi.extend((0..n).map(|i| {
            let g = group[i] as usize;
            if coarse[g] == NONE {
                Vec3::ZERO
            } else {
                (x[i].as_dvec3() - centre[g]).as_vec3()
            }
        }));
        self.lever.extend(self.xi.iter().zip(normal).map(|(xi, n)| match n.try_normalize() {
            Some(n) => xi.cross(n).length(),
            None => xi.length(),
        }));
    }

    /// Raises each particle's mobility `out` (1/kg, store order) to the
    /// body-wide share of it: the pressure solve's rows around a body are
    /// coupled through its rigid motion, one row's push moves every other
    /// row's particles. With `contact` (1 for a particle with a pair of the
    /// solve outside its body) the n_c contact particles of body b pushing
    /// together move particle i by at most
    /// kappa_i = n_c / M_b + |x_i - c_b| sum_contact |(x_j - c_b) x n_j| |I_b^-1|
    /// per newton on each along its normal n_j (|I_b^-1| its largest row
    /// sum, a bound of its largest eigenvalue), a bound of the row sum of
    /// the coupling. out_i = max(out_i, kappa_i / 2): relaxed Jacobi at
    /// omega = 1/2 converges where the eigenvalues of D^-1 A lie in (0, 4),
    /// and with the diagonal at least half the coupling they are at most
    /// 1 + 2 (Gershgorin). A Jacobi diagonal
    /// from the particle's own mobility alone is, for a stiff light body,
    /// n_c times too small (the placement of issue 34 with its top layer
    /// of 30 particles against the ceiling: the sweeps alternated between
    /// 8.5e4 Pa and 0 on its rows).
    ///
    /// Nothing to do where [`RigidModes::is_empty`].
    pub fn couple_mobility(&self, contact: &[u32], out: &mut [f32]) {
        if self.is_empty() {
            return;
        }
        let k = self.inv_mass.len();
        let (mut count, mut arm) = (vec![0.0f64; k], vec![0.0f64; k]);
        for (i, &b) in self.body.iter().enumerate() {
            if b != NONE && contact[i] != 0 {
                count[b as usize] += 1.0;
                arm[b as usize] += f64::from(self.lever[i]);
            }
        }
        let norm: Vec<f64> = self
            .inv_inertia
            .iter()
            .map(|m| {
                let t = m.transpose();
                [t.x_axis, t.y_axis, t.z_axis].iter().map(|r| r.abs().element_sum()).fold(0.0, f64::max)
            })
            .collect();
        out.par_iter_mut().enumerate().for_each(|(i, c)| {
            let b = self.body[i];
            if b == NONE {
                return;
            }
            let b = b as usize;
            let kappa = count[b] * self.inv_mass[b] + f64::from(self.xi[i].length()) * arm[b] * norm[b];
            *c = c.max((0.5 * kappa) as f32);
        });
    }

    /// Whether there is a coarse body (else the preconditioner is D alone).
    pub fn is_empty(&self) -> bool {
        self.inv_mass.is_empty()
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * self.body.capacity()
            + 12 * self.xi.capacity()
            + 4 * self.lever.capacity()
            + 8 * self.inv_mass.capacity()
            + 72 * self.inv_inertia.capacity()
    }

    /// The rigid response (t_b, w_b) of each coarse body to the particle
    /// forces `f(i)`, Phi (Phi^T M Phi)^-1 Phi^T f, into `out`.
    fn response(
        &self,
        parts: &mut Vec<Part>,
        sums: &mut Vec<(DVec3, DVec3)>,
        out: &mut Vec<(Vec3, Vec3)>,
        n: usize,
        f: impl Fn(usize) -> Vec3 + Sync,
    ) {
        let (body, xi) = (&self.body, &self.xi);
        parts.resize_with(nblocks(n), Vec::new);
        parts.par_iter_mut().enumerate().for_each(|(b, part)| {
            part.clear();
            for i in b * BLOCK..((b + 1) * BLOCK).min(n) {
                let k = body[i];
                if k == NONE {
                    continue;
                }
                let fi = f(i).as_dvec3();
                let t = xi[i].as_dvec3().cross(fi);
                match part.last_mut() {
                    Some(last) if last.0 == k => {
                        last.1 += fi;
                        last.2 += t;
                    }
                    _ => part.push((k, fi, t)),
                }
            }
        });
        sums.clear();
        sums.resize(self.inv_mass.len(), (DVec3::ZERO, DVec3::ZERO));
        for part in parts.iter() {
            for &(k, f, t) in part {
                sums[k as usize].0 += f;
                sums[k as usize].1 += t;
            }
        }
        out.clear();
        out.extend(
            sums.iter()
                .enumerate()
                .map(|(k, &(f, t))| ((f * self.inv_mass[k]).as_vec3(), (self.inv_inertia[k] * t).as_vec3())),
        );
    }

    /// z = P r = R r + (I - R M) D (I - M R) r, with D = diag(`jacobi`)
    /// (1/kg) and `mass` M; z_i = 0 where `fixed`.
    pub fn precondition(
        &self,
        scratch: &mut CoarseScratch,
        r: &[Vec3],
        jacobi: &[f32],
        mass: &[f32],
        fixed: &[u32],
        z: &mut [Vec3],
    ) {
        let n = r.len();
        let CoarseScratch { parts, sums, u, my } = scratch;
        self.response(parts, sums, u, n, |i| r[i]);
        let u = &*u;
        let (body, xi) = (&self.body, &self.xi);
        let rigid = |resp: &[(Vec3, Vec3)], i: usize| {
            let k = body[i];
            if k == NONE {
                Vec3::ZERO
            } else {
                let (t, w) = resp[k as usize];
                t + w.cross(xi[i])
            }
        };
        // z = u + y with y = D (r - M u), then z -= R (M y).
        z.par_iter_mut().enumerate().for_each(|(i, z)| {
            let ui = rigid(u, i);
            *z = ui + jacobi[i] * (r[i] - mass[i] * ui);
        });
        let zr = &*z;
        self.response(parts, sums, my, n, |i| mass[i] * (zr[i] - rigid(u, i)));
        let my = &*my;
        let (body, xi) = (&self.body, &self.xi);
        z.par_iter_mut().enumerate().for_each(|(i, z)| {
            let k = body[i];
            if fixed[i] != 0 {
                *z = Vec3::ZERO;
            } else if k != NONE {
                let (t, w) = my[k as usize];
                *z -= t + w.cross(xi[i]);
            }
        });
    }
}

fn outer(a: DVec3, b: DVec3) -> DMat3 {
    DMat3::from_cols(a * b.x, a * b.y, a * b.z)
}
