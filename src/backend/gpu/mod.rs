//! The GPU backend: a wgpu device (Vulkan; on a machine without a GPU, the
//! software driver lavapipe from Debian's `mesa-vulkan-drivers`), its
//! buffers, and one compiled pipeline set per offloaded pass. The WGSL of
//! a pass is `shaders/<pass>.wgsl`, the twin of `kernels/src/<pass>.rs`.

mod buffers;
pub mod drift;
pub mod iisph;
pub mod neighbors;
pub mod ranges;
#[cfg(test)]
mod shader_tests;

pub use drift::{DriftGpu, DriftInput, DriftOutput, DriftParams};
pub use iisph::{IisphGpu, IisphParams, SolveInput, SolveOutput, SolveReport, SolveSettings};
pub use neighbors::{NeighborParams, NeighborsGpu};
pub use ranges::{RangesGpu, RangesParams};

use super::GpuPasses;
use std::fmt;

/// The WGSL sources, by file name (compiled into the binary).
pub const SHADERS: [(&str, &str); 4] = [
    ("drift.wgsl", include_str!("../../../shaders/drift.wgsl")),
    ("iisph.wgsl", include_str!("../../../shaders/iisph.wgsl")),
    ("neighbors.wgsl", include_str!("../../../shaders/neighbors.wgsl")),
    ("ranges.wgsl", include_str!("../../../shaders/ranges.wgsl")),
];

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

    /// Compiles `shaders/<file>` into a module.
    pub fn shader(&self, file: &str) -> wgpu::ShaderModule {
        let src = SHADERS.iter().find(|(f, _)| *f == file).map(|(_, s)| *s).unwrap_or_default();
        self.device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some(file),
            source: wgpu::ShaderSource::Wgsl(src.into()),
        })
    }
}

/// The GPU backend of a run: the device, which passes it runs, and the
/// pipelines and resident buffers of each (built on first use).
pub struct GpuBackend {
    pub ctx: GpuContext,
    pub passes: GpuPasses,
    iisph: Option<IisphGpu>,
    neighbors: Option<NeighborsGpu>,
    drift: Option<DriftGpu>,
}

impl GpuBackend {
    /// Opens the GPU (an error says why there is none).
    pub fn new(passes: GpuPasses) -> Result<Self, GpuError> {
        Ok(Self { ctx: GpuContext::new()?, passes, iisph: None, neighbors: None, drift: None })
    }

    /// Morton keys and sort of pass 0 on the GPU; see [`NeighborsGpu::sort`].
    pub fn sort_permutation(
        &mut self,
        pts: porosph_kernels::neighbors::Points,
        inv_cell: f32,
        sort: &mut Vec<(u64, u32)>,
        perm: &mut Vec<u32>,
    ) -> Result<Option<f64>, GpuError> {
        let ctx = &self.ctx;
        self.neighbors.get_or_insert_with(|| NeighborsGpu::new(ctx)).sort(ctx, pts, inv_cell, sort, perm)
    }

    /// The IISPH Jacobi loop (pass 5) on the GPU; see [`IisphGpu::solve`].
    pub fn pressure_solve(&mut self, input: &SolveInput, out: SolveOutput) -> Result<SolveReport, GpuError> {
        let ctx = &self.ctx;
        self.iisph.get_or_insert_with(|| IisphGpu::new(ctx)).solve(ctx, input, out)
    }

    /// The drift velocities (pass 10) on the GPU; see [`DriftGpu::run`].
    pub fn drift(&mut self, input: &DriftInput, out: DriftOutput) -> Result<Option<f64>, GpuError> {
        let ctx = &self.ctx;
        self.drift.get_or_insert_with(|| DriftGpu::new(ctx)).run(ctx, input, out)
    }
}
