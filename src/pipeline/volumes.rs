//! Passes 2 and 4a-b (PHYSICS.md §6; P §5, §6.1): the current volumes
//! V = V0 / sum_j V0_j W_ij of the fluid, the active walls and the solids
//! (pressure boundaries, PHYSICS.md §2.3), and the densities of the output
//! (the fluid's: its outer mixture's rest density times V0 / V).

use super::phases::PhaseState;
use super::step::StepCtx;
use super::timing::Pass;
use super::{in_sorted_order, PairSet, Params, Workspace};
use crate::store::{FluidStore, SolidStore, WallStore};
use glam::Vec3;
use porosph_kernels::elasticity::RestState;
use porosph_kernels::iisph::{self, FluidSums, SolidPairs};
use porosph_kernels::soa::zeros;
use porosph_kernels::solid_rows::{self, SolidNeighbours};
use rayon::prelude::*;

/// What passes 2 and 4a-b give the pressure solve.
pub(super) struct Volumes<'a> {
    /// Fluid: sigma = sum_j V0_j W_ij, V = V0 / sigma (m^3), V / m (m^3/kg).
    pub sigma: &'a [f32],
    pub vol: &'a [f32],
    pub vm: &'a [f32],
    /// Active walls (the order of `w.active`): sigma and V.
    pub sigma_wall: &'a [f32],
    pub vol_wall: &'a [f32],
    /// V of every wall (0 for inactive ones), m^3.
    pub vol_wall_full: &'a [f32],
    /// Solid rows, in the sorted solid order: the body of each particle,
    /// sigma_s and V_s (m^3; `solid_rows::solid_volumes`, V0_s from [`rest_rows`]).
    pub body_solid: &'a [u32],
    /// 1 for the fixed solid particles (sorted order).
    pub fixed_solid: &'a [u32],
    /// 1 for the solid particles without wall pairs in the solve: fixed or
    /// granular (sorted order).
    pub no_walls_solid: &'a [u32],
    pub sigma_solid: &'a [f32],
    pub vol_solid: &'a [f32],
}

/// Passes 2 and 4a-b; writes the output densities of the fluid and the walls.
/// `ff_sums`: the fluid part of the fluid rows' sigma, which the neighbour
/// pass took (`neighbours::FluidDensity`).
#[allow(clippy::too_many_arguments)]
pub(super) fn volumes<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    solids: &SolidStore,
    w: &Workspace,
    pairs: &PairSet,
    ph: &PhaseState,
    ff_sums: &[f32],
) -> Volumes<'a> {
    let (p, arena) = (cx.p, cx.arena);
    let tm = &mut cx.tm;
    let (n, na, ns) = (fluid.len(), w.active.len(), solids.len());
    let (sigma, vol, vm) = (zeros(arena, n), zeros(arena, n), zeros(arena, n));
    let (sigma_b, vol_b, vol_b_full) = (zeros(arena, na), zeros(arena, na), zeros(arena, walls.len()));
    let perm = &w.solid_perm;
    let body_s = in_sorted_order(arena, perm, |i| p.solid_group[solids.body[i] as usize]);
    let fixed_s = in_sorted_order(arena, perm, |i| solids.fixed[i]);
    let v0_s = in_sorted_order(arena, perm, |i| w.solid_v0[i]);
    let no_walls_s =
        in_sorted_order(arena, perm, |i| u32::from(solids.fixed[i] != 0 || p.solid_granular[solids.body[i] as usize]));
    let v0_free = arena.alloc_slice_fill_copy(ns, 0.0f32);
    v0_free.par_iter_mut().zip(no_walls_s.par_iter().zip(v0_s.par_iter())).for_each(|(o, (&f, &v))| {
        *o = if f != 0 { 0.0 } else { v };
    });
    let own = in_sorted_order(arena, perm, |i| w.solid_own[i]);
    let (sigma_s, vol_s) = (zeros(arena, ns), zeros(arena, ns));
    tm.time(Pass::Densities, || {
        let fs = (ns > 0).then_some(SolidPairs { pairs: &pairs.fs, values: &*v0_s });
        iisph::fluid_volumes(FluidSums::Done(ff_sums), &pairs.fb, fs, ph.v0, &walls.rest_volume, sigma, vol);
        iisph::wall_volumes(&pairs.bf, &w.active, &walls.sigma_static, &walls.rest_volume, ph.v0, sigma_b, vol_b);
        if ns > 0 {
            let nb = SolidNeighbours {
                sf: &pairs.sf,
                sb: &pairs.sb,
                ss: &pairs.ss,
                body: body_s,
                fixed: fixed_s,
                no_walls: no_walls_s,
            };
            solid_rows::solid_volumes(nb, own, ph.v0, &walls.rest_volume, v0_s, sigma_s, vol_s);
            solid_rows::wall_solid_volumes(&pairs.bs, &w.active, &walls.rest_volume, v0_free, sigma_b, vol_b);
        }
        // Output density of every wall: its fluid-free value, then the
        // active walls' (no dependence on the last step's active set, which
        // a resumed run does not have).
        let rho_ref = p.wall_reference_density();
        walls.density.par_iter_mut().zip(walls.sigma_static.par_iter()).for_each(|(d, s)| *d = rho_ref * s);
        for (k, &b) in w.active.iter().enumerate() {
            vol_b_full[b as usize] = vol_b[k];
            walls.density[b as usize] = rho_ref * sigma_b[k];
        }
        // Output density: the outer mixture's rest density times sigma =
        // V0 / V (the solve's compression), or for a wholly absorbed
        // particle its inner mixture's rest density. (m / V mixed the whole
        // particle's mass, inner fluid included, with the outer volume,
        // faded by `iisph::row_weight`: 1.8e6 kg/m^3 at alpha_f 0.507.)
        let (alpha, beta, rho_k) = (&fluid.alpha, &fluid.beta, &p.phase_density);
        fluid.density.par_iter_mut().zip(vm.par_iter_mut()).enumerate().for_each(|(i, (d, vm))| {
            let (mut outer, mut inner, mut beta_f) = (0.0f32, 0.0f32, 0.0f32);
            for k in 0..rho_k.len() {
                outer += alpha[k][i] * rho_k[k];
                inner += beta[k][i] * rho_k[k];
                beta_f += beta[k][i];
            }
            *d = if ph.alpha_f[i] > 0.0 {
                outer / ph.alpha_f[i] * sigma[i]
            } else if beta_f > 0.0 {
                inner / beta_f
            } else {
                ph.rest_density[i]
            };
            *vm = if ph.mass[i] > 0.0 { vol[i] / ph.mass[i] } else { 0.0 };
        });
    });
    Volumes {
        sigma,
        vol,
        vm,
        sigma_wall: sigma_b,
        vol_wall: vol_b,
        vol_wall_full: vol_b_full,
        body_solid: body_s,
        fixed_solid: fixed_s,
        no_walls_solid: no_walls_s,
        sigma_solid: sigma_s,
        vol_solid: vol_s,
    }
}

