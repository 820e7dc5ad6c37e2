//! Passes 4c and 5: the IISPH pressure solve with pressure boundaries
//! (PHYSICS.md §2.2-2.4; P §6.1). [`setup`] builds the rows: the pair
//! volumes V̄_ij in the pair lists, the sources of the fluid rows ([AC]'s
//! alpha_f (1 + dt div - V0/V), README "Porous solids") and of the wall and
//! solid rows (P-Eq. 26; `porosph_kernels::solid_rows`), and the
//! diagonals; and warm-starts the pressures. [`solve`] hands the system to
//! the backend's Jacobi loop (P-Eqs. 27-28), in which the elastic bodies
//! move with their compliance (strong coupling), and returns the pressure
//! accelerations of the fluid and the solids.

use super::phases::PhaseState;
use super::prediction::Prediction;
use super::solid::{BodyResponse, SolidModel, SolidStats};
use super::step::StepCtx;
use super::timing::Pass;
use super::volumes::Volumes;
use super::{in_sorted_order, PairSet, Workspace};
use crate::backend::passes::{
    Passes, PressureSystem, SolidSystem, SolidUnknowns, SolveReport, SolveSettings, Unknowns, WallInput,
};
use crate::store::{FluidStore, SolidStore, WallStore};
use glam::Vec3;
use porosph_kernels::blocks::{nblocks, sum_f64, BLOCK};
use porosph_kernels::hydrostatic::{self, Columns, Matter};
use porosph_kernels::iisph::{self, FluidRows, Rows, WallRows};
use porosph_kernels::soa::{zeros, zeros3, Vel, VelMut};
use porosph_kernels::solid_rows::{self, SolidNeighbours, SolidNeighboursMut, SolidRows};
use rayon::prelude::*;

/// The rows of the system and the warm-started boundary pressures.
pub(super) struct PressureRows<'a> {
    /// Fluid rows (S, a_ii).
    pub fluid: Rows<'a>,
    /// Active wall rows.
    pub walls: Rows<'a>,
    /// Solid rows (sorted solid order).
    pub solids: Rows<'a>,
    /// Pressures of the active walls and of the solids, warm-started, Pa.
    pub p_active: &'a mut [f32],
    pub p_solid: &'a mut [f32],
    /// The pair lists, scaled.
    pub pairs: ScaledPairs<'a>,
}

/// The step's pair lists after pass 4c: every gradient is V̄_ij grad W_ij
/// (`iisph::fluid_setup`, `iisph::wall_setup`, `solid_rows::solid_setup`,
/// `solid_rows::wall_solid_setup`). Only [`setup`] makes one, from the
/// plain lists it scales, which stay borrowed while the step runs.
#[derive(Clone, Copy)]
pub(super) struct ScaledPairs<'a>(&'a PairSet);

impl<'a> ScaledPairs<'a> {
    /// The lists (their gradients scaled).
    pub fn lists(self) -> &'a PairSet {
        self.0
    }
}

