//! Sampling shapes into particles on the lattice of spacing d.
//!
//! Two lattices are used, both with spacing d = `simulation.particle_spacing`:
//!
//! - a box is sampled on its own lattice, `x = min + (i + 1/2) d` per axis with
//!   `i in 0..n`, `n = round((max - min) / d)`. When `(max - min) / d` is not an
//!   integer the box is snapped: it is treated as `n d` long from `min`;
//! - spheres, cylinders and meshes are sampled on the global lattice
//!   `x = (i + 1/2) d`.
//!
//! Walls are sampled as a shell two layers deep, the width of the kernel
//! support H = 2 d: wall particles deeper inside a solid are never neighbours of
//! a fluid particle. Overlaps are resolved by dropping any particle closer than
//! d / 2 to one kept before it (walls in file order, then fluid blocks in file
//! order), with a hash grid of cell size d.

use super::{Scene, Shape, Wall};
use std::collections::HashMap;

/// Fluid particles sampled from all `[[fluid]]` blocks.
#[derive(Clone, Debug, Default)]
pub struct SampledFluid {
    /// Positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Velocities, m/s.
    pub velocities: Vec<[f32; 3]>,
    /// Per particle, the volume fraction of each phase (len = number of phases).
    pub fractions: Vec<Vec<f32>>,
}

/// Solid particles sampled from all `[[solid]]` entries.
#[derive(Clone, Debug, Default)]
pub struct SampledSolids {
    /// Positions, m.
    pub positions: Vec<[f32; 3]>,
    /// Velocities, m/s.
    pub velocities: Vec<[f32; 3]>,
    /// Index of the `[[solid]]` entry of each particle.
    pub body: Vec<u32>,
    /// 1 for particles inside the solid's `fixed` shape.
    pub fixed: Vec<u32>,
}

/// Static wall particles sampled from all `[[wall]]` entries.
#[derive(Clone, Debug, Default)]
pub struct SampledWalls {
    /// Positions, m.
    pub positions: Vec<[f32; 3]>,
}

/// The least distance of a fluid particle from a solid particle at the
/// start, in units of d: the rest spacing, less 1e-3 d for the rounding of
/// lattice positions. The pressure solve reads a fluid-solid pair
/// closer than d as compression and removes it within the first step,
/// whatever the body weighs. Measured (issue 34, placement seed 432: a 120 kg/m^3 box
/// of 3 layers at the surface of a pool at d = 1 cm, max_dt 2 ms): its
/// mean velocity after step 1 is 2.74, 2.29, 1.65, 1.02, 0.44, 0.07 and
/// -0.02 m/s with its lowest layer 0.76, 0.80, 0.85, 0.90, 0.95, 0.99 and
/// 1.00 d above the fluid's top layer. With the old bound, 3/4 d, that box
/// left the water at 2.5 m/s and flew to the container's ceiling.
pub const FLUID_SOLID_GAP: f64 = 1.0 - 1e-3;

/// The least distance of a free (not `fixed`) solid particle from a wall
/// particle at the start, in units of d: as [`FLUID_SOLID_GAP`], for the
/// same reason (a solid row closer than d to a wall reads as compression).
/// Measured (issue 34): a 1500 kg/m^3 box of 0.1 x 0.06 x 0.1 m standing
/// on the floor of a pool at d = 1 cm, max_dt 2 ms, its lowest lattice
/// layer 0.7 d above the floor's inner wall layer (the box's `min` 3 mm
/// below the floor) had a particle at 1.59 m/s after step 1 (0.022 m/s with
/// the layer at d). A fixed particle does not move, so the rows between it
/// and a wall have no mobility to act on: clamped bodies keep d / 2.
pub const SOLID_WALL_GAP: f64 = FLUID_SOLID_GAP;

/// The least distance of a fluid particle from a wall particle at the
/// start, in units of d: as [`FLUID_SOLID_GAP`]. Measured (issue 34): a
/// pool at d = 1 cm whose fluid box starts 3 mm (0.3 d) below the floor,
/// its lowest layer 0.7 d above the floor's inner wall layer: the first
/// step's solve ran to its cap of 100 sweeps and the fastest particle
/// reached 1.59 m/s (2.46 m/s after step 3), against 0.022 m/s with the box
/// on the floor's lattice.
pub const FLUID_WALL_GAP: f64 = FLUID_SOLID_GAP;

