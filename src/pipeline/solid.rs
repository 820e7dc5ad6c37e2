//! Elastic solids in the step (PHYSICS.md §3; passes 6 and 8 of §6).
//!
//! The fluid code sees a solid only as particles with positions,
//! velocities and masses (the [`SolidStore`]) and, within the pressure
//! solve, the bodies' response to forces; how a solid deforms is behind
//! [`SolidModel`]. [`Peer2018`] is the implicit
//! corotated SPH elasticity of Peer et al. 2018; the granular continuum of
//! the paper's Example 7 runs next to it (`granular.rs`, [`super::granular::Mixed`]).

use super::step::StepCtx;
use super::timing::Pass;
use crate::backend::passes::Compliance;
use crate::store::SolidStore;
use glam::{Mat3, Quat, Vec3};
use porosph_kernels::elasticity::{
    conjugate_gradients_from, conjugate_gradients_relative_to, deform, forces, stress_rl, trace, CarriedResidual,
    CgBuffers, CgStats, Deformation, Lame, RestState, System,
};
use porosph_kernels::granular::Walls;
use porosph_kernels::kernel::Kernel;
use porosph_kernels::neighbors::PairLists;
use porosph_kernels::rigid_modes::RigidModes;
use porosph_kernels::soa::{Vel, VelMut};
use rayon::prelude::*;

/// What a solid model did in one step.
pub type SolidStats = CgStats;

/// A model of how solid particles deform and move. One step of it is split
/// in three, around the pressure solve (P Alg. 2 and 4):
/// [`SolidModel::deform`] (the strain at the current positions, which the
/// pore pressure needs), [`SolidModel::predict`] (the velocities under
/// gravity and the model's own forces alone), and, within the pressure
/// solve, [`SolidModel::respond`] (the accelerations under given forces,
/// the model's compliance) from which the step's velocities are
/// v^{n+1} = v^pred + dt a.
pub trait SolidModel: Send + Sync {
    /// A short name, e.g. "peer2018".
    fn name(&self) -> &'static str;

    /// The deformation at the current positions; writes the output
    /// `strain_trace` (and whatever else the model keeps per particle).
    fn deform(&mut self, solids: &mut SolidStore);

    /// The velocities every particle would have at the end of the step
    /// under gravity `g` and the model's own forces (with `pore`, the pore
    /// stress eta p^pore of each particle in Pa, or `None`), in
    /// [`SolidModel::predicted`]; fixed particles keep their prescribed
    /// velocity. Writes the output `stress`. `near` is the current
    /// neighbourhood, for a model without rest neighbours.
    fn predict(
        &mut self,
        solids: &mut SolidStore,
        g: Vec3,
        pore: Option<&[f32]>,
        dt: f32,
        near: &Current,
    ) -> SolidStats;

    /// The velocities of the last [`SolidModel::predict`] (store order), m/s.
    fn predicted(&self) -> &[Vec3];

    /// The accelerations `accel` (store order, m/s^2; the warm start on
    /// entry) of the particles under the forces `force` (N) within this
    /// step: the solution of the implicit step's system for a force alone
    /// (fixed particles: 0), to the relative residual `tolerance` or
    /// `max_iterations`. `last` false: a Jacobi sweep's response, which
    /// continues the last one of this step's system from its answer, so a
    /// model may carry its residual over instead of recomputing it. `last`
    /// true: the step's final response, to the solve's final pressure
    /// forces, from its true residual; a model whose prediction stopped
    /// short of `tolerance` also takes on what it left unsolved (its
    /// residual / dt, added to the force), so that the predicted velocities
    /// plus dt `accel` solve the implicit step with the force to
    /// `tolerance`.
    fn respond(
        &mut self,
        solids: &SolidStore,
        force: &[Vec3],
        accel: &mut [Vec3],
        tolerance: f32,
        max_iterations: u32,
        last: bool,
    ) -> SolidStats;

    /// An estimate of each particle's mobility, d a_i / d F_i of
    /// [`SolidModel::respond`] (1/kg; 0 for fixed particles), for the
    /// pressure solve's diagonals; `contact` (store order) is 1 for the
    /// particles with a pair of the solve outside their body, the rows a
    /// body's motion couples (empty unless [`SolidModel::couples_bodies`]).
    fn mobility(&self, solids: &SolidStore, contact: &[u32], out: &mut [f32]);