/// Pass 4c. Scales the pair lists by the pair volumes, in place, and hands
/// them on as [`ScaledPairs`], borrowed for the rest of the step. The solids'
/// u*_s are their predicted velocities ([`SolidModel::predict`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn setup<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    (solids, model): (&SolidStore, &dyn SolidModel),
    w: &Workspace,
    pairs: &'a mut PairSet,
    (ph, vols, pred): (&PhaseState, &Volumes, &Prediction),
) -> PressureRows<'a> {
    let (dt, arena, p) = (cx.dt, cx.arena, cx.p);
    let tm = &mut cx.tm;
    let (n, na, ns) = (fluid.len(), w.active.len(), solids.len());
    let (src, diag) = (zeros(arena, n), zeros(arena, n));
    let (src_b, diag_b, p_b) = (zeros(arena, na), zeros(arena, na), zeros(arena, na));
    let VelMut { x: usx, y: usy, z: usz } = zeros3(arena, ns);
    let mobility = zeros(arena, ns);
    if ns > 0 {
        let v = model.predicted();
        let c = zeros(arena, ns);
        // The particles with a pair of the solve outside their body (store
        // order): a fluid or wall pair, or another body's particle. Only a
        // model that couples a body's rows through its rigid motion reads
        // them (none where every body is clamped).
        let contact: &[u32] = if model.couples_bodies() {
            let body = vols.body_solid;
            let sorted = arena.alloc_slice_fill_copy(ns, 0u32);
            let blocks = pairs.sf.used().par_iter().zip(pairs.sb.used().par_iter()).zip(pairs.ss.used().par_iter());
            sorted.par_chunks_mut(BLOCK).zip(blocks).enumerate().for_each(|(b, (marks, ((sf, sb), ss)))| {
                for (q, mark) in marks.iter_mut().enumerate() {
                    let k = b * BLOCK + q;
                    let walls = vols.no_walls_solid[k] == 0 && !sb.range(q).is_empty();
                    let others = ss.range(q).any(|m| body[ss.j[m] as usize] != body[k]);
                    *mark = u32::from(!sf.range(q).is_empty() || walls || others);
                }
            });
            let contact = arena.alloc_slice_fill_copy(ns, 0u32);
            contact.par_iter_mut().zip(w.solid_inv.par_iter()).for_each(|(c, &k)| *c = sorted[k as usize]);
            contact
        } else {
            &[]
        };
        model.mobility(solids, contact, c);
        let u = (&mut *usx, &mut *usy, &mut *usz, &mut *mobility, &w.solid_perm[..]);
        u.into_par_iter().for_each(|(x, y, z, m, &i)| {
            let i = i as usize;
            (*x, *y, *z) = (v[i].x, v[i].y, v[i].z);
            *m = c[i];
        });
    }
    let u_solid = Vel { x: usx, y: usy, z: usz };
    let (src_s, diag_s) = (zeros(arena, ns), zeros(arena, ns));
    let p_s = in_sorted_order(arena, &w.solid_perm, |i| 0.5 * solids.pressure[i]);
    let scratch = cx.scratch.fresh();
    tm.time(Pass::PpeSetup, || {
        // u* and V/m packed for the rows' pair loops.
        let packed = scratch.alloc_slice_fill_copy(n, [0.0f32; 4]);
        let (u, vm) = (pred.u_star, vols.vm);
        packed.par_chunks_mut(BLOCK).enumerate().for_each(|(b, o)| {
            for (q, o) in o.iter_mut().enumerate() {
                let i = b * BLOCK + q;
                *o = [u.x[i], u.y[i], u.z[i], vm[i]];
            }
        });
        let packed = Some(&*packed);
        let rows = FluidRows {
            u_star: pred.u_star,
            vol: vols.vol,
            vm: vols.vm,
            packed,
            alpha_f: ph.alpha_f,
            sigma: vols.sigma,
            vol_wall: vols.vol_wall_full,
            vol_solid: vols.vol_solid,
            u_solid,
            mobility_solid: mobility,
        };
        let fs = if ns > 0 { Some(&mut pairs.fs) } else { None };
        iisph::fluid_setup(&mut pairs.ff, &mut pairs.fb, fs, rows, dt, src, diag);
        // `wall_rows = "lattice"`: the rows' own part at the lattice volume
        // and the walls' coupled diagonal.
        let (sigma, fluid_wall_gradient) = if p.lattice_wall_rows {
            let mut g = zeros3(arena, fluid.len());
            iisph::wall_gradient_sums(&pairs.fb, g.reborrow());
            let sigma_row = zeros(arena, w.active.len());
            let gamma_cell = p.kernel.flat_wall_gamma(p.h) * p.cell_volume();
            let (rest, stat) = (&walls.rest_volume, &walls.sigma_static);
            iisph::wall_row_sigma(&w.active, vols.sigma_wall, rest, stat, gamma_cell, sigma_row);
            (&*sigma_row, Some(g.into_view()))
        } else {
            (vols.sigma_wall, None)
        };
        let (u_star, vm_fluid, vol_fluid) = (pred.u_star, vols.vm, vols.vol);
        let rows = WallRows { vol: vols.vol_wall, sigma, u_star, vm_fluid, packed, vol_fluid, fluid_wall_gradient };
        iisph::wall_setup(&mut pairs.bf, rows, dt, src_b, diag_b);
        if ns > 0 {
            let vol_free = zeros(arena, ns);
            let free = vols.vol_solid.par_iter().zip(vols.no_walls_solid.par_iter());
            vol_free.par_iter_mut().zip(free).for_each(|(o, (&v, &f))| *o = if f != 0 { 0.0 } else { v });
            solid_rows::wall_solid_setup(&mut pairs.bs, vols.vol_wall, vol_free, u_solid, mobility, dt, src_b, diag_b);
            let rows = SolidRows {
                vol: vols.vol_solid,
                sigma: vols.sigma_solid,
                u: u_solid,
                mobility,
                vol_fluid: vols.vol,
                vm_fluid: vols.vm,
                u_fluid: pred.u_star,
                vol_wall: vols.vol_wall_full,
            };
            let nb = SolidNeighboursMut {
                sf: &mut pairs.sf,
                sb: &mut pairs.sb,
                ss: &mut pairs.ss,
                body: vols.body_solid,
                fixed: vols.fixed_solid,
                no_walls: vols.no_walls_solid,
            };
            solid_rows::solid_setup(nb, rows, dt, src_s, diag_s);
        }
        // Warm start from half the last pressure (PHYSICS.md §2.2) or, with
        // `pressure_warm_start = "hydrostatic"`, that and half the
        // hydrostatic estimate, the weight of the fluid and the solids in
        // the column above (`hydrostatic` says why).
        let x = Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z };
        let xs = Vel { x: &solids.x, y: &solids.y, z: &solids.z };
        let obstacles = [Vel { x: &walls.x, y: &walls.y, z: &walls.z }, xs];
        let columns = if p.hydrostatic_warm_start {
            // A solid particle's density: its mass over its lattice cell.
            let volume = p.h * p.h * p.h;
            let rho_s = arena.alloc_slice_fill_iter(solids.mass.iter().map(|&m| m / volume));
            let fluid_matter = Matter { x, rho: ph.rest_density };
            Columns::with_faces(fluid_matter, &[Matter { x: xs, rho: rho_s }], &obstacles, p.gravity, p.h, arena)
        } else {
            None
        };
        let at = |i: usize| Vec3::new(x.x[i], x.y[i], x.z[i]);
        hydrostatic::warm_start(columns.as_ref(), at, &mut fluid.pressure);
        match &columns {
            None => {
                for (k, &b) in w.active.iter().enumerate() {
                    p_b[k] = 0.5 * walls.pressure[b as usize];
                }
            }
            Some(c) => {
                for (k, &b) in w.active.iter().enumerate() {
                    p_b[k] = walls.pressure[b as usize];
                }
                let at = |k: usize| {
                    let b = w.active[k] as usize;
                    Vec3::new(walls.x[b], walls.y[b], walls.z[b])
                };
                hydrostatic::warm_start(Some(c), at, p_b);
                // The solids' rows (already half their last pressure): a
                // body's rows carry the column's weight at their height.
                p_s.par_iter_mut().zip(w.solid_perm.par_iter()).for_each(|(p, &i)| {
                    let i = i as usize;
                    *p += 0.5 * c.pressure(Vec3::new(solids.x[i], solids.y[i], solids.z[i]));
                });
            }
        }
        walls.pressure.iter_mut().for_each(|x| *x = 0.0);
        for (k, &b) in w.active.iter().enumerate() {
            walls.pressure[b as usize] = p_b[k];
        }
    });
    PressureRows {
        fluid: Rows { source: src, diag },
        walls: Rows { source: src_b, diag: diag_b },
        solids: Rows { source: src_s, diag: diag_s },
        p_active: p_b,
        p_solid: p_s,
        pairs: ScaledPairs(pairs),
    }
}