/// The least distance at the start between particles of two bodies of
/// which at least one is free, in units of d: as [`SOLID_WALL_GAP`].
/// Measured (issue 34): a 1500 kg/m^3 box of 0.08 x 0.04 x 0.08 m set 3 mm
/// (0.3 d) into another standing on the floor of a pool at d = 1 cm, max_dt
/// 2 ms: a particle at 1.54 m/s after step 1 (0.022 m/s with the two on one
/// lattice, a spacing apart).
pub const SOLID_SOLID_GAP: f64 = FLUID_SOLID_GAP;

/// Samples the fluid blocks of a scene, block by block in file order, each in
/// lattice order (z outermost, then y, then x).
///
/// A box block takes its own lattice points (`min + (i + 1/2) d`, `i in 0..n`);
/// a sphere or cylinder block takes the global lattice points `(i + 1/2) d`
/// inside it (signed distance <= 0). A point is dropped when it is closer than
/// [`FLUID_WALL_GAP`] to a wall particle or d / 2 to a particle of an earlier
/// block, or when it lies inside a solid (non-container) wall shape, whose
/// core holds no wall particles but is not fluid either. Velocity and phase fractions come from
/// the block.
///
/// Fluid is also kept out of solids: a point inside a `[[solid]]` shape, or
/// closer than [`FLUID_SOLID_GAP`] to a solid particle, is dropped (solids
/// sampled on a box lattice of their own may be offset from the fluid's).
pub fn sample_fluid(scene: &Scene, walls: &SampledWalls) -> SampledFluid {
    let mut out = SampledFluid::default();
    let solid_particles = sample_solids(scene, walls);
    let Some(d) = spacing(scene) else {
        return out;
    };
    let min_dist = 0.5 * d;
    let mut grid = PointGrid::new(d);
    let mut wall_grid = PointGrid::new(d);
    for &p in &walls.positions {
        wall_grid.insert(p);
    }
    let solids: Vec<&Wall> = scene.walls.iter().filter(|w| !w.container).collect();
    let mut solid_grid = PointGrid::new(d);
    for &p in &solid_particles.positions {
        solid_grid.insert(p);
    }
    let in_solid =
        |p: [f32; 3]| scene.solids.iter().any(|s| inside(&s.shape, p)) || solid_grid.any_within(p, FLUID_SOLID_GAP * d);
    for block in &scene.fluids {
        let mut candidates = Vec::new();
        filled(&block.shape, d, &mut candidates);
        for p in candidates {
            if solids.iter().any(|w| inside(&w.shape, p))
                || wall_grid.any_within(p, FLUID_WALL_GAP * d)
                || grid.any_within(p, min_dist)
                || in_solid(p)
            {
                continue;
            }
            grid.insert(p);
            out.positions.push(p);
            out.velocities.push(block.velocity);
            out.fractions.push(block.fractions.clone());
        }
    }
    out
}

