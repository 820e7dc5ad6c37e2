//! Cell-range tables: how a GPU pass finds the neighbours of a particle
//! without pair lists. A query row (a fluid cell, or one active wall) has
//! 27 (start, end) particle ranges of a target set sorted by cell: the
//! occupied cells among the 27 around the row's cell, in the fixed order of
//! [`CellGrid::neighbor_ranges`], then empty (0, 0) slots. A pass scans these
//! ranges and keeps the targets closer than the support H, the same set the
//! CPU neighbour search stores as pairs.
//!
//! [`RangesGpu`] builds the same tables on the GPU (`shaders/ranges.wgsl`),
//! bitwise equal (`tests/gpu_ranges.rs`), into device buffers that the GPU
//! passes (`IisphGpu`, `DriftGpu`) bind: one build per step, shared by the
//! passes, no read-back. [`fluid_rows`] and [`wall_rows`] here are the CPU
//! reference the tests compare against.

use super::buffers::{read_back, GpuArray, READBACK, STORAGE};
use super::{GpuContext, GpuError};
pub use crate::backend::passes::WallInput;
use porosph_kernels::grid::{cell_of, unmorton, CellGrid};
use porosph_kernels::soa::Vel;
use rayon::prelude::*;

/// Ranges per query row.
pub const RANGES: usize = 27;

fn fill(target: &CellGrid, cell: [u32; 3], out: &mut [[u32; 2]]) {
    let mut r = [(0u32, 0u32); RANGES];
    let n = if target.is_empty() { 0 } else { target.neighbor_ranges(cell, &mut r) };
    for (o, &(s, e)) in out.iter_mut().zip(&r[..n]) {
        *o = [s, e];
    }
    out[n..].fill([0, 0]);
}

/// Rows of the fluid particles, one per occupied fluid cell: `cell_row[i]`
/// is the cell of fluid particle i (the fluid is sorted by cell), and row c
/// of `ff` / `fb` holds the fluid / wall ranges around cell c.
pub fn fluid_rows(
    fluid_grid: &CellGrid,
    wall_grid: &CellGrid,
    cell_row: &mut Vec<u32>,
    ff: &mut Vec<[u32; 2]>,
    fb: &mut Vec<[u32; 2]>,
) {
    let cells = fluid_grid.len();
    let n = fluid_grid.starts.last().copied().unwrap_or(0) as usize;
    cell_row.resize(n, 0);
    for (c, w) in fluid_grid.starts.windows(2).enumerate() {
        cell_row[w[0] as usize..w[1] as usize].fill(c as u32);
    }
    ff.resize(cells * RANGES, [0, 0]);
    fb.resize(cells * RANGES, [0, 0]);
    ff.par_chunks_mut(RANGES).zip(fb.par_chunks_mut(RANGES)).zip(fluid_grid.cells.par_iter()).for_each(
        |((f, b), &key)| {
            let c = unmorton(key);
            fill(fluid_grid, c, f);
            fill(wall_grid, c, b);
        },
    );
}

/// Rows of the active walls, one per wall: row k of `bf` holds the fluid
/// ranges around the cell of wall `active[k]`.
pub fn wall_rows(walls: Vel, active: &[u32], fluid_grid: &CellGrid, bf: &mut Vec<[u32; 2]>) {
    bf.resize(active.len() * RANGES, [0, 0]);
    bf.par_chunks_mut(RANGES).zip(active.par_iter()).for_each(|(out, &b)| {
        let b = b as usize;
        fill(fluid_grid, cell_of(walls.x[b], walls.y[b], walls.z[b], fluid_grid.inv_cell), out);
    });
}

/// The uniform parameters of `shaders/ranges.wgsl` (`struct RangesParams`);
/// a test checks that the layouts match.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RangesParams {
    pub n_fluid_cells: u32,
    pub n_wall_cells: u32,
    pub n_active: u32,
    /// 1 / cell size of the fluid grid, 1/m.
    pub inv_cell: f32,
}

const ENTRY_POINTS: [&str; 2] = ["fluid_rows", "wall_rows"];
const NAMES: [&str; 10] =
    ["fluid_cells", "fluid_starts", "wall_cells", "wall_starts", "wall_pos", "active", "ff", "fb", "bf", "cell_row"];