/// What pass 5 gives the later passes.
pub(super) struct Solved<'a> {
    /// a^p of the fluid, m/s^2 (the later passes add to it).
    pub ap: VelMut<'a>,
    /// Solid pressures (sorted solid order), Pa.
    pub p_solid: &'a [f32],
    /// a^p_s of the solids, the bodies' response to the final pressures
    /// (store order), m/s^2.
    pub accel_solid: &'a [Vec3],
    /// How the solve went, and the bodies' compliance solves within it.
    pub report: SolveReport,
    pub solid_stats: SolidStats,
    /// The pair lists, scaled (for the later passes).
    pub pairs: ScaledPairs<'a>,
}

/// Pass 5 on the step's backend: the pressures of every row and the final
/// accelerations, until the mean predicted density error is at most eta.
#[allow(clippy::too_many_arguments)]
pub(super) fn solve<'a>(
    cx: &mut StepCtx<'a>,
    fluid: &mut FluidStore,
    walls: &mut WallStore,
    (solids, model): (&SolidStore, &mut dyn SolidModel),
    w: &Workspace,
    backend: &mut dyn Passes,
    vols: &Volumes,
    rows: PressureRows<'a>,
) -> Solved<'a> {
    let (p, dt, arena) = (cx.p, cx.dt, cx.arena);
    let tmp = cx.scratch.fresh();
    let (n, ns) = (fluid.len(), solids.len());
    let VelMut { x: apx, y: apy, z: apz } = zeros3(arena, n);
    // The solids' accelerations in the rows' order (the bodies' own order
    // in `accel_solid` is what the step keeps).
    let VelMut { x: asx, y: asy, z: asz } = zeros3(tmp, ns);
    let parts = tmp.alloc_slice_fill_copy(nblocks(n), 0.0f64);
    let rows_active = sum_f64(n, parts, |i| (rows.fluid.diag[i] != 0.0) as u32 as f64).max(1.0);
    let PressureRows { fluid: fluid_rows, walls: wall_rows, solids: solid_rows, p_active, p_solid, pairs: scaled } =
        rows;
    let pairs = scaled.lists();
    let sys = PressureSystem {
        kernel: &p.kernel,
        fluid_grid: &w.fluid_grid,
        fluid: Vel { x: &fluid.x, y: &fluid.y, z: &fluid.z },
        walls: WallInput {
            grid: &w.wall_grid,
            walls: Vel { x: &walls.x, y: &walls.y, z: &walls.z },
            active: &w.active,
        },
        ff: &pairs.ff,
        fb: &pairs.fb,
        bf: &pairs.bf,
        vol: vols.vol,
        vm: vols.vm,
        rows: fluid_rows,
        vol_wall: vols.vol_wall_full,
        wall_rows,
        solids: (ns > 0).then_some(SolidSystem {
            fs: &pairs.fs,
            solid: SolidNeighbours {
                sf: &pairs.sf,
                sb: &pairs.sb,
                ss: &pairs.ss,
                body: vols.body_solid,
                fixed: vols.fixed_solid,
                no_walls: vols.no_walls_solid,
            },
            bs: &pairs.bs,
            vol: vols.vol_solid,
            rows: solid_rows,
        }),
        settings: SolveSettings {
            dt,
            omega: p.omega,
            chebyshev_radius: p.chebyshev_radius,
            min_iterations: p.min_iterations,
            max_iterations: p.max_iterations,
            max_density_error: p.max_density_error,
            max_row_density_error: p.max_row_density_error,
            rows_active: rows_active as f32,
        },
    };
    let accel_solid = arena.alloc_slice_fill_copy(ns, Vec3::ZERO);
    let mut response = BodyResponse {
        model,
        solids,
        perm: &w.solid_perm,
        inv: &w.solid_inv,
        force: tmp.alloc_slice_fill_copy(ns, Vec3::ZERO),
        accel: &mut *accel_solid,
        tolerance: p.elastic_tolerance,
        max_iterations: p.elastic_max_iterations,
        stats: SolidStats::default(),
    };
    let x = Unknowns {
        p: &mut fluid.pressure,
        p_wall: &mut walls.pressure,
        p_active,
        ap: VelMut { x: &mut *apx, y: &mut *apy, z: &mut *apz },
        solids: (ns > 0).then_some(SolidUnknowns {
            p: &mut *p_solid,
            accel: VelMut { x: &mut *asx, y: &mut *asy, z: &mut *asz },
            response: &mut response,
        }),
    };
    let report = cx.tm.time(Pass::PressureSolve, || backend.pressure_solve(&sys, x, tmp));
    cx.tm.set_gpu(Pass::PressureSolve, report.gpu_ms.unwrap_or(0.0));
    let solid_stats = response.stats;
    Solved { ap: VelMut { x: apx, y: apy, z: apz }, p_solid, accel_solid, report, solid_stats, pairs: scaled }
}
