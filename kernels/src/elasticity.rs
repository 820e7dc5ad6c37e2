//! Elastic solids: implicit corotated SPH elasticity of Peer et al. 2018
//! (PHYSICS.md §3.1-3.3, the paper's P-Eqs. 4-5), pass 8 of PHYSICS.md §6.
//!
//! Notation: solid particle i, its rest neighbours j in SS0 (same body,
//! within the support H in the rest configuration, fixed at t = 0), rest
//! positions x0, rest volumes V_i0, the gradient correction L_i, the
//! rotation R_i, RL_i = R_i L_i. Every pair stores w_ij = V_j0 grad W_ij0
//! (grad W_ij0 = grad_i W(x_i0 - x_j0), pointing from i towards j,
//! PHYSICS.md §0), at 16 bits ([`RestState::quantize`]). With T_i = P_i RL_i, Peer's force
//! f_i = sum_j V_i0 V_j0 (P_i RL_i grad W_ij0 - P_j RL_j grad W_ji0)
//! becomes the gather f_i = V_i0 sum_j (T_i + T_j) w_ij.
//!
//! Every loop is a gather over particles in store order; the dot products
//! of the conjugate gradients are blocked f64 sums
//! ([`crate::blocks::sum_f64`]), so results do not depend on the number of
//! threads. Scalar code: solids are few next to fluid particles, and a 3x3
//! matrix per particle does not fit the SIMD pair layout of the fluid.

use crate::blocks::{combine, max_f32, nblocks, sum_f64, BLOCK};
use crate::kernel::Kernel;
use crate::rest_lattice::{LatticeScratch, RestLattice};
use crate::rigid_modes::{CoarseScratch, RigidModes};
use glam::{Mat3, Mat3A, Quat, Vec3, Vec3A};
use rayon::prelude::*;
use std::collections::HashMap;

/// Lamé parameters of a solid material, Pa. `mu` is the shear modulus, the
/// paper's "nu" (PHYSICS.md §8.6).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lame {
    pub mu: f32,
    pub lambda: f32,
}

/// The rest-configuration data of all solid particles (PHYSICS.md §3.1),
/// computed once from the rest positions.
#[derive(Clone, Debug, Default)]
pub struct RestState {
    /// SS0 as CSR: the neighbours of particle i are `start[i]..start[i+1]`.
    pub start: Vec<u32>,
    /// Neighbour index j of each pair (ascending per particle, self
    /// excluded), each below `n` ([`RestState::j`]; private so that the
    /// product's unchecked gathers stay in bounds).
    j: Vec<u32>,
    /// The number of particles the pairs were built for.
    n: usize,
    /// w_ij = V_j0 grad W_ij0 of each pair, 1/m, at 16 bits
    /// ([`RestState::quantize`]): three i16 a pair, V_i0 w_ij in multiples
    /// of `w_scale`, and four zeros after the last pair (the product loads
    /// 8 bytes a pair).
    wq: Vec<i16>,
    /// The unit U of V_i0 w_ij, one for all pairs: w_ij = q_ij U / V_i0.
    w_scale: f32,
    /// Rest positions x_i0, m ([`RestState::dx0`] of a pair: one position
    /// a particle instead of a difference a pair).
    x0: Vec<Vec3>,
    /// Rest volume V_i0 = m_i / (m_i W(0) + sum_j m_j W_ij0), m^3.
    pub volume: Vec<f32>,
    /// Gradient correction L_i (PHYSICS.md §3.1).
    pub correction: Vec<Mat3>,
    /// sum_j (x_j0 - x_i0) (x) w_ij: the rest part of [`deform`]'s sum
    /// (the transpose of L_i^-1 where L_i is not the identity's fallback).
    xw: Vec<Mat3>,
    /// s_i = sum_j w_ij, 1/m: the own-stress term T_i s_i of the force.
    pub wsum: Vec<Vec3>,
    /// sum_j |w_ij|^2, 1/m^2: the stiffness of [`System::inverse_diagonal`],
    /// the same every step.
    w2: Vec<f32>,
    /// The pairs as lattice stencils, for [`System::apply`] (`None` where
    /// a body is not on a lattice: the product gathers over the pairs).
    lattice: Option<RestLattice>,
}

impl RestState {
    /// Number of particles.
    pub fn len(&self) -> usize {
        self.volume.len()
    }

    /// Whether there are no particles.
    pub fn is_empty(&self) -> bool {
        self.volume.is_empty()
    }

    /// Neighbour index j of each pair (ascending per particle, self excluded).
    pub fn j(&self) -> &[u32] {
        &self.j
    }

    /// w_ij of pair p of particle i, 1/m (its 16-bit form: every sum over
    /// the pairs, the corrections and sums at rest included, uses these
    /// values).
    #[inline]
    pub fn w(&self, i: usize, p: usize) -> Vec3 {
        self.w_steps(p) * self.w_unit(i)
    }

    /// The unit of particle i's w_ij, U / V_i0.
    #[inline(always)]
    fn w_unit(&self, i: usize) -> f32 {
        self.w_scale / self.volume[i]
    }

    /// The unit U of the stored integers (w_ij = q_ij U / V_i0).
    pub(crate) fn w_scale(&self) -> f32 {
        self.w_scale
    }

    /// V_i0 w_ij of pair p in units of `w_scale` (exact integers).
    #[inline(always)]
    fn w_steps(&self, p: usize) -> Vec3 {
        let q = &self.wq[3 * p..3 * p + 3];
        Vec3::new(f32::from(q[0]), f32::from(q[1]), f32::from(q[2]))
    }

    /// V_i0 w_ij of pair p in units of `w_scale`, as stored.
    #[inline]
    pub(crate) fn w_integers(&self, p: usize) -> [i16; 3] {
        [self.wq[3 * p], self.wq[3 * p + 1], self.wq[3 * p + 2]]
    }

    /// The rest positions x_i0, m.
    pub(crate) fn x0(&self) -> &[Vec3] {
        &self.x0
    }

    /// Whether [`System::apply`] runs on the lattice stencils
    /// ([`crate::rest_lattice`]).
    pub fn has_lattice(&self) -> bool {
        self.lattice.is_some()
    }

    /// The lattice stencils, if the bodies are on a lattice.
    pub fn lattice(&self) -> Option<&RestLattice> {
        self.lattice.as_ref()
    }

    /// The same rest state without the lattice stencils: its product
    /// gathers over the pair list (for tests and benchmarks that compare
    /// the two).
    pub fn without_lattice(mut self) -> RestState {
        self.lattice = None;
        self
    }

    /// x_j0 - x_i0 of pair p of particle i, m.
    #[inline]
    pub fn dx0(&self, i: usize, p: usize) -> Vec3 {
        self.x0[self.j[p] as usize] - self.x0[i]
    }

    /// The pair range of particle i.
    #[inline]
    pub fn range(&self, i: usize) -> std::ops::Range<usize> {
        self.start[i] as usize..self.start[i + 1] as usize
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        4 * (self.start.capacity() + self.j.capacity() + self.volume.capacity())
            + 2 * self.wq.capacity()
            + 12 * (self.x0.capacity() + self.wsum.capacity())
            + 4 * self.w2.capacity()
            + 36 * (self.correction.capacity() + self.xw.capacity())
            + self.lattice.as_ref().map_or(0, RestLattice::bytes)
    }

