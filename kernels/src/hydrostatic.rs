//! The warm start of the pressure solve (pass 4c, PHYSICS.md §2.2): half
//! the last step's pressure and half a hydrostatic estimate rho_i |g|
//! depth_i, the depth under the top of the fluid particle's connected
//! column.
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
//! bench/RESULTS.md). So the estimate also falls towards lateral free
//! faces ([`Columns::with_faces`]): a point is taken no deeper than its
//! distance across to air (an empty cell holding no wall or solid
//! particle), 0.18 m/s after the first step there, 0.036 with
//! `wall_rows = "lattice"`; in a closed tank there is no air and the
//! estimate is the column's depth as before.

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

/// p_i <- 0.5 p_i + 0.5 rho_i |g| depth_i for the points i of `p`, at
/// `at(i)` with rest densities `rho(i)` (kg/m^3), or p_i <- 0.5 p_i
/// without `columns`. The points are given by index, so that a caller's
/// subset (the active walls) needs no copy of its positions.
pub fn warm_start(
    columns: Option<&Columns>,
    at: impl Fn(usize) -> Vec3 + Sync,
    rho: impl Fn(usize) -> f32 + Sync,
    p: &mut [f32],
) {
    match columns {
        Some(c) => p.par_iter_mut().enumerate().for_each(|(i, p)| {
            *p = 0.5 * *p + 0.5 * rho(i) * c.g * c.depth(at(i));
        }),
        None => p.par_iter_mut().for_each(|p| *p *= 0.5),
    }
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

    /// The cell of the point at `x` in the grid widened by one cell on
    /// each side across (dims `[na + 2, nb + 2, nu]`), if it lies there.
    #[inline]
    fn cell_widened(&self, x: Vec3) -> Option<usize> {
        let q = [x[self.across[0]], x[self.across[1]], self.sign * x[self.axis]];
        let widen = [1usize, 1, 0];
        let mut idx = [0usize; 3];
        for k in 0..3 {
            let f = (q[k] - self.origin[k]) / self.cell + widen[k] as f32;
            let n = self.dims[k] + 2 * widen[k];
            if !(f >= 0.0 && f < n as f32) {
                return None;
            }
            idx[k] = (f as usize).min(n - 1);
        }
        Some((idx[0] * (self.dims[1] + 2) + idx[1]) * self.dims[2] + idx[2])
    }

    /// For every cell, the distance in cells, across (within its layer),
    /// to the nearest air: a cell above the highest fluid cell of its
    /// column (`occupied`) that holds none of `obstacles`, inside the grid
    /// or in the ring of cells around it across (a ring cell holds no
    /// fluid). An empty cell with fluid above it (a hole in the bulk, a
    /// cavity under a sheet) is not air: capping there would put an
    /// estimate near 0 amid the fluid. `f32::MAX` where a layer has none. A 3 x 3 chamfer transform (steps
    /// 1 and sqrt 2), two sweeps a layer, over the widened grid.
    fn air_distance<'a>(&self, occupied: &[bool], obstacles: &[Vel], arena: &'a Bump) -> &'a [f32] {
        let [na, nb, nu] = self.dims;
        let (wa, wb) = (na + 2, nb + 2);
        let widened = |a: usize, b: usize, u: usize| (a * wb + b) * nu + u;
        let solid = arena.alloc_slice_fill_copy(wa * wb * nu, false);
        for o in obstacles {
            for i in 0..o.x.len() {
                if let Some(c) = self.cell_widened(Vec3::new(o.x[i], o.y[i], o.z[i])) {
                    solid[c] = true;
                }
            }
        }
        let dist = arena.alloc_slice_fill_copy(wa * wb * nu, f32::MAX);
        for a in 0..wa {
            for b in 0..wb {
                let inner = (1..=na).contains(&a) && (1..=nb).contains(&b);
                let column = |u: usize| inner && occupied[((a - 1) * nb + (b - 1)) * nu + u];
                // Open to the sky: above the column's highest fluid cell.
                let open_from = (0..nu).rev().find(|&u| column(u)).map_or(0, |u| u + 1);
                for u in open_from..nu {
                    if !solid[widened(a, b, u)] {
                        dist[widened(a, b, u)] = 0.0;
                    }
                }
            }
        }
        let diag = std::f32::consts::SQRT_2;
        for u in 0..nu {
            let at = |a: usize, b: usize| widened(a, b, u);
            for a in 0..wa {
                for b in 0..wb {
                    let mut m = dist[at(a, b)];
                    if a > 0 {
                        m = m.min(dist[at(a - 1, b)] + 1.0);
                        if b > 0 {
                            m = m.min(dist[at(a - 1, b - 1)] + diag);
                        }
                        if b + 1 < wb {
                            m = m.min(dist[at(a - 1, b + 1)] + diag);
                        }
                    }
                    if b > 0 {
                        m = m.min(dist[at(a, b - 1)] + 1.0);
                    }
                    dist[at(a, b)] = m;
                }
            }
            for a in (0..wa).rev() {
                for b in (0..wb).rev() {
                    let mut m = dist[at(a, b)];
                    if a + 1 < wa {
                        m = m.min(dist[at(a + 1, b)] + 1.0);
                        if b > 0 {
                            m = m.min(dist[at(a + 1, b - 1)] + diag);
                        }
                        if b + 1 < wb {
                            m = m.min(dist[at(a + 1, b + 1)] + diag);
                        }
                    }
                    if b + 1 < wb {
                        m = m.min(dist[at(a, b + 1)] + 1.0);
                    }
                    dist[at(a, b)] = m;
                }
            }
        }
        arena.alloc_slice_fill_iter((0..na * nb * nu).map(|c| {
            let (ab, u) = (c / nu, c % nu);
            dist[widened(ab / nb + 1, ab % nb + 1, u)]
        }))
    }

    /// For every cell, the "up" coordinate of the highest point of `x` in
    /// the gap-free run of occupied cells it belongs to (-inf if empty).
    fn run_tops<'a>(&self, x: Vel, arena: &'a Bump) -> &'a [f32] {
        let top = arena.alloc_slice_fill_copy(self.dims.iter().product(), f32::NEG_INFINITY);
        for i in 0..x.x.len() {
            let (c, up) = self.cell(Vec3::new(x.x[i], x.y[i], x.z[i]));
            top[c] = top[c].max(up);
        }
        top.par_chunks_mut(self.dims[2]).for_each(|col| {
            for u in (0..col.len().saturating_sub(1)).rev() {
                if col[u] != f32::NEG_INFINITY && col[u + 1] != f32::NEG_INFINITY {
                    col[u] = col[u + 1];
                }
            }
        });
        top
    }
}

