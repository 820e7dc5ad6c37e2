//! Pass 0 (P Alg. 1's neighbour search; PHYSICS.md §0, §6): the Morton sort
//! of the fluid (keys and sort by the backend), the fluid cell grid, the
//! pairs FF, fluid-wall and active-wall-fluid, the active walls (those with
//! a fluid or solid neighbour: the wall rows of the pressure solve,
//! PHYSICS.md §2.4), and with solids the solids' Morton order and the pairs
//! FS, SF, SS, solid-wall and active-wall-solid. Everything it builds lives in the [`Workspace`].

use super::phases;
use super::step::StepCtx;
use super::timing::Pass;
use super::{PairSet, Params, Workspace};
use crate::backend::passes::{Passes, StepShape, WallInput};
use crate::store::{FluidStore, SolidStore, WallStore};
use porosph_kernels::neighbors::{build_gradient_pairs, build_pairs, compute_keys, sort_permutation};
use porosph_kernels::soa::Vel;
use rayon::prelude::*;

/// The fluid's rest volumes V0 (pass 1's) and the fluid part of the
/// density sums, sum_j V0_j W_ij over the pairs FF, which the neighbour
/// pass computes as it finds the pairs instead of storing W_ij.
pub(super) struct FluidDensity<'a> {
    pub v0: &'a [f32],
    pub own: &'a mut [f32],
}

/// Pass 0 for the fluid, walls and solids. The fluid store is reordered
/// along the Morton curve; solids keep their store order (the pair lists
/// see them in a sorted copy, `w.solid_perm`).
///
/// The pairs FF keep no kernel values (16 bytes a pair slot instead of
/// 20): the one sum over them that needs W is taken here
/// ([`FluidDensity`]). A porous partition that then changes some rest
/// volumes updates it (`porous::partition`).
pub(super) fn search<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &mut FluidStore,
    walls: &WallStore,
    solids: &SolidStore,
    w: &mut Workspace,
    pairs: &mut PairSet,
    backend: &mut dyn Passes,
) -> FluidDensity<'a> {
    let (p, arena) = (cx.p, cx.arena);
    let tm = &mut cx.tm;
    let support = p.kernel.support;
    let mut gpu_ms = 0.0;
    let n = fluid.len();
    let (v0, own) = (arena.alloc_slice_fill_copy(n, 0.0f32), arena.alloc_slice_fill_copy(n, 0.0f32));
    tm.time(Pass::Neighbors, || {
        let fp = Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        // The sort's buffers live for this pass only (28 B a fluid
        // particle that the workspace held through the step).
        let scratch = cx.scratch.fresh();
        let keys = scratch.alloc_slice_fill_copy(n, 0u64);
        let sort = scratch.alloc_slice_fill_copy(n, (0u64, 0u32));
        let perm = scratch.alloc_slice_fill_copy(n, 0u32);
        gpu_ms += backend.sort(fp, 1.0 / support, keys, sort, perm);
        if perm.iter().enumerate().any(|(i, &j)| i as u32 != j) {
            fluid.reorder(perm, &mut w.reorder);
        }
        keys.par_iter_mut().zip(sort.par_iter()).for_each(|(k, &(key, _))| *k = key);
        w.fluid_grid.build(keys, support);
        let fp = Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        let wp = Vel { x: &walls.x, y: &walls.y, z: &walls.z };
        phases::rest_volumes(p.cell_volume(), fluid, v0);
        build_gradient_pairs(&mut pairs.ff, fp, fp, &w.fluid_grid, None, &p.kernel, v0, own);
        build_pairs(&mut pairs.fb, fp, wp, &w.wall_grid, Some(&w.wall_near), &p.kernel);
        if !solids.is_empty() {
            solid_pairs(p, fluid, solids, walls, w, pairs);
        }
        active_walls(walls.len(), !solids.is_empty(), w, pairs);
        let ax = arena.alloc_slice_fill_iter(w.active.iter().map(|&b| walls.x[b as usize]));
        let ay = arena.alloc_slice_fill_iter(w.active.iter().map(|&b| walls.y[b as usize]));
        let az = arena.alloc_slice_fill_iter(w.active.iter().map(|&b| walls.z[b as usize]));
        let ap = Vel { x: ax, y: ay, z: az };
        build_pairs(&mut pairs.bf, ap, fp, &w.fluid_grid, None, &p.kernel);
        if !solids.is_empty() {
            let [sx, sy, sz] = &w.solid_sorted;
            build_pairs(&mut pairs.bs, ap, Vel { x: sx, y: sy, z: sz }, &w.solid_grid, Some(&w.solid_near), &p.kernel);
        }
        let shape = StepShape { fluid: !fluid.is_empty(), solids: !solids.is_empty(), mixture: p.mixture() };
        let walls = WallInput { grid: &w.wall_grid, walls: wp, active: &w.active };
        gpu_ms += backend.prepare(&w.fluid_grid, walls, shape);
    });
    tm.set_gpu(Pass::Neighbors, gpu_ms);
    FluidDensity { v0, own }
}