/// Samples the solids of a scene, body by body in file order, each in lattice
/// order, like fluid blocks: a box on its own lattice, a sphere or cylinder
/// on the global one. A point closer than d / 2 to a wall particle or to a
/// particle of an earlier solid, or inside a solid (non-container) wall
/// shape, is dropped, and so is a free point (outside the body's `fixed`
/// shape) closer than [`SOLID_WALL_GAP`] to a wall particle or than
/// [`SOLID_SOLID_GAP`] to a particle of an earlier body, as is a fixed
/// point that close to a free particle of an earlier body. Particles
/// inside the body's `fixed` shape are marked.
pub fn sample_solids(scene: &Scene, walls: &SampledWalls) -> SampledSolids {
    let mut out = SampledSolids::default();
    let Some(d) = spacing(scene) else {
        return out;
    };
    let min_dist = 0.5 * d;
    let mut wall_grid = PointGrid::new(d);
    for &p in &walls.positions {
        wall_grid.insert(p);
    }
    // Every solid particle so far, and those of the earlier bodies, free
    // and fixed.
    let mut grid = PointGrid::new(d);
    let (mut free_grid, mut fixed_grid) = (PointGrid::new(d), PointGrid::new(d));
    let obstacles: Vec<&Wall> = scene.walls.iter().filter(|w| !w.container).collect();
    for (b, solid) in scene.solids.iter().enumerate() {
        let mut candidates = Vec::new();
        filled(&solid.shape, d, &mut candidates);
        let first = out.positions.len();
        for p in candidates {
            let fixed = solid.fixed.as_ref().is_some_and(|f| inside(f, p));
            let too_close = if fixed {
                wall_grid.any_within(p, min_dist) || free_grid.any_within(p, SOLID_SOLID_GAP * d)
            } else {
                wall_grid.any_within(p, SOLID_WALL_GAP * d)
                    || free_grid.any_within(p, SOLID_SOLID_GAP * d)
                    || fixed_grid.any_within(p, SOLID_SOLID_GAP * d)
            };
            if obstacles.iter().any(|w| inside(&w.shape, p)) || grid.any_within(p, min_dist) || too_close {
                continue;
            }
            grid.insert(p);
            out.positions.push(p);
            out.velocities.push(solid.velocity);
            out.body.push(b as u32);
            out.fixed.push(fixed as u32);
        }
        for k in first..out.positions.len() {
            if out.fixed[k] != 0 {
                fixed_grid.insert(out.positions[k]);
            } else {
                free_grid.insert(out.positions[k]);
            }
        }
    }
    out
}

/// Samples the walls of a scene, wall by wall in file order, each in lattice
/// order (z outermost, then y, then x).
///
/// - A container box (`container = true`) gets two layers of particles outside
///   its faces: its lattice points `min + (i + 1/2) d` with every index in
///   `-2..=n+1` and at least one index outside `0..n` (the interior lattice is
///   where fluid goes). With `open_top`, points above the box (y index >= n)
///   are left out, so the side walls end at the top of the box. A box whose
///   size is not a multiple of d is snapped to `n d` as described in the module
///   documentation.
/// - A solid box (an obstacle) gets its lattice points within two layers of
///   its faces (index < 2 or >= n - 2 on some axis).
/// - A solid sphere, cylinder or mesh gets the global lattice points
///   `(i + 1/2) d` with signed distance in (-2 d, 0]: a shell two particles
///   deep (for an axis-aligned cube mesh, the particles of the same box).
///
/// A point closer than d / 2 to a point of an earlier wall is dropped.
pub fn sample_walls(scene: &Scene) -> SampledWalls {
    let mut out = SampledWalls::default();
    let Some(d) = spacing(scene) else {
        return out;
    };
    let min_dist = 0.5 * d;
    let mut grid = PointGrid::new(d);
    for wall in &scene.walls {
        let mut candidates = Vec::new();
        match &wall.shape {
            Shape::Box { min, max } if wall.container => container_lattice(min, max, d, wall.open_top, &mut candidates),
            Shape::Box { min, max } => box_lattice(min, max, d, Some(2), &mut candidates),
            // Inside, and nearer the surface than two spacings.
            Shape::Mesh(m) => {
                m.lattice_inside(d, &mut candidates, |p| m.distance_below(p.map(f64::from), 2.0 * d).is_some())
            }
            shape => global_lattice(shape, d, &mut candidates, |s| s > -2.0 * d && s <= 0.0),
        }
        for p in candidates {
            if !grid.any_within(p, min_dist) {
                grid.insert(p);
                out.positions.push(p);
            }
        }
    }
    out
}

/// The lattice points a fluid block or solid of `shape` takes: a box its
/// own lattice, the other shapes the global lattice points inside them.
fn filled(shape: &Shape, d: f64, out: &mut Vec<[f32; 3]>) {
    match shape {
        Shape::Box { min, max } => box_lattice(min, max, d, None, out),
        Shape::Mesh(m) => m.lattice_inside(d, out, |_| true),
        shape => global_lattice(shape, d, out, |s| s <= 0.0),
    }
}

/// Whether `p` is inside `shape` (signed distance <= 0; for a mesh, its
/// winding number, without the distance).
fn inside(shape: &Shape, p: [f32; 3]) -> bool {
    match shape {
        Shape::Mesh(m) => m.contains(p.map(f64::from)),
        shape => sdf(shape, p) <= 0.0,
    }
}

