//! The GPU backend: a wgpu device (Vulkan; on a machine without a GPU, the
//! software driver lavapipe from Debian's `mesa-vulkan-drivers`), its
//! buffers, and one compiled pipeline set per offloaded pass. The WGSL of
//! a pass is `shaders/<pass>.wgsl`, the twin of `kernels/src/<pass>.rs`.

mod buffers;
pub mod drift;
pub mod iisph;
pub mod kernel;
pub mod neighbors;
pub mod ranges;
#[cfg(test)]
mod shader_tests;

pub use drift::{DriftGpu, DriftInput, DriftOutput, DriftParams, PorousDriftInput};
pub use iisph::{IisphGpu, IisphParams, SolveInput, SolveOutput, SolveReport, SolveSettings};
pub use kernel::KernelParams;
pub use neighbors::{NeighborParams, NeighborsGpu};
pub use ranges::{RangesGpu, RangesParams, WallInput};

use super::cpu::Cpu;
use super::passes::{DriftProblem, DriftReport, Passes, PressureSystem, StepShape, Unknowns};
use super::{BackendKind, GpuPasses};
use bumpalo::Bump;
use porosph_kernels::drift::max_drift_speed;
use porosph_kernels::grid::CellGrid;
use porosph_kernels::phases::PhaseVel;
use porosph_kernels::soa::Vel;
use std::fmt;

/// Shared WGSL (WGSL has no include), by file name: prepended to the
/// shaders of [`SHADERS`] that list it. `common_grid.wgsl`: WG, RANGES, the
/// grid constants, `linear_index`, `cell_coord`, `morton`;
/// `common_kernel.wgsl`: `KernelParams` (the scene's kernel, [`KernelParams`]),
/// `grad_over_r`, `harmonic_volumes`, `pair_gradient`, which read the
/// shader's `P.kernel`.
pub const COMMON: [(&str, &str); 2] = [
    ("common_grid.wgsl", include_str!("../../../shaders/common_grid.wgsl")),
    ("common_kernel.wgsl", include_str!("../../../shaders/common_kernel.wgsl")),
];

/// The WGSL sources of the passes, by file name (compiled into the binary),
/// with the [`COMMON`] files prepended to each, in order.
pub const SHADERS: [(&str, &[&str], &str); 4] = [
    ("drift.wgsl", &["common_grid.wgsl", "common_kernel.wgsl"], include_str!("../../../shaders/drift.wgsl")),
    ("iisph.wgsl", &["common_grid.wgsl", "common_kernel.wgsl"], include_str!("../../../shaders/iisph.wgsl")),
    ("neighbors.wgsl", &["common_grid.wgsl"], include_str!("../../../shaders/neighbors.wgsl")),
    ("ranges.wgsl", &["common_grid.wgsl"], include_str!("../../../shaders/ranges.wgsl")),
];

/// The full source of `shaders/<file>` as compiled: its [`COMMON`] files,
/// then the file; `None` for a file not in [`SHADERS`].
pub fn shader_source(file: &str) -> Option<String> {
    let (_, common, src) = SHADERS.iter().find(|(f, _, _)| *f == file)?;
    let mut out = String::new();
    for c in *common {
        let (_, text) = COMMON.iter().find(|(f, _)| f == c)?;
        out.push_str(text);
        out.push('\n');
    }
    out.push_str(src);
    Some(out)
}

/// Why the GPU backend cannot run.
#[derive(Clone, Debug, PartialEq)]
pub struct GpuError(pub String);

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for GpuError {}

/// A wgpu device and queue, and what the adapter offers.
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    /// Whether compute passes can write timestamps (per-pass GPU times).
    pub timestamps: bool,
    /// Largest storage-buffer binding, bytes.
    pub max_binding: u64,
}