    /// SS0, rest volumes and corrections (PHYSICS.md §3.1) of particles at
    /// rest positions `x0` with bodies `body` and masses `mass`. Pairs
    /// within a body closer than the support H, less those at H to rounding
    /// (`retain_contributing_pairs` below; the rest volumes sum over
    /// all of them); a deterministic cell grid (neighbours sorted by index).
    pub fn new(x0: &[Vec3], body: &[u32], mass: &[f32], kernel: &Kernel) -> RestState {
        let n = x0.len();
        let h = kernel.support;
        let cell =
            |p: Vec3| -> [i32; 3] { [(p.x / h).floor() as i32, (p.y / h).floor() as i32, (p.z / h).floor() as i32] };
        let mut grid: HashMap<[i32; 3], Vec<u32>> = HashMap::new();
        for (i, &p) in x0.iter().enumerate() {
            grid.entry(cell(p)).or_default().push(i as u32);
        }
        let neighbors: Vec<Vec<u32>> = (0..n)
            .into_par_iter()
            .map(|i| {
                let c = cell(x0[i]);
                let mut out = Vec::new();
                for dz in -1..=1 {
                    for dy in -1..=1 {
                        for dx in -1..=1 {
                            if let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                                for &j in list {
                                    let j_us = j as usize;
                                    if j_us != i && body[j_us] == body[i] && (x0[j_us] - x0[i]).length() < h {
                                        out.push(j);
                                    }
                                }
                            }
                        }
                    }
                }
                out.sort_unstable();
                out
            })
            .collect();
        let mut start = Vec::with_capacity(n + 1);
        start.push(0u32);
        let mut j = Vec::new();
        for list in &neighbors {
            j.extend_from_slice(list);
            start.push(j.len() as u32);
        }
        let mut rest = RestState {
            start,
            j,
            n,
            wq: Vec::new(),
            w_scale: 1.0,
            x0: x0.to_vec(),
            volume: vec![0.0; n],
            correction: vec![Mat3::IDENTITY; n],
            xw: Vec::new(),
            wsum: Vec::new(),
            w2: Vec::new(),
            lattice: None,
        };
        // V_i0 = m_i / (m_i W(0) + sum_j m_j W_ij0).
        let volume: Vec<f32> = (0..n)
            .into_par_iter()
            .map(|i| {
                let s: f32 = rest
                    .range(i)
                    .map(|p| mass[rest.j[p] as usize] * kernel.w((x0[i] - x0[rest.j[p] as usize]).length()))
                    .sum();
                mass[i] / (mass[i] * kernel.w0() + s)
            })
            .collect();
        // grad W_ij0 of each pair (w_ij = V_j0 grad W_ij0).
        let g: Vec<Vec3> = (0..rest.j.len())
            .into_par_iter()
            .map(|p| {
                let i = rest.start.partition_point(|&s| s as usize <= p) - 1;
                let jj = rest.j[p] as usize;
                let xij = x0[i] - x0[jj];
                kernel.grad_over_r(xij.length()) * xij
            })
            .collect();
        let g = rest.retain_contributing_pairs(g, &volume);
        rest.quantize(&g, &volume);
        rest.volume = volume;
        // L_i = (sum_j V_j0 grad W_ij0 (x) (x_j0 - x_i0))^-1, identity where
        // the sum is (nearly) singular: a particle with too few neighbours;
        // the sum's transpose is `xw`.
        let (correction, xw): (Vec<Mat3>, Vec<Mat3>) = (0..n)
            .into_par_iter()
            .map(|i| {
                let m = rest.range(i).fold(Mat3::ZERO, |m, p| m + outer(rest.w(i, p), rest.dx0(i, p)));
                let l = if m.determinant().abs() > 1e-9 { m.inverse() } else { Mat3::IDENTITY };
                (l, m.transpose())
            })
            .unzip();
        rest.correction = correction;
        rest.xw = xw;
        rest.wsum = (0..n).map(|i| rest.range(i).map(|p| rest.w(i, p)).sum()).collect();
        rest.w2 = (0..n).into_par_iter().map(|i| rest.range(i).map(|p| rest.w(i, p).length_squared()).sum()).collect();
        rest.lattice = RestLattice::new(&rest, body);
        rest
    }

    /// Stores `w` (one per pair) at 16 bits. What is rounded is the pair's
    /// term of the force, V_i0 w_ij = V_i0 V_j0 grad W_ij0, which is
    /// antisymmetric (the product V_i0 V_j0 is the same both ways, grad
    /// W_ji0 = -grad W_ij0 exactly): q_ij = V_i0 w_ij / U rounded to the
    /// nearest integer (half away from zero), with one unit U = max |V_i0
    /// w_ij component| / 32767 for all pairs, so q_ji = -q_ij exactly and
    /// the elastic forces f_i = V_i0 sum_j (T_i + T_j) w_ij stay pairwise
    /// opposite, as with f32 (a unit per particle broke that at 1e-5: the
    /// cantilever's sum of forces went from 3e-8 to 1.4e-6 of sum |f|).
    /// Then w_ij = q_ij U / V_i0 (`w_scale` is U). A component's error is at
    /// most U / 2, 1.5e-5 of the largest term; a lattice's opposite
    /// neighbours of equal volume stay exactly opposite, so sum_j w_ij of
    /// its interior is 0 to the rounding of the sum, as before. The
    /// product reads 6 bytes of w a pair instead of 12 (bench/RESULTS.md).
    fn quantize(&mut self, g: &[Vec3], volume: &[f32]) {
        let n = self.start.len() - 1;
        // V_i0 V_j0 grad W_ij0: the product of the volumes is the same
        // both ways, and grad W_ji0 = -grad W_ij0 bit for bit.
        let term = |i: usize, p: usize| (volume[i] * volume[self.j[p] as usize]) * g[p];
        let largest = (0..n)
            .into_par_iter()
            .map(|i| self.range(i).map(|p| term(i, p).abs().max_element()).fold(0.0f32, f32::max))
            .reduce(|| 0.0, f32::max);
        let unit = if largest > 0.0 { largest / 32767.0 } else { 1.0 };
        self.w_scale = unit;
        let inv = 1.0 / unit;
        let mut wq = Vec::with_capacity(3 * g.len() + 4);
        for i in 0..n {
            for p in self.range(i) {
                let s = term(i, p) * inv;
                // Within +-32767 (the largest is 32767 to rounding).
                wq.extend([s.x, s.y, s.z].map(|c| c.round().clamp(-32767.0, 32767.0) as i16));
            }
        }
        wq.extend([0; 4]);
        self.wq = wq;
    }

    /// Drops the pairs at the support's edge to rounding: a lattice puts
    /// neighbours at r = H exactly, and where the rounding of x_j0 - x_i0
    /// makes r a few ulps short of H the pair passes `r < H` with a
    /// gradient of order (1 - q)^2, about 1e-14 of the particle's largest
    /// (Example 1's block at d = 2.4 mm: 580,600 of 4,455,936 rest pairs
    /// below 1e-9 of their particle's largest |w|, none between 1e-9 and
    /// 1e-2). Such a pair changes no sum it enters beyond f32 rounding,
    /// yet costs the elastic product as much as any other; kept are the
    /// pairs with |w_ij| above f32's epsilon times particle i's largest.
    /// Returns the gradients of the pairs kept (`g`: grad W_ij0 of every
    /// pair before; `volume`: V_j0, with which w_ij = V_j0 grad W_ij0).
    fn retain_contributing_pairs(&mut self, mut g: Vec<Vec3>, volume: &[f32]) -> Vec<Vec3> {
        let n = self.start.len() - 1;
        let w = |j: &[u32], g: &[Vec3], p: usize| volume[j[p] as usize] * g[p];
        let mut to = 0;
        for i in 0..n {
            let r = self.range(i);
            let largest = r.clone().map(|p| w(&self.j, &g, p).length()).fold(0.0f32, f32::max);
            self.start[i] = to as u32;
            for p in r {
                if w(&self.j, &g, p).length() > f32::EPSILON * largest {
                    (self.j[to], g[to]) = (self.j[p], g[p]);
                    to += 1;
                }
            }
        }
        self.start[n] = to as u32;
        self.j.truncate(to);
        g.truncate(to);
        self.j.shrink_to_fit();
        g
    }
}

/// The outer product a (x) b (matrix with entries a_r b_c).
#[inline(always)]
pub fn outer(a: Vec3, b: Vec3) -> Mat3 {
    Mat3::from_cols(a * b.x, a * b.y, a * b.z)
}

/// The rotation of `a` by the method of Müller et al. 2016 (PHYSICS.md §3.2),
/// warm-started from `q`, at most `iterations` times:
/// omega = sum_c (R_c x A_c) / (|sum_c R_c . A_c| + 1e-9), R <- rot(omega) R
/// (a turn about omega by 2 atan(|omega| / 2), below), stopping once
/// |omega| is below 1e-7 rad (f32 resolution).
pub fn extract_rotation(a: &Mat3, mut q: Quat, iterations: u32) -> Quat {
    for _ in 0..iterations {
        let r = Mat3::from_quat(q);
        let num = r.x_axis.cross(a.x_axis) + r.y_axis.cross(a.y_axis) + r.z_axis.cross(a.z_axis);
        let den = (r.x_axis.dot(a.x_axis) + r.y_axis.dot(a.y_axis) + r.z_axis.dot(a.z_axis)).abs() + 1e-9;
        let omega = num / den;
        let angle = omega.length();
        if angle.is_nan() || angle <= 1e-7 {
            break;
        }
        // The update rotation as the normalised quaternion (omega / 2, 1),
        // a turn by 2 atan(|omega| / 2) about omega: the axis-angle
        // rotation to second order and the same fixed point (omega = 0),
        // without its sine and cosine (with them `deform` took 23.5 against
        // 20.0 ms a step at the paper's size, bench/RESULTS.md).
        let h = 0.5 * omega;
        q = (Quat::from_xyzw(h.x, h.y, h.z, 1.0) * q).normalize();
    }
    q
}

/// Linear-elastic stress of a strain, P-Eq. 5 without the pore term:
/// P = 2 mu eps + lambda tr(eps) I.
#[inline(always)]
pub fn stress(eps: &Mat3, m: Lame) -> Mat3 {
    *eps * (2.0 * m.mu) + Mat3::from_diagonal(Vec3::splat(m.lambda * trace(eps)))
}

/// The trace of a matrix.
#[inline(always)]
pub fn trace(m: &Mat3) -> f32 {
    m.x_axis.x + m.y_axis.y + m.z_axis.z
}

