//! Pass 10 on the GPU: the drift velocities of the mixture model
//! (`shaders/drift.wgsl`, the twin of `kernels/src/drift.rs`; PHYSICS.md
//! §4.1). Per step the host uploads positions and current volumes, the
//! fractions, p / alpha_f (fraction pressures only) and a = -(a^visc + a^p);
//! the fluid cell-range tables are bound from [`RangesGpu`] (built on the
//! device, shared with the pressure solve); three dispatches (phase_velocity,
//! mixture_velocity, drift_velocity) run on the device, and the drift
//! velocities u_mk and phase fluxes F_k are read back. With porous solids
//! the same three dispatches run a second time in the step for the inner
//! fractions (P-Eq. 12), over the buffers already on the device: only the
//! inner fractions and q_k,f are uploaded for it.

use super::buffers::{read_back, GpuArray, READBACK, STORAGE};
use super::kernel::KernelParams;
use super::ranges::RangesGpu;
use super::{GpuContext, GpuError};
pub use crate::backend::passes::{DriftInput, DriftOutput, PorousDriftInput};
use bytemuck::{Pod, Zeroable};
use porosph_kernels::band::BandVel;
use porosph_kernels::soa::VelMut;

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
    /// The scene's kernel.
    pub kernel: KernelParams,
    /// 1: add `extra_scale` e_k (P-Eqs. 11-12's porous terms); 0: none.
    pub extra_term: u32,
    pub extra_scale: f32,
    /// > 0: every particle's volume (the inner pass: h^3), m^3.
    pub uniform_volume: f32,
    pub pad: u32,
    /// Per phase (rho_k, tau_k, sigma_k, 0).
    pub phase: [[f32; 4]; MAX_PHASES],
}

const ENTRY_POINTS: [&str; 3] = ["phase_velocity", "mixture_velocity", "drift_velocity"];
/// Storage bindings 1..=12 of the shader: whether each is read-only.
const READ_ONLY: [bool; 12] = [true, true, true, true, true, true, true, false, false, false, false, true];
const NAMES: [&str; 12] =
    ["pos", "alpha", "alpha_f", "pf", "acc", "cell_row", "ff_ranges", "v", "w", "s", "m", "extra"];
const ALPHA: usize = 1;
const ALPHA_F: usize = 2;
// Bound from the cell-range tables (their own slots stay unused).
const CELL_ROW: usize = 5;
const FF: usize = 6;
const V: usize = 7;
const W: usize = 8;
const EXTRA: usize = 11;
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
    /// u_mk, F_k of the outer pass, then of the inner pass.
    reads: [GpuArray; 4],
    queries: Option<(wgpu::QuerySet, GpuArray, GpuArray)>,
    pos: Vec<[f32; 4]>,
    alpha: Vec<f32>,
    extra: Vec<[f32; 4]>,
    acc: Vec<[f32; 4]>,
}