impl GpuContext {
    /// Opens the first Vulkan adapter (a discrete GPU if there is one), with
    /// the adapter's own limits and timestamp queries where supported.
    pub fn new() -> Result<Self, GpuError> {
        let desc = wgpu::InstanceDescriptor {
            backends: wgpu::Backends::VULKAN,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        };
        let instance = wgpu::Instance::new(desc);
        let options = wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            ..Default::default()
        };
        let adapter = pollster::block_on(instance.request_adapter(&options)).map_err(|e| {
            GpuError(format!(
                "--backend gpu: no GPU adapter found ({e}). porosph's GPU backend needs a Vulkan driver; \
                 on a machine without a GPU install the software one (Debian: apt-get install \
                 mesa-vulkan-drivers, which `bash scripts/setup.sh` does), or run with --backend cpu"
            ))
        })?;
        let info = adapter.get_info();
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let limits = adapter.limits();
        let desc = wgpu::DeviceDescriptor {
            label: Some("porosph"),
            required_features: features,
            required_limits: limits.clone(),
            experimental_features: wgpu::ExperimentalFeatures::default(),
            memory_hints: wgpu::MemoryHints::Performance,
            trace: wgpu::Trace::default(),
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&desc))
            .map_err(|e| GpuError(format!("--backend gpu: cannot open {} ({:?}): {e}", info.name, info.backend)))?;
        Ok(Self {
            device,
            queue,
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
            max_binding: limits.max_storage_buffer_binding_size,
            info,
        })
    }

    /// "name (device type, backend)" of the adapter.
    pub fn describe(&self) -> String {
        format!("{} ({:?}, {:?})", self.info.name, self.info.device_type, self.info.backend)
    }

    /// Compiles `shaders/<file>`, with its common files prepended
    /// ([`shader_source`]), into a module.
    pub fn shader(&self, file: &str) -> wgpu::ShaderModule {
        let src = shader_source(file).unwrap_or_default();
        self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(file),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        })
    }

    /// The compute pipelines of `shaders/<file>`, one per entry point, over
    /// one bind group: binding 0 a uniform parameter block of `params`
    /// bytes, bindings 1.. storage buffers (read-only as `read_only` says).
    /// Returns the bind group layout, the pipelines and the parameter buffer.
    pub fn compute_pipelines(
        &self,
        file: &str,
        read_only: &[bool],
        entry_points: &[&str],
        params: usize,
    ) -> (wgpu::BindGroupLayout, Vec<wgpu::ComputePipeline>, wgpu::Buffer) {
        let label = file.trim_end_matches(".wgsl");
        let module = self.shader(file);
        let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
            count: None,
        };
        let mut entries = vec![buffer(0, wgpu::BufferBindingType::Uniform)];
        for (k, &read_only) in read_only.iter().enumerate() {
            entries.push(buffer(k as u32 + 1, wgpu::BufferBindingType::Storage { read_only }));
        }
        let layout = self
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries });
        let pl = self.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipelines = entry_points
            .iter()
            .map(|e| {
                self.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(e),
                    layout: Some(&pl),
                    module: &module,
                    entry_point: Some(e),
                    compilation_options: Default::default(),
                    cache: None,
                })
            })
            .collect();
        let params = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(&format!("{label} params")),
            size: params as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        (layout, pipelines, params)
    }

    /// `count` timestamp queries with their resolve (`label`) and read-back
    /// (`read_label`) buffers, or `None` where the adapter has no timestamps.
    pub fn timestamp_queries(
        &self,
        label: &'static str,
        read_label: &'static str,
        count: u32,
    ) -> Option<(wgpu::QuerySet, buffers::GpuArray, buffers::GpuArray)> {
        self.timestamps.then(|| {
            let set = self.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some(label),
                ty: wgpu::QueryType::Timestamp,
                count,
            });
            let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
            let mut resolve = buffers::GpuArray::new(self, label, usage);
            let mut read = buffers::GpuArray::new(self, read_label, buffers::READBACK);
            let bytes = 8 * u64::from(count);
            // Small buffers: these cannot fail.
            let _ = resolve.reserve(self, bytes, false);
            let _ = read.reserve(self, bytes, false);
            (set, resolve, read)
        })
    }
}