/// The symmetric part (m + m^T) / 2.
#[inline(always)]
pub fn sym(m: &Mat3) -> Mat3 {
    (*m + m.transpose()) * 0.5
}

/// The von Mises equivalent of a stress, Pa.
pub fn von_mises(s: &Mat3) -> f32 {
    let (xx, yy, zz) = (s.x_axis.x, s.y_axis.y, s.z_axis.z);
    let (xy, yz, zx) =
        (0.5 * (s.y_axis.x + s.x_axis.y), 0.5 * (s.z_axis.y + s.y_axis.z), 0.5 * (s.x_axis.z + s.z_axis.x));
    (0.5 * ((xx - yy).powi(2) + (yy - zz).powi(2) + (zz - xx).powi(2)) + 3.0 * (xy * xy + yz * yz + zx * zx)).sqrt()
}

/// Most iterations of the rotation extraction per particle and step
/// (PHYSICS.md §3.2 suggests 10 with a warm start; the loop stops as soon
/// as it has converged).
pub const ROTATION_ITERATIONS: u32 = 100;

/// The per-step state of the solids after [`deform`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Deformation {
    /// RL_i = R_i L_i.
    pub rl: Mat3,
    /// The corotated strain eps_i = sym(F_i) - I (P-Eq. 4, PHYSICS.md §8.6).
    pub strain: Mat3,
}

/// Steps 1-5 of PHYSICS.md §3.2 for every particle: F~_i, the rotation R_i
/// (warm-started from and written back to `rot`), RL_i, the corotated
/// deformation gradient F_i = I + sum_j ((x_j - x_i) - R_i (x_j0 - x_i0))
/// (x) RL_i grad W_ij0 V_j0, and the strain eps_i = sym(F_i) - I.
pub fn deform(rest: &RestState, x: &[Vec3], rot: &mut [Quat], out: &mut [Deformation]) {
    rot.par_chunks_mut(BLOCK).zip(out.par_chunks_mut(BLOCK)).enumerate().for_each(|(b, (rot, out))| {
        for (q, (r, o)) in rot.iter_mut().zip(out.iter_mut()).enumerate() {
            let i = b * BLOCK + q;
            let mut s1 = Mat3::ZERO;
            for p in rest.range(i) {
                s1 += outer(x[rest.j[p] as usize] - x[i], rest.w_steps(p));
            }
            let s1 = s1 * rest.w_unit(i);
            let l = rest.correction[i];
            let f_tilde = s1 * l.transpose();
            // Warm-started from the last step's rotation, this converges
            // in a few iterations; a large rotation within one step (a
            // rigidly rotated initial state) takes more.
            *r = extract_rotation(&f_tilde, *r, ROTATION_ITERATIONS);
            let rm = Mat3::from_quat(*r);
            let rl = rm * l;
            // sum_j (x_ij - R X_ij) (x) w_ij = s1 - R sum_j X_ij (x) w_ij,
            // the second sum kept at rest: one pass over the pairs, not two.
            let a = s1 - rm * rest.xw[i];
            let f = Mat3::IDENTITY + a * rl.transpose();
            *o = Deformation { rl, strain: sym(&f) - Mat3::IDENTITY };
        }
    });
}

/// T_i = P_i RL_i of every particle, with P_i = stress(eps_i) - eta p_pore I
/// (P-Eq. 5; `pore` gives eta p^pore_i, or `None` without pore pressure).
pub fn stress_rl(def: &[Deformation], lame: &[Lame], pore: Option<&[f32]>, t: &mut [Mat3], vm: &mut [f32]) {
    t.par_iter_mut().zip(vm.par_iter_mut()).enumerate().for_each(|(i, (t, vm))| {
        let mut p = stress(&def[i].strain, lame[i]);
        if let Some(pore) = pore {
            p -= Mat3::from_diagonal(Vec3::splat(pore[i]));
        }
        *vm = von_mises(&p);
        *t = p * def[i].rl;
    });
}

/// Elastic forces f_i = V_i0 sum_j (T_i + T_j) w_ij (PHYSICS.md §3.2 step 6).
pub fn forces(rest: &RestState, t: &[Mat3], f: &mut [Vec3]) {
    f.par_iter_mut().enumerate().for_each(|(i, f)| {
        let ti = t[i];
        let mut acc = Vec3::ZERO;
        for p in rest.range(i) {
            acc += (ti + t[rest.j[p] as usize]) * rest.w_steps(p);
        }
        // V_i0 w_ij = q_ij U: the pair terms exactly opposite but for the sum.
        *f = rest.w_scale * acc;
    });
}

/// The implicit system of PHYSICS.md §3.3 in mass-weighted (symmetric) form:
/// (M A v)_i = m_i v_i - dt f^(v)_i, with f^ the elastic force of the strain
/// increment eps^_i = dt sym(sum_j V_j0 (v_j - v_i) (x) RL_i grad W_ij0).
/// Rows of fixed particles are the identity (m_i v_i).
pub struct System<'a> {
    pub rest: &'a RestState,
    pub def: &'a [Deformation],
    pub lame: &'a [Lame],
    pub mass: &'a [f32],
    /// 1 for particles whose velocity is prescribed.
    pub fixed: &'a [u32],
    pub dt: f32,
    /// The Jacobi preconditioner of CG, 1 / diag(M A) per particle
    /// ([`System::inverse_diagonal`]); `None`: plain CG.
    pub jacobi: Option<&'a [f32]>,
    /// With `jacobi`: the free bodies' rigid motions, the coarse space of a
    /// two-level preconditioner ([`crate::rigid_modes`]); `None`: Jacobi
    /// alone.
    pub coarse: Option<&'a RigidModes>,
}

impl System<'_> {
    /// The diagonal of M A for a particle moved alone, as an inverse
    /// (rest lattice, no rotation, isotropic average of the direction):
    /// out_i = 1 / (m_i + dt^2 k_i), k_i = V_i0 sum_j |w_ij|^2 (4 mu +
    /// lambda) / 3. The Jacobi preconditioner of CG and the pressure
    /// solve's mobility of a particle.
    pub fn inverse_diagonal(&self, out: &mut Vec<f32>) {
        let dt2 = self.dt * self.dt;
        out.resize(self.mass.len(), 0.0);
        out.par_iter_mut().enumerate().for_each(|(i, c)| {
            let Lame { mu, lambda } = self.lame[i];
            let k = self.rest.volume[i] * self.rest.w2[i] * (4.0 * mu + lambda) / 3.0;
            *c = 1.0 / (self.mass[i] + dt2 * k);
        });
    }

    /// out = (M A) v; `scratch` holds T^_i = P^_i RL_i and v in 16-byte
    /// lanes.
    ///
    /// This product is most of an elastic body's cost: the CG of the
    /// prediction and the bodies' response in every Jacobi sweep call it.
    /// Its two gathers over the rest pairs run on glam's 16-byte SIMD types
    /// (`Vec3A`, `Mat3A`: one SSE operation a column; w_ij read at 16 bits
    /// and its unit applied once a particle) with fused
    /// multiply-adds into two sets of accumulators ([`rest_sum`]); the
    /// force's own-stress term is T^_i s_i with s_i = sum_j w_ij kept at
    /// rest, so the second gather reads T^_j only. It is the scalar
    /// `Vec3`/`Mat3` form's product to rounding
    /// (`simd_apply_is_the_scalar_apply_to_rounding`).
    pub fn apply(&self, v: &[Vec3], scratch: &mut ProductScratch, out: &mut [Vec3]) {
        if let Some(lattice) = &self.rest.lattice {
            return lattice.apply(self, v, &mut scratch.lattice, out);
        }
        let (rest, dt) = (self.rest, self.dt);
        let n = v.len();
        scratch.t.resize(n, Mat3A::ZERO);
        scratch.v.resize(n, Vec3A::ZERO);
        let ProductScratch { t, v: va, .. } = scratch;
        // v in 16-byte lanes: one load a pair in the gather below.
        va.par_iter_mut().zip(v.par_iter()).for_each(|(a, v)| *a = Vec3A::from(*v));
        let va = &va[..];
        t.par_iter_mut().enumerate().for_each(|(i, t)| {
            let vi = va[i];
            // G = sum_j (v_j - v_i) (x) w_ij, column c the sum of d w_c.
            let [g0, g1, g2] = rest_sum(rest, i, va, |vj| {
                let d = *vj - vi;
                [d, d, d]
            });
            let rl = Mat3A::from(self.def[i].rl);
            // eps^ = dt sym(G RL^T), T^ = (2 mu eps^ + lambda tr(eps^) I) RL.
            let a = Mat3A::from_cols(g0, g1, g2) * rl.transpose();
            let eps = (a + a.transpose()) * (0.5 * dt);
            let Lame { mu, lambda } = self.lame[i];
            let tr = lambda * (eps.x_axis.x + eps.y_axis.y + eps.z_axis.z);
            *t = (eps * (2.0 * mu) + Mat3A::from_diagonal(Vec3::splat(tr))) * rl;
        });
        let t = &t[..];
        out.par_iter_mut().enumerate().for_each(|(i, o)| {
            if self.fixed[i] != 0 {
                *o = self.mass[i] * v[i];
                return;
            }
            // f^_i / V_i0 = T^_i s_i + sum_j T^_j w_ij.
            let [a, b, c] = rest_sum(rest, i, t, |tj| [tj.x_axis, tj.y_axis, tj.z_axis]);
            let acc = t[i] * Vec3A::from(rest.wsum[i]) + (a + b + c);
            *o = self.mass[i] * v[i] - dt * rest.volume[i] * Vec3::from(acc);
        });
    }
}