/// The fluid's columns along gravity: a [`Grid`] over the fluid's box and,
/// for every cell, the "up" coordinate of the highest particle of the
/// gap-free run of occupied cells it belongs to.
pub struct Columns<'a> {
    grid: Grid,
    /// |g|, m/s^2.
    g: f32,
    /// Particle spacing, m.
    d: f32,
    top: &'a [f32],
    /// Per cell, the distance across to air (`Grid::air_distance`), in
    /// cells; empty without obstacles given.
    air: &'a [f32],
}

impl<'a> Columns<'a> {
    /// The columns of the fluid at positions `x` (particle spacing `d`)
    /// along `gravity`, or `None` where gravity is not along one axis or
    /// the fluid's box is too large a grid (then the warm start is the
    /// plain half).
    pub fn new(x: Vel, gravity: [f32; 3], d: f32, arena: &'a Bump) -> Option<Columns<'a>> {
        let (axis, sign) = up_axis(gravity)?;
        let grid = Grid::new(x, axis, sign, 2.0 * d)?;
        let top = grid.run_tops(x, arena);
        Some(Columns { grid, g: gravity[axis].abs(), d, top, air: &[] })
    }

    /// [`Columns::new`] that also sees lateral free faces: an empty cell
    /// (in the grid or one cell beyond the fluid's box across) open to
    /// the sky that holds none of the `obstacles` (walls, solids) is air, and a point some
    /// cells across from air is estimated no deeper than that distance
    /// (`depth`); where there is no air, the same estimate as `new`. A dam's vertical face then starts near p = 0, as the
    /// flow will have it, instead of at rho g depth.
    pub fn with_faces(x: Vel, obstacles: &[Vel], gravity: [f32; 3], d: f32, arena: &'a Bump) -> Option<Columns<'a>> {
        let (axis, sign) = up_axis(gravity)?;
        let grid = Grid::new(x, axis, sign, 2.0 * d)?;
        let occupied = arena.alloc_slice_fill_copy(grid.dims.iter().product(), false);
        for i in 0..x.x.len() {
            let (c, _) = grid.cell(Vec3::new(x.x[i], x.y[i], x.z[i]));
            occupied[c] = true;
        }
        let air = grid.air_distance(occupied, obstacles, arena);
        let top = grid.run_tops(x, arena);
        Some(Columns { grid, g: gravity[axis].abs(), d, top, air })
    }

    /// The depth of the point at `x` under the top of its column's run
    /// plus half a spacing (the free surface above the top particle), m; 0
    /// in an empty cell or above the top.
    #[inline]
    pub fn depth(&self, x: Vec3) -> f32 {
        let (c, up) = self.grid.cell(x);
        let depth = (self.top[c] - up + 0.5 * self.d).max(0.0);
        match self.air.get(c) {
            Some(&cells) => depth.min((cells - 0.5).max(0.0) * self.grid.cell),
            None => depth,
        }
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
        let c = Columns::new(x, [0.0, -g, 0.0], d, &arena);
        assert!(c.is_some());
        warm_start(c.as_ref(), |i| at(x, i), |_| 1000.0, &mut p);
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
        warm_start(Columns::new(x, [0.0, 0.0, -g], d, &arena).as_ref(), |i| at(x, i), |_| 1000.0, &mut p);
        for (i, (&p, &z)) in p.iter().zip(&zs).enumerate() {
            let top = if z < 0.06 { 0.06 } else { 0.15 };
            let want = 50.0 + 0.5 * 1000.0 * g * (top - z);
            assert!((p - want).abs() <= 1e-3 * want, "particle {i} at z {z}: {p} against {want}");
        }
    }

    /// A dam: a 20 x 20 x 4 column at d = 1 cm between walls (behind it
    /// at x < 0, under it, in front and behind in z), open at x = 0.2 m
    /// (the walls there only below the floor and beside it in z). Without the walls given as
    /// obstacles the estimate is rho g depth everywhere; with them the
    /// column's particles next to the open face are estimated at most a
    /// spacing deep (the face is at p = 0), those one cell (2 d) further
    /// at most 3 d, and the ones along the wall keep rho g depth down to
    /// the depth of the face's distance.
    #[test]
    fn a_lateral_free_face_lowers_the_estimate_and_a_wall_does_not() {
        let (d, g) = (0.01f32, 9.81f32);
        let x = lattice([20, 20, 4], d, 0.0);
        // Wall layers (3 deep) at x < 0, under the floor, and in front of
        // and behind the column (z < 0, z > 0.04 m); none at x > 0.2 m.
        let wall = {
            let mut w = [Vec::new(), Vec::new(), Vec::new()];
            for k in -3..7 {
                for j in -3..23 {
                    for i in -3..23 {
                        let inside = (0..4).contains(&k) && j >= 0 && i >= 0;
                        if !inside {
                            w[0].push((i as f32 + 0.5) * d);
                            w[1].push((j as f32 + 0.5) * d);
                            w[2].push((k as f32 + 0.5) * d);
                        }
                    }
                }
            }
            w
        };
        let arena = Bump::new();
        let xv = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let walls = [Vel { x: &wall[0], y: &wall[1], z: &wall[2] }];
        let faces = Columns::with_faces(xv, &walls, [0.0, -g, 0.0], d, &arena).expect("a grid");
        let plain = Columns::new(xv, [0.0, -g, 0.0], d, &arena).expect("a grid");
        for i in 0..x[0].len() {
            let at = at(xv, i);
            let depth = 0.2 - at.y;
            assert!((plain.depth(at) - depth).abs() < 1e-5, "plain, particle {i}");
            let est = faces.depth(at);
            if at.x > 0.18 {
                assert!(est <= d + 1e-6, "particle {i} at {at}: {est} m beside the face");
            } else if at.x > 0.16 {
                assert!(est <= 3.0 * d + 1e-6, "particle {i} at {at}: {est} m a cell from the face");
            } else if at.x < 0.02 {
                // Capped only by the face 9.5 cells (0.19 m) across.
                assert!((est - depth.min(0.19)).abs() < 1e-5, "particle {i} at {at}: {est} m along the wall");
            }
            assert!(est <= depth + 1e-6);
        }
    }

    /// A hole in the bulk is not a free face: the dam of the test above
    /// with the particles of one cell (x and y in [0.08, 0.10) m, every z)
    /// taken out; the particles in the cells beside it across keep the
    /// depth of their columns (the face is 0.12 m away, deeper than they
    /// are).
    #[test]
    fn a_hole_in_the_bulk_does_not_lower_the_estimate_beside_it() {
        let (d, g) = (0.01f32, 9.81f32);
        let full = lattice([20, 20, 4], d, 0.0);
        let hole = |x: f32, y: f32| (0.08..0.10).contains(&x) && (0.08..0.10).contains(&y);
        let keep: Vec<usize> = (0..full[0].len()).filter(|&i| !hole(full[0][i], full[1][i])).collect();
        let x = [0, 1, 2].map(|k| keep.iter().map(|&i| full[k][i]).collect::<Vec<f32>>());
        let wall = lattice([26, 26, 10], d, 0.0).map(|c| c.iter().map(|&v| v - 3.0 * d).collect::<Vec<f32>>());
        let out = |i: usize| wall[2][i] < 0.0 || wall[2][i] > 0.04 || wall[1][i] < 0.0 || wall[0][i] < 0.0;
        let sel: Vec<usize> = (0..wall[0].len()).filter(|&i| out(i)).collect();
        let wall = [0, 1, 2].map(|k| sel.iter().map(|&i| wall[k][i]).collect::<Vec<f32>>());
        let arena = Bump::new();
        let xv = Vel { x: &x[0], y: &x[1], z: &x[2] };
        let walls = [Vel { x: &wall[0], y: &wall[1], z: &wall[2] }];
        let faces = Columns::with_faces(xv, &walls, [0.0, -g, 0.0], d, &arena).expect("a grid");
        let mut beside = 0;
        for i in 0..x[0].len() {
            let at = at(xv, i);
            if (0.06..0.08).contains(&at.x) && (0.08..0.10).contains(&at.y) {
                beside += 1;
                let depth = 0.2 - at.y;
                assert!((faces.depth(at) - depth).abs() < 1e-5, "particle {i} at {at}: {} m", faces.depth(at));
            }
        }
        assert_eq!(beside, 16);
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
            let c = Columns::new(x, gravity, 0.01, &arena);
            assert!(c.is_none());
            warm_start(c.as_ref(), |i| at(x, i), |_| 1000.0, &mut p);
            assert!(p.iter().all(|&v| v == 5.0));
        }
    }
}
