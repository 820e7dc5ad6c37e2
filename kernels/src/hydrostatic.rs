//! The warm start of the pressure solve (pass 4c, PHYSICS.md §2.2): half
//! the last step's pressure and half a hydrostatic estimate, the weight
//! per unit area of the connected column above the point: |g| times the
//! integral of rho over the column (rho |g| depth where one density fills
//! it). The column holds the fluid and the solids in it, each cell with
//! the mean density of its particles, so a heavy phase over a light one
//! weighs on the light one, and a body resting on the floor presses on
//! the floor with its own weight and the fluid's above it.
//!
//! Why: relaxed Jacobi moves the smooth, long-wavelength pressure modes by
//! very little a sweep (a deep pool's hydrostatic gradient is the
//! slowest), so with the plain 0.5 warm start a deep pool spends most of
//! its sweeps rebuilding the half of rho g depth the warm start dropped
//! (Example 1 at d = 5 mm: 17.9 sweeps a step against 4.3 with a full warm
//! start). A full warm start keeps the smooth modes but also lets the ones
//! the density criterion does not see wander from step to step (the tank
//! at rest 10x faster, tests/hydrostatic.rs). Half of an estimate that
//! depends only on the positions keeps the hydrostatic part and anchors it
//! to the geometry, while the rest of the last pressure still decays by
//! half a step as before. It is only the solve's starting point: the
//! solve still runs to its density tolerance.
//!
//! Opt-in (`simulation.pressure_warm_start = "hydrostatic"`): where the
//! fluid is far from hydrostatic the column's depth is too high (a dam
//! break's vertical free face carries rho g depth in it and none in the
//! flow), and the solve's stop criterion counts compression only, so a
//! solve that ends after its two minimum sweeps keeps part of the excess
//! (Example 1 at d = 4 mm: 0.34 m/s after the first step against 0.02,
//! bench/RESULTS.md). So the depth is scaled by the factor of the fluid at
//! rest ([`Columns::with_faces`]): the coarse potential problem of the
//! fluid released at rest in its current shape, solved on the column grid
//! (cells of 2 d) with p = 0 in air and rho g . n at walls, over the
//! column's hydrostatic pressure. In a pool at rest the factor is 1; for a
//! dam column it is the released column's pressure (within 1.5 d of head
//! of the exact potential solution, unit test), and Example 1 at d =
//! 4 mm starts at 0.039 m/s after the first step (lattice wall rows; 0.34
//! with the column's depth alone).

use crate::blocks::{nblocks, sum_f64, BLOCK};
use crate::soa::Vel;
use bumpalo::Bump;
use glam::Vec3;
use rayon::prelude::*;

/// Largest grid, in cells per fluid particle (plus a constant), for which
/// the estimate is made; a fluid spread thin over a large box (spray)
/// falls back to the plain half warm start.
const MAX_CELLS_PER_PARTICLE: usize = 4;

/// The axis gravity points along and the sign of "up" on it, if gravity
/// has one non-zero component.
fn up_axis(gravity: [f32; 3]) -> Option<(usize, f32)> {
    let mut axes = (0..3).filter(|&a| gravity[a] != 0.0);
    match (axes.next(), axes.next()) {
        (Some(a), None) => Some((a, -gravity[a].signum())),
        _ => None,
    }
}

/// p_i <- 0.5 p_i + 0.5 p^col_i for the points i of `p`, at `at(i)`, with
/// p^col the column's weight above the point ([`Columns::pressure`]), or
/// p_i <- 0.5 p_i without `columns`. The points are given by index, so
/// that a caller's subset (the active walls) needs no copy of its
/// positions.
pub fn warm_start(columns: Option<&Columns>, at: impl Fn(usize) -> Vec3 + Sync, p: &mut [f32]) {
    match columns {
        Some(c) => p.par_iter_mut().enumerate().for_each(|(i, p)| {
            *p = 0.5 * *p + 0.5 * c.pressure(at(i));
        }),
        None => p.par_iter_mut().for_each(|p| *p *= 0.5),
    }
}

/// Points that weigh on the columns: positions and densities (kg/m^3).
#[derive(Clone, Copy)]
pub struct Matter<'a> {
    pub x: Vel<'a>,
    pub rho: &'a [f32],
}

/// A dense grid over the fluid's box, each column a run of cells along
/// "up" (index (a * nb + b) * nu + u).
#[derive(Clone, Copy)]
struct Grid {
    axis: usize,
    sign: f32,
    /// The two other axes.
    across: [usize; 2],
    cell: f32,
    /// Lower corner in (across 0, across 1, up) coordinates.
    origin: [f32; 3],
    dims: [usize; 3],
}