/// The product's per-particle scratch ([`System::apply`]), kept across
/// calls for its capacity.
#[derive(Clone, Debug, Default)]
pub struct ProductScratch {
    t: Vec<Mat3A>,
    v: Vec<Vec3A>,
    lattice: LatticeScratch,
}

impl ProductScratch {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        48 * self.t.capacity() + 16 * self.v.capacity() + self.lattice.bytes()
    }
}

/// sum_j (x_0(s_j) w_ij.x, x_1(s_j) w_ij.y, x_2(s_j) w_ij.z) over the rest
/// pairs of particle i, s_j = `src[j]`: two pairs a round into their own
/// accumulators, so the fused multiply-adds of one pair do not wait on the
/// last pair's. The gathers `src[j]` are unchecked (a bounds check a pair
/// was a tenth of the product, bench/RESULTS.md): every j is below
/// `rest.n` (built so by [`RestState::new`], private), checked against
/// `src.len()` once a particle.
#[inline(always)]
fn rest_sum<S>(rest: &RestState, i: usize, src: &[S], x: impl Fn(&S) -> [Vec3A; 3]) -> [Vec3A; 3] {
    assert!(src.len() >= rest.n, "rest_sum: {} values for {} particles", src.len(), rest.n);
    // SAFETY: j < rest.n <= src.len() for every j of `rest.j` (above).
    let at = |j: u32| x(unsafe { src.get_unchecked(j as usize) });
    let r = rest.range(i);
    let js = &rest.j[r.clone()];
    // Pair k's w in units of w_unit(i); 8 bytes a pair from 3k (the last
    // pair's read ends in the four zeros after the pairs).
    let wq = &rest.wq[3 * r.start..3 * r.end + 4];
    let w_at = |k: usize| -> Vec3A {
        #[cfg(all(target_arch = "x86_64", target_feature = "sse4.1"))]
        {
            use std::arch::x86_64::{__m128i, _mm_cvtepi16_epi32, _mm_cvtepi32_ps, _mm_loadl_epi64};
            let q = &wq[3 * k..3 * k + 4];
            // SAFETY: the load reads the 4 i16 (8 bytes) of `q`.
            Vec3A::from(unsafe { _mm_cvtepi32_ps(_mm_cvtepi16_epi32(_mm_loadl_epi64(q.as_ptr() as *const __m128i))) })
        }
        #[cfg(not(all(target_arch = "x86_64", target_feature = "sse4.1")))]
        {
            Vec3A::new(f32::from(wq[3 * k]), f32::from(wq[3 * k + 1]), f32::from(wq[3 * k + 2]))
        }
    };
    let add = |c: &mut [Vec3A], x: [Vec3A; 3], w: Vec3A| {
        c[0] = madd(x[0], Vec3A::splat(w.x), c[0]);
        c[1] = madd(x[1], Vec3A::splat(w.y), c[1]);
        c[2] = madd(x[2], Vec3A::splat(w.z), c[2]);
    };
    let mut c = [Vec3A::ZERO; 6];
    let m = js.len();
    let mut k = 0;
    while k + 2 <= m {
        let (a, b) = c.split_at_mut(3);
        add(a, at(js[k]), w_at(k));
        add(b, at(js[k + 1]), w_at(k + 1));
        k += 2;
    }
    if k < m {
        add(&mut c[..3], at(js[k]), w_at(k));
    }
    let u = Vec3A::splat(rest.w_unit(i));
    [(c[0] + c[3]) * u, (c[1] + c[4]) * u, (c[2] + c[5]) * u]
}

/// a b + c, one fused multiply-add a lane where the CPU has FMA (the
/// `target-cpu=native` build on any AVX2 machine), else a product and a sum.
#[inline(always)]
fn madd(a: Vec3A, b: Vec3A, c: Vec3A) -> Vec3A {
    #[cfg(target_feature = "fma")]
    {
        a.mul_add(b, c)
    }
    #[cfg(not(target_feature = "fma"))]
    {
        a * b + c
    }
}

/// Buffers of the conjugate gradients, kept across steps.
#[derive(Clone, Debug, Default)]
pub struct CgBuffers {
    r: Vec<Vec3>,
    p: Vec<Vec3>,
    ap: Vec<Vec3>,
    /// P r with the two-level preconditioner.
    z: Vec<Vec3>,
    prod: ProductScratch,
    parts: Vec<f64>,
    coarse: CoarseScratch,
}

impl CgBuffers {
    /// Bytes held.
    pub fn bytes(&self) -> usize {
        12 * (self.r.capacity() + self.p.capacity() + self.ap.capacity() + self.z.capacity())
            + self.coarse.bytes()
            + self.prod.bytes()
            + 8 * self.parts.capacity()
    }
}

/// What a conjugate-gradient solve did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CgStats {
    pub iterations: u32,
    /// |r| / |b| at the end.
    pub residual: f32,
}

/// Solves (M A) v = rhs by conjugate gradients, with the Jacobi
/// preconditioner `sys.jacobi` where there is one ([SPH] uses none; on
/// Example 1 it takes 9-13 % fewer iterations, bench/RESULTS.md),
/// filtered so that fixed particles keep the velocity `v` holds on entry
/// (their residual and search direction are 0). `v` is the warm start on
/// entry and the solution on exit. Stops at |r| <= tol |rhs| or after
/// `max_iterations`.
///
/// The system is solved scaled by a power of two, [`rhs_scale`], that
/// brings the largest component of the free particles' `rhs` into [1, 2):
/// in f32 the products of p.Ap lie near |rhs|^2 m, which for the tiny
/// forces of a nearly dry body's first wet step (|F| = 1.6e-18 N on a
/// 0.5 g particle, issue 34) are below f32's smallest normal number
/// (1.2e-38): the subnormals lost the conjugacy at the second iteration
/// and CG diverged to infinity. Scaling by 2^k is exact in floating point,
/// so for every rhs that does not underflow or overflow the iterates are
/// bit for bit those of the unscaled solve.
pub fn conjugate_gradients(
    sys: &System,
    rhs: &[Vec3],
    v: &mut [Vec3],
    tol: f32,
    max_iterations: u32,
    buf: &mut CgBuffers,
) -> CgStats {
    cg(sys, rhs, None, v, tol, max_iterations, buf, None)
}

/// What a solve leaves for the next solve of the same system
/// ([`conjugate_gradients_from`]): its answer v and the product
/// (M A) v that CG's recurrence implies for it, rhs - r at the end.
#[derive(Clone, Debug, Default)]
pub struct CarriedResidual {
    valid: bool,
    v: Vec<Vec3>,
    av: Vec<Vec3>,
}

impl CarriedResidual {
    /// Drops what is kept (the system changed): the next solve computes
    /// its residual.
    pub fn forget(&mut self) {
        self.valid = false;
    }

    /// The product (M A) v that the last solve's recurrence implies for its
    /// answer v (rhs - its residual); `None` if it kept none (forgotten, or
    /// nothing drove the solve: v = 0 exactly).
    pub fn product(&self) -> Option<&[Vec3]> {
        self.valid.then_some(&self.av[..])
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        12 * (self.v.capacity() + self.av.capacity())
    }
}

/// [`conjugate_gradients`] for a sequence of solves of one system with
/// changing right-hand sides, each warm-started from the last answer (the
/// bodies' response in the pressure solve's sweeps): where `v` on entry is
/// bit for bit the answer `carry` kept, the start residual is
/// r = rhs - (M A) v with the product the last solve's recurrence ended
/// with, which saves the product that starts a solve, one of the three of
/// a two-iteration solve. The recurrence's rounding accumulates over the
/// sweeps; the caller forgets the carry (and so starts from the true
/// residual) for a solve whose accuracy it needs.
#[allow(clippy::too_many_arguments)]
pub fn conjugate_gradients_from(
    sys: &System,
    rhs: &[Vec3],
    v: &mut [Vec3],
    tol: f32,
    max_iterations: u32,
    buf: &mut CgBuffers,
    carry: &mut CarriedResidual,
) -> CgStats {
    cg(sys, rhs, None, v, tol, max_iterations, buf, Some(carry))
}