/// The active walls, in wall order: the targets of the fluid-wall pairs
/// (and with solids of the solid-wall pairs) with a positive kernel weight.
fn active_walls(nw: usize, solids: bool, w: &mut Workspace, pairs: &PairSet) {
    w.wall_flag.resize(nw, 0);
    for &b in &w.active {
        w.wall_flag[b as usize] = 0;
    }
    let sb = if solids { pairs.sb.used() } else { &[] };
    for blk in pairs.fb.used().iter().chain(sb) {
        for (&b, &wt) in blk.j.iter().zip(&blk.w) {
            if wt > 0.0 {
                w.wall_flag[b as usize] = 1;
            }
        }
    }
    w.active.clear();
    w.active.extend((0..nw as u32).filter(|&b| w.wall_flag[b as usize] != 0));
}

/// Pass 0 for solids: Morton order of the solid positions (a sorted copy;
/// the store keeps its order), the solid grid, and the fluid-solid,
/// solid-fluid, solid-solid and solid-wall pairs (solids in the sorted order).
fn solid_pairs(
    p: &Params,
    fluid: &FluidStore,
    solids: &SolidStore,
    walls: &WallStore,
    w: &mut Workspace,
    pairs: &mut PairSet,
) {
    let ns = solids.len();
    let support = p.kernel.support;
    w.solid_keys.resize(ns, 0);
    compute_keys(&solids.x, &solids.y, &solids.z, 1.0 / support, &mut w.solid_keys);
    // Solids move little: where the last step's order is still the sorted
    // order of (key, store index), the sort would return it unchanged.
    let keys = &w.solid_keys;
    let sorted = w.solid_perm.len() == ns
        && w.solid_perm.par_windows(2).all(|p| (keys[p[0] as usize], p[0]) < (keys[p[1] as usize], p[1]));
    if sorted {
        w.solid_sort.clear();
        w.solid_sort.par_extend(w.solid_perm.par_iter().map(|&i| (keys[i as usize], i)));
    } else {
        sort_permutation(&w.solid_keys, &mut w.solid_sort, &mut w.solid_perm);
        w.solid_inv.resize(ns, 0);
        for (k, &i) in w.solid_perm.iter().enumerate() {
            w.solid_inv[i as usize] = k as u32;
        }
    }
    w.solid_keys.clear();
    w.solid_keys.extend(w.solid_sort.iter().map(|&(k, _)| k));
    w.solid_grid.build(&w.solid_keys, support);
    // The dilation sorts 27 keys a cell: only when the solids' cells change.
    if w.solid_grid.cells != w.solid_near_of {
        w.solid_grid.dilated_keys_into(&mut w.solid_near_keys);
        w.solid_near.build(&w.solid_near_keys, support);
        w.solid_near_of.clone_from(&w.solid_grid.cells);
    }
    for (dst, src) in w.solid_sorted.iter_mut().zip([&solids.x, &solids.y, &solids.z]) {
        dst.resize(ns, 0.0);
        dst.par_iter_mut().zip(w.solid_perm.par_iter()).for_each(|(d, &i)| *d = src[i as usize]);
    }
    if w.solid_rows.len() != ns {
        w.solid_rows.clear();
        w.solid_rows.extend(0..ns as u32);
    }
    let [sx, sy, sz] = &w.solid_sorted;
    let sp = Vel { x: sx, y: sy, z: sz };
    let fp = Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z };
    // Most of a pool is far from every solid: its queries skip the lookup.
    build_pairs(&mut pairs.fs, fp, sp, &w.solid_grid, Some(&w.solid_near), &p.kernel);
    build_pairs(&mut pairs.sf, sp, fp, &w.fluid_grid, None, &p.kernel);
    if p.solid_pairs_read() {
        build_pairs(&mut pairs.ss, sp, sp, &w.solid_grid, None, &p.kernel);
    } else {
        pairs.ss.clear_to(ns);
    }
    let wp = Vel { x: &walls.x, y: &walls.y, z: &walls.z };
    build_pairs(&mut pairs.sb, sp, wp, &w.wall_grid, Some(&w.wall_near), &p.kernel);
}
