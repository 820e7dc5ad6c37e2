//! Elastic solids in the step (PHYSICS.md §3; passes 6 and 8 of §6).
//!
//! The fluid code sees a solid only as particles with positions,
//! velocities, masses and pressure-solve rest volumes (the [`SolidStore`]);
//! how a solid deforms is behind [`SolidModel`]. [`Peer2018`] is the implicit
//! corotated SPH elasticity of Peer et al. 2018; another model (the paper's
//! Example 7 uses a granular one) implements the same trait.

use super::timing::{pass, PassTimes};
use super::{Params, Workspace};
use crate::store::{SolidStore, WallStore};
use bumpalo::Bump;
use glam::{Mat3, Quat, Vec3};
use porosph_kernels::cubic_spline::CubicSpline;
use porosph_kernels::elasticity::{
    conjugate_gradients, deform, forces, stress_rl, trace, CgBuffers, CgStats, Deformation, Lame, RestState, System,
};
use porosph_kernels::iisph::{self, VelMut};
use rayon::prelude::*;

/// Rest volumes of the solid particles in the pressure solve, Akinci-style
/// as PHYSICS.md §2.3 gives them: V0_s = gamma / sum_{s'} W_ss' over the
/// rest neighbours in the same body (incl. self), with `gamma` the flat
/// two-layer lattice sum of the walls ([`super::setup::flat_wall_gamma`]):
/// so V0_s = d^3 at a flat surface (the only layer within reach of the
/// fluid is the surface and the one behind it), more at convex edges and
/// corners. (V0_s = d^3 everywhere made the rows of block edges
/// ill-conditioned, as it did for walls: a floating block blew up in 9
/// steps.)
/// `group` is the elastic body of each particle.
pub fn pressure_volumes(solids: &SolidStore, group: &[u32], kernel: &CubicSpline, gamma: f32) -> Vec<f32> {
    let x0: Vec<Vec3> = (0..solids.len()).map(|i| Vec3::new(solids.x0[i], solids.y0[i], solids.z0[i])).collect();
    let rest = RestState::new(&x0, group, &solids.mass, kernel);
    (0..solids.len())
        .map(|i| {
            let s = kernel.w0() + rest.range(i).map(|p| kernel.w(rest.dx0[p].length())).sum::<f32>();
            gamma / s
        })
        .collect()
}

/// What a solid model did in one step.
pub type SolidStats = CgStats;

/// A model of how solid particles deform and move.
pub trait SolidModel: Send + Sync {
    /// A short name, e.g. "peer2018".
    fn name(&self) -> &'static str;

    /// One step for every solid particle: sets the new velocities v^{n+1}
    /// in `solids` (positions are integrated by the pipeline afterwards),
    /// given the external acceleration `a_ext` of each particle (gravity and
    /// the fluid's pressure force over the mass, m/s^2) and `pore`, the pore
    /// stress eta p^pore of each particle (Pa) or `None`. The velocities of
    /// fixed particles are already prescribed in `solids` and stay. Writes
    /// the outputs `stress` and `strain_trace`.
    fn advance(&mut self, solids: &mut SolidStore, a_ext: &[Vec3], pore: Option<&[f32]>, dt: f32) -> SolidStats;

    /// Bytes held.
    fn bytes(&self) -> usize;
}

/// Implicit corotated SPH elasticity (Peer et al. 2018, PHYSICS.md §3.1-3.3):
/// rotations by Müller's extraction, corotated strain and stress (P-Eqs.
/// 4-5), and the velocities from conjugate gradients on the linearised
/// implicit system with frozen rotations.
pub struct Peer2018 {
    rest: RestState,
    /// Lamé parameters of each particle (from its body).
    lame: Vec<Lame>,
    /// Relative residual at which CG stops.
    tolerance: f32,
    max_iterations: u32,
    // Per-step buffers, kept for their capacity.
    x: Vec<Vec3>,
    v: Vec<Vec3>,
    rot: Vec<Quat>,
    def: Vec<Deformation>,
    t: Vec<Mat3>,
    von_mises: Vec<f32>,
    force: Vec<Vec3>,
    rhs: Vec<Vec3>,
    cg: CgBuffers,
}