/// [`conjugate_gradients_from`] with the tolerance relative to the norm of
/// the vector `reference(i)` where that is larger than the right-hand
/// side's: the solve of a correction to another solve's answer, whose
/// residual counts against that solve's right-hand side (the step's last
/// response, which also solves what the prediction left: `reference` = b /
/// dt + F).
#[allow(clippy::too_many_arguments)]
pub fn conjugate_gradients_relative_to(
    sys: &System,
    rhs: &[Vec3],
    reference: &(dyn Fn(usize) -> Vec3 + Sync),
    v: &mut [Vec3],
    tol: f32,
    max_iterations: u32,
    buf: &mut CgBuffers,
    carry: &mut CarriedResidual,
) -> CgStats {
    cg(sys, rhs, Some(reference), v, tol, max_iterations, buf, Some(carry))
}

#[allow(clippy::too_many_arguments)]
fn cg(
    sys: &System,
    rhs: &[Vec3],
    reference: Option<&(dyn Fn(usize) -> Vec3 + Sync)>,
    v: &mut [Vec3],
    tol: f32,
    max_iterations: u32,
    buf: &mut CgBuffers,
    carry: Option<&mut CarriedResidual>,
) -> CgStats {
    let n = v.len();
    buf.r.resize(n, Vec3::ZERO);
    buf.p.resize(n, Vec3::ZERO);
    buf.ap.resize(n, Vec3::ZERO);
    buf.parts.resize(2 * nblocks(n), 0.0);
    let fixed = sys.fixed;
    // The two-level preconditioner, where there are bodies to coarsen.
    let two_level = match (sys.jacobi, sys.coarse) {
        (Some(d), Some(c)) if !c.is_empty() => Some((d, c)),
        _ => None,
    };
    if two_level.is_some() {
        buf.z.resize(n, Vec3::ZERO);
    }
    let CgBuffers { r, p, ap, z: zt, prod, parts, coarse } = buf;
    let scale = rhs_scale(rhs, fixed);
    let b2 = sum_f64(n, parts, |i| if fixed[i] != 0 { 0.0 } else { f64::from((scale * rhs[i]).length_squared()) });
    if b2 == 0.0 {
        // Nothing drives the free particles: the solution is 0 for them
        // (the pressure solve asks this of bodies no fluid touches).
        v.par_iter_mut().enumerate().for_each(|(i, v)| {
            if fixed[i] == 0 {
                *v = Vec3::ZERO;
            }
        });
        if let Some(c) = carry {
            c.forget();
        }
        return CgStats { iterations: 0, residual: 0.0 };
    }
    let carried = carry.as_deref().filter(|c| c.valid && c.v.len() == n && c.v.par_iter().eq(v.par_iter()));
    if carried.is_none() {
        v.par_iter_mut().for_each(|v| *v *= scale);
        // (M A) 0 = 0: a start from rest (the bodies' first response of a
        // step, whose accelerations start at 0) needs no product; the same
        // bits as taking it (it would be +0 in every component).
        if v.par_iter().any(|v| *v != Vec3::ZERO) {
            sys.apply(v, prod, ap);
        } else {
            ap.par_iter_mut().for_each(|a| *a = Vec3::ZERO);
        }
    }
    // z = P r with the Jacobi preconditioner P (1 without one).
    let z = |i: usize, r: Vec3| sys.jacobi.map_or(r, |c| c[i] * r);
    // r = rhs - (M A) v (the carried product, or the one just taken), p = z,
    // and the block sums of r.r and r.z, in one pass.
    let (rr0, rz0) = update_and_dot(n, r, v, parts, |i, r, v| {
        if carried.is_some() {
            *v *= scale;
        }
        *r = if fixed[i] != 0 {
            Vec3::ZERO
        } else if let Some(c) = carried {
            scale * (rhs[i] - c.av[i])
        } else {
            scale * rhs[i] - ap[i]
        };
        z(i, *r)
    });
    // z = P r with the two-level preconditioner, and r.z.
    let mut precondition = |r: &[Vec3], zt: &mut [Vec3], parts: &mut [f64]| -> f64 {
        let (d, c) = two_level.expect("two-level preconditioner");
        c.precondition(coarse, r, d, sys.mass, fixed, zt);
        sum_f64(n, parts, |i| f64::from(r[i].dot(zt[i])))
    };
    let mut rz = if two_level.is_some() {
        let rz = precondition(r, zt, parts);
        p.copy_from_slice(zt);
        rz
    } else {
        p.par_iter_mut().zip(r.par_iter()).enumerate().for_each(|(i, (p, r))| *p = z(i, *r));
        if sys.jacobi.is_some() {
            rz0
        } else {
            rr0
        }
    };
    let mut rr = rr0;
    // The norm the tolerance is relative to.
    let b2 = match reference {
        Some(b) => {
            b2.max(sum_f64(n, parts, |i| if fixed[i] != 0 { 0.0 } else { f64::from((scale * b(i)).length_squared()) }))
        }
        None => b2,
    };
    let goal = f64::from(tol).powi(2) * b2;
    let mut it = 0;
    while it < max_iterations && rr > goal && rr > 0.0 {
        sys.apply(p, prod, ap);
        // Fixed rows: (M A) p is 0 there (p is 0 there, so p.(A p) is too).
        let ap_free = |i: usize| if fixed[i] != 0 { Vec3::ZERO } else { ap[i] };
        let pap = sum_f64(n, parts, |i| f64::from(p[i].dot(ap_free(i))));
        if pap.is_nan() || pap <= 0.0 {
            break;
        }
        let alpha = (rz / pap) as f32;
        let (rr_new, rz_new) = update_and_dot(n, r, v, parts, |i, r, v| {
            *v += alpha * p[i];
            *r -= alpha * ap_free(i);
            z(i, *r)
        });
        rr = rr_new;
        it += 1;
        if it >= max_iterations || rr <= goal || rr <= 0.0 {
            // The loop ends: the next direction would not be used.
            break;
        }
        if two_level.is_some() {
            let rz_new = precondition(r, zt, parts);
            let beta = (rz_new / rz) as f32;
            p.par_iter_mut().zip(zt.par_iter()).for_each(|(p, z)| *p = *z + beta * *p);
            rz = rz_new;
            continue;
        }
        let rz_new = if sys.jacobi.is_some() { rz_new } else { rr };
        let beta = (rz_new / rz) as f32;
        p.par_iter_mut().zip(r.par_iter()).enumerate().for_each(|(i, (p, r))| *p = z(i, *r) + beta * *p);
        rz = rz_new;
    }
    let unscale = 1.0 / scale;
    match carry {
        Some(c) => {
            // v unscaled, and what the next solve of this system starts from
            // (v and the product its recurrence implies), in one pass.
            c.av.resize(n, Vec3::ZERO);
            c.v.resize(n, Vec3::ZERO);
            (v.par_iter_mut(), c.v.par_iter_mut(), c.av.par_iter_mut()).into_par_iter().enumerate().for_each(
                |(i, (v, cv, a))| {
                    *v *= unscale;
                    *cv = *v;
                    *a = rhs[i] - unscale * r[i];
                },
            );
            c.valid = true;
        }
        None => v.par_iter_mut().for_each(|v| *v *= unscale),
    }
    let residual = if b2 > 0.0 { (rr / b2).sqrt() as f32 } else { 0.0 };
    CgStats { iterations: it, residual }
}

/// Updates each r_i (and v_i) by `f` (which returns z_i = P r_i) and sums r.r and
/// r.z: one pass, the sums in the blocks and order of [`sum_f64`] (so the
/// same bits as two `sum_f64` passes after the update). `parts` needs
/// 2 [`nblocks`]`(n)` entries.
fn update_and_dot(
    n: usize,
    r: &mut [Vec3],
    v: &mut [Vec3],
    parts: &mut [f64],
    f: impl Fn(usize, &mut Vec3, &mut Vec3) -> Vec3 + Sync,
) -> (f64, f64) {
    let nb = nblocks(n);
    let (prr, prz) = parts[..2 * nb].split_at_mut(nb);
    let chunks = r[..n].par_chunks_mut(BLOCK).zip(v[..n].par_chunks_mut(BLOCK));
    chunks.zip(prr.par_iter_mut().zip(prz.par_iter_mut())).enumerate().for_each(|(b, ((rc, vc), (srr, srz)))| {
        let (mut arr, mut arz) = (0.0f64, 0.0f64);
        for (q, (r, v)) in rc.iter_mut().zip(vc.iter_mut()).enumerate() {
            let z = f(b * BLOCK + q, r, v);
            arr += f64::from(r.dot(*r));
            arz += f64::from(r.dot(z));
        }
        (*srr, *srz) = (arr, arz);
    });
    (combine(prr), combine(prz))
}