/// Storage bindings 1..=10: whether each is read-only.
const READ_ONLY: [bool; 10] = [true, true, true, true, true, true, false, false, false, false];
// Index into `bufs` (binding - 1).
const FLUID_CELLS: usize = 0;
const FLUID_STARTS: usize = 1;
const WALL_CELLS: usize = 2;
const WALL_STARTS: usize = 3;
const WALL_POS: usize = 4;
const ACTIVE: usize = 5;
const FF: usize = 6;
const FB: usize = 7;
const BF: usize = 8;
const CELL_ROW: usize = 9;
/// The buffers the passes bind: a replaced one bumps [`RangesGpu::version`].
const SHARED: [usize; 6] = [WALL_POS, ACTIVE, FF, FB, BF, CELL_ROW];
const WG: u32 = 64;

fn dims(groups: u32) -> (u32, u32) {
    let x = groups.min(65535);
    (x, groups.div_ceil(x.max(1)))
}

/// Makes `dst` a copy of `src`; true if it was not one already.
fn stage<T: PartialEq>(dst: &mut Vec<T>, src: impl ExactSizeIterator<Item = T> + Clone) -> bool {
    if dst.len() == src.len() && dst.iter().zip(src.clone()).all(|(a, b)| *a == b) {
        return false;
    }
    dst.clear();
    dst.extend(src);
    true
}

/// The cell-range tables of the current grids on the GPU
/// (`shaders/ranges.wgsl`), bitwise those of [`fluid_rows`] and
/// [`wall_rows`], in device buffers the passes bind (`cell_row`, `ff`,
/// `fb`, `bf`, with the wall positions and active walls they were built
/// from). [`RangesGpu::ensure`] rebuilds them only when its input differs
/// from that of the last build (host copies of the grids are kept for
/// that comparison and for the upload), so the passes of a step share one
/// build, and the static wall grid and wall positions are uploaded once.
pub struct RangesGpu {
    pipelines: Vec<wgpu::ComputePipeline>,
    layout: wgpu::BindGroupLayout,
    bind_group: Option<wgpu::BindGroup>,
    params: wgpu::Buffer,
    bufs: Vec<GpuArray>,
    queries: Option<(wgpu::QuerySet, GpuArray, GpuArray)>,
    version: u64,
    builds: u64,
    /// Tables on the device: None (none yet), Some(false) fluid rows only
    /// (no walls: `fb` empty, no `bf`), Some(true) with the walls.
    built: Option<bool>,
    // What the tables were built from (host copies, also the upload staging).
    inv_cell: f32,
    fluid_keys: Vec<[u32; 2]>,
    fluid_starts: Vec<u32>,
    wall_keys: Vec<[u32; 2]>,
    wall_starts: Vec<u32>,
    wall_pos: Vec<[f32; 4]>,
    active: Vec<u32>,
}