impl Grid {
    /// The grid of cell size `cell` over the points `x`, or `None` where
    /// there are none or it would be too large.
    fn new(x: Vel, axis: usize, sign: f32, cell: f32) -> Option<Grid> {
        let n = x.x.len();
        if n == 0 {
            return None;
        }
        let across = [(axis + 1) % 3, (axis + 2) % 3];
        let range = |s: &[f32], f: f32| {
            s.par_iter()
                .map(|&v| f * v)
                .fold(|| (f32::MAX, f32::MIN), |(lo, hi), v| (lo.min(v), hi.max(v)))
                .reduce(|| (f32::MAX, f32::MIN), |a, b| (a.0.min(b.0), a.1.max(b.1)))
        };
        let r = [range(coord(x, across[0]), 1.0), range(coord(x, across[1]), 1.0), range(coord(x, axis), sign)];
        if r.iter().any(|&(lo, hi)| !(lo.is_finite() && hi.is_finite())) {
            return None;
        }
        let dims = r.map(|(lo, hi)| ((hi - lo) / cell) as usize + 1);
        let cells = dims.iter().try_fold(1usize, |a, &b| a.checked_mul(b))?;
        if cells > MAX_CELLS_PER_PARTICLE * n + 4096 {
            return None;
        }
        Some(Grid { axis, sign, across, cell, origin: r.map(|(lo, _)| lo), dims })
    }

    /// The cell of the point at `x` (clamped into the grid: a wall point
    /// beside or under the fluid takes the nearest column and cell) and
    /// its "up" coordinate.
    #[inline]
    fn cell(&self, x: Vec3) -> (usize, f32) {
        let q = [x[self.across[0]], x[self.across[1]], self.sign * x[self.axis]];
        // A negative offset saturates to cell 0.
        let idx = |k: usize| (((q[k] - self.origin[k]) / self.cell) as usize).min(self.dims[k] - 1);
        ((idx(0) * self.dims[1] + idx(1)) * self.dims[2] + idx(2), q[2])
    }

    /// The cell of the point at `x` in the grid widened by `low` cells
    /// below each axis's first and `high` above its last (dims `dims + low
    /// + high`), if it lies there, and its "up" coordinate.
    #[inline]
    fn cell_in(&self, x: Vec3, low: [usize; 3], high: [usize; 3]) -> Option<(usize, f32)> {
        let q = [x[self.across[0]], x[self.across[1]], self.sign * x[self.axis]];
        let mut idx = [0usize; 3];
        let mut n = [0usize; 3];
        for k in 0..3 {
            let f = (q[k] - self.origin[k]) / self.cell + low[k] as f32;
            n[k] = self.dims[k] + low[k] + high[k];
            if !(f >= 0.0 && f < n[k] as f32) {
                return None;
            }
            idx[k] = (f as usize).min(n[k] - 1);
        }
        Some(((idx[0] * n[1] + idx[1]) * n[2] + idx[2], q[2]))
    }

    /// The cell of the point at `x` in the grid widened by one cell on
    /// each side across and by one layer of cells below (dims `[na + 2, nb
    /// + 2, nu + 1]`), if it lies there.
    #[inline]
    fn cell_widened(&self, x: Vec3) -> Option<usize> {
        self.cell_in(x, [1, 1, 1], [1, 1, 0]).map(|(c, _)| c)
    }

