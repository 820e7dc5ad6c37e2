//! Pass 5 on the GPU: the IISPH relaxed Jacobi loop with pressure boundaries
//! (`shaders/iisph.wgsl`, the twin of the Jacobi part of
//! `kernels/src/iisph.rs`; PHYSICS.md §2.2-2.4).
//!
//! Per step the host uploads what the loop reads (positions and volumes,
//! V/m, the warm-started pressures, the rows S and a_ii), and the loop
//! binds the cell-range tables, wall positions and active walls that
//! [`RangesGpu`] built on the device for this step's grids (no upload of
//! its own); then every iteration runs on the device: a^p, the fluid and
//! wall Jacobi updates, and the mean error in a fixed reduction tree that
//! also decides convergence. The host queues
//! [`ITERATIONS_PER_SUBMIT`] iterations per submission and reads back only
//! the 16-byte status between submissions; iterations after convergence
//! return at once, so the result does not depend on how iterations are
//! grouped. At the end it reads back p, a^p and the wall pressures.

use super::buffers::{read_back, GpuArray, READBACK, STORAGE};
use super::kernel::KernelParams;
use super::ranges::RangesGpu;
use super::{GpuContext, GpuError};
pub use crate::backend::passes::{SolveReport, SolveSettings};
use bytemuck::{Pod, Zeroable};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph::Rows;
use porosph_kernels::kernel::Kernel;
use porosph_kernels::soa::{Vel, VelMut};

/// Iterations queued per submission (the status is read back after each).
pub const ITERATIONS_PER_SUBMIT: u32 = 4;

/// The uniform parameters of `shaders/iisph.wgsl` (`struct IisphParams`);
/// a test checks that the layouts match.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct IisphParams {
    pub n_fluid: u32,
    pub n_active: u32,
    pub min_iterations: u32,
    pub max_iterations: u32,
    /// The scene's kernel.
    pub kernel: KernelParams,
    /// Time step, s.
    pub dt: f32,
    /// Jacobi relaxation omega.
    pub omega: f32,
    /// Target mean density error (fraction).
    pub max_density_error: f32,
    /// Fluid rows in the solve (diag != 0), at least 1.
    pub rows_active: f32,
    /// The Chebyshev semi-iteration's radius estimate, 0 = plain Jacobi.
    pub chebyshev_radius: f32,
    /// Plain sweeps before it starts (`chebyshev::PLAIN_SWEEPS`).
    pub chebyshev_plain: u32,
    pub pad0: u32,
    pub pad1: u32,
}

impl IisphParams {
    /// The parameters of a solve with the scene's kernel.
    pub fn new(kernel: &Kernel, s: &SolveSettings, n_fluid: usize, n_active: usize) -> Self {
        Self {
            n_fluid: n_fluid as u32,
            n_active: n_active as u32,
            min_iterations: s.min_iterations,
            max_iterations: s.max_iterations,
            kernel: KernelParams::from(kernel),
            dt: s.dt,
            omega: s.omega,
            max_density_error: s.max_density_error,
            rows_active: s.rows_active,
            chebyshev_radius: s.chebyshev_radius,
            chebyshev_plain: porosph_kernels::chebyshev::PLAIN_SWEEPS,
            pad0: 0,
            pad1: 0,
        }
    }
}

/// What the loop reads. The fluid is sorted by the cells of `fluid_grid`,
/// the walls by those of `wall_grid`; the grids, wall positions and active
/// walls are what the cell-range tables ([`RangesGpu::ensure`]) are built
/// from: the loop itself reads them from the tables on the device.
pub struct SolveInput<'a> {
    /// The scene's kernel (the one the rows were set up with).
    pub kernel: &'a Kernel,
    pub fluid_grid: &'a CellGrid,
    pub wall_grid: &'a CellGrid,
    pub fluid: Vel<'a>,
    pub walls: Vel<'a>,
    /// Fluid current volume V and V/m.
    pub vol: &'a [f32],
    pub vm: &'a [f32],
    /// Fluid rows (S, a_ii).
    pub rows: Rows<'a>,
    /// Current volume of every wall (0 for inactive walls), m^3.
    pub vol_wall: &'a [f32],
    /// Active walls, ascending, and their rows.
    pub active: &'a [u32],
    pub wall_rows: Rows<'a>,
    pub settings: SolveSettings,
}