/// 2^-k with 2^k <= max |rhs_i| (components, free particles) < 2^(k+1),
/// k within f32's normal exponents (1 for a zero or non-finite rhs): the
/// exact scale under which [`conjugate_gradients`] works.
pub fn rhs_scale(rhs: &[Vec3], fixed: &[u32]) -> f32 {
    let m = max_f32(rhs.len(), |i| if fixed[i] != 0 { 0.0 } else { rhs[i].abs().max_element() });
    if m == 0.0 || !m.is_finite() {
        return 1.0;
    }
    // The exponent of m (subnormals count as 2^-126), kept where 2^-k is a
    // normal number both ways.
    let k = ((m.to_bits() >> 23) as i32 - 127).clamp(-126, 126);
    f32::from_bits(((127 - k) as u32) << 23)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rigid_modes::RigidModes;

    fn block(n: [usize; 3], d: f32) -> Vec<Vec3> {
        let mut x = Vec::new();
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    x.push(Vec3::new(i as f32, j as f32, k as f32) * d);
                }
            }
        }
        x
    }

    #[test]
    fn rotation_of_a_rotation_is_itself() {
        let r = Quat::from_axis_angle(Vec3::new(1.0, 2.0, -0.5).normalize(), 1.1);
        let a = Mat3::from_quat(r) * Mat3::from_diagonal(Vec3::new(1.2, 0.9, 1.05));
        let q = extract_rotation(&a, Quat::IDENTITY, 50);
        assert!((Mat3::from_quat(q) - Mat3::from_quat(r)).abs_diff_eq(Mat3::ZERO, 1e-5));
    }

    #[test]
    fn correction_reproduces_linear_fields() {
        let d = 0.01;
        let x0 = block([6, 6, 6], d);
        let n = x0.len();
        let rest = RestState::new(&x0, &vec![0; n], &vec![1000.0 * d * d * d; n], &Kernel::new(2.0 * d));
        for i in 0..n {
            let mut c = Mat3::ZERO;
            for p in rest.range(i) {
                c += outer(rest.dx0(i, p), rest.correction[i] * rest.w(i, p));
            }
            assert!(c.abs_diff_eq(Mat3::IDENTITY, 1e-4), "particle {i}: {c:?}");
        }
    }

    /// The 16-bit w_ij against the f32 value V_j0 grad W_ij0 computed here
    /// from the rest positions (reference), on a jittered block (uneven
    /// volumes and gradients): every component within half the unit U / V_i0
    /// (plus f32 rounding), the force's pair terms V_i0 w_ij exactly
    /// opposite to V_j0 w_ji (as i16 integers), and at the centre of a
    /// lattice block (its neighbours' neighbourhoods full) the integers of
    /// its w_ij summing to exactly 0.
    #[test]
    fn sixteen_bit_w_is_within_half_a_unit_and_pairwise_opposite() {
        let d = 0.01f32;
        let kernel = Kernel::new(2.0 * d);
        let lattice = block([7, 7, 7], d);
        let jitter =
            |i: usize| 0.05 * d * Vec3::new((i as f32 * 0.7).sin(), (i as f32 * 1.3).cos(), (i as f32 * 2.1).sin());
        let x0: Vec<Vec3> = lattice.iter().enumerate().map(|(i, &p)| p + jitter(i)).collect();
        let n = x0.len();
        let rest = RestState::new(&x0, &vec![0; n], &vec![1000.0 * d * d * d; n], &kernel);
        let mut worst = 0.0f32;
        for i in 0..n {
            for p in rest.range(i) {
                let j = rest.j[p] as usize;
                let xij = x0[i] - x0[j];
                let exact = rest.volume[j] * (kernel.grad_over_r(xij.length()) * xij);
                let err = (rest.w(i, p) - exact).abs().max_element() / rest.w_unit(i);
                worst = worst.max(err);
                let back = rest.range(j).find(|&m| rest.j[m] as usize == i).expect("symmetric rest pairs");
                for c in 0..3 {
                    assert_eq!(rest.wq[3 * p + c], -rest.wq[3 * back + c], "pair ({i}, {j}) component {c}");
                }
            }
        }
        assert!(worst <= 0.5 + 1e-3, "largest error {worst} units");
        let lattice = block([9, 9, 9], d);
        let n = lattice.len();
        let rest = RestState::new(&lattice, &vec![0; n], &vec![1000.0 * d * d * d; n], &kernel);
        let centre = (0..n).find(|&i| lattice[i].abs_diff_eq(Vec3::splat(4.0 * d), 1e-6)).expect("a centre");
        for c in 0..3 {
            let total: i32 = rest.range(centre).map(|p| i32::from(rest.wq[3 * p + c])).sum();
            assert_eq!(total, 0, "component {c}");
        }
    }

    /// A free 6^3 block at rest (d = 1 cm), for systems at dt 2 ms.
    struct BallBody {
        x0: Vec<Vec3>,
        rest: RestState,
        def: Vec<Deformation>,
        lame: Vec<Lame>,
        mass: Vec<f32>,
    }

    impl BallBody {
        /// The issue-34 ball's material (500 kg/m^3, mu 5e4 Pa, lambda 2e4
        /// Pa).
        fn new() -> BallBody {
            Self::with(500.0, Lame { mu: 5e4, lambda: 2e4 })
        }

        /// The block of `density` (kg/m^3) and Lamé parameters `lame`.
        fn with(density: f32, lame: Lame) -> BallBody {
            let d = 0.01;
            let x0 = block([6, 6, 6], d);
            let n = x0.len();
            let mass = vec![density * d * d * d; n];
            let rest = RestState::new(&x0, &vec![0; n], &mass, &Kernel::new(2.0 * d));
            let (mut rot, mut def) = (vec![Quat::IDENTITY; n], vec![Deformation::default(); n]);
            deform(&rest, &x0, &mut rot, &mut def);
            BallBody { x0, rest, def, lame: vec![lame; n], mass }
        }

        fn system<'a>(&'a self, fixed: &'a [u32]) -> System<'a> {
            System {
                rest: &self.rest,
                def: &self.def,
                lame: &self.lame,
                mass: &self.mass,
                fixed,
                dt: 0.002,
                jacobi: None,
                coarse: None,
            }
        }
    }

    /// The response of a body at rest (the issue-34 ball: d = 1 cm, 500
    /// kg/m^3, mu 5e4 Pa, lambda 2e4 Pa, dt 2 ms) to a force on three of
    /// its particles, `f` N each way, solved from rest to 1e-4.
    fn response_to(f: f32) -> (Vec<Vec3>, CgStats) {
        let body = BallBody::new();
        let n = body.mass.len();
        let fixed = vec![0; n];
        let sys = body.system(&fixed);
        let mut rhs = vec![Vec3::ZERO; n];
        for (k, i) in [5usize, 100, 211].into_iter().enumerate() {
            rhs[i] = f * Vec3::new(1.0 + k as f32, -2.0, 0.5 * k as f32);
        }
        let mut a = vec![Vec3::ZERO; n];
        let stats = conjugate_gradients(&sys, &rhs, &mut a, 1e-4, 2000, &mut CgBuffers::default());
        (a, stats)
    }

    /// Issue 34: forces of 1e-18 N (a ball's first wet step) drove the f32
    /// products of p.Ap below the smallest normal number and CG diverged
    /// to infinity (rr 5e-35 -> 6e33 in 320 iterations). Reference: the
    /// system is linear, so the response to s F is s times the response to
    /// F; exactly so, bit for bit, for s a power of two (the scaled solve).
    #[test]
    fn response_to_a_tiny_force_is_the_scaled_response() {
        let (big, sb) = response_to(1e-2);
        assert!(sb.residual <= 1e-4, "{sb:?}");
        let vmax = big.iter().map(|v| v.length()).fold(0.0, f32::max);
        assert!(vmax > 0.0);
        // 2^-60 1e-2 N = 8.7e-21 N: every iterate exactly scaled.
        let s = 2.0f32.powi(-60);
        let (tiny, st) = response_to(1e-2 * s);
        assert_eq!(st, sb);
        for (a, b) in tiny.iter().zip(&big) {
            assert_eq!(*a, *b * s);
        }
        // 1.6e-18 N, not a power of two apart: the same answer to the CG
        // tolerance (1e-4 of the residual; 1e-3 of the largest response).
        let s = 1.6e-16f32;
        let (tiny, st) = response_to(1e-2 * s);
        assert!(st.residual <= 1e-4, "{st:?}");
        for (i, (a, b)) in tiny.iter().zip(&big).enumerate() {
            let e = (*a / s - *b).length() / vmax;
            assert!(e < 1e-3, "particle {i}: {a:?} / {s} vs {b:?} ({e:.2e})");
        }
    }

    /// The Jacobi-preconditioned CG solves the same system as plain CG:
    /// the ball's block with a fixed bottom layer and a heavier half (the
    /// diagonal then varies: surface rows have fewer neighbours, the heavy
    /// half twice the mass), a force on every free particle. Reference: a
    /// plain CG solve to 1e-7; both solves to 1e-5 agree with it within
    /// 1e-3 of the largest answer, and the preconditioned one needs no more
    /// iterations.
    #[test]
    fn jacobi_preconditioned_cg_solves_the_same_system() {
        let mut body = BallBody::new();
        let n = body.mass.len();
        for (i, m) in body.mass.iter_mut().enumerate() {
            if i % 6 >= 3 {
                *m *= 2.0;
            }
        }
        let fixed: Vec<u32> = (0..n).map(|i| u32::from(i < 36)).collect();
        let rhs: Vec<Vec3> =
            (0..n).map(|i| Vec3::new((i % 7) as f32 - 3.0, 1.0, (i % 5) as f32 * 0.3) * 1e-3).collect();
        let plain = body.system(&fixed);
        let mut jacobi = Vec::new();
        plain.inverse_diagonal(&mut jacobi);
        let pre = System { jacobi: Some(&jacobi), ..body.system(&fixed) };
        let solve = |sys: &System, tol: f32| {
            let mut a = vec![Vec3::ZERO; n];
            let st = conjugate_gradients(sys, &rhs, &mut a, tol, 5000, &mut CgBuffers::default());
            (a, st)
        };
        let (exact, _) = solve(&plain, 1e-7);
        let amax = exact.iter().map(|a| a.length()).fold(0.0, f32::max);
        let (a, sa) = solve(&plain, 1e-5);
        let (b, sb) = solve(&pre, 1e-5);
        assert!(sa.residual <= 1e-5 && sb.residual <= 1e-5, "{sa:?} {sb:?}");
        assert!(sb.iterations <= sa.iterations, "preconditioned {sb:?}, plain {sa:?}");
        for i in 0..n {
            let (ea, eb) = ((a[i] - exact[i]).length() / amax, (b[i] - exact[i]).length() / amax);
            assert!(ea < 1e-3 && eb < 1e-3, "particle {i}: plain {ea:.2e}, preconditioned {eb:.2e}");
        }
        println!("iterations to 1e-5: plain {}, Jacobi {}", sa.iterations, sb.iterations);
    }

    /// The two-level preconditioner ([`crate::rigid_modes`]) on issue 34's
    /// placement 432 material (120 kg/m^3, mu 2.6e5 Pa, lambda 4.6e5 Pa;
    /// dt^2 k 87 times a particle's mass at dt = 2 ms) as a free 6^3 block
    /// at d = 1 cm, pushed up on its top layer (36 particles, 0.1 N each).
    /// References: Newton's second law for the body (the elastic forces
    /// are internal, so the exact response has sum m a = sum F), and a
    /// Jacobi-preconditioned solve to 1e-7. One iteration from rest, what
    /// the pressure solve's sweeps see: the two-level CG gives the body
    /// more than half the momentum of the push (measured 0.786: the line
    /// search scales the rigid and the stiff part together), Jacobi's
    /// under 1 % (0.0018: the pushed layer alone moves). Both solves to
    /// 1e-5 agree with the reference within 1e-3 of the largest answer,
    /// the two-level one in no more iterations (measured 49 against 68).
    #[test]
    fn two_level_cg_moves_a_stiff_light_body_as_a_whole() {
        let d = 0.01;
        let body = BallBody::with(119.7, Lame { mu: 2.6e5, lambda: 4.6e5 });
        let (x0, mass) = (&body.x0, &body.mass);
        let n = x0.len();
        let fixed = vec![0; n];
        let plain = body.system(&fixed);
        let mut jacobi = Vec::new();
        plain.inverse_diagonal(&mut jacobi);
        let normal: Vec<Vec3> = body.rest.wsum.clone();
        let mut modes = RigidModes::default();
        modes.update(&vec![0; n], &fixed, mass, x0, &normal);
        let pre = System { jacobi: Some(&jacobi), ..plain };
        let two = System { jacobi: Some(&jacobi), coarse: Some(&modes), ..plain };
        let top = x0.iter().map(|x| x.y).fold(f32::MIN, f32::max);
        let rhs: Vec<Vec3> =
            x0.iter().map(|x| if x.y > top - 0.5 * d { Vec3::new(0.0, 0.1, 0.0) } else { Vec3::ZERO }).collect();
        let push: f32 = rhs.iter().map(|f| f.y).sum();
        let solve = |sys: &System, tol: f32, max: u32| {
            let mut a = vec![Vec3::ZERO; n];
            let st = conjugate_gradients(sys, &rhs, &mut a, tol, max, &mut CgBuffers::default());
            (a, st)
        };
        let momentum = |a: &[Vec3]| a.iter().zip(mass).map(|(a, m)| m * a.y).sum::<f32>();
        let (one_two, _) = solve(&two, 0.0, 1);
        let (one_jacobi, _) = solve(&pre, 0.0, 1);
        let (p2, pj) = (momentum(&one_two) / push, momentum(&one_jacobi) / push);
        assert!(p2 > 0.5 && pj < 0.01, "one iteration: momentum {p2} (two-level), {pj} (Jacobi) of the push");
        let (exact, _) = solve(&pre, 1e-7, 20000);
        let amax = exact.iter().map(|a| a.length()).fold(0.0, f32::max);
        let (a, sa) = solve(&pre, 1e-5, 20000);
        let (b, sb) = solve(&two, 1e-5, 20000);
        assert!(sa.residual <= 1e-5 && sb.residual <= 1e-5, "{sa:?} {sb:?}");
        assert!(sb.iterations <= sa.iterations, "two-level {sb:?}, Jacobi {sa:?}");
        for i in 0..n {
            let (ea, eb) = ((a[i] - exact[i]).length() / amax, (b[i] - exact[i]).length() / amax);
            assert!(ea < 1e-3 && eb < 1e-3, "particle {i}: Jacobi {ea:.2e}, two-level {eb:.2e}");
        }
        println!(
            "one iteration: momentum {p2:.4} (two-level), {pj:.4} (Jacobi) of the push; to 1e-5: {} and {} iterations",
            sb.iterations, sa.iterations
        );
    }

    /// [`System::apply`] on glam's SIMD types with fused multiply-adds and
    /// the own-stress term T_i s_i against the scalar form (PHYSICS.md
    /// §3.3's expressions on `Vec3`/`Mat3`, written out here as the
    /// reference), on a rotated, sheared block with a fixed particle and a
    /// velocity field with all three components: T and (M A) v within 1e-5
    /// of each field's largest value (f32 rounding of sums of ~30 terms;
    /// measured 2026-12-05: 2.0e-7 and 1.4e-7).
    #[test]
    fn simd_apply_is_the_scalar_apply_to_rounding() {
        let d = 0.01;
        let x0 = block([7, 6, 5], d);
        let n = x0.len();
        let mass: Vec<f32> = (0..n).map(|i| 500.0 * d * d * d * (1.0 + 0.01 * (i % 7) as f32)).collect();
        // The pair list's product (the lattice's: the test below).
        let rest = RestState::new(&x0, &vec![0; n], &mass, &Kernel::new(2.0 * d)).without_lattice();
        let def = rotated_and_sheared(&rest, &x0);
        let lame: Vec<Lame> = (0..n).map(|i| Lame { mu: 5e4 + 10.0 * i as f32, lambda: 2e4 }).collect();
        let mut fixed = vec![0; n];
        fixed[17] = 1;
        let sys = System {
            rest: &rest,
            def: &def,
            lame: &lame,
            mass: &mass,
            fixed: &fixed,
            dt: 0.002,
            jacobi: None,
            coarse: None,
        };
        let v = swirl(n);
        let (mut scratch, mut out) = (ProductScratch::default(), vec![Vec3::ZERO; n]);
        sys.apply(&v, &mut scratch, &mut out);
        let t = &scratch.t;
        // The scalar reference.
        let t_ref: Vec<Mat3> = (0..n)
            .map(|i| {
                let mut g = Mat3::ZERO;
                for p in rest.range(i) {
                    g += outer(v[rest.j[p] as usize] - v[i], rest.w(i, p));
                }
                let rl = def[i].rl;
                let eps = sym(&(g * rl.transpose())) * sys.dt;
                stress(&eps, lame[i]) * rl
            })
            .collect();
        let want: Vec<Vec3> = (0..n)
            .map(|i| {
                if fixed[i] != 0 {
                    return mass[i] * v[i];
                }
                let mut acc = Vec3::ZERO;
                for p in rest.range(i) {
                    acc += (t_ref[i] + t_ref[rest.j[p] as usize]) * rest.w(i, p);
                }
                mass[i] * v[i] - sys.dt * rest.volume[i] * acc
            })
            .collect();
        let t_max = t_ref.iter().map(|m| m.abs().to_cols_array().into_iter().fold(0.0, f32::max)).fold(0.0, f32::max);
        let out_max = want.iter().map(|o| o.abs().max_element()).fold(0.0, f32::max);
        let (mut t_err, mut out_err) = (0.0f32, 0.0f32);
        for i in 0..n {
            let dt = (Mat3::from(t[i]) - t_ref[i]).abs().to_cols_array().into_iter().fold(0.0, f32::max);
            t_err = t_err.max(dt / t_max);
            out_err = out_err.max((out[i] - want[i]).abs().max_element() / out_max);
        }
        assert_eq!(out[17], want[17], "the fixed row is m v");
        assert!(t_err < 1e-5 && out_err < 1e-5, "T {t_err:.2e}, (M A) v {out_err:.2e} of the largest value");
        println!("T {t_err:.2e}, (M A) v {out_err:.2e} of the largest value");
    }

    /// The deformation of `rest`'s particles at `x0` rotated and sheared
    /// (RL_i a full matrix), for the products' tests.
    fn rotated_and_sheared(rest: &RestState, x0: &[Vec3]) -> Vec<Deformation> {
        let n = x0.len();
        let r = Mat3::from_quat(Quat::from_axis_angle(Vec3::new(0.3, 1.0, -0.4).normalize(), 0.7));
        let shear = Mat3::from_cols(Vec3::new(1.05, 0.02, 0.0), Vec3::new(0.1, 0.93, 0.01), Vec3::new(0.0, -0.03, 1.1));
        let x: Vec<Vec3> = x0.iter().map(|&p| r * (shear * p)).collect();
        let (mut rot, mut def) = (vec![Quat::IDENTITY; n], vec![Deformation::default(); n]);
        deform(rest, &x, &mut rot, &mut def);
        def
    }

    /// A velocity field with all three components, for the products' tests.
    fn swirl(n: usize) -> Vec<Vec3> {
        (0..n).map(|i| Vec3::new((i as f32 * 0.37).sin(), (i as f32 * 0.11).cos() - 0.5, 0.01 * i as f32)).collect()
    }

    /// The lattice stencils' product ([`crate::rest_lattice`]) is the pair
    /// list's (reference: [`System::apply`] without the lattice, itself
    /// checked against the scalar formulas above) to f32 rounding of sums
    /// of about 30 terms in another order: within 1e-5 of the largest
    /// |(M A) v| for four bodies in one rest state (a block with holes
    /// cut out and a fixed particle, a ball, a block offset by a
    /// non-multiple of d, a bar long enough for chunks of the template
    /// pattern) and three particles without rest pairs, a body each,
    /// rotated and sheared, with masses and Lamé
    /// parameters varying by particle. A body off the lattice (one
    /// particle moved by 0.3 d) leaves the whole rest state on the pair
    /// list; a long bar far from the origin does not.
    #[test]
    fn lattice_apply_is_the_pair_apply_to_rounding() {
        let d = 0.01;
        let mut x0 = Vec::new();
        let mut body = Vec::new();
        for p in block([9, 7, 6], d) {
            // Holes: a column and a slab corner missing.
            let c = (p / d).round();
            if (c.x == 4.0 && c.y == 3.0) || (c.x < 2.0 && c.z > 3.0) {
                continue;
            }
            x0.push(p);
            body.push(0);
        }
        for p in block([9, 9, 9], d) {
            if (p - Vec3::splat(4.0 * d)).length() <= 4.2 * d {
                x0.push(p + Vec3::new(0.3, 0.0, 0.0));
                body.push(1);
            }
        }
        for p in block([5, 4, 3], d) {
            x0.push(p + Vec3::new(0.0, 0.2 + 0.37 * d, 0.013));
            body.push(2);
        }
        // A long bar: chunks of slots inside it read the box's template.
        for p in block([40, 6, 6], d) {
            x0.push(p + Vec3::new(0.0, -0.3, 0.0));
            body.push(3);
        }
        // Particles without rest pairs, a body each (as granular ones).
        for k in 0..3 {
            x0.push(Vec3::new(-0.5, 0.1 * k as f32, 0.0));
            body.push(4 + k);
        }
        let n = x0.len();
        // Masses that vary by particle, but for the bar (whose interior
        // then has one pattern of w_ij).
        let vary = |i: usize| if body[i] == 3 { 1.0 } else { 1.0 + 0.01 * (i % 7) as f32 };
        let mass: Vec<f32> = (0..n).map(|i| 500.0 * d * d * d * vary(i)).collect();
        let kernel = Kernel::new(2.0 * d);
        let rest = RestState::new(&x0, &body, &mass, &kernel);
        let (template, chunks) = rest.lattice().expect("lattice bodies get stencils").template_chunks();
        assert!(template > 0 && template < chunks, "{template} of {chunks} chunks read a template");
        let pairs = rest.clone().without_lattice();
        let def = rotated_and_sheared(&rest, &x0);
        let lame: Vec<Lame> =
            (0..n).map(|i| Lame { mu: 5e4 + 10.0 * i as f32, lambda: 2e4 + 5.0 * i as f32 }).collect();
        let mut fixed = vec![0; n];
        fixed[17] = 1;
        let v = swirl(n);
        let product = |rest: &RestState| {
            let sys = System {
                rest,
                def: &def,
                lame: &lame,
                mass: &mass,
                fixed: &fixed,
                dt: 0.002,
                jacobi: None,
                coarse: None,
            };
            let (mut scratch, mut out) = (ProductScratch::default(), vec![Vec3::ZERO; n]);
            // After a call with other velocities, in the same scratch:
            // nothing is left over from a call.
            let other: Vec<Vec3> = v.iter().map(|&v| 3.0 * Vec3::new(v.y, v.z, v.x) + Vec3::ONE).collect();
            sys.apply(&other, &mut scratch, &mut out);
            sys.apply(&v, &mut scratch, &mut out);
            out
        };
        let (got, want) = (product(&rest), product(&pairs));
        let largest = want.iter().map(|o| o.abs().max_element()).fold(0.0, f32::max);
        let err = got.iter().zip(&want).map(|(a, b)| (*a - *b).abs().max_element()).fold(0.0, f32::max) / largest;
        assert_eq!(got[17], want[17], "the fixed row is m v");
        assert_eq!(got[n - 3..], want[n - 3..], "rows without rest pairs are m v");
        assert!(err < 1e-5, "(M A) v {err:.2e} of the largest value");
        println!("lattice against pairs: {err:.2e} of the largest value, {n} particles, {template} of {chunks} chunks from templates");
        let mut moved = x0.clone();
        moved[40].x += 0.3 * d;
        assert!(!RestState::new(&moved, &body, &mass, &kernel).has_lattice(), "a particle off the lattice");
        // A long bar far from the origin at the paper's spacing: the f32
        // rounding of its positions and spacing does not hide its lattice.
        let d = 0.0024;
        let bar: Vec<Vec3> = block([400, 3, 3], d).into_iter().map(|p| p + Vec3::new(1.3, 0.7, 0.2)).collect();
        let m = bar.len();
        let rest = RestState::new(&bar, &vec![0; m], &vec![600.0 * d * d * d; m], &Kernel::new(2.0 * d));
        assert!(rest.has_lattice(), "a 400-particle bar at x = 1.3 m is on a lattice");
    }

    /// [`conjugate_gradients_from`]: a pressure solve's sequence of
    /// two-iteration responses, each from the last answer with a new force,
    /// gives what the same sequence with the start residual recomputed each
    /// time gives, to the rounding of the recurrence (reference: linearity,
    /// r = b - A v); a changed warm start falls back to the product.
    #[test]
    fn carried_residual_continues_a_sequence_of_solves() {
        let body = BallBody::new();
        let n = body.mass.len();
        let mut fixed = vec![0; n];
        fixed[..36].fill(1);
        let sys = body.system(&fixed);
        let force = |s: usize| -> Vec<Vec3> {
            (0..n).map(|i| 1e-3 * Vec3::new(((i + s) as f32 * 0.3).sin(), -1.0, 0.1 * s as f32)).collect()
        };
        let (mut a, mut b) = (vec![Vec3::ZERO; n], vec![Vec3::ZERO; n]);
        let (mut ba, mut bb, mut carry) = (CgBuffers::default(), CgBuffers::default(), CarriedResidual::default());
        for s in 0..30 {
            let f = force(s);
            conjugate_gradients_from(&sys, &f, &mut a, 1e-6, 2, &mut ba, &mut carry);
            conjugate_gradients(&sys, &f, &mut b, 1e-6, 2, &mut bb);
        }
        let scale = b.iter().map(|v| v.length()).fold(0.0, f32::max);
        assert!(scale > 0.0);
        let err = a.iter().zip(&b).map(|(x, y)| (*x - *y).length()).fold(0.0, f32::max) / scale;
        assert!(err < 1e-4, "carried vs recomputed after 30 solves: {err:.2e}");
        // Another warm start than the kept answer: the true residual.
        let f = force(30);
        let mut c = a.clone();
        c[100] += Vec3::X;
        let mut d2 = c.clone();
        conjugate_gradients_from(&sys, &f, &mut c, 1e-6, 2, &mut ba, &mut carry);
        conjugate_gradients(&sys, &f, &mut d2, 1e-6, 2, &mut bb);
        assert_eq!(c, d2);
    }
}