    /// For every cell, the factor f <= 1 by which the pressure of the
    /// fluid at rest in this geometry falls below its column's rho g
    /// depth: the coarse potential problem of a fluid released at rest
    /// (P-Eq. 24 with u = 0), lap p = 0 in the fluid's cells, p = 0 in air
    /// and above the grid, dp/dn = rho g . n at walls, solids and the
    /// grid's other sides. Air is a cell that holds none of `obstacles`, in
    /// the grid, in the ring of cells around it across or in the layer of
    /// cells under it, and no fluid, above its column's highest fluid cell
    /// or with no fluid below it in its column (a gap under the fluid: a
    /// fluid held up by a perforated plate or a body meets air at the
    /// holes, as a drop in the air does); an empty cell with fluid above
    /// and below is a hole in the bulk and counts as fluid (7-point
    /// stencil on the cells, conjugate gradients from
    /// the column's hydrostatic pressure, in units of rho |g| cell); f =
    /// p / p_column where the column is open above, 1 elsewhere. In a pool
    /// at rest p = p_column and f = 1; at a dam's face f -> 0.
    fn static_factor<'a>(&self, occupied: &[bool], obstacles: &[Vel], arena: &'a Bump) -> &'a [f32] {
        let [na, nb, nu] = self.dims;
        // The widened grid: index u = 0 is the layer under the grid, u the
        // grid's u - 1.
        let (wa, wb, wu) = (na + 2, nb + 2, nu + 1);
        let widened = |a: usize, b: usize, u: usize| (a * wb + b) * wu + u;
        let solid = arena.alloc_slice_fill_copy(wa * wb * wu, false);
        for o in obstacles {
            for i in 0..o.x.len() {
                if let Some(c) = self.cell_widened(Vec3::new(o.x[i], o.y[i], o.z[i])) {
                    solid[c] = true;
                }
            }
        }
        // Cell kinds on the widened grid: fluid (the unknowns), air, wall.
        const FLUID: u8 = 0;
        const AIR: u8 = 1;
        const WALL: u8 = 2;
        let kind = arena.alloc_slice_fill_copy(wa * wb * wu, WALL);
        for a in 0..wa {
            for b in 0..wb {
                let inner = (1..=na).contains(&a) && (1..=nb).contains(&b);
                let has_fluid = |u: usize| inner && u > 0 && occupied[((a - 1) * nb + (b - 1)) * nu + u - 1];
                let open_from = (0..wu).rev().find(|&u| has_fluid(u)).map_or(0, |u| u + 1);
                let mut fluid_below = false;
                for u in 0..wu {
                    let c = widened(a, b, u);
                    let fluid = has_fluid(u);
                    kind[c] = if solid[c] && !fluid {
                        WALL
                    } else if fluid || (u < open_from && fluid_below) {
                        FLUID
                    } else {
                        AIR
                    };
                    fluid_below = match kind[c] {
                        WALL => false,
                        _ => fluid_below || fluid,
                    };
                }
            }
        }
        // Column pressure (cells from the first non-fluid cell above, if
        // it is air or the sky), the start and the reference.
        let column = arena.alloc_slice_fill_copy(wa * wb * wu, f32::NAN);
        for a in 0..wa {
            for b in 0..wb {
                let mut above: Option<f32> = Some(0.0); // the sky
                for u in (0..wu).rev() {
                    let c = widened(a, b, u);
                    match kind[c] {
                        FLUID => {
                            column[c] = above.map_or(f32::NAN, |p| p + 0.5);
                            above = above.map(|p| p + 1.0);
                        }
                        AIR => above = Some(0.0),
                        _ => above = None,
                    }
                }
            }
        }
        // The unknowns in a compact order (the widened grid's), each with its
        // diagonal and its fluid neighbours (lateral, then below and above;
        // u32::MAX where none), so that the conjugate gradients below run
        // over contiguous arrays in parallel.
        let cells = wa * wb * wu;
        let unknowns = arena.alloc_slice_fill_copy(kind.iter().filter(|&&k| k == FLUID).count(), 0u32);
        let slot = arena.alloc_slice_fill_copy(cells, u32::MAX);
        for (k, c) in (0..cells).filter(|&c| kind[c] == FLUID).enumerate() {
            unknowns[k] = c as u32;
            slot[c] = k as u32;
        }
        let (unknowns, slot) = (&*unknowns, &*slot);
        let m = unknowns.len();
        let diag = arena.alloc_slice_fill_copy(m, 0.0f32);
        let links = arena.alloc_slice_fill_copy(m, [u32::MAX; 6]);
        let (rhs, p) = (arena.alloc_slice_fill_copy(m, 0.0f32), arena.alloc_slice_fill_copy(m, 0.0f32));
        let stencil = diag.par_iter_mut().zip(links.par_iter_mut()).zip(rhs.par_iter_mut().zip(p.par_iter_mut()));
        stencil.zip(unknowns.par_iter()).for_each(|(((dg, ln), (b, p)), &c)| {
            let c = c as usize;
            let u = c % wu;
            let ab = c / wu;
            let (a, bb) = (ab / wb, ab % wb);
            let lateral = [
                (a > 0).then(|| c - wb * wu),
                (a + 1 < wa).then(|| c + wb * wu),
                (bb > 0).then(|| c - wu),
                (bb + 1 < wb).then(|| c + wu),
            ];
            // Unknowns are never in the layer under the grid (u = 0).
            let vertical = [Some(c - 1), (u + 1 < wu).then(|| c + 1)];
            let mut k = 0;
            for n in lateral.into_iter().chain(vertical).flatten() {
                match kind[n] {
                    FLUID => {
                        *dg += 1.0;
                        ln[k] = slot[n];
                        k += 1;
                    }
                    // p = 0 on the face between the cells.
                    AIR => *dg += 2.0,
                    _ => {}
                }
            }
            // Above the grid: the sky.
            if u + 1 == wu {
                *dg += 2.0;
            }
            let below_wall = kind[c - 1] == WALL;
            let above_wall = u + 1 < wu && kind[c + 1] == WALL;
            *b = below_wall as u32 as f32 - above_wall as u32 as f32;
            *p = if column[c].is_nan() { 0.0 } else { column[c] };
        });
        let (diag, links, rhs) = (&*diag, &*links, &*rhs);
        // A p for p over the unknowns (0 outside the fluid).
        let apply = |p: &[f32], out: &mut [f32]| {
            out.par_chunks_mut(BLOCK).enumerate().for_each(|(blk, o)| {
                for (q, o) in o.iter_mut().enumerate() {
                    let i = blk * BLOCK + q;
                    let mut off = 0.0f32;
                    for &n in links[i].iter().take_while(|&&n| n != u32::MAX) {
                        off += p[n as usize];
                    }
                    *o = diag[i] * p[i] - off;
                }
            });
        };
        let parts = arena.alloc_slice_fill_copy(nblocks(m), 0.0f64);
        let mut dot = |x: &[f32], y: &[f32]| sum_f64(m, parts, |i| f64::from(x[i]) * f64::from(y[i]));
        let (r, q, dir) = (
            arena.alloc_slice_fill_copy(m, 0.0f32),
            arena.alloc_slice_fill_copy(m, 0.0f32),
            arena.alloc_slice_fill_copy(m, 0.0f32),
        );
        apply(p, q);
        r.par_iter_mut().zip(dir.par_iter_mut()).enumerate().for_each(|(i, (r, d))| {
            *r = rhs[i] - q[i];
            *d = *r;
        });
        let mut rr = dot(r, r);
        // A warm start's accuracy: the residual to 1e-3 of the source, and
        // at most the grid's extent in iterations (CG's reach on a
        // Laplacian; 1e-4 and four times the extent took 205 ms a step of
        // Example 1 at the paper's size, bench/RESULTS.md).
        let stop = 1e-6 * dot(rhs, rhs).max(1.0);
        for _ in 0..na + nb + nu {
            if rr <= stop {
                break;
            }
            apply(dir, q);
            let alpha = (rr / dot(dir, q)) as f32;
            p.par_iter_mut().zip(r.par_iter_mut()).enumerate().for_each(|(i, (p, r))| {
                *p += alpha * dir[i];
                *r -= alpha * q[i];
            });
            let rr_next = dot(r, r);
            let beta = (rr_next / rr) as f32;
            dir.par_iter_mut().zip(r.par_iter()).for_each(|(d, &r)| *d = r + beta * *d);
            rr = rr_next;
        }
        let p = &*p;
        arena.alloc_slice_fill_iter((0..na * nb * nu).map(|i| {
            let (ab, u) = (i / nu, i % nu);
            let c = widened(ab / nb + 1, ab % nb + 1, u + 1);
            if kind[c] == FLUID && column[c] > 0.0 {
                (p[slot[c] as usize] / column[c]).clamp(0.0, 1.0)
            } else {
                1.0
            }
        }))
    }

    /// The columns' runs and weights. A run is a gap-free run of cells
    /// along "up" that hold points of `fluid` (all of them, clamped into the
    /// grid) or of `solids` (those inside the grid). Per cell: `top`, the
    /// "up" coordinate of the run's highest point (-inf if empty); `rho`,
    /// the mean density of its points; `ceil`, where its matter ends above
    /// (the run's top plus half a spacing in the run's highest cell, the
    /// cell's upper face below it); `above`, the run's mass per unit area
    /// above `ceil` (kg/m^2).
    fn runs<'a>(&self, fluid: Matter, solids: &[Matter], d: f32, arena: &'a Bump) -> Runs<'a> {
        let cells = self.dims.iter().product();
        let top = arena.alloc_slice_fill_copy(cells, f32::NEG_INFINITY);
        let rho = arena.alloc_slice_fill_copy(cells, 0.0f32);
        let count = arena.alloc_slice_fill_copy(cells, 0u32);
        let mut add = |(c, up): (usize, f32), r: f32| {
            top[c] = top[c].max(up);
            rho[c] += r;
            count[c] += 1;
        };
        let x = fluid.x;
        for i in 0..x.x.len() {
            add(self.cell(Vec3::new(x.x[i], x.y[i], x.z[i])), fluid.rho[i]);
        }
        for s in solids {
            let x = s.x;
            for i in 0..x.x.len() {
                if let Some(at) = self.cell_in(Vec3::new(x.x[i], x.y[i], x.z[i]), [0; 3], [0; 3]) {
                    add(at, s.rho[i]);
                }
            }
        }
        let ceil = arena.alloc_slice_fill_copy(cells, 0.0f32);
        let above = arena.alloc_slice_fill_copy(cells, 0.0f32);
        let nu = self.dims[2];
        let (origin, cell) = (self.origin[2], self.cell);
        let columns = top.par_chunks_mut(nu).zip(rho.par_chunks_mut(nu)).zip(count.par_chunks(nu));
        columns.zip(ceil.par_chunks_mut(nu)).zip(above.par_chunks_mut(nu)).for_each(
            |((((top, rho), count), ceil), above)| {
                let mut mass = 0.0f32;
                for u in (0..nu).rev() {
                    if count[u] == 0 {
                        continue;
                    }
                    rho[u] /= count[u] as f32;
                    let highest = u + 1 == nu || count[u + 1] == 0;
                    if highest {
                        mass = 0.0;
                        ceil[u] = top[u] + 0.5 * d;
                    } else {
                        top[u] = top[u + 1];
                        ceil[u] = origin + (u + 1) as f32 * cell;
                    }
                    above[u] = mass;
                    mass += rho[u] * (ceil[u] - (origin + u as f32 * cell)).max(0.0);
                }
            },
        );
        Runs { top, rho, ceil, above }
    }
}