/// The GPU backend of a run: the device, which passes it runs, and the
/// pipelines and resident buffers of each (built on first use). The
/// cell-range tables are shared: the first pass of a step that needs them
/// builds them on the device for the step's grids, the others bind the
/// same buffers. As the step's [`Passes`], it runs the passes of
/// `passes` on the device and hands the others to the CPU, as it does a
/// pass whose device run fails (the error is reported after the step).
pub struct GpuBackend {
    pub ctx: GpuContext,
    pub passes: GpuPasses,
    iisph: Option<IisphGpu>,
    neighbors: Option<NeighborsGpu>,
    drift: Option<DriftGpu>,
    ranges: Option<RangesGpu>,
    /// What the device does not run.
    cpu: Cpu,
    /// Why a device pass of the last step failed.
    error: Option<String>,
}

impl GpuBackend {
    /// Opens the GPU (an error says why there is none).
    pub fn new(passes: GpuPasses) -> Result<Self, GpuError> {
        Ok(Self {
            ctx: GpuContext::new()?,
            passes,
            iisph: None,
            neighbors: None,
            drift: None,
            ranges: None,
            cpu: Cpu,
            error: None,
        })
    }

    /// Morton keys and sort of pass 0 on the GPU; see [`NeighborsGpu::sort`].
    pub fn sort_permutation(
        &mut self,
        pts: porosph_kernels::soa::Vel,
        inv_cell: f32,
        sort: &mut Vec<(u64, u32)>,
        perm: &mut Vec<u32>,
    ) -> Result<Option<f64>, GpuError> {
        let ctx = &self.ctx;
        sort.resize(pts.len(), (0, 0));
        perm.resize(pts.len(), 0);
        self.neighbors.get_or_insert_with(|| NeighborsGpu::new(ctx)).sort(ctx, pts, inv_cell, sort, perm)
    }

    /// The cell-range tables of the GPU passes (with the walls' rows where
    /// `walls` is given) built on the device for this step's grids, the
    /// last part of the neighbour search on the GPU; a pass that finds them
    /// current does not build them again. Returns the device time, ms.
    pub fn cell_ranges(&mut self, fluid_grid: &CellGrid, walls: Option<WallInput>) -> Result<f64, GpuError> {
        let Self { ctx, ranges, .. } = self;
        ranges.get_or_insert_with(|| RangesGpu::new(ctx)).ensure(ctx, fluid_grid, walls)
    }

    /// The IISPH Jacobi loop (pass 5) on the GPU; see [`IisphGpu::solve`].
    /// Builds the cell-range tables with the walls first where this step's
    /// are not on the device yet (their device time is in `gpu_ms`).
    pub fn pressure_solve(&mut self, input: &SolveInput, out: SolveOutput) -> Result<SolveReport, GpuError> {
        let Self { ctx, ranges, iisph, .. } = self;
        let ranges = ranges.get_or_insert_with(|| RangesGpu::new(ctx));
        let walls = WallInput { grid: input.wall_grid, walls: input.walls, active: input.active };
        let ms = ranges.ensure(ctx, input.fluid_grid, Some(walls))?;
        let mut report = iisph.get_or_insert_with(|| IisphGpu::new(ctx)).solve(ctx, ranges, input, out)?;
        report.gpu_ms = report.gpu_ms.map(|t| t + ms);
        Ok(report)
    }

    /// The drift velocities (pass 10; with porous solids also the inner
    /// ones, into `inner`) on the GPU; see [`DriftGpu::run`]. Builds the
    /// fluid cell-range tables first where this step's are not on the
    /// device yet (the pressure solve's serve; the device time of a build
    /// is in the result).
    pub fn drift(
        &mut self,
        input: &DriftInput,
        out: DriftOutput,
        inner: Option<DriftOutput>,
    ) -> Result<Option<f64>, GpuError> {
        let Self { ctx, ranges, drift, .. } = self;
        let ranges = ranges.get_or_insert_with(|| RangesGpu::new(ctx));
        let ms = ranges.ensure(ctx, input.fluid_grid, None)?;
        let t = drift.get_or_insert_with(|| DriftGpu::new(ctx)).run(ctx, ranges, input, out, inner)?;
        Ok(t.map(|t| t + ms))
    }
}

impl Passes for GpuBackend {
    fn kind(&self) -> BackendKind {
        BackendKind::Gpu
    }