    /// Whether [`SolidModel::mobility`] reads `contact`: a free body's
    /// rows are coupled through its rigid motion. False by default.
    fn couples_bodies(&self) -> bool {
        false
    }

    /// After the step's velocities are set ([`finish`]): a model whose
    /// walls are not in the pressure solve keeps its particles out of them
    /// (the granular walls, `granular::Granular::wall_contact`). Nothing
    /// by default.
    fn wall_contact(&self, _solids: &mut SolidStore, _near: &Current) {}

    /// Explicit sub-steps the last [`SolidModel::predict`] took (the
    /// granular continuum's); 0 for a model without them.
    fn substeps(&self) -> u32 {
        0
    }

    /// Bytes held.
    fn bytes(&self) -> usize;
}

/// The solids' current neighbourhood from pass 0, in the sorted order of
/// the solid pair lists.
#[derive(Clone, Copy)]
pub struct Current<'a> {
    /// Solid-solid pairs (all bodies; targets sorted solids).
    pub ss: &'a PairLists,
    /// Solid-wall pairs (targets wall indices).
    pub sb: &'a PairLists,
    /// Sorted index -> store index.
    pub perm: &'a [u32],
    /// Sorted solid positions, m.
    pub x: [&'a [f32]; 3],
    /// The walls' positions.
    pub walls: Walls<'a>,
}

/// Implicit corotated SPH elasticity (Peer et al. 2018, PHYSICS.md §3.1-3.3):
/// rotations by Müller's extraction, corotated strain and stress (P-Eqs.
/// 4-5), and the velocities from conjugate gradients on the linearised
/// implicit system with frozen rotations: (M + dt^2 K) v = M v^n + dt (f +
/// M g) for the prediction, (M + dt^2 K) a = F for the response to a force.
pub struct Peer2018 {
    rest: RestState,
    /// Lamé parameters of each particle (from its body).
    lame: Vec<Lame>,
    /// Relative residual at which the prediction's CG stops (the
    /// responses get theirs from the pressure solve).
    prediction_tolerance: f32,
    max_iterations: u32,
    /// dt of the last prediction (the system of the response).
    dt: f32,
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
    /// The last response's residual, for the next sweep's
    /// ([`SolidModel::respond`], not `last`).
    carry: CarriedResidual,
    /// The prediction's answer and the product its recurrence implies:
    /// rhs - that is what the prediction left unsolved, which the step's
    /// last response takes on.
    prediction: CarriedResidual,
    /// The last response's force with the prediction's residual / dt.
    last_force: Vec<Vec3>,
    /// 1 / diag(M A) of this step's system (`System::inverse_diagonal`):
    /// CG's Jacobi preconditioner and the particles' mobility.
    jacobi: Vec<f32>,
    /// The elastic body of each particle (store order).
    group: Vec<u32>,
    /// The current surface normal direction of each particle (store order).
    normal: Vec<Vec3>,
    /// The free bodies' rigid motions at this step's positions: the coarse
    /// space of CG's preconditioner (`porosph_kernels::rigid_modes`).
    modes: RigidModes,
}

impl Peer2018 {
    /// The model for the particles of `solids` (rest positions, and the
    /// Lamé parameters of each entry `body_lame`), `group` the elastic body
    /// of each particle (rest neighbours only within a body) and `rest_mass`
    /// its mass before it absorbed anything (the rest volumes); the
    /// prediction's CG stops at the relative residual
    /// `prediction_tolerance`.
    pub fn new(
        solids: &SolidStore,
        group: &[u32],
        rest_mass: &[f32],
        body_lame: &[Lame],
        kernel: &Kernel,
        prediction_tolerance: f32,
        max_iterations: u32,
    ) -> Self {
        let x0: Vec<Vec3> = (0..solids.len()).map(|i| Vec3::new(solids.x0[i], solids.y0[i], solids.z0[i])).collect();
        let rest = RestState::new(&x0, group, rest_mass, kernel);
        let lame = solids.body.iter().map(|&b| body_lame[b as usize]).collect();
        Peer2018 {
            rest,
            lame,
            prediction_tolerance,
            max_iterations,
            dt: 0.0,
            x: Vec::new(),
            v: Vec::new(),
            rot: Vec::new(),
            def: Vec::new(),
            t: Vec::new(),
            von_mises: Vec::new(),
            force: Vec::new(),
            rhs: Vec::new(),
            cg: CgBuffers::default(),
            carry: CarriedResidual::default(),
            prediction: CarriedResidual::default(),
            last_force: Vec::new(),
            jacobi: Vec::new(),
            group: group.to_vec(),
            normal: Vec::new(),
            modes: RigidModes::default(),
        }
    }