impl Peer2018 {
    /// The model for the particles of `solids` (rest positions, and the
    /// Lamé parameters of each entry `body_lame`), `group` the elastic body
    /// of each particle (rest neighbours only within a body) and `rest_mass`
    /// its mass before it absorbed anything (the rest volumes).
    pub fn new(
        solids: &SolidStore,
        group: &[u32],
        rest_mass: &[f32],
        body_lame: &[Lame],
        kernel: &CubicSpline,
        tolerance: f32,
        max_iterations: u32,
    ) -> Self {
        let x0: Vec<Vec3> = (0..solids.len()).map(|i| Vec3::new(solids.x0[i], solids.y0[i], solids.z0[i])).collect();
        let rest = RestState::new(&x0, group, rest_mass, kernel);
        let lame = solids.body.iter().map(|&b| body_lame[b as usize]).collect();
        Peer2018 {
            rest,
            lame,
            tolerance,
            max_iterations,
            x: Vec::new(),
            v: Vec::new(),
            rot: Vec::new(),
            def: Vec::new(),
            t: Vec::new(),
            von_mises: Vec::new(),
            force: Vec::new(),
            rhs: Vec::new(),
            cg: CgBuffers::default(),
        }
    }

    /// The rest-configuration data (SS0, V_i0, L_i).
    pub fn rest(&self) -> &RestState {
        &self.rest
    }

    /// The elastic forces f_i of the last [`SolidModel::advance`], N.
    pub fn elastic_forces(&self) -> &[Vec3] {
        &self.force
    }
}

impl SolidModel for Peer2018 {
    fn name(&self) -> &'static str {
        "peer2018"
    }

    fn advance(&mut self, s: &mut SolidStore, a_ext: &[Vec3], pore: Option<&[f32]>, dt: f32) -> SolidStats {
        let n = s.len();
        self.x.clear();
        self.x.extend((0..n).map(|i| Vec3::new(s.x[i], s.y[i], s.z[i])));
        self.rot.clear();
        self.rot.extend((0..n).map(|i| Quat::from_xyzw(s.qx[i], s.qy[i], s.qz[i], s.qw[i])));
        self.def.resize(n, Deformation::default());
        self.t.resize(n, Mat3::ZERO);
        self.von_mises.resize(n, 0.0);
        self.force.resize(n, Vec3::ZERO);

        // PHYSICS.md §3.2: rotations, strain, stress, elastic forces.
        deform(&self.rest, &self.x, &mut self.rot, &mut self.def);
        stress_rl(&self.def, &self.lame, pore, &mut self.t, &mut self.von_mises);
        forces(&self.rest, &self.t, &mut self.force);
        for (i, q) in self.rot.iter().enumerate() {
            (s.qx[i], s.qy[i], s.qz[i], s.qw[i]) = (q.x, q.y, q.z, q.w);
        }
        s.stress.copy_from_slice(&self.von_mises);
        s.strain_trace.par_iter_mut().zip(self.def.par_iter()).for_each(|(t, d)| *t = trace(&d.strain));

        // PHYSICS.md §3.3: M A v = m v + dt (m a_ext + f), warm start
        // v + dt a_ext; fixed particles keep their prescribed velocity.
        self.v.clear();
        self.v.extend((0..n).map(|i| {
            let v = Vec3::new(s.vx[i], s.vy[i], s.vz[i]);
            if s.fixed[i] != 0 {
                v
            } else {
                v + dt * a_ext[i]
            }
        }));
        self.rhs.clear();
        self.rhs.extend((0..n).map(|i| {
            let m = s.mass[i];
            let v = Vec3::new(s.vx[i], s.vy[i], s.vz[i]);
            if s.fixed[i] != 0 {
                m * v
            } else {
                m * v + dt * (m * a_ext[i] + self.force[i])
            }
        }));
        let sys = System { rest: &self.rest, def: &self.def, lame: &self.lame, mass: &s.mass, fixed: &s.fixed, dt };
        let stats =
            conjugate_gradients(&sys, &self.rhs, &mut self.v, self.tolerance, self.max_iterations, &mut self.cg);
        for (i, v) in self.v.iter().enumerate() {
            (s.vx[i], s.vy[i], s.vz[i]) = (v.x, v.y, v.z);
        }
        stats
    }

    fn bytes(&self) -> usize {
        self.rest.bytes()
            + 8 * self.lame.capacity()
            + 12 * (self.x.capacity() + self.v.capacity() + self.force.capacity() + self.rhs.capacity())
            + 16 * self.rot.capacity()
            + std::mem::size_of::<Deformation>() * self.def.capacity()
            + 36 * self.t.capacity()
            + 4 * self.von_mises.capacity()
            + self.cg.bytes()
    }
}

