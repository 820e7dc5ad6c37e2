//! Cell-range tables: how a GPU pass finds the neighbours of a particle
//! without pair lists. A query row (a fluid cell, or one active wall) has
//! 27 (start, end) particle ranges of a target set sorted by cell: the
//! occupied cells among the 27 around the row's cell, in the fixed order of
//! [`CellGrid::neighbor_ranges`], then empty (0, 0) slots. A pass scans these
//! ranges and keeps the targets closer than the support H, the same set the
//! CPU neighbour search stores as pairs.
//!
//! [`RangesGpu`] builds the same tables on the GPU (`shaders/ranges.wgsl`),
//! bitwise equal (`tests/gpu_ranges.rs`); the GPU passes do not use it yet
//! (they upload the tables built here on the CPU).

use super::buffers::{read_back, GpuArray, READBACK, STORAGE};
use super::{GpuContext, GpuError};
use porosph_kernels::grid::{cell_of, unmorton, CellGrid};
use porosph_kernels::neighbors::Points;
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
pub fn wall_rows(walls: Points, active: &[u32], fluid_grid: &CellGrid, bf: &mut Vec<[u32; 2]>) {
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
const NAMES: [&str; 9] =
    ["fluid_cells", "fluid_starts", "wall_cells", "wall_starts", "wall_pos", "active", "ff", "fb", "bf"];
/// Storage bindings 1..=9: whether each is read-only.
const READ_ONLY: [bool; 9] = [true, true, true, true, true, true, false, false, false];
const WG: u32 = 64;

fn dims(groups: u32) -> (u32, u32) {
    let x = groups.min(65535);
    (x, groups.div_ceil(x.max(1)))
}

/// The cell-range tables built on the GPU (`shaders/ranges.wgsl`), bitwise
/// those of [`fluid_rows`] and [`wall_rows`].
pub struct RangesGpu {
    pipelines: Vec<wgpu::ComputePipeline>,
    layout: wgpu::BindGroupLayout,
    bind_group: Option<wgpu::BindGroup>,
    params: wgpu::Buffer,
    bufs: Vec<GpuArray>,
    reads: Vec<GpuArray>,
    keys: [Vec<[u32; 2]>; 2],
    wall_pos: Vec<[f32; 4]>,
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
            reads: ["read ff", "read fb", "read bf"].iter().map(|n| GpuArray::new(ctx, n, READBACK)).collect(),
            keys: [Vec::new(), Vec::new()],
            wall_pos: Vec::new(),
        }
    }

    /// Builds the tables of [`fluid_rows`] (`ff`, `fb`; one row per fluid
    /// cell) and [`wall_rows`] (`bf`; one row per active wall) on the GPU
    /// and reads them back.
    #[allow(clippy::too_many_arguments)]
    pub fn build(
        &mut self,
        ctx: &GpuContext,
        fluid_grid: &CellGrid,
        wall_grid: &CellGrid,
        walls: Points,
        active: &[u32],
        ff: &mut Vec<[u32; 2]>,
        fb: &mut Vec<[u32; 2]>,
        bf: &mut Vec<[u32; 2]>,
    ) -> Result<(), GpuError> {
        let (nf, nw, na) = (fluid_grid.len(), wall_grid.len(), active.len());
        for (keys, grid) in self.keys.iter_mut().zip([fluid_grid, wall_grid]) {
            keys.clear();
            keys.extend(grid.cells.iter().map(|&k| [(k >> 32) as u32, k as u32]));
        }
        self.wall_pos.clear();
        self.wall_pos.extend((0..walls.len()).map(|i| [walls.x[i], walls.y[i], walls.z[i], 0.0]));
        let rows = |n: usize| (8 * RANGES * n) as u64;
        let sizes: [u64; 9] = [
            8 * nf as u64,
            4 * fluid_grid.starts.len() as u64,
            8 * nw as u64,
            4 * wall_grid.starts.len() as u64,
            16 * walls.len() as u64,
            4 * na as u64,
            rows(nf),
            rows(nf),
            rows(na),
        ];
        let mut replaced = false;
        for (b, &bytes) in self.bufs.iter_mut().zip(&sizes) {
            replaced |= b.reserve(ctx, bytes, true)?;
        }
        for (r, &bytes) in self.reads.iter_mut().zip(&sizes[6..]) {
            r.reserve(ctx, bytes, false)?;
        }
        if replaced || self.bind_group.is_none() {
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
            n_wall_cells: nw as u32,
            n_active: na as u32,
            inv_cell: fluid_grid.inv_cell,
        };
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let b = &self.bufs;
        b[0].upload(ctx, &self.keys[0]);
        b[1].upload(ctx, &fluid_grid.starts);
        b[2].upload(ctx, &self.keys[1]);
        b[3].upload(ctx, &wall_grid.starts);
        b[4].upload(ctx, &self.wall_pos);
        b[5].upload(ctx, active);
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass =
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("ranges"), timestamp_writes: None });
            pass.set_bind_group(0, self.bind_group.as_ref(), &[]);
            for (p, n) in self.pipelines.iter().zip([nf, na]) {
                let (x, y) = dims((n as u32).div_ceil(WG));
                if x > 0 && y > 0 {
                    pass.set_pipeline(p);
                    pass.dispatch_workgroups(x, y, 1);
                }
            }
        }
        for (k, r) in self.reads.iter().enumerate() {
            if sizes[6 + k] > 0 {
                enc.copy_buffer_to_buffer(&self.bufs[6 + k].buf, 0, &r.buf, 0, sizes[6 + k]);
            }
        }
        ctx.queue.submit([enc.finish()]);
        ff.resize(nf * RANGES, [0, 0]);
        fb.resize(nf * RANGES, [0, 0]);
        bf.resize(na * RANGES, [0, 0]);
        let reads: Vec<(&wgpu::Buffer, u64)> = self.reads.iter().zip(&sizes[6..]).map(|(r, &s)| (&r.buf, s)).collect();
        let mut outs = [ff, fb, bf];
        read_back(ctx, &reads, |k, bytes| {
            for (o, v) in outs[k].iter_mut().zip(bytes.chunks_exact(8)) {
                *o = bytemuck::pod_read_unaligned(v);
            }
        })
    }
}