    /// The rest-configuration data (SS0, V_i0, L_i).
    pub fn rest(&self) -> &RestState {
        &self.rest
    }

    /// The elastic forces f_i of the last [`SolidModel::predict`], N.
    pub fn elastic_forces(&self) -> &[Vec3] {
        &self.force
    }

    fn system<'a>(&'a self, solids: &'a SolidStore) -> System<'a> {
        System {
            rest: &self.rest,
            def: &self.def,
            lame: &self.lame,
            mass: &solids.mass,
            fixed: &solids.fixed,
            dt: self.dt,
            jacobi: Some(&self.jacobi),
            coarse: Some(&self.modes),
        }
    }
}

impl SolidModel for Peer2018 {
    fn name(&self) -> &'static str {
        "peer2018"
    }

    fn deform(&mut self, s: &mut SolidStore) {
        self.carry.forget();
        let n = s.len();
        self.x.resize(n, Vec3::ZERO);
        self.x.par_iter_mut().enumerate().for_each(|(i, x)| *x = Vec3::new(s.x[i], s.y[i], s.z[i]));
        self.rot.resize(n, Quat::IDENTITY);
        self.rot.par_iter_mut().enumerate().for_each(|(i, q)| *q = Quat::from_xyzw(s.qx[i], s.qy[i], s.qz[i], s.qw[i]));
        self.def.resize(n, Deformation::default());
        // PHYSICS.md §3.2 steps 1-5: rotations and strain.
        deform(&self.rest, &self.x, &mut self.rot, &mut self.def);
        let store = (&mut s.qx[..], &mut s.qy[..], &mut s.qz[..], &mut s.qw[..], &self.rot[..]);
        store.into_par_iter().for_each(|(x, y, z, w, q)| (*x, *y, *z, *w) = (q.x, q.y, q.z, q.w));
        s.strain_trace.par_iter_mut().zip(self.def.par_iter()).for_each(|(t, d)| *t = trace(&d.strain));
    }

    fn predict(&mut self, s: &mut SolidStore, g: Vec3, pore: Option<&[f32]>, dt: f32, _: &Current) -> SolidStats {
        let n = s.len();
        self.dt = dt;
        // A new system: the last step's residual is not this one's.
        self.carry.forget();
        self.t.resize(n, Mat3::ZERO);
        self.von_mises.resize(n, 0.0);
        self.force.resize(n, Vec3::ZERO);
        // PHYSICS.md §3.2 steps 5-6: stress and elastic forces.
        stress_rl(&self.def, &self.lame, pore, &mut self.t, &mut self.von_mises);
        forces(&self.rest, &self.t, &mut self.force);
        s.stress.copy_from_slice(&self.von_mises);
        // PHYSICS.md §3.3: (M + dt^2 K) v = m v + dt (m g + f), warm start
        // v + dt g; fixed particles keep their prescribed velocity. Solved
        // to the prediction's tolerance only: the last response takes on
        // the rest (`respond`).
        self.v.resize(n, Vec3::ZERO);
        self.rhs.resize(n, Vec3::ZERO);
        let force = &self.force;
        self.v.par_iter_mut().zip(self.rhs.par_iter_mut()).enumerate().for_each(|(i, (v, rhs))| {
            let (m, u) = (s.mass[i], Vec3::new(s.vx[i], s.vy[i], s.vz[i]));
            (*v, *rhs) = if s.fixed[i] != 0 { (u, m * u) } else { (u + dt * g, m * u + dt * (m * g + force[i])) };
        });
        // A push from outside acts along the surface normal: the rest
        // s_i = sum_j w_ij (inward at the surface), rotated.
        self.normal.clear();
        self.normal.extend(self.rot.iter().zip(&self.rest.wsum).map(|(q, w)| *q * *w));
        self.modes.update(&self.group, &s.fixed, &s.mass, &self.x, &self.normal);
        let mut jacobi = std::mem::take(&mut self.jacobi);
        let sys = System {
            rest: &self.rest,
            def: &self.def,
            lame: &self.lame,
            mass: &s.mass,
            fixed: &s.fixed,
            dt,
            jacobi: None,
            coarse: None,
        };
        sys.inverse_diagonal(&mut jacobi);
        let sys = System { jacobi: Some(&jacobi), coarse: Some(&self.modes), ..sys };
        self.prediction.forget();
        let stats = conjugate_gradients_from(
            &sys,
            &self.rhs,
            &mut self.v,
            self.prediction_tolerance,
            self.max_iterations,
            &mut self.cg,
            &mut self.prediction,
        );
        self.jacobi = jacobi;
        stats
    }

    fn predicted(&self) -> &[Vec3] {
        &self.v
    }

    fn respond(
        &mut self,
        s: &SolidStore,
        force: &[Vec3],
        accel: &mut [Vec3],
        tolerance: f32,
        max_iterations: u32,
        last: bool,
    ) -> SolidStats {
        let mut cg = std::mem::take(&mut self.cg);
        let mut carry = std::mem::take(&mut self.carry);
        if last {
            carry.forget();
        }
        // The last response also solves the rest of the prediction's system:
        // force + (b - (M A) v_pred) / dt, to the tolerance relative to the
        // step's whole right-hand side b / dt + force (v_pred + dt a solves
        // (M A) v = b + dt force).
        let mut last_force = std::mem::take(&mut self.last_force);
        let product = self.prediction.product().filter(|_| last);
        let stats = if let Some(av) = product {
            let inv_dt = 1.0 / self.dt;
            let b = &self.rhs;
            let free = |i: usize, f: Vec3| if s.fixed[i] != 0 { force[i] } else { f };
            last_force.clear();
            last_force.extend((0..force.len()).map(|i| free(i, force[i] + (b[i] - av[i]) * inv_dt)));
            let whole = |i: usize| force[i] + b[i] * inv_dt;
            let sys = self.system(s);
            conjugate_gradients_relative_to(
                &sys,
                &last_force,
                &whole,
                accel,
                tolerance,
                max_iterations,
                &mut cg,
                &mut carry,
            )
        } else {
            conjugate_gradients_from(&self.system(s), force, accel, tolerance, max_iterations, &mut cg, &mut carry)
        };
        self.last_force = last_force;
        self.cg = cg;
        self.carry = carry;
        stats
    }

    fn mobility(&self, s: &SolidStore, contact: &[u32], out: &mut [f32]) {
        // The diagonal of M + dt^2 K of the last prediction's system, raised
        // to the body-wide coupling of its rigid motion (the response sees
        // it through CG's coarse space).
        out.par_iter_mut().enumerate().for_each(|(i, c)| *c = if s.fixed[i] != 0 { 0.0 } else { self.jacobi[i] });
        self.modes.couple_mobility(contact, out);
    }

    fn couples_bodies(&self) -> bool {
        !self.modes.is_empty()
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
            + self.carry.bytes()
            + self.prediction.bytes()
            + 12 * self.last_force.capacity()
            + 4 * self.jacobi.capacity()
            + 4 * self.group.capacity()
            + 12 * self.normal.capacity()
            + self.modes.bytes()
    }
}