    /// The keys and sort on the GPU (bitwise the CPU's order), or on the CPU.
    fn sort(&mut self, fluid: Vel, inv_cell: f32, keys: &mut [u64], sort: &mut [(u64, u32)], perm: &mut [u32]) -> f64 {
        if self.passes.neighbors {
            let ctx = &self.ctx;
            match self.neighbors.get_or_insert_with(|| NeighborsGpu::new(ctx)).sort(ctx, fluid, inv_cell, sort, perm) {
                Ok(ms) => return ms.unwrap_or(0.0),
                Err(e) => self.error = Some(format!("GPU neighbour sort failed: {e}")),
            }
        }
        self.cpu.sort(fluid, inv_cell, keys, sort, perm)
    }

    /// With the neighbour search on the GPU, the cell-range tables of the
    /// step's other GPU passes (with the walls' rows where the pressure
    /// solve runs here), built on the device; without it, the first pass
    /// that needs them builds them.
    fn prepare(&mut self, fluid_grid: &CellGrid, walls: WallInput, step: StepShape) -> f64 {
        let solve_here = self.passes.pressure_solve && !step.solids;
        let tables = self.passes.neighbors && (solve_here || (self.passes.drift && step.mixture));
        if !(step.fluid && tables) {
            return 0.0;
        }
        match self.cell_ranges(fluid_grid, solve_here.then_some(walls)) {
            Ok(ms) => ms,
            Err(e) => {
                self.error = Some(format!("GPU cell-range tables failed: {e}"));
                0.0
            }
        }
    }

    /// The Jacobi loop on the GPU (`shaders/iisph.wgsl`, data resident).
    /// The GPU system has fluid and wall rows only: with solids the solve
    /// runs on the CPU.
    fn pressure_solve(&mut self, sys: &PressureSystem, mut x: Unknowns, arena: &Bump) -> SolveReport {
        if self.passes.pressure_solve && sys.solids.is_none() && sys.settings.max_row_density_error == f32::INFINITY {
            let inp = SolveInput {
                kernel: sys.kernel,
                fluid_grid: sys.fluid_grid,
                wall_grid: sys.walls.grid,
                fluid: sys.fluid,
                walls: sys.walls.walls,
                vol: sys.vol,
                vm: sys.vm,
                rows: sys.rows,
                vol_wall: sys.vol_wall,
                active: sys.walls.active,
                wall_rows: sys.wall_rows,
                settings: sys.settings,
            };
            let out = SolveOutput { p: &mut *x.p, p_wall: &mut *x.p_wall, ap: x.ap.reborrow() };
            match GpuBackend::pressure_solve(self, &inp, out) {
                Ok(r) => return r,
                Err(e) => self.error = Some(format!("GPU pressure solve failed: {e}")),
            }
        }
        self.cpu.pressure_solve(sys, x, arena)
    }

    /// The three gathers of the drift on the GPU (`shaders/drift.wgsl`),
    /// with porous solids twice: outer and inner (P-Eqs. 11-12); the
    /// largest drift speed is taken here.
    fn drift(
        &mut self,
        prob: &DriftProblem,
        mut out: DriftOutput,
        mut inner: Option<DriftOutput>,
        arena: &Bump,
    ) -> DriftReport {
        if self.passes.drift {
            let n = prob.input.alpha_f.len();
            match GpuBackend::drift(self, &prob.input, out.reborrow(), inner.as_mut().map(|o| o.reborrow())) {
                Ok(ms) => {
                    let speed = |o: &DriftOutput| max_drift_speed(PhaseVel::split(arena, o.u.view(), n), n);
                    let max_speed = speed(&out).max(inner.as_ref().map_or(0.0, speed));
                    return DriftReport { max_speed, gpu_ms: ms.unwrap_or(0.0) };
                }
                Err(e) => self.error = Some(format!("GPU drift pass failed: {e}")),
            }
        }
        self.cpu.drift(prob, out, inner, arena)
    }

    fn take_error(&mut self) -> Option<String> {
        self.error.take()
    }

    fn as_any(&self) -> &dyn std::any::Any {
        self
    }
}