/// What the loop writes: the pressures (read as the warm start) and the
/// final a^p.
pub struct SolveOutput<'a> {
    pub p: &'a mut [f32],
    /// Pressure of every wall (inactive walls: 0 on entry, left so).
    pub p_wall: &'a mut [f32],
    pub ap: VelMut<'a>,
}

const ENTRY_POINTS: [&str; 8] = [
    "pressure_acceleration",
    "fluid_jacobi",
    "wall_jacobi",
    "mean_error_partial",
    "mean_error",
    "pressure_acceleration_final",
    "chebyshev_fluid",
    "chebyshev_walls",
];
const PA: usize = 0;
const FJ: usize = 1;
const WJ: usize = 2;
const MEP: usize = 3;
const ME: usize = 4;
const PAF: usize = 5;
const CF: usize = 6;
const CW: usize = 7;

/// Storage bindings 1..=19 of the shader: whether each is read-only.
const READ_ONLY: [bool; 19] = [
    true, true, false, false, true, false, true, true, true, true, true, false, true, true, true, false, false, false,
    false,
];
// The loop's own buffers (index into `bufs`).
const POS: usize = 0;
const VM: usize = 1;
const P: usize = 2;
const AP: usize = 3;
const ROWS: usize = 4;
const ERR: usize = 5;
const WALL_VOL: usize = 6;
const P_WALL: usize = 7;
const WALL_ROWS: usize = 8;
const PARTIALS: usize = 9;
const STATUS: usize = 10;
const CHEB: usize = 11;
const CHEB_WALL: usize = 12;
const NAMES: [&str; 13] = [
    "pos",
    "vm",
    "p",
    "ap",
    "rows",
    "err",
    "wall_vol",
    "p_wall",
    "wall_rows",
    "partials",
    "status",
    "cheb",
    "cheb_wall",
];

/// Where a storage binding's buffer comes from: the loop's own, or the
/// cell-range tables (shared with the other passes).
#[derive(Clone, Copy)]
enum Source {
    Own(usize),
    Tables(fn(&RangesGpu) -> &wgpu::Buffer),
}

/// Storage bindings 1..=19 of the shader.
const BINDINGS: [Source; 19] = [
    Source::Own(POS),
    Source::Own(VM),
    Source::Own(P),
    Source::Own(AP),
    Source::Own(ROWS),
    Source::Own(ERR),
    Source::Tables(RangesGpu::cell_row),
    Source::Tables(RangesGpu::ff),
    Source::Tables(RangesGpu::fb),
    Source::Tables(RangesGpu::wall_pos),
    Source::Own(WALL_VOL),
    Source::Own(P_WALL),
    Source::Tables(RangesGpu::active),
    Source::Own(WALL_ROWS),
    Source::Tables(RangesGpu::bf),
    Source::Own(PARTIALS),
    Source::Own(STATUS),
    Source::Own(CHEB),
    Source::Own(CHEB_WALL),
];

/// Workgroup size of the gather entry points and span of one partial sum.
const WG: u32 = 64;
const RED_SPAN: u32 = 1024;
const MAX_DIM: u32 = 65535;

/// Workgroup counts (x, y) of a 2D dispatch covering `groups` workgroups.
fn dims(groups: u32) -> (u32, u32) {
    let x = groups.min(MAX_DIM);
    (x, groups.div_ceil(x.max(1)))
}