/// Inner iterations of the bodies' response per Jacobi sweep of the
/// pressure solve (warm-started from the last sweep's answer; with the
/// carried residual each costs one elastic product). Measured on a dropped
/// stiff block and a floating soft cube: 1, 2 and 4 give the same sweep
/// counts and stability. On Example 1 (bench/RESULTS.md, "The bodies'
/// response: one CG iteration a sweep") 1, 2 and 4 give the same sweeps
/// and speeds step for step; 1 leaves more to the exact solve at the end
/// (d = 2.4 mm: 40.5 against 36.8 CG iterations a step, prediction
/// included) but costs the fewest products: 52.6 a step against 61.0 with
/// 2 (d = 4 mm: 90 against 113, and 170 with 4). 0 (no response within
/// the sweeps) blows up: the fluid then pushes the bodies as if rigid.
pub const RESPONSE_ITERATIONS_PER_SWEEP: u32 = 1;

/// The bodies' compliance as the pressure solve asks for it
/// (`backend::passes::Compliance`): forces and accelerations in the sorted
/// order of the pair lists, the model's in store order.
pub(super) struct BodyResponse<'a> {
    pub model: &'a mut dyn SolidModel,
    pub solids: &'a SolidStore,
    /// Sorted index -> store index, and its inverse.
    pub perm: &'a [u32],
    pub inv: &'a [u32],
    /// Store-order scratch: forces and accelerations.
    pub force: &'a mut [Vec3],
    pub accel: &'a mut [Vec3],
    pub tolerance: f32,
    pub max_iterations: u32,
    /// The last exact response.
    pub stats: SolidStats,
}