/// What [`Grid::runs`] finds per cell.
struct Runs<'a> {
    top: &'a [f32],
    rho: &'a [f32],
    ceil: &'a [f32],
    above: &'a [f32],
}

/// The columns along gravity: a [`Grid`] over the fluid's box and, for
/// every cell, its run of matter ([`Grid::runs`]).
pub struct Columns<'a> {
    grid: Grid,
    /// |g|, m/s^2.
    g: f32,
    runs: Runs<'a>,
    /// Per cell, the factor of the fluid at rest (`Grid::static_factor`);
    /// empty without obstacles given.
    factor: &'a [f32],
}

impl<'a> Columns<'a> {
    /// The columns of the `fluid` (particle spacing `d`) and of the
    /// `solids` in its box along `gravity`, or `None` where gravity is not
    /// along one axis or the fluid's box is too large a grid (then the
    /// warm start is the plain half).
    pub fn new(fluid: Matter, solids: &[Matter], gravity: [f32; 3], d: f32, arena: &'a Bump) -> Option<Columns<'a>> {
        let (axis, sign) = up_axis(gravity)?;
        let grid = Grid::new(fluid.x, axis, sign, 2.0 * d)?;
        let runs = grid.runs(fluid, solids, d, arena);
        Some(Columns { grid, g: gravity[axis].abs(), runs, factor: &[] })
    }

    /// [`Columns::new`] that also sees lateral free faces: the column's
    /// weight times the factor by which the pressure of the fluid at rest
    /// in this geometry falls below its column's ([`Grid::static_factor`];
    /// air is an empty cell, in the grid or one cell beyond the fluid's box
    /// across, open to the sky and holding none of the `obstacles`, walls
    /// and solids). A dam's face then starts near p = 0 and a released
    /// column near its free fall, as the flow will have them, instead of
    /// at rho g depth; in a pool at rest the factor is 1 and the estimate
    /// is `new`'s.
    pub fn with_faces(
        fluid: Matter,
        solids: &[Matter],
        obstacles: &[Vel],
        gravity: [f32; 3],
        d: f32,
        arena: &'a Bump,
    ) -> Option<Columns<'a>> {
        let mut c = Columns::new(fluid, solids, gravity, d, arena)?;
        let x = fluid.x;
        let occupied = arena.alloc_slice_fill_copy(c.grid.dims.iter().product(), false);
        for i in 0..x.x.len() {
            let (cell, _) = c.grid.cell(Vec3::new(x.x[i], x.y[i], x.z[i]));
            occupied[cell] = true;
        }
        c.factor = c.grid.static_factor(occupied, obstacles, arena);
        Some(c)
    }