/// Pass 8 (P Alg. 2): the solids' step under gravity and the fluid's
/// pressure force F_s (the reaction of the solid terms of a^p,
/// `iisph::solid_pressure_force`), with the pore stress `pore` (P-Eq. 5);
/// then their contact with the walls. `p_solid` are the solid pressures of
/// the solve (sorted order), `p_fluid` and `vol_fluid` the fluid's.
#[allow(clippy::too_many_arguments)]
pub(super) fn advance(
    p: &Params,
    solids: &mut SolidStore,
    model: &mut dyn SolidModel,
    walls: &WallStore,
    w: &Workspace,
    p_solid: &[f32],
    p_fluid: &[f32],
    vol_fluid: &[f32],
    pore: Option<&[f32]>,
    dt: f32,
    arena: &Bump,
    tm: &mut PassTimes,
) -> SolidStats {
    let ns = solids.len();
    tm.time(pass::ELASTICITY, || {
        let zeros = |n: usize| arena.alloc_slice_fill_copy(n, 0.0f32);
        let (fx, fy, fz) = (zeros(ns), zeros(ns), zeros(ns));
        iisph::solid_pressure_force(&w.sf, p_solid, p_fluid, vol_fluid, VelMut { x: fx, y: fy, z: fz });
        let g = Vec3::from(p.gravity);
        let a_ext = arena.alloc_slice_fill_copy(ns, g);
        for (k, &i) in w.solid_perm.iter().enumerate() {
            let i = i as usize;
            solids.pressure[i] = p_solid[k];
            a_ext[i] = g + Vec3::new(fx[k], fy[k], fz[k]) / solids.mass[i];
        }
        let stats = model.advance(solids, a_ext, pore, dt);
        wall_contact(p, solids, walls, w);
        stats
    })
}

/// Contact of solids with the static walls (walls do not take part in the
/// elastic solve): a solid particle closer than d to a wall particle may
/// not move further towards the wall. Its velocity loses the component
/// along the wall normal n that points into the wall, n the direction of
/// -sum_b grad W_sb over its wall neighbours (frictionless, inelastic
/// contact; a velocity projection after the elastic solve).
fn wall_contact(p: &Params, solids: &mut SolidStore, walls: &WallStore, w: &Workspace) {
    let d2 = p.h * p.h;
    for (b, blk) in w.sb.used().iter().enumerate() {
        for q in 0..blk.start.len().saturating_sub(1) {
            let k = b * porosph_kernels::blocks::BLOCK + q;
            let i = w.solid_perm[k] as usize;
            if solids.fixed[i] != 0 {
                continue;
            }
            let (xs, ys, zs) = (solids.x[i], solids.y[i], solids.z[i]);
            let mut touching = false;
            let mut n = Vec3::ZERO;
            for pr in blk.range(q) {
                if blk.w[pr] <= 0.0 {
                    continue;
                }
                let j = blk.j[pr] as usize;
                let r2 = (xs - walls.x[j]).powi(2) + (ys - walls.y[j]).powi(2) + (zs - walls.z[j]).powi(2);
                touching |= r2 < d2;
                n -= Vec3::new(blk.gx[pr], blk.gy[pr], blk.gz[pr]);
            }
            let len = n.length();
            if !touching || len <= 0.0 {
                continue;
            }
            let n = n / len;
            let v = Vec3::new(solids.vx[i], solids.vy[i], solids.vz[i]);
            let vn = v.dot(n);
            if vn < 0.0 {
                let v = v - vn * n;
                (solids.vx[i], solids.vy[i], solids.vz[i]) = (v.x, v.y, v.z);
            }
        }
    }
}