impl Compliance for BodyResponse<'_> {
    fn respond(&mut self, force: Vel, accel: VelMut, exact: bool) {
        self.force.par_iter_mut().zip(self.inv.par_iter()).for_each(|(f, &k)| {
            let k = k as usize;
            *f = Vec3::new(force.x[k], force.y[k], force.z[k]);
        });
        let (tol, max) =
            if exact { (self.tolerance, self.max_iterations) } else { (self.tolerance, RESPONSE_ITERATIONS_PER_SWEEP) };
        // Every sweep's response continues the last one (the same system,
        // warm-started from its answer); the exact one at the end starts
        // from its true residual and takes on what the prediction left.
        let stats = self.model.respond(self.solids, self.force, self.accel, tol, max, exact);
        if exact {
            self.stats = stats;
        }
        let src = &*self.accel;
        (accel.x, accel.y, accel.z, self.perm).into_par_iter().for_each(|(x, y, z, &i)| {
            let a = src[i as usize];
            (*x, *y, *z) = (a.x, a.y, a.z);
        });
    }
}

/// Alg. 2's first line: the solids' strain at the current positions.
pub(super) fn strain(cx: &mut StepCtx, solids: &mut SolidStore, model: &mut dyn SolidModel) {
    let tm = &mut cx.tm;
    tm.time(Pass::Elasticity, || model.deform(solids));
}

/// Alg. 2's last line: stress, elastic forces and the predicted velocities
/// under gravity (P-Eq. 5 with the pore stress `pore`).
pub(super) fn predict(
    cx: &mut StepCtx,
    solids: &mut SolidStore,
    model: &mut dyn SolidModel,
    pore: Option<&[f32]>,
    near: &Current,
) -> SolidStats {
    let (p, dt) = (cx.p, cx.dt);
    let tm = &mut cx.tm;
    tm.time(Pass::Elasticity, || model.predict(solids, Vec3::from(p.gravity), pore, dt, near))
}

/// Alg. 4's first line: v^{n+1} = v^pred + dt a^p_s for the free particles
/// (`accel` in store order; fixed ones keep their prescribed velocity), and
/// the pressures of the solve (`p_solid` in the sorted order `perm`).
pub(super) fn finish(
    cx: &mut StepCtx,
    solids: &mut SolidStore,
    model: &dyn SolidModel,
    accel: &[Vec3],
    p_solid: &[f32],
    inv: &[u32],
) {
    let dt = cx.dt;
    let tm = &mut cx.tm;
    tm.time(Pass::Elasticity, || {
        solids.pressure.par_iter_mut().zip(inv.par_iter()).for_each(|(p, &k)| *p = p_solid[k as usize]);
        let store = (&mut solids.vx[..], &mut solids.vy[..], &mut solids.vz[..], &solids.fixed[..]);
        let update = (model.predicted(), accel).into_par_iter();
        store.into_par_iter().zip(update).for_each(|((x, y, z, &fixed), (v, a))| {
            if fixed == 0 {
                let v = *v + dt * *a;
                (*x, *y, *z) = (v.x, v.y, v.z);
            }
        });
    });
}