impl RangesGpu {
    /// Compiles `shaders/ranges.wgsl` and builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Self {
        let (layout, pipelines, params) =
            ctx.compute_pipelines("ranges.wgsl", &READ_ONLY, &ENTRY_POINTS, std::mem::size_of::<RangesParams>());
        Self {
            pipelines,
            layout,
            bind_group: None,
            params,
            bufs: NAMES.iter().map(|n| GpuArray::new(ctx, n, STORAGE)).collect(),
            queries: ctx.timestamp_queries("ranges timestamps", "ranges timestamps read", 2),
            version: 0,
            builds: 0,
            built: None,
            inv_cell: 0.0,
            fluid_keys: Vec::new(),
            fluid_starts: Vec::new(),
            wall_keys: Vec::new(),
            wall_starts: Vec::new(),
            wall_pos: Vec::new(),
            active: Vec::new(),
        }
    }

    /// Makes the tables on the device those of `fluid_grid` and, with
    /// `walls`, of the walls: builds them (`fluid_rows`: `cell_row`, `ff`,
    /// `fb`; `wall_rows`: `bf`) unless the last build had the same input
    /// (tables with walls also serve a pass that asks for none). Uploads
    /// only what changed (the fluid grid, once per step; the walls' grid
    /// and positions when they change, i.e. once; the active walls). No
    /// read-back but the timestamps: returns the device time of the build,
    /// ms, 0 where nothing was built or the adapter has no timestamps.
    pub fn ensure(
        &mut self,
        ctx: &GpuContext,
        fluid_grid: &CellGrid,
        walls: Option<WallInput>,
    ) -> Result<f64, GpuError> {
        let key = |k: &u64| [(k >> 32) as u32, *k as u32];
        let mut fluid_new = stage(&mut self.fluid_keys, fluid_grid.cells.iter().map(key));
        fluid_new |= stage(&mut self.fluid_starts, fluid_grid.starts.iter().copied());
        fluid_new |= self.inv_cell.to_bits() != fluid_grid.inv_cell.to_bits();
        self.inv_cell = fluid_grid.inv_cell;
        let (mut wall_grid_new, mut wall_pos_new, mut active_new) = (false, false, false);
        if let Some(w) = walls {
            wall_grid_new = stage(&mut self.wall_keys, w.grid.cells.iter().map(key));
            wall_grid_new |= stage(&mut self.wall_starts, w.grid.starts.iter().copied());
            let p = w.walls;
            wall_pos_new = stage(&mut self.wall_pos, (0..p.len()).map(|i| [p.x[i], p.y[i], p.z[i], 0.0]));
            active_new = stage(&mut self.active, w.active.iter().copied());
        }
        let with_walls = walls.is_some();
        let current = match self.built {
            Some(had_walls) => {
                !fluid_new && (!with_walls || had_walls && !(wall_grid_new || wall_pos_new || active_new))
            }
            None => false,
        };
        if current {
            return Ok(0.0);
        }
        // Until this build is submitted: a failure below leaves the device
        // buffers unknown, and the next build uploads everything.
        let first = self.built.is_none();
        self.built = None;
        // A pass that asks for no walls gets fluid rows only (fb empty).
        let (nf, nwc, na) =
            (self.fluid_keys.len(), if with_walls { self.wall_keys.len() } else { 0 }, self.active_len(with_walls));
        let n = self.fluid_starts.last().copied().unwrap_or(0) as usize;
        let rows = |k: usize| (8 * RANGES * k) as u64;
        let sizes: [u64; 10] = [
            8 * nf as u64,
            4 * self.fluid_starts.len() as u64,
            8 * self.wall_keys.len() as u64,
            4 * self.wall_starts.len() as u64,
            16 * self.wall_pos.len() as u64,
            4 * self.active.len() as u64,
            rows(nf),
            rows(nf),
            rows(na),
            4 * n as u64,
        ];
        let mut replaced = [false; 10];
        for ((b, &bytes), r) in self.bufs.iter_mut().zip(&sizes).zip(&mut replaced) {
            *r = b.reserve(ctx, bytes, true)?;
        }
        if SHARED.iter().any(|&k| replaced[k]) {
            self.version += 1;
        }
        if replaced.iter().any(|&r| r) || self.bind_group.is_none() {
            let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() }];
            entries.extend(
                self.bufs
                    .iter()
                    .enumerate()
                    .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32 + 1, resource: b.buf.as_entire_binding() }),
            );
            self.bind_group = Some(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ranges"),
                layout: &self.layout,
                entries: &entries,
            }));
        }
        let params = RangesParams {
            n_fluid_cells: nf as u32,
            n_wall_cells: nwc as u32,
            n_active: na as u32,
            inv_cell: self.inv_cell,
        };
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        // A replaced buffer lost its contents: upload it again.
        let b = &self.bufs;
        if fluid_new || first || replaced[FLUID_CELLS] || replaced[FLUID_STARTS] {
            b[FLUID_CELLS].upload(ctx, &self.fluid_keys);
            b[FLUID_STARTS].upload(ctx, &self.fluid_starts);
        }
        if with_walls {
            if wall_grid_new || first || replaced[WALL_CELLS] || replaced[WALL_STARTS] {
                b[WALL_CELLS].upload(ctx, &self.wall_keys);
                b[WALL_STARTS].upload(ctx, &self.wall_starts);
            }
            if wall_pos_new || first || replaced[WALL_POS] {
                b[WALL_POS].upload(ctx, &self.wall_pos);
            }
            if active_new || first || replaced[ACTIVE] {
                b[ACTIVE].upload(ctx, &self.active);
            }
        }
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let timestamp_writes = self.queries.as_ref().map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            });
            let mut pass =
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("ranges"), timestamp_writes });
            pass.set_bind_group(0, self.bind_group.as_ref(), &[]);
            for (p, n) in self.pipelines.iter().zip([nf, na]) {
                let (x, y) = dims((n as u32).div_ceil(WG));
                if x > 0 && y > 0 {
                    pass.set_pipeline(p);
                    pass.dispatch_workgroups(x, y, 1);
                }
            }
        }
        if let Some((set, resolve, read)) = &self.queries {
            enc.resolve_query_set(set, 0..2, &resolve.buf, 0);
            enc.copy_buffer_to_buffer(&resolve.buf, 0, &read.buf, 0, 16);
        }
        ctx.queue.submit([enc.finish()]);
        self.built = Some(with_walls);
        self.builds += 1;
        let Some((_, _, read)) = &self.queries else { return Ok(0.0) };
        let mut stamps = [0u64; 2];
        read_back(ctx, &[(&read.buf, 16)], |_, bytes| stamps = bytemuck::pod_read_unaligned(bytes))?;
        let period = f64::from(ctx.queue.get_timestamp_period());
        Ok(stamps[1].saturating_sub(stamps[0]) as f64 * period * 1e-6)
    }

    fn active_len(&self, with_walls: bool) -> usize {
        if with_walls {
            self.active.len()
        } else {
            0
        }
    }

    /// Fluid particles of the tables on the device (the length of `cell_row`).
    pub fn n_fluid(&self) -> usize {
        if self.built.is_some() {
            self.fluid_starts.last().copied().unwrap_or(0) as usize
        } else {
            0
        }
    }

    /// Whether the tables on the device have the walls; then the number of
    /// walls (of `wall_pos`) and of active walls (rows of `bf`).
    pub fn walls(&self) -> Option<(usize, usize)> {
        (self.built == Some(true)).then_some((self.wall_pos.len(), self.active.len()))
    }

    /// How many times the tables were built.
    pub fn builds(&self) -> u64 {
        self.builds
    }

    /// Bumped whenever a buffer the passes bind is replaced (a pass then
    /// rebuilds its bind group).
    pub fn version(&self) -> u64 {
        self.version
    }

    /// Per fluid particle its row of `ff` / `fb` (u32).
    pub fn cell_row(&self) -> &wgpu::Buffer {
        &self.bufs[CELL_ROW].buf
    }

    /// Per fluid cell, 27 fluid ranges ((u32, u32)).
    pub fn ff(&self) -> &wgpu::Buffer {
        &self.bufs[FF].buf
    }

    /// Per fluid cell, 27 wall ranges.
    pub fn fb(&self) -> &wgpu::Buffer {
        &self.bufs[FB].buf
    }

    /// Per active wall, 27 fluid ranges.
    pub fn bf(&self) -> &wgpu::Buffer {
        &self.bufs[BF].buf
    }

    /// Wall positions (x, y, z, 0), m.
    pub fn wall_pos(&self) -> &wgpu::Buffer {
        &self.bufs[WALL_POS].buf
    }

    /// The active walls (u32 wall indices, ascending).
    pub fn active(&self) -> &wgpu::Buffer {
        &self.bufs[ACTIVE].buf
    }

    /// Reads the tables on the device back (tests; the step never does):
    /// `cell_row`, `ff`, `fb` and `bf` (empty without walls).
    pub fn read_tables(
        &self,
        ctx: &GpuContext,
        cell_row: &mut Vec<u32>,
        ff: &mut Vec<[u32; 2]>,
        fb: &mut Vec<[u32; 2]>,
        bf: &mut Vec<[u32; 2]>,
    ) -> Result<(), GpuError> {
        let (nf, na) =
            (if self.built.is_some() { self.fluid_keys.len() } else { 0 }, self.active_len(self.built == Some(true)));
        let n = self.n_fluid();
        let sizes = [4 * n as u64, (8 * RANGES * nf) as u64, (8 * RANGES * nf) as u64, (8 * RANGES * na) as u64];
        let reads: Vec<GpuArray> = ["read cell_row", "read ff", "read fb", "read bf"]
            .into_iter()
            .zip(&sizes)
            .map(|(l, &bytes)| {
                let mut r = GpuArray::new(ctx, l, READBACK);
                r.reserve(ctx, bytes, false).map(|_| r)
            })
            .collect::<Result<_, _>>()?;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for ((r, k), &bytes) in reads.iter().zip([CELL_ROW, FF, FB, BF]).zip(&sizes) {
            if bytes > 0 {
                enc.copy_buffer_to_buffer(&self.bufs[k].buf, 0, &r.buf, 0, bytes);
            }
        }
        ctx.queue.submit([enc.finish()]);
        cell_row.resize(n, 0);
        ff.resize(nf * RANGES, [0, 0]);
        fb.resize(nf * RANGES, [0, 0]);
        bf.resize(na * RANGES, [0, 0]);
        let list: Vec<(&wgpu::Buffer, u64)> = reads.iter().zip(&sizes).map(|(r, &s)| (&r.buf, s)).collect();
        read_back(ctx, &list, |k, bytes| {
            if k == 0 {
                for (o, v) in cell_row.iter_mut().zip(bytes.chunks_exact(4)) {
                    *o = bytemuck::pod_read_unaligned(v);
                }
                return;
            }
            let out = match k {
                1 => &mut *ff,
                2 => &mut *fb,
                _ => &mut *bf,
            };
            for (o, v) in out.iter_mut().zip(bytes.chunks_exact(8)) {
                *o = bytemuck::pod_read_unaligned(v);
            }
        })
    }
}