/// Pipelines, resident buffers and host staging of the GPU Jacobi loop.
pub struct IisphGpu {
    pipelines: Vec<wgpu::ComputePipeline>,
    layout: wgpu::BindGroupLayout,
    bind_group: Option<wgpu::BindGroup>,
    /// The [`RangesGpu::version`] the bind group was made with.
    tables_version: Option<u64>,
    params: wgpu::Buffer,
    bufs: Vec<GpuArray>,
    read_p: GpuArray,
    read_ap: GpuArray,
    read_p_wall: GpuArray,
    read_status: GpuArray,
    queries: Option<(wgpu::QuerySet, GpuArray, GpuArray)>,
    // Host staging, reused.
    pos: Vec<[f32; 4]>,
    rows: Vec<[f32; 2]>,
    wall_rows: Vec<[f32; 2]>,
    cheb: Vec<[f32; 2]>,
}

/// Most submissions one solve may take (`max_iterations` up to 1000) + the final pass.
const MAX_QUERIES: u32 = 2 * (1000 / ITERATIONS_PER_SUBMIT + 2);

impl IisphGpu {
    /// Compiles `shaders/iisph.wgsl` and builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Self {
        let (layout, pipelines, params) =
            ctx.compute_pipelines("iisph.wgsl", &READ_ONLY, &ENTRY_POINTS, std::mem::size_of::<IisphParams>());
        let queries = ctx.timestamp_queries("iisph timestamps", "iisph timestamps read", MAX_QUERIES);
        Self {
            pipelines,
            layout,
            bind_group: None,
            tables_version: None,
            params,
            bufs: NAMES.iter().map(|n| GpuArray::new(ctx, n, STORAGE)).collect(),
            read_p: GpuArray::new(ctx, "read p", READBACK),
            read_ap: GpuArray::new(ctx, "read ap", READBACK),
            read_p_wall: GpuArray::new(ctx, "read p_wall", READBACK),
            read_status: GpuArray::new(ctx, "read status", READBACK),
            queries,
            pos: Vec::new(),
            rows: Vec::new(),
            wall_rows: Vec::new(),
            cheb: Vec::new(),
        }
    }

    /// Runs the relaxed Jacobi loop of PHYSICS.md §2.2 until the mean
    /// predicted density error is at most the target (after at least
    /// `min_iterations`) or `max_iterations`, then computes a^p from the
    /// final pressures. The same loop as the CPU pass in `pipeline::step`.
    /// `tables` must hold the tables of `inp` with its walls
    /// ([`RangesGpu::ensure`] with `inp`'s grids, walls and active walls;
    /// `GpuBackend::pressure_solve` does that).
    pub fn solve(
        &mut self,
        ctx: &GpuContext,
        tables: &RangesGpu,
        inp: &SolveInput,
        out: SolveOutput,
    ) -> Result<SolveReport, GpuError> {
        let n = inp.fluid.len();
        let na = inp.active.len();
        let nw = inp.walls.len();
        let s = &inp.settings;
        if n == 0 {
            out.p_wall.iter_mut().for_each(|p| *p = 0.0);
            return Ok(SolveReport { iterations: s.min_iterations.max(1), ..Default::default() });
        }

        if tables.n_fluid() != n || tables.walls() != Some((nw, na)) {
            return Err(GpuError(format!(
                "the cell-range tables on the GPU are not those of the solve ({} fluid particles, walls {:?}; \
                 the solve has {n}, ({nw}, {na}))",
                tables.n_fluid(),
                tables.walls()
            )));
        }

        // Host staging: packed particle data.
        let f = inp.fluid;
        self.pos.clear();
        self.pos.extend((0..n).map(|i| [f.x[i], f.y[i], f.z[i], inp.vol[i]]));
        self.rows.clear();
        self.rows.extend(inp.rows.source.iter().zip(inp.rows.diag).map(|(&s, &d)| [s, d]));
        self.wall_rows.clear();
        self.wall_rows.extend(inp.wall_rows.source.iter().zip(inp.wall_rows.diag).map(|(&s, &d)| [s, d]));

        // Room on the device; a replaced buffer means a new bind group.
        let (n64, na64, nw64) = (n as u64, na as u64, nw as u64);
        let parts = u64::from((n as u32).div_ceil(RED_SPAN));
        // The semi-iteration's iterates only when it runs (8 bytes else).
        let cheb = s.chebyshev_radius > 0.0;
        let (nc, nca) = if cheb { (n64, na64) } else { (1, 1) };
        let sizes: [u64; 13] = [
            16 * n64,
            4 * n64,
            4 * n64,
            16 * n64,
            8 * n64,
            4 * n64,
            4 * nw64,
            4 * nw64,
            8 * na64,
            4 * parts,
            16,
            8 * nc,
            8 * nca,
        ];
        let mut replaced = false;
        for (b, &bytes) in self.bufs.iter_mut().zip(&sizes) {
            replaced |= b.reserve(ctx, bytes, true)?;
        }
        self.read_p.reserve(ctx, sizes[P], false)?;
        self.read_ap.reserve(ctx, sizes[AP], false)?;
        self.read_p_wall.reserve(ctx, sizes[P_WALL], false)?;
        self.read_status.reserve(ctx, 16, false)?;
        if replaced || self.bind_group.is_none() || self.tables_version != Some(tables.version()) {
            let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() }];
            entries.extend(BINDINGS.iter().enumerate().map(|(k, src)| {
                let buf = match *src {
                    Source::Own(b) => &self.bufs[b].buf,
                    Source::Tables(table) => table(tables),
                };
                wgpu::BindGroupEntry { binding: k as u32 + 1, resource: buf.as_entire_binding() }
            }));
            self.tables_version = Some(tables.version());
            self.bind_group = Some(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("iisph"),
                layout: &self.layout,
                entries: &entries,
            }));
        }

        // Uploads: once per step, only what the loop reads (the tables,
        // wall positions and active walls are on the device already).
        let params = IisphParams::new(inp.kernel, s, n, na);
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let b = &self.bufs;
        b[POS].upload(ctx, &self.pos);
        b[VM].upload(ctx, inp.vm);
        b[P].upload(ctx, out.p);
        b[ROWS].upload(ctx, &self.rows);
        b[WALL_VOL].upload(ctx, inp.vol_wall);
        b[P_WALL].upload(ctx, out.p_wall);
        b[WALL_ROWS].upload(ctx, &self.wall_rows);
        // Status: 0 iterations, not done, error 0, Chebyshev weight 1.
        b[STATUS].upload(ctx, &[0u32, 0, 0, 1.0f32.to_bits()]);
        if cheb {
            self.cheb.clear();
            self.cheb.extend(out.p.iter().map(|&p| [0.0, p]));
            b[CHEB].upload(ctx, &self.cheb);
            self.cheb.clear();
            self.cheb.extend(inp.active.iter().map(|&w| [0.0, out.p_wall[w as usize]]));
            b[CHEB_WALL].upload(ctx, &self.cheb);
        }

        // The loop: ITERATIONS_PER_SUBMIT iterations per submission, then
        // the status; converged iterations are no-ops on the device.
        let fluid_groups = dims((n as u32).div_ceil(WG));
        let wall_groups = dims((na as u32).div_ceil(WG));
        let part_groups = dims(parts as u32);
        let mut submits = 0u32;
        let mut status = [0u32; 4];
        loop {
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            {
                let mut pass = self.begin(&mut enc, submits);
                for _ in 0..ITERATIONS_PER_SUBMIT {
                    self.dispatch(&mut pass, PA, fluid_groups);
                    self.dispatch(&mut pass, FJ, fluid_groups);
                    self.dispatch(&mut pass, WJ, wall_groups);
                    self.dispatch(&mut pass, MEP, part_groups);
                    self.dispatch(&mut pass, ME, (1, 1));
                    if cheb {
                        self.dispatch(&mut pass, CF, fluid_groups);
                        self.dispatch(&mut pass, CW, wall_groups);
                    }
                }
            }
            enc.copy_buffer_to_buffer(&self.bufs[STATUS].buf, 0, &self.read_status.buf, 0, 16);
            ctx.queue.submit([enc.finish()]);
            submits += 1;
            read_back(ctx, &[(&self.read_status.buf, 16)], |_, bytes| status = bytemuck::pod_read_unaligned(bytes))?;
            if status[1] != 0 || 2 * (submits + 1) > MAX_QUERIES {
                break;
            }
        }

        // a^p from the final pressures, then the results.
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let mut pass = self.begin(&mut enc, submits);
            self.dispatch(&mut pass, PAF, fluid_groups);
        }
        let used_queries = 2 * (submits + 1);
        enc.copy_buffer_to_buffer(&self.bufs[P].buf, 0, &self.read_p.buf, 0, sizes[P]);
        enc.copy_buffer_to_buffer(&self.bufs[AP].buf, 0, &self.read_ap.buf, 0, sizes[AP]);
        if nw > 0 {
            enc.copy_buffer_to_buffer(&self.bufs[P_WALL].buf, 0, &self.read_p_wall.buf, 0, sizes[P_WALL]);
        }
        if let Some((set, resolve, read)) = &self.queries {
            enc.resolve_query_set(set, 0..used_queries, &resolve.buf, 0);
            enc.copy_buffer_to_buffer(&resolve.buf, 0, &read.buf, 0, 8 * u64::from(used_queries));
        }
        ctx.queue.submit([enc.finish()]);
        let mut stamps = vec![0u64; used_queries as usize];
        let mut reads =
            vec![(&self.read_p.buf, sizes[P]), (&self.read_ap.buf, sizes[AP]), (&self.read_p_wall.buf, sizes[P_WALL])];
        if let Some((_, _, read)) = &self.queries {
            reads.push((&read.buf, 8 * u64::from(used_queries)));
        }
        let SolveOutput { p, p_wall, ap } = out;
        read_back(ctx, &reads, |k, bytes| match k {
            0 => copy_f32(bytes, p),
            1 => {
                for (i, v) in bytes.chunks_exact(16).enumerate() {
                    let a: [f32; 4] = bytemuck::pod_read_unaligned(v);
                    ap.x[i] = a[0];
                    ap.y[i] = a[1];
                    ap.z[i] = a[2];
                }
            }
            2 => copy_f32(bytes, p_wall),
            _ => {
                for (t, v) in stamps.iter_mut().zip(bytes.chunks_exact(8)) {
                    *t = bytemuck::pod_read_unaligned(v);
                }
            }
        })?;
        let gpu_ms = self.queries.as_ref().map(|_| {
            let period = f64::from(ctx.queue.get_timestamp_period());
            stamps.chunks_exact(2).map(|t| t[1].saturating_sub(t[0]) as f64 * period * 1e-6).sum()
        });
        Ok(SolveReport {
            iterations: status[0],
            density_error: f32::from_bits(status[2]),
            gpu_ms,
            submits,
            restarts: 0,
            solid_error: 0.0,
            largest_error: 0.0,
        })
    }

    /// A compute pass with the bind group set, timed as submission `k`.
    fn begin<'e>(&'e self, enc: &'e mut wgpu::CommandEncoder, k: u32) -> wgpu::ComputePass<'e> {
        let timestamp_writes = self.queries.as_ref().map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
            query_set: set,
            beginning_of_pass_write_index: Some(2 * k),
            end_of_pass_write_index: Some(2 * k + 1),
        });
        let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("iisph"), timestamp_writes });
        pass.set_bind_group(0, self.bind_group.as_ref(), &[]);
        pass
    }

    fn dispatch(&self, pass: &mut wgpu::ComputePass, entry: usize, (x, y): (u32, u32)) {
        if x > 0 && y > 0 {
            pass.set_pipeline(&self.pipelines[entry]);
            pass.dispatch_workgroups(x, y, 1);
        }
    }
}

fn copy_f32(bytes: &[u8], out: &mut [f32]) {
    for (o, v) in out.iter_mut().zip(bytes.chunks_exact(4)) {
        *o = bytemuck::pod_read_unaligned(v);
    }
}
