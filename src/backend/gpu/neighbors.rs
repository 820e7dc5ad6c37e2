//! Pass 0 on the GPU, sort part (`shaders/neighbors.wgsl`, the twin of
//! `compute_keys` and `sort_permutation` in `kernels/src/neighbors.rs`):
//! Morton cell keys and the sort permutation. Upload: positions; download:
//! the sorted (key, index) pairs. The order is bitwise the CPU's (integer
//! keys from the same f32 products, unique with the index), so the rest of
//! the step (reorder, cell ranges, pairs on the CPU) is unchanged.

use super::buffers::{read_back, GpuArray, READBACK, STORAGE};
use super::{GpuContext, GpuError};
use bytemuck::{Pod, Zeroable};
use porosph_kernels::soa::Vel;

/// The uniform parameters of `shaders/neighbors.wgsl` (`struct NeighborParams`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct NeighborParams {
    pub n: u32,
    pub n_pow2: u32,
    /// Bitonic step: sequence size k and compare distance j.
    pub k: u32,
    pub j: u32,
    /// 1 / cell size, 1/m.
    pub inv_cell: f32,
    pub pad0: u32,
    pub pad1: u32,
    pub pad2: u32,
}

/// Stride of the per-dispatch parameters (dynamic uniform offsets).
const STRIDE: u64 = 256;
const WG: u32 = 64;

/// Pipelines and buffers of the GPU sort.
pub struct NeighborsGpu {
    keys_pipeline: wgpu::ComputePipeline,
    sort_pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    bind_group: Option<wgpu::BindGroup>,
    params: GpuArray,
    pos: GpuArray,
    keys: GpuArray,
    read: GpuArray,
    queries: Option<(wgpu::QuerySet, GpuArray, GpuArray)>,
    staging_pos: Vec<[f32; 4]>,
    staging_params: Vec<u8>,
}