    /// The estimate at the point at `x`, Pa: |g| (above + rho (ceil - up))
    /// of its cell (the column's mass per unit area above the point), 0 in
    /// an empty cell or above the top; with [`Columns::with_faces`], times
    /// its cell's factor.
    #[inline]
    pub fn pressure(&self, x: Vec3) -> f32 {
        let (c, up) = self.grid.cell(x);
        let r = &self.runs;
        if r.top[c] == f32::NEG_INFINITY {
            return 0.0;
        }
        let weight = r.above[c] + r.rho[c] * (r.ceil[c] - up).max(0.0);
        self.g * weight * self.factor.get(c).copied().unwrap_or(1.0)
    }
}

fn coord<'a>(x: Vel<'a>, k: usize) -> &'a [f32] {
    match k {
        0 => x.x,
        1 => x.y,
        _ => x.z,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn at(x: Vel, i: usize) -> Vec3 {
        Vec3::new(x.x[i], x.y[i], x.z[i])
    }

    fn lattice(n: [usize; 3], d: f32, lift: f32) -> [Vec<f32>; 3] {
        let mut out = [Vec::new(), Vec::new(), Vec::new()];
        for k in 0..n[2] {
            for j in 0..n[1] {
                for i in 0..n[0] {
                    out[0].push((i as f32 + 0.5) * d);
                    out[1].push((j as f32 + 0.5) * d + lift);
                    out[2].push((k as f32 + 0.5) * d);
                }
            }
        }
        out
    }

    /// A 10 x 30 x 10 block of water at d = 1 cm with gravity -y, from a
    /// zero last pressure: p = 0.5 rho g depth with depth from the block's
    /// top (the top particle half a spacing below it), to f32 rounding.
    #[test]
    fn a_resting_block_gets_half_its_hydrostatic_pressure() {
        let (d, g) = (0.01f32, 9.81f32);
        let x = lattice([10, 30, 10], d, 0.0);
        let n = x[0].len();
        let mut p = vec![0.0; n];
        let arena = Bump::new();
        let x = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let rho = vec![1000.0; n];
        let c = Columns::new(Matter { x, rho: &rho }, &[], [0.0, -g, 0.0], d, &arena);
        assert!(c.is_some());
        warm_start(c.as_ref(), |i| at(x, i), &mut p);
        for (i, (&p, &y)) in p.iter().zip(x.y).enumerate() {
            let want = 0.5 * 1000.0 * g * (0.3 - y);
            assert!((p - want).abs() <= 1e-4 * 1000.0 * g * 0.3, "particle {i}: {p} against {want}");
        }
    }

    /// Two blocks one above the other with a gap of 3 cm (more than a
    /// cell of 2d): the lower block's depth is from its own top, not the
    /// upper block's. Gravity along -z this time, and a last pressure that
    /// is halved.
    #[test]
    fn a_gap_ends_the_column_and_the_last_pressure_is_halved() {
        let (d, g) = (0.01f32, 9.81f32);
        let low = lattice([6, 6, 6], d, 0.0);
        let high = lattice([6, 6, 6], d, 0.09);
        // Gravity along -z: swap y and z of the lattices.
        let xs: Vec<f32> = low[0].iter().chain(&high[0]).copied().collect();
        let ys: Vec<f32> = low[2].iter().chain(&high[2]).copied().collect();
        let zs: Vec<f32> = low[1].iter().chain(&high[1]).copied().collect();
        let n = xs.len();
        let mut p = vec![100.0; n];
        let arena = Bump::new();
        let x = Vel { x: &xs, y: &ys, z: &zs };
        let rho = vec![1000.0; n];
        let c = Columns::new(Matter { x, rho: &rho }, &[], [0.0, 0.0, -g], d, &arena);
        warm_start(c.as_ref(), |i| at(x, i), &mut p);
        for (i, (&p, &z)) in p.iter().zip(&zs).enumerate() {
            let top = if z < 0.06 { 0.06 } else { 0.15 };
            let want = 50.0 + 0.5 * 1000.0 * g * (top - z);
            assert!((p - want).abs() <= 1e-3 * want, "particle {i} at z {z}: {p} against {want}");
        }
    }

    /// Particles of an `n` lattice at spacing `d` from the origin, and
    /// wall layers (3 deep) around the box [0, n d] but for its top and,
    /// with `open_x`, its side at x = n[0] d.
    fn boxed(n: [usize; 3], d: f32, open_x: bool) -> ([Vec<f32>; 3], [Vec<f32>; 3]) {
        let x = lattice(n, d, 0.0);
        let mut w = [Vec::new(), Vec::new(), Vec::new()];
        let n = n.map(|v| v as i32);
        for k in -3..n[2] + 3 {
            for j in -3..n[1] + 10 {
                for i in -3..n[0] + 30 {
                    let (in_x, in_y, in_z) = (i >= 0 && (open_x || i < n[0]), j >= 0, (0..n[2]).contains(&k));
                    if !(in_x && in_y && in_z) {
                        w[0].push((i as f32 + 0.5) * d);
                        w[1].push((j as f32 + 0.5) * d);
                        w[2].push((k as f32 + 0.5) * d);
                    }
                }
            }
        }
        (x, w)
    }

    /// The estimate at `x` in metres of water (the tests' fluids are 1000
    /// kg/m^3 under g = 9.81 m/s^2): the column's depth where it is full.
    fn head(c: &Columns, x: Vec3) -> f32 {
        c.pressure(x) / (1000.0 * 9.81)
    }

    /// [`Columns::with_faces`] of the particles `x` among the walls `w`
    /// (d = 1 cm, gravity -y).
    fn faces<'a>(x: &'a [Vec<f32>; 3], w: &'a [Vec<f32>; 3], arena: &'a Bump) -> Columns<'a> {
        let xv = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let walls = [Vel { x: &w[0], y: &w[1], z: &w[2] }];
        let rho = arena.alloc_slice_fill_copy(x[0].len(), 1000.0f32);
        Columns::with_faces(Matter { x: xv, rho }, &[], &walls, [0.0, -9.81, 0.0], 0.01, arena).expect("a grid")
    }

    /// A dam: a column 0.15 m wide and 0.3 m high at d = 1 cm, 4 layers in
    /// z between walls, a wall behind it (x < 0) and none in front (x >
    /// 0.15 m). Reference: the exact pressure of the column released at
    /// rest (incompressible potential flow, 2-D: p / rho g = (H - y) -
    /// sum_n 2 / (H k_n^2) cos(k_n y) cosh(k_n x) / cosh(k_n L), with
    /// k_n = (n + 1/2) pi / H, x from the back wall, L the width). Bound:
    /// 1.5 d of head, what placing p = 0 on the face of a cell of 2 d, up
    /// to 1.5 d beyond the fluid's edge (0.165 m here, the face at 0.15
    /// m), shifts under a slope of at most rho g; the column's depth alone
    /// is up to 0.28 m off (at the face's foot). Measured (2026-12-06): largest difference 0.0115 m (x =
    /// 0.075 m, y = 0.055 m: 0.0609 against 0.0494 m), at the back wall's
    /// floor 0.1101 against 0.1059 m, beside the face at the floor 0.0203
    /// against 0.0112 m.
    #[test]
    fn a_released_dam_column_is_estimated_at_its_potential_flow_pressure() {
        let d = 0.01f32;
        let (x, w) = boxed([15, 30, 4], d, true);
        let arena = Bump::new();
        let c = faces(&x, &w, &arena);
        let (h, l) = (0.3f64, 0.15f64);
        let exact = |x: f64, y: f64| {
            let q: f64 = (0..200)
                .map(|n| {
                    let k = (n as f64 + 0.5) * std::f64::consts::PI / h;
                    2.0 / (h * k * k) * (k * y).cos() * (k * x).cosh() / (k * l).cosh()
                })
                .sum();
            (h - y) - q
        };
        let mut worst = 0.0f64;
        for xi in [0.005f32, 0.045, 0.075, 0.105, 0.145] {
            for yi in [0.005f32, 0.055, 0.105, 0.155, 0.205, 0.255, 0.295] {
                let est = f64::from(head(&c, Vec3::new(xi, yi, 0.015)));
                let want = exact(f64::from(xi), f64::from(yi));
                println!("x {xi} y {yi}: estimate {est:.4} m, exact {want:.4} m");
                worst = worst.max((est - want).abs());
            }
        }
        assert!(worst <= 1.5 * f64::from(d), "largest difference {worst} m of head");
    }

    /// In a closed tank (walls all around but the top) there is no air
    /// beside the fluid: the estimate is the column's depth to the bit.
    #[test]
    fn a_closed_tank_keeps_the_column_depth() {
        let (x, w) = boxed([12, 20, 6], 0.01, false);
        let arena = Bump::new();
        let with = faces(&x, &w, &arena);
        let xv = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let rho = vec![1000.0; x[0].len()];
        let plain = Columns::new(Matter { x: xv, rho: &rho }, &[], [0.0, -9.81, 0.0], 0.01, &arena).expect("a grid");
        for i in 0..x[0].len() {
            let at = at(xv, i);
            assert_eq!(with.pressure(at).to_bits(), plain.pressure(at).to_bits(), "particle {i} at {at}");
        }
    }

    /// A hole in the bulk is not a free face: the closed tank of the test
    /// above with the particles of one cell (x and y in [0.04, 0.06) m,
    /// every z) taken out keeps the column's depth beside it (an empty
    /// cell with fluid above and below is fluid).
    #[test]
    fn a_hole_in_the_bulk_does_not_lower_the_estimate_beside_it() {
        let (full, w) = boxed([12, 20, 6], 0.01, false);
        let hole = |x: f32, y: f32| (0.04..0.06).contains(&x) && (0.04..0.06).contains(&y);
        let keep: Vec<usize> = (0..full[0].len()).filter(|&i| !hole(full[0][i], full[1][i])).collect();
        let x = [0, 1, 2].map(|k| keep.iter().map(|&i| full[k][i]).collect::<Vec<f32>>());
        let arena = Bump::new();
        let with = faces(&x, &w, &arena);
        let xv = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let mut beside = 0;
        for i in 0..x[0].len() {
            let at = at(xv, i);
            if (0.02..0.04).contains(&at.x) && (0.04..0.06).contains(&at.y) {
                beside += 1;
                let depth = 0.2 - at.y;
                assert!((head(&with, at) - depth).abs() < 1e-5, "particle {i} at {at}: {} m", head(&with, at));
            }
        }
        assert_eq!(beside, 24);
    }

    /// Two fluids stacked, 1500 kg/m^3 (15 layers) over 1000 kg/m^3 (15
    /// layers), d = 1 cm, gravity -y. Reference: hydrostatics, p(y) = g
    /// times the mass per unit area above y: 1500 g (0.3 - y) in the heavy
    /// fluid, 1500 g 0.15 + 1000 g (0.15 - y) in the light one. The column's
    /// depth with each particle's own density gave the light fluid's top
    /// 1000 g 0.15 instead of 1500 g 0.15 (Rayleigh-Taylor with the
    /// hydrostatic warm start blew up at step 74, bench/RESULTS.md). Bound:
    /// (1500 - 1000) g d, the resolution of cells of 2 d: a cell that
    /// holds both fluids spreads their mean density over its height, which
    /// moves the interface by up to half a cell (measured: 24.5 Pa, that is
    /// 500 g d / 2, where the cells' faces lie half a spacing off the
    /// layers').
    #[test]
    fn a_heavy_fluid_over_a_light_one_weighs_on_it() {
        let (d, g) = (0.01f32, 9.81f32);
        let x = lattice([10, 30, 4], d, 0.0);
        let rho: Vec<f32> = x[1].iter().map(|&y| if y > 0.15 { 1500.0 } else { 1000.0 }).collect();
        let arena = Bump::new();
        let xv = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let c = Columns::new(Matter { x: xv, rho: &rho }, &[], [0.0, -g, 0.0], d, &arena).expect("a grid");
        for (i, &y) in x[1].iter().enumerate() {
            let want = if y > 0.15 { 1500.0 * g * (0.3 - y) } else { 1500.0 * g * 0.15 + 1000.0 * g * (0.15 - y) };
            let got = c.pressure(at(xv, i));
            assert!((got - want).abs() <= 500.0 * g * d, "particle {i} at y {y}: {got} against {want} Pa");
        }
    }

    /// A body on the floor of a pool carries its weight and the fluid's
    /// above it down to the floor. A 1500 kg/m^3 solid block, 4 cells
    /// across and 6 layers high (0-0.06 m) in the middle of a 12-layer pool
    /// of water (0-0.12 m), d = 1 cm: reference, hydrostatics, the floor
    /// under the block at 1000 g 0.06 + 1500 g 0.06 (the fluid above it and
    /// the block), the floor beside it at 1000 g 0.12, the fluid above the
    /// block at 1000 g (0.12 - y). A point of the body outside the fluid's
    /// box weighs on nothing. Bound: (1500 - 1000) g d, the cells'
    /// resolution of the block's top (the test above; measured 24.5 Pa
    /// under the block).
    #[test]
    fn a_body_on_the_floor_presses_it_with_its_weight_and_the_fluid_above() {
        let (d, g) = (0.01f32, 9.81f32);
        let all = lattice([16, 12, 4], d, 0.0);
        let in_block = |x: f32, y: f32| (0.04..0.12).contains(&x) && y < 0.06;
        let (fluid, solid): (Vec<usize>, Vec<usize>) =
            (0..all[0].len()).partition(|&i| !in_block(all[0][i], all[1][i]));
        let pick = |ids: &[usize]| [0, 1, 2].map(|k| ids.iter().map(|&i| all[k][i]).collect::<Vec<f32>>());
        let (xf, mut xs) = (pick(&fluid), pick(&solid));
        // One stray body point far above the fluid's box.
        xs[0].push(0.05);
        xs[1].push(0.5);
        xs[2].push(0.015);
        let (rf, rs) = (vec![1000.0f32; xf[0].len()], vec![1500.0f32; xs[0].len()]);
        let arena = Bump::new();
        let (vf, vs) = (Vel { x: &xf[0], y: &xf[1], z: &xf[2] }, Vel { x: &xs[0], y: &xs[1], z: &xs[2] });
        let solids = [Matter { x: vs, rho: &rs }];
        let c = Columns::new(Matter { x: vf, rho: &rf }, &solids, [0.0, -g, 0.0], d, &arena).expect("a grid");
        let tol = 500.0 * g * d;
        let under = c.pressure(Vec3::new(0.08, -0.005, 0.015));
        let want = 1000.0 * g * 0.06 + 1500.0 * g * 0.06 + 1500.0 * g * 0.005;
        assert!((under - want).abs() <= tol, "floor under the block: {under} against {want} Pa");
        let beside = c.pressure(Vec3::new(0.015, -0.005, 0.015));
        let want = 1000.0 * g * 0.125;
        assert!((beside - want).abs() <= tol, "floor beside the block: {beside} against {want} Pa");
        for (i, (&x, &y)) in xf[0].iter().zip(&xf[1]).enumerate() {
            if (0.04..0.12).contains(&x) {
                let (got, want) = (c.pressure(at(vf, i)), 1000.0 * g * (0.12 - y));
                assert!((got - want).abs() <= tol, "fluid at x {x} y {y} above the block: {got} against {want} Pa");
            }
        }
    }

    /// No gravity, or gravity not along an axis: the plain half warm start.
    #[test]
    fn without_an_axis_of_gravity_it_only_halves() {
        let xs = lattice([4, 4, 4], 0.01, 0.0);
        let n = xs[0].len();
        let arena = Bump::new();
        for gravity in [[0.0, 0.0, 0.0], [1.0, -9.0, 0.0]] {
            let mut p = vec![10.0; n];
            let x = Vel { x: &xs[0], y: &xs[1], z: &xs[2] };
            let rho = vec![1000.0; n];
            let c = Columns::new(Matter { x, rho: &rho }, &[], gravity, 0.01, &arena);
            assert!(c.is_none());
            warm_start(c.as_ref(), |i| at(x, i), &mut p);
            assert!(p.iter().all(|&v| v == 5.0));
        }
    }
}