/// Signed distance from `p` to the surface of `shape`, m: negative inside,
/// positive outside, exact for all four shapes (the cylinder is capped at
/// both ends; a mesh's distance is to its nearest triangle).
pub fn sdf(shape: &Shape, p: [f32; 3]) -> f32 {
    let p = p.map(f64::from);
    let dist = match shape {
        Shape::Mesh(m) => m.signed_distance(p),
        Shape::Box { min, max } => {
            // Standard box distance: q = |p - centre| - half extent per axis.
            let mut q = [0.0; 3];
            for i in 0..3 {
                let (lo, hi) = (f64::from(min[i]), f64::from(max[i]));
                q[i] = (p[i] - 0.5 * (lo + hi)).abs() - 0.5 * (hi - lo);
            }
            let outside = norm(q.map(|c| c.max(0.0)));
            let inside = q[0].max(q[1]).max(q[2]).min(0.0);
            outside + inside
        }
        Shape::Sphere { center, radius } => {
            let v = [0, 1, 2].map(|i| p[i] - f64::from(center[i]));
            norm(v) - f64::from(*radius)
        }
        Shape::Cylinder { base, axis, radius, height } => {
            let v = [0, 1, 2].map(|i| p[i] - f64::from(base[i]));
            let a = axis.map(f64::from);
            let t = v[0] * a[0] + v[1] * a[1] + v[2] * a[2];
            let radial = norm([0, 1, 2].map(|i| v[i] - t * a[i]));
            let h = f64::from(*height);
            // 2-D box distance in (radial, axial) coordinates.
            let q_r = radial - f64::from(*radius);
            let q_a = (t - 0.5 * h).abs() - 0.5 * h;
            norm([q_r.max(0.0), q_a.max(0.0), 0.0]) + q_r.max(q_a).min(0.0)
        }
    };
    dist as f32
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

/// The particle spacing as f64, or `None` when it is unusable (a [`Scene`] built
/// by hand rather than parsed).
fn spacing(scene: &Scene) -> Option<f64> {
    let d = f64::from(scene.simulation.particle_spacing);
    (d.is_finite() && d > 0.0).then_some(d)
}

/// Largest lattice index range per axis: keeps index arithmetic far from
/// overflow for scenes built by hand (parsed scenes are limited much more).
const MAX_CELLS_PER_AXIS: f64 = (1u64 << 30) as f64;

/// Number of lattice cells of a box axis: `round((max - min) / d)`.
fn cells(lo: f32, hi: f32, d: f64) -> i64 {
    let n = ((f64::from(hi) - f64::from(lo)) / d).round();
    if n.is_nan() {
        0
    } else {
        n.clamp(0.0, MAX_CELLS_PER_AXIS) as i64
    }
}

/// Position of lattice index `i` on a box axis starting at `lo`.
fn box_coord(lo: f32, i: i64, d: f64) -> f32 {
    (f64::from(lo) + (i as f64 + 0.5) * d) as f32
}

/// The lattice points of a box, `min + (i + 1/2) d` with `i in 0..n` per axis.
/// With `layers = Some(L)`, only the points fewer than L layers from a face
/// (index < L or >= n - L on some axis); with `None`, all of them.
fn box_lattice(min: &[f32; 3], max: &[f32; 3], d: f64, layers: Option<i64>, out: &mut Vec<[f32; 3]>) {
    let n = [0, 1, 2].map(|a| cells(min[a], max[a], d));
    let layers = layers.unwrap_or(i64::MAX);
    let depth = |i: i64, n: i64| i.min(n - 1 - i);
    for k in 0..n[2] {
        let z = box_coord(min[2], k, d);
        for j in 0..n[1] {
            let y = box_coord(min[1], j, d);
            let push = |out: &mut Vec<[f32; 3]>, i: i64| out.push([box_coord(min[0], i, d), y, z]);
            if depth(j, n[1]).min(depth(k, n[2])) < layers {
                (0..n[0]).for_each(|i| push(out, i));
            } else {
                // Deep row: only the layers at both x ends.
                let front = layers.min(n[0]);
                (0..front).for_each(|i| push(out, i));
                (front.max(n[0] - layers)..n[0]).for_each(|i| push(out, i));
            }
        }
    }
}

/// The two layers of lattice points outside a container box: every index in
/// `-2..=n+1`, at least one outside `0..n`; with `open_top`, the y index stops
/// at `n - 1`.
fn container_lattice(min: &[f32; 3], max: &[f32; 3], d: f64, open_top: bool, out: &mut Vec<[f32; 3]>) {
    let n = [0, 1, 2].map(|a| cells(min[a], max[a], d));
    let inside = |i: i64, n: i64| (0..n).contains(&i);
    let j_end = if open_top { n[1] - 1 } else { n[1] + 1 };
    for k in -2..=n[2] + 1 {
        let z = box_coord(min[2], k, d);
        for j in -2..=j_end {
            let y = box_coord(min[1], j, d);
            if inside(j, n[1]) && inside(k, n[2]) {
                // The row crosses the interior: only the end layers are wall.
                for i in [-2, -1, n[0], n[0] + 1] {
                    out.push([box_coord(min[0], i, d), y, z]);
                }
            } else {
                for i in -2..=n[0] + 1 {
                    out.push([box_coord(min[0], i, d), y, z]);
                }
            }
        }
    }
}

/// The global lattice points `(i + 1/2) d` in the bounding box of `shape`
/// (a sphere or cylinder) whose signed distance passes `keep`.
fn global_lattice(shape: &Shape, d: f64, out: &mut Vec<[f32; 3]>, keep: impl Fn(f64) -> bool) {
    let (lo, hi) = bounds(shape);
    // Index range covering [lo, hi] with one cell to spare on each side.
    let range = |a: usize| {
        let first = (lo[a] / d - 0.5).floor() - 1.0;
        let last = (hi[a] / d - 0.5).ceil() + 1.0;
        if !(first.is_finite() && last.is_finite()) || last - first > MAX_CELLS_PER_AXIS {
            return (0, -1);
        }
        (first as i64, last as i64)
    };
    let (rx, ry, rz) = (range(0), range(1), range(2));
    let coord = |i: i64| ((i as f64 + 0.5) * d) as f32;
    for k in rz.0..=rz.1 {
        for j in ry.0..=ry.1 {
            for i in rx.0..=rx.1 {
                let p = [coord(i), coord(j), coord(k)];
                if keep(f64::from(sdf(shape, p))) {
                    out.push(p);
                }
            }
        }
    }
}

/// Axis-aligned bounding box of a shape, m.
fn bounds(shape: &Shape) -> ([f64; 3], [f64; 3]) {
    match shape {
        Shape::Mesh(m) => m.bounds(),
        Shape::Box { min, max } => (min.map(f64::from), max.map(f64::from)),
        Shape::Sphere { center, radius } => {
            let r = f64::from(*radius);
            (center.map(|c| f64::from(c) - r), center.map(|c| f64::from(c) + r))
        }
        Shape::Cylinder { base, axis, radius, height } => {
            let mut lo = [0.0; 3];
            let mut hi = [0.0; 3];
            for i in 0..3 {
                let a = f64::from(axis[i]);
                let b = f64::from(base[i]);
                let top = b + f64::from(*height) * a;
                // The end discs reach r sqrt(1 - a_i^2) along axis i.
                let reach = f64::from(*radius) * (1.0 - a * a).max(0.0).sqrt();
                lo[i] = b.min(top) - reach;
                hi[i] = b.max(top) + reach;
            }
            (lo, hi)
        }
    }
}

/// Points hashed into cubic cells of size `cell`, for "is any point within r"
/// queries with r <= cell.
struct PointGrid {
    cell: f64,
    cells: HashMap<[i64; 3], Vec<[f32; 3]>>,
}

impl PointGrid {
    fn new(cell: f64) -> Self {
        PointGrid { cell, cells: HashMap::new() }
    }

    fn key(&self, p: [f32; 3]) -> [i64; 3] {
        // `as` saturates, so far-away or non-finite points cannot overflow.
        p.map(|c| (f64::from(c) / self.cell).floor() as i64)
    }

    fn insert(&mut self, p: [f32; 3]) {
        let key = self.key(p);
        self.cells.entry(key).or_default().push(p);
    }

    /// Whether a stored point is closer than `r` (<= the cell size) to `p`.
    fn any_within(&self, p: [f32; 3], r: f64) -> bool {
        debug_assert!(r <= self.cell);
        let c = self.key(p);
        let r2 = r * r;
        for dz in -1..=1i64 {
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let key = [c[0].saturating_add(dx), c[1].saturating_add(dy), c[2].saturating_add(dz)];
                    let Some(points) = self.cells.get(&key) else {
                        continue;
                    };
                    let hit = points.iter().any(|q| {
                        let v = [0, 1, 2].map(|a| f64::from(p[a]) - f64::from(q[a]));
                        v[0] * v[0] + v[1] * v[1] + v[2] * v[2] < r2
                    });
                    if hit {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// A particle of an elastic body whose rest neighbourhood is flat: its
/// neighbours in the body (closer than the kernel support H = 2 d) lie on
/// a line or in a plane, or it has none. Its gradient correction
/// L_i = (sum_j V_j0 grad W_ij0 (x) (x_j0 - x_i0))^-1 (P-Eq. 4, PHYSICS.md
/// §3.1) does not exist, so its strain has no response across that plane.
pub(super) struct FlatParticle {
    /// Index, among `shapes`, of the shape it was sampled from.
    pub shape: usize,
    pub position: [f32; 3],
    /// Its neighbours in the body.
    pub neighbours: usize,
    /// Particles of the body, and how many of them are flat.
    pub particles: usize,
    pub flat: usize,
}

/// The first flat particle (see [`FlatParticle`]) of the body made of
/// `shapes` (each with its `fixed` shape: fixed particles move as told and
/// need no strain), sampled as [`sample_solids`] does, without the walls
/// and other bodies that may take points away.
pub(super) fn first_flat_particle(shapes: &[(&Shape, Option<&Shape>)], d: f64) -> Option<FlatParticle> {
    let mut grid = PointGrid::new(d);
    let mut points: Vec<([f32; 3], usize, bool)> = Vec::new();
    for (k, (shape, fixed)) in shapes.iter().enumerate() {
        let mut candidates = Vec::new();
        filled(shape, d, &mut candidates);
        for p in candidates {
            if !grid.any_within(p, 0.5 * d) {
                grid.insert(p);
                points.push((p, k, fixed.is_some_and(|f| inside(f, p))));
            }
        }
    }
    let support = PointGrid { cell: 2.0 * d, cells: HashMap::new() };
    let mut cells: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, (p, _, _)) in points.iter().enumerate() {
        cells.entry(support.key(*p)).or_default().push(i);
    }
    let (h2, mut first, mut flat) = (4.0 * d * d, None, 0);
    for (i, &(p, k, fixed)) in points.iter().enumerate() {
        if fixed {
            continue;
        }
        // The scatter matrix sum_j (x_j - x_i) (x) (x_j - x_i) is singular
        // exactly when the neighbours do not span three dimensions.
        let (mut s, mut n) = ([[0.0f64; 3]; 3], 0);
        let c = support.key(p);
        for dz in -1..=1i64 {
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    for &j in cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]).map_or(&[][..], |v| v) {
                        let v = [0, 1, 2].map(|a| f64::from(points[j].0[a]) - f64::from(p[a]));
                        let r2 = v[0] * v[0] + v[1] * v[1] + v[2] * v[2];
                        if j != i && r2 < h2 {
                            n += 1;
                            for (a, row) in s.iter_mut().enumerate() {
                                for (b, e) in row.iter_mut().enumerate() {
                                    *e += v[a] * v[b];
                                }
                            }
                        }
                    }
                }
            }
        }
        let det = s[0][0] * (s[1][1] * s[2][2] - s[1][2] * s[2][1]) - s[0][1] * (s[1][0] * s[2][2] - s[1][2] * s[2][0])
            + s[0][2] * (s[1][0] * s[2][1] - s[1][1] * s[2][0]);
        let scale = (s[0][0] + s[1][1] + s[2][2]) / 3.0;
        if det <= 1e-6 * scale * scale * scale {
            flat += 1;
            first.get_or_insert((k, p, n));
        }
    }
    first.map(|(shape, position, neighbours)| FlatParticle {
        shape,
        position,
        neighbours,
        particles: points.len(),
        flat,
    })
}