/// The rest data of the solid rows of every solid particle (store order),
/// from the body's rest lattice: with n_i = h^3 sum_j W_ij over the body's
/// rest neighbours (incl. itself) and gamma the same sum at a flat face
/// (`Kernel::flat_wall_gamma`, 0.850 for the cubic spline):
/// - omega_s = min(n_i, gamma), the share of the row's neighbourhood its own
///   body fills: a solid is sampled on the fluid's lattice, so at its faces,
///   edges and corners this is the share the fluid does not fill at rest
///   (0.850 at a face, less at an edge or corner: sigma_s = 1 with the fluid
///   at rest spacing). Inside the body the full lattice sum (1) is cut to
///   gamma: a row there would read any fluid particle at the edge of its
///   support as compression, with a diagonal ~ |grad W|^2 near 0, and answer
///   it with an unbounded pressure.
/// - V0_s = h^3 min(1, gamma / n_i), the volume the other rows see: h^3 at
///   faces, edges and corners (the lattice's own share, as for the fluid),
///   Akinci's gamma / sum_j W_ij (PHYSICS.md §2.3) inside, where the
///   absorbed liquid shares the space with the solid (with h^3 there, a
///   partly absorbed particle inside a soaking block read as compressed by
///   the solid alone and was pushed out at up to 1.8e3 m/s).
///
/// Both are constant: the body's own density is the elastic model's
/// (`solid_rows` module doc). (Akinci's volumes everywhere, used before,
/// give the edges and corners of a body more than their lattice share: a
/// cube's edges read sigma 1.18 and its corners 1.31 with the fluid at
/// rest, 3.2e4 Pa on the corners of a soft cube after one step, which
/// kicked them into the body at 1.6 m/s.)
pub(super) fn rest_rows(p: &Params, solids: &SolidStore) -> (Vec<f32>, Vec<f32>) {
    let kernel = &p.kernel;
    let gamma = kernel.flat_wall_gamma(p.h);
    let x0: Vec<Vec3> = (0..solids.len()).map(|i| Vec3::new(solids.x0[i], solids.y0[i], solids.z0[i])).collect();
    let rest = RestState::new(&x0, &p.particle_groups(solids), &p.particle_rest_mass(solids), kernel);
    let cell = p.cell_volume();
    (0..solids.len())
        .map(|i| {
            let n = cell * (kernel.w0() + rest.range(i).map(|k| kernel.w(rest.dx0(i, k).length())).sum::<f32>());
            (n.min(gamma), cell * (gamma / n).min(1.0))
        })
        .unzip()
}
