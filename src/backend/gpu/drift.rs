//! Pass 10 on the GPU: the drift velocities of the mixture model
//! (`shaders/drift.wgsl`, the twin of `kernels/src/drift.rs`; PHYSICS.md
//! §4.1). Per step the host uploads positions and current volumes, the
//! fractions, p / alpha_f (fraction pressures only) and a = -(a^visc + a^p);
//! the fluid cell-range tables are bound from [`RangesGpu`] (built on the
//! device, shared with the pressure solve); three dispatches (phase_velocity,
//! mixture_velocity, drift_velocity) run on the device, and the drift
//! velocities u_mk and phase fluxes F_k are read back.

use super::buffers::{read_back, GpuArray, READBACK, STORAGE};
use super::ranges::RangesGpu;
use super::{GpuContext, GpuError};
use bytemuck::{Pod, Zeroable};
use porosph_kernels::grid::CellGrid;
use porosph_kernels::iisph::Vel;
use porosph_kernels::neighbors::Points;
use porosph_kernels::phases::PhaseConstants;
use std::f32::consts::PI;

/// Phases the shader's parameter block has room for.
pub const MAX_PHASES: usize = 8;

/// The uniform parameters of `shaders/drift.wgsl` (`struct DriftParams`);
/// a test checks that the layouts match.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct DriftParams {
    pub n: u32,
    pub n_phases: u32,
    /// 1: p_k = alphahat_k p; 0: a pressure shared by all phases.
    pub fraction_pressure: u32,
    /// 1: F_k = w_k - alpha_k m; 0: F_k = alpha_k u_mk.
    pub conservative: u32,
    /// Kernel support H, m.
    pub support: f32,
    /// 1 / H, 1/m.
    pub inv_support: f32,
    /// 8 / (pi H^3), 1/m^3.
    pub kernel_k: f32,
    /// 48 / (pi H^4), 1/m^4.
    pub kernel_l: f32,
    /// Per phase (rho_k, tau_k, sigma_k, 0).
    pub phase: [[f32; 4]; MAX_PHASES],
}

/// What the pass reads. The fluid is sorted by the cells of `fluid_grid`.
pub struct DriftInput<'a> {
    /// Kernel support H, m.
    pub support: f32,
    pub fluid_grid: &'a CellGrid,
    pub fluid: Points<'a>,
    /// Current volume V of each particle (the volume of the harmonic pair
    /// volumes the CPU pair lists are scaled by), m^3.
    pub vol: &'a [f32],
    /// alpha_k per phase.
    pub alpha: &'a [&'a [f32]],
    pub alpha_f: &'a [f32],
    /// p / alpha_f (`drift::pressure_per_fraction`) for phase pressures
    /// p_k = alphahat_k p; `None` for a shared pressure.
    pub p_per_fraction: Option<&'a [f32]>,
    pub a_visc: Vel<'a>,
    pub a_p: Vel<'a>,
    pub phases: &'a [PhaseConstants],
    /// The conservative transport's fluxes F_k = w_k - alpha_k m.
    pub conservative: bool,
}

/// What the pass writes, phase-major (phase k at `[k n, (k + 1) n)`): the
/// drift velocities u_mk and the phase fluxes F_k, m/s.
pub struct DriftOutput<'a> {
    pub ux: &'a mut [f32],
    pub uy: &'a mut [f32],
    pub uz: &'a mut [f32],
    pub fx: &'a mut [f32],
    pub fy: &'a mut [f32],
    pub fz: &'a mut [f32],
}

const ENTRY_POINTS: [&str; 3] = ["phase_velocity", "mixture_velocity", "drift_velocity"];
/// Storage bindings 1..=11 of the shader: whether each is read-only.
const READ_ONLY: [bool; 11] = [true, true, true, true, true, true, true, false, false, false, false];
const NAMES: [&str; 11] = ["pos", "alpha", "alpha_f", "pf", "acc", "cell_row", "ff_ranges", "v", "w", "s", "m"];
// Bound from the cell-range tables (their own slots stay unused).
const CELL_ROW: usize = 5;
const FF: usize = 6;
const V: usize = 7;
const W: usize = 8;
const WG: u32 = 64;
const MAX_DIM: u32 = 65535;

