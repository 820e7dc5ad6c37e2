//! Pass 2 (PHYSICS.md §6 4a-b; P §5, §6.1): the current volumes
//! V = V0 / sum_j V0_j W_ij of the fluid, the active walls and the solids
//! (pressure boundaries, PHYSICS.md §2.3), and the densities m / V of the
//! output.

use super::phases::PhaseState;
use super::timing::{pass, PassTimes};
use super::{Params, Workspace};
use crate::store::{FluidStore, SolidStore, WallStore};
use bumpalo::Bump;
use porosph_kernels::iisph::{self, SolidPairs};
use rayon::prelude::*;

/// What pass 2 gives the pressure solve.
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
    /// sigma_s (own body and fluid) and V_s (m^3).
    pub body_solid: &'a [u32],
    pub sigma_solid: &'a [f32],
    pub vol_solid: &'a [f32],
}

/// Pass 2; writes the output densities of the fluid and the walls.
#[allow(clippy::too_many_arguments)]
pub(super) fn volumes<'a>(
    p: &Params,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    solids: &SolidStore,
    w: &Workspace,
    ph: &PhaseState,
    arena: &'a Bump,
    tm: &mut PassTimes,
) -> Volumes<'a> {
    let (n, na, ns) = (fluid.len(), w.active.len(), solids.len());
    let zeros = |n: usize| arena.alloc_slice_fill_copy(n, 0.0f32);
    let (sigma, vol, vm) = (zeros(n), zeros(n), zeros(n));
    let (sigma_b, vol_b, vol_b_full) = (zeros(na), zeros(na), zeros(walls.len()));
    let body_s =
        arena.alloc_slice_fill_iter(w.solid_perm.iter().map(|&i| p.solid_group[solids.body[i as usize] as usize]));
    let v0_s = arena.alloc_slice_fill_iter(w.solid_perm.iter().map(|&i| solids.ppe_volume[i as usize]));
    let (sigma_s, vol_s) = (zeros(ns), zeros(ns));
    tm.time(pass::DENSITIES, || {
        let fs = (ns > 0).then_some(SolidPairs { pairs: &w.fs, values: &*v0_s });
        iisph::fluid_volumes(&w.ff, &w.fb, fs, ph.v0, &walls.rest_volume, sigma, vol);
        if ns > 0 {
            // A solid row counts only its own body (PHYSICS.md §2.3).
            let sigma_ss = zeros(ns);
            iisph::kernel_sums_within(&w.ss, v0_s, body_s, sigma_ss);
            iisph::wall_volumes(&w.sf, &w.solid_rows, sigma_ss, v0_s, ph.v0, sigma_s, vol_s);
        }
        iisph::wall_volumes(&w.bf, &w.active, &walls.sigma_static, &walls.rest_volume, ph.v0, sigma_b, vol_b);
        // Output density of every wall: its fluid-free value, then the
        // active walls' (no dependence on the last step's active set, which
        // a resumed run does not have).
        let rho_ref = p.wall_reference_density();
        walls.density.par_iter_mut().zip(walls.sigma_static.par_iter()).for_each(|(d, s)| *d = rho_ref * s);
        for (k, &b) in w.active.iter().enumerate() {
            vol_b_full[b as usize] = vol_b[k];
            walls.density[b as usize] = rho_ref * sigma_b[k];
        }
        fluid.density.par_iter_mut().zip(vm.par_iter_mut()).enumerate().for_each(|(i, (d, vm))| {
            *d = if vol[i] > 0.0 { ph.mass[i] / vol[i] } else { ph.rest_density[i] };
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
        sigma_solid: sigma_s,
        vol_solid: vol_s,
    }
}