impl DriftGpu {
    /// Compiles `shaders/drift.wgsl` and builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Self {
        let (layout, pipelines, params) =
            ctx.compute_pipelines("drift.wgsl", &READ_ONLY, &ENTRY_POINTS, std::mem::size_of::<DriftParams>());
        let queries = ctx.timestamp_queries("drift timestamps", "drift timestamps read", 4);
        Self {
            pipelines,
            layout,
            bind_group: None,
            tables_version: None,
            params,
            bufs: NAMES.iter().map(|n| GpuArray::new(ctx, n, STORAGE)).collect(),
            reads: ["read u", "read F", "read inner u", "read inner F"].map(|l| GpuArray::new(ctx, l, READBACK)),
            queries,
            pos: Vec::new(),
            alpha: Vec::new(),
            extra: Vec::new(),
            acc: Vec::new(),
        }
    }

    /// Runs the three gathers of pass 10 (as `pipeline::step` runs
    /// `drift::{phase_velocity, mixture_velocity, drift_velocity}`) and
    /// writes u_mk and F_k, and with `inp.porous` the inner drift
    /// velocities and fluxes of P-Eq. 12 into `inner` (which must then be
    /// given); returns the device time of both, ms, where the adapter has
    /// timestamps. `tables` must hold the fluid tables of `inp.fluid_grid`
    /// ([`RangesGpu::ensure`]; `GpuBackend::drift` does that).
    pub fn run(
        &mut self,
        ctx: &GpuContext,
        tables: &RangesGpu,
        inp: &DriftInput,
        out: DriftOutput,
        inner: Option<DriftOutput>,
    ) -> Result<Option<f64>, GpuError> {
        let n = inp.fluid.len();
        let np = inp.alpha.len();
        if np > MAX_PHASES || inp.phases.len() != np {
            return Err(GpuError(format!("the GPU drift pass takes at most {MAX_PHASES} phases, the scene has {np}")));
        }
        if inp.porous.as_ref().is_some_and(|p| p.beta.len() != np) || inp.porous.is_some() != inner.is_some() {
            return Err(GpuError("the GPU drift pass: porous input and inner output go together".into()));
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
        pack(&mut self.alpha, inp.alpha, n);
        let (av, ap) = (inp.a_visc, inp.a_p);
        self.acc.clear();
        self.acc.extend((0..n).map(|i| [-(av.x[i] + ap.x[i]), -(av.y[i] + ap.y[i]), -(av.z[i] + ap.z[i]), 0.0]));
        if let Some(pd) = &inp.porous {
            pack_band(&mut self.extra, pd.grad_pore, n, np);
        }

        let (n64, np64) = (n as u64, np as u64);
        let sizes: [u64; 12] = [
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
            if inp.porous.is_some() { 16 * n64 * np64 } else { 16 },
        ];
        let mut replaced = false;
        for (b, &bytes) in self.bufs.iter_mut().zip(&sizes) {
            replaced |= b.reserve(ctx, bytes, true)?;
        }
        let passes = if inp.porous.is_some() { 2 } else { 1 };
        for r in &mut self.reads[..2 * passes] {
            r.reserve(ctx, sizes[V], false)?;
        }
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

        let mut params = DriftParams {
            n: n as u32,
            n_phases: np as u32,
            fraction_pressure: inp.p_per_fraction.is_some() as u32,
            conservative: inp.conservative as u32,
            kernel: KernelParams::from(inp.kernel),
            extra_term: inp.porous.is_some() as u32,
            extra_scale: inp.porous.as_ref().map_or(0.0, |pd| -pd.pore_drift),
            uniform_volume: 0.0,
            pad: 0,
            phase: [[0.0; 4]; MAX_PHASES],
        };
        for (o, c) in params.phase.iter_mut().zip(inp.phases) {
            *o = [c.density, c.tau, c.sigma, 0.0];
        }
        ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let b = &self.bufs;
        b[0].upload(ctx, &self.pos);
        b[ALPHA].upload(ctx, &self.alpha);
        b[ALPHA_F].upload(ctx, &inp.alpha_f[..n]);
        if let Some(pf) = inp.p_per_fraction {
            b[3].upload(ctx, &pf[..n]);
        }
        b[4].upload(ctx, &self.acc);
        if inp.porous.is_some() {
            b[EXTRA].upload(ctx, &self.extra);
        }
        ctx.queue.submit([self.encode(ctx, n, 0, sizes[V], passes == 1)]);

        // P-Eq. 12 over the same positions, accelerations and tables: the
        // writes below are ordered after the first submission's reads.
        if let Some(pd) = &inp.porous {
            params.fraction_pressure = 0;
            params.extra_scale = -pd.inner_tau;
            params.uniform_volume = pd.cell_volume;
            for o in params.phase.iter_mut().take(np) {
                o[2] = pd.inner_sigma;
            }
            ctx.queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
            pack(&mut self.alpha, pd.beta, n);
            pack_band(&mut self.extra, pd.q, n, np);
            let b = &self.bufs;
            b[ALPHA].upload(ctx, &self.alpha);
            b[ALPHA_F].upload(ctx, &pd.beta_f[..n]);
            b[EXTRA].upload(ctx, &self.extra);
            ctx.queue.submit([self.encode(ctx, n, 1, sizes[V], true)]);
        }

        let mut reads: Vec<(&wgpu::Buffer, u64)> =
            self.reads[..2 * passes].iter().map(|r| (&r.buf, sizes[V])).collect();
        if let Some((_, _, read)) = &self.queries {
            reads.push((&read.buf, 32));
        }
        let mut stamps = [0u64; 4];
        let mut outs = [Some(out), inner];
        read_back(ctx, &reads, |k, bytes| {
            if k == 2 * passes {
                stamps = bytemuck::pod_read_unaligned(bytes);
                return;
            }
            let Some(DriftOutput { u, f }) = &mut outs[k / 2] else { return };
            let VelMut { x, y, z } = if k % 2 == 0 { u } else { f };
            for (i, v) in bytes.chunks_exact(16).enumerate() {
                let a: [f32; 4] = bytemuck::pod_read_unaligned(v);
                (x[i], y[i], z[i]) = (a[0], a[1], a[2]);
            }
        })?;
        Ok(self.queries.as_ref().map(|_| {
            let period = f64::from(ctx.queue.get_timestamp_period());
            let ticks: u64 = (0..passes).map(|p| stamps[2 * p + 1].saturating_sub(stamps[2 * p])).sum();
            ticks as f64 * period * 1e-6
        }))
    }

    /// The three dispatches of pass `pass` (0 outer, 1 inner) with its
    /// timestamps, and the copies of u_mk and F_k (`bytes` each) into that
    /// pass's read-back buffers; `last` also resolves the timestamps.
    fn encode(&self, ctx: &GpuContext, n: usize, pass: usize, bytes: u64, last: bool) -> wgpu::CommandBuffer {
        let groups = dims((n as u32).div_ceil(WG));
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let q = 2 * pass as u32;
            let timestamp_writes = self.queries.as_ref().map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(q),
                end_of_pass_write_index: Some(q + 1),
            });
            let mut cp =
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("drift"), timestamp_writes });
            cp.set_bind_group(0, self.bind_group.as_ref(), &[]);
            for p in &self.pipelines {
                cp.set_pipeline(p);
                cp.dispatch_workgroups(groups.0, groups.1, 1);
            }
        }
        enc.copy_buffer_to_buffer(&self.bufs[V].buf, 0, &self.reads[2 * pass].buf, 0, bytes);
        enc.copy_buffer_to_buffer(&self.bufs[W].buf, 0, &self.reads[2 * pass + 1].buf, 0, bytes);
        if last {
            if let Some((set, resolve, read)) = &self.queries {
                let count = 2 * (pass as u32 + 1);
                enc.resolve_query_set(set, 0..count, &resolve.buf, 0);
                enc.copy_buffer_to_buffer(&resolve.buf, 0, &read.buf, 0, 8 * u64::from(count));
            }
        }
        enc.finish()
    }
}

/// Per-phase arrays, phase-major, into one flat array.
fn pack(out: &mut Vec<f32>, phases: &[&[f32]], n: usize) {
    out.clear();
    for a in phases {
        out.extend_from_slice(&a[..n]);
    }
}

/// A per-phase field on the fluid-solid band as the shaders read it:
/// phase k of fluid particle i at `k n + i`, 0 outside the band.
fn pack_band(out: &mut Vec<[f32; 4]>, c: BandVel, n: usize, np: usize) {
    out.clear();
    out.extend((0..n * np).map(|r| {
        let [x, y, z] = c.get(r / n, r % n);
        [x, y, z, 0.0]
    }));
}