impl NeighborsGpu {
    /// Compiles `shaders/neighbors.wgsl` and builds the pipelines.
    pub fn new(ctx: &GpuContext) -> Self {
        let module = ctx.shader("neighbors.wgsl");
        let buffer = |binding, ty, dynamic| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: dynamic,
                min_binding_size: if dynamic {
                    wgpu::BufferSize::new(std::mem::size_of::<NeighborParams>() as u64)
                } else {
                    None
                },
            },
            count: None,
        };
        let entries = [
            buffer(0, wgpu::BufferBindingType::Uniform, true),
            buffer(1, wgpu::BufferBindingType::Storage { read_only: true }, false),
            buffer(2, wgpu::BufferBindingType::Storage { read_only: false }, false),
        ];
        let layout = ctx
            .device
            .create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some("neighbors"), entries: &entries });
        let pl = ctx.device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("neighbors"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str| {
            ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(&pl),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let queries = ctx.timestamps.then(|| {
            let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("neighbors timestamps"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
            (set, GpuArray::new(ctx, "neighbors timestamps", usage), GpuArray::new(ctx, "neighbors ts read", READBACK))
        });
        Self {
            keys_pipeline: pipeline("compute_keys"),
            sort_pipeline: pipeline("sort_permutation"),
            layout,
            bind_group: None,
            params: GpuArray::new(ctx, "neighbors params", wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST),
            pos: GpuArray::new(ctx, "neighbors pos", STORAGE),
            keys: GpuArray::new(ctx, "neighbors keys", STORAGE),
            read: GpuArray::new(ctx, "neighbors keys read", READBACK),
            queries,
            staging_pos: Vec::new(),
            staging_params: Vec::new(),
        }
    }

    /// The Morton keys of `pts` (cells of size 1/`inv_cell`) sorted with
    /// their indices, into `sort` (key, index) and `perm` (`perm[new] =
    /// old`), as `compute_keys` + `sort_permutation` give them on the CPU;
    /// both of `pts`' length. Returns the device time, ms, where timestamps
    /// are supported.
    pub fn sort(
        &mut self,
        ctx: &GpuContext,
        pts: Vel,
        inv_cell: f32,
        sort: &mut [(u64, u32)],
        perm: &mut [u32],
    ) -> Result<Option<f64>, GpuError> {
        let n = pts.len();
        assert!(sort.len() == n && perm.len() == n, "sort buffers of the points' length");
        if n == 0 {
            return Ok(None);
        }
        let n_pow2 = (n as u32).next_power_of_two();
        // Dispatch parameters: the keys, then every bitonic step (k, j).
        let mut steps = vec![(0u32, 0u32)];
        let mut k = 2;
        while k <= n_pow2 {
            let mut j = k / 2;
            while j > 0 {
                steps.push((k, j));
                j /= 2;
            }
            k *= 2;
        }
        self.staging_params.clear();
        for &(k, j) in &steps {
            let p = NeighborParams { n: n as u32, n_pow2, k, j, inv_cell, ..Default::default() };
            self.staging_params.extend_from_slice(bytemuck::bytes_of(&p));
            self.staging_params.resize(self.staging_params.len().next_multiple_of(STRIDE as usize), 0);
        }
        self.staging_pos.clear();
        self.staging_pos.extend((0..n).map(|i| [pts.x[i], pts.y[i], pts.z[i], 0.0]));
        let key_bytes = 16 * u64::from(n_pow2);
        let mut replaced = self.params.reserve(ctx, self.staging_params.len() as u64, false)?;
        replaced |= self.pos.reserve(ctx, 16 * n as u64, true)?;
        replaced |= self.keys.reserve(ctx, key_bytes, true)?;
        self.read.reserve(ctx, 16 * n as u64, false)?;
        if let Some((_, resolve, read)) = &mut self.queries {
            resolve.reserve(ctx, 16, false)?;
            read.reserve(ctx, 16, false)?;
        }
        if replaced || self.bind_group.is_none() {
            let params = wgpu::BufferBinding {
                buffer: &self.params.buf,
                offset: 0,
                size: wgpu::BufferSize::new(std::mem::size_of::<NeighborParams>() as u64),
            };
            self.bind_group = Some(ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("neighbors"),
                layout: &self.layout,
                entries: &[
                    wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::Buffer(params) },
                    wgpu::BindGroupEntry { binding: 1, resource: self.pos.buf.as_entire_binding() },
                    wgpu::BindGroupEntry { binding: 2, resource: self.keys.buf.as_entire_binding() },
                ],
            }));
        }
        self.params.upload(ctx, &self.staging_params);
        self.pos.upload(ctx, &self.staging_pos);

        let groups = n_pow2.div_ceil(WG);
        let (x, y) = (groups.min(65535), groups.div_ceil(groups.min(65535)));
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        {
            let timestamp_writes = self.queries.as_ref().map(|(set, _, _)| wgpu::ComputePassTimestampWrites {
                query_set: set,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            });
            let mut pass =
                enc.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("neighbors"), timestamp_writes });
            for (s, _) in steps.iter().enumerate() {
                pass.set_pipeline(if s == 0 { &self.keys_pipeline } else { &self.sort_pipeline });
                pass.set_bind_group(0, self.bind_group.as_ref(), &[(s as u64 * STRIDE) as u32]);
                pass.dispatch_workgroups(x, y, 1);
            }
        }
        enc.copy_buffer_to_buffer(&self.keys.buf, 0, &self.read.buf, 0, 16 * n as u64);
        if let Some((set, resolve, read)) = &self.queries {
            enc.resolve_query_set(set, 0..2, &resolve.buf, 0);
            enc.copy_buffer_to_buffer(&resolve.buf, 0, &read.buf, 0, 16);
        }
        ctx.queue.submit([enc.finish()]);
        let mut stamps = [0u64; 2];
        let mut reads = vec![(&self.read.buf, 16 * n as u64)];
        if let Some((_, _, read)) = &self.queries {
            reads.push((&read.buf, 16));
        }
        read_back(ctx, &reads, |k, bytes| {
            if k == 0 {
                for ((v, s), p) in bytes.chunks_exact(16).zip(sort.iter_mut()).zip(perm.iter_mut()) {
                    let e: [u32; 4] = bytemuck::pod_read_unaligned(v);
                    *s = ((u64::from(e[0]) << 32) | u64::from(e[1]), e[2]);
                    *p = e[2];
                }
            } else {
                stamps = bytemuck::pod_read_unaligned(bytes);
            }
        })?;
        let period = f64::from(ctx.queue.get_timestamp_period());
        Ok(self.queries.as_ref().map(|_| stamps[1].saturating_sub(stamps[0]) as f64 * period * 1e-6))
    }
}