fn dims(groups: u32) -> (u32, u32) {
    let x = groups.min(MAX_DIM);
    (x, groups.div_ceil(x.max(1)))
}

/// Pipelines, resident buffers and host staging of the GPU drift pass.
pub struct DriftGpu {
    pipelines: Vec<wgpu::ComputePipeline>,
    layout: wgpu::BindGroupLayout,
    bind_group: Option<wgpu::BindGroup>,
    /// The [`RangesGpu::version`] the bind group was made with.
    tables_version: Option<u64>,
    params: wgpu::Buffer,
    bufs: Vec<GpuArray>,
    read_v: GpuArray,
    read_w: GpuArray,
    queries: Option<(wgpu::QuerySet, GpuArray, GpuArray)>,
    pos: Vec<[f32; 4]>,
    alpha: Vec<f32>,
    acc: Vec<[f32; 4]>,
}

impl DriftGpu {
    /// Compiles `shaders/drift.wgsl` and builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Self {
        let (layout, pipelines, params) =
            ctx.compute_pipelines("drift.wgsl", &READ_ONLY, &ENTRY_POINTS, std::mem::size_of::<DriftParams>());
        let queries = ctx.timestamp_queries("drift timestamps", "drift timestamps read", 2);
        Self {
            pipelines,
            layout,
            bind_group: None,
            tables_version: None,
            params,
            bufs: NAMES.iter().map(|n| GpuArray::new(ctx, n, STORAGE)).collect(),
            read_v: GpuArray::new(ctx, "read u", READBACK),
            read_w: GpuArray::new(ctx, "read F", READBACK),
            queries,
            pos: Vec::new(),
            alpha: Vec::new(),
            acc: Vec::new(),
        }
    }

    /// Runs the three gathers of pass 10 (as `pipeline::step` runs
    /// `drift::{phase_velocity, mixture_velocity, drift_velocity}`) and
    /// writes u_mk and F_k; returns the device time, ms, where the adapter
    /// has timestamps. `tables` must hold the fluid tables of
    /// `inp.fluid_grid` ([`RangesGpu::ensure`]; `GpuBackend::drift` does that).
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        tables: &RangesGpu,
        inp: &DriftInput,
        out: DriftOutput,
    ) -> Result<Option<f64>, GpuError> {
        let n = inp.fluid.len();
        let np = inp.alpha.len();
        if np > MAX_PHASES || inp.phases.len() != np {
            return Err(GpuError(format!("the GPU drift pass takes at most {MAX_PHASES} phases, the scene has {np}")));
        }
        if n == 0 || np == 0 {
            return Ok(Some(0.0));
        }

        if tables.n_fluid() != n {
            return Err(GpuError(format!(
                "the cell-range tables on the GPU have {} particles, not {n}",
                tables.n_fluid()
            )));
        }

        // Host staging.
        let f = inp.fluid;
        self.pos.clear();
        self.pos.extend((0..n).map(|i| [f.x[i], f.y[i], f.z[i], inp.vol[i]]));
        self.alpha.clear();
        for a in inp.alpha {
            self.alpha.extend_from_slice(&a[..n]);
        }
        let (av, ap) = (inp.a_visc, inp.a_p);
        self.acc.clear();
        self.acc.extend((0..n).map(|i| [-(av.x[i] + ap.x[i]), -(av.y[i] + ap.y[i]), -(av.z[i] + ap.z[i]), 0.0]));

        let (n64, np64) = (n as u64, np as u64);
        let sizes: [u64; 11] = [
            16 * n64,
            4 * n64 * np64,
            4 * n64,
            if inp.p_per_fraction.is_some() { 4 * n64 } else { 4 },
            16 * n64,
            0,
            0,
            16 * n64 * np64,
            16 * n64 * np64,
            16 * n64,
            16 * n64,
        ];
        let mut replaced = false;
        for (b, &bytes) in self.bufs.iter_mut().zip(&sizes) {
            replaced |= b.reserve(ctx, bytes, true)?;
        }
        self.read_v.reserve(ctx, sizes[V], false)?;
        self.read_w.reserve(ctx, sizes[W], false)?;
        if replaced || self.bind_group.is_none() || self.tables_version != Some(tables.version()) {
            let mut entries = vec![wgpu::BindGroupEntry { binding: 0, resource: self.params.as_entire_binding() }];
            entries.extend(self.bufs.iter().enumerate().map(|(k, b)| {
                let buf = match k {
                    CELL_ROW => tables.cell_row(),
                    FF => tables.ff(),
                    _ => &b.buf,
                };
                wgpu::BindGroupEntry { binding: k as u32 + 1, resource: buf.as_entire_binding() }
            }));
            self.tables_version = Some(tables.version());
            self.bind_group = Some(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("drift"),
                layout: &self.layout,
                entries: &entries,
            }));
        }

        let h = inp.support;
        let mut params = DriftParams {
            n: n as u32,
            n_phases: np as u32,
            fraction_pressure: inp.p_per_fraction.is_some() as u32,
            conservative: inp.conservative as u32,
            support: h,
            inv_support: 1.0 / h,
            kernel_k: 8.0 / (PI * h * h * h),
            kernel_l: 48.0 / (PI * h * h * h * h),
            phase: [[0.0; 4]; MAX_PHASES],
        };
        for (o, c) in params.phase.iter_mut().zip(inp.phases) {
            *o = [c.density, c.tau, c.sigma, 0.0];
        }
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let b = &self.bufs;
        b[0].upload(ctx, &self.pos);
        b[1].upload(ctx, &self.alpha);
        b[2].upload(ctx, &inp.alpha_f[..n]);
        if let Some(pf) = inp.p_per_fraction {
            b[3].upload(ctx, &pf[..n]);
        }
        b[4].upload(ctx, &self.acc);

        let groups = dims((n as u32).div_ceil(WG));
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let timestamp_writes = self.queries.as_ref().map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            });
            let mut pass =
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("drift"), timestamp_writes });
            pass.set_bind_group(0, self.bind_group.as_ref(), &[]);
            for p in &self.pipelines {
                pass.set_pipeline(p);
                pass.dispatch_workgroups(groups.0, groups.1, 1);
            }
        }
        enc.copy_buffer_to_buffer(&self.bufs[V].buf, 0, &self.read_v.buf, 0, sizes[V]);
        enc.copy_buffer_to_buffer(&self.bufs[W].buf, 0, &self.read_w.buf, 0, sizes[W]);
        if let Some((set, resolve, read)) = &self.queries {
            enc.resolve_query_set(set, 0..2, &resolve.buf, 0);
            enc.copy_buffer_to_buffer(&resolve.buf, 0, &read.buf, 0, 16);
        }
        ctx.queue.submit([enc.finish()]);
        let mut reads = vec![(&self.read_v.buf, sizes[V]), (&self.read_w.buf, sizes[W])];
        if let Some((_, _, read)) = &self.queries {
            reads.push((&read.buf, 16));
        }
        let mut stamps = [0u64; 2];
        let DriftOutput { ux, uy, uz, fx, fy, fz } = out;
        read_back(ctx, &reads, |k, bytes| {
            let (x, y, z) = match k {
                0 => (&mut *ux, &mut *uy, &mut *uz),
                1 => (&mut *fx, &mut *fy, &mut *fz),
                _ => {
                    stamps = bytemuck::pod_read_unaligned(bytes);
                    return;
                }
            };
            for (i, v) in bytes.chunks_exact(16).enumerate() {
                let a: [f32; 4] = bytemuck::pod_read_unaligned(v);
                (x[i], y[i], z[i]) = (a[0], a[1], a[2]);
            }
        })?;
        Ok(self.queries.as_ref().map(|_| {
            let period = f64::from(ctx.queue.get_timestamp_period());
            stamps[1].saturating_sub(stamps[0]) as f64 * period * 1e-6
        }))
    }
}
