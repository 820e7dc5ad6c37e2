//! Device buffers that grow to fit and are reused from step to step.

use super::{GpuContext, GpuError};

/// A device buffer with room for `capacity` bytes (at least 256).
pub struct GpuArray {
    pub buf: wgpu::Buffer,
    capacity: u64,
    usage: wgpu::BufferUsages,
    label: &'static str,
}

impl GpuArray {
    pub fn new(ctx: &GpuContext, label: &'static str, usage: wgpu::BufferUsages) -> Self {
        Self { buf: create(ctx, label, usage, 256), capacity: 256, usage, label }
    }

    /// Makes room for `bytes`; true if the buffer was replaced (its bind
    /// groups must be rebuilt). Grows by a quarter more than asked, so a
    /// slowly growing set reallocates rarely.
    pub fn reserve(&mut self, ctx: &GpuContext, bytes: u64, binding: bool) -> Result<bool, GpuError> {
        if binding && bytes > ctx.max_binding {
            return Err(GpuError(format!(
                "GPU buffer `{}` needs {bytes} bytes, more than the adapter's storage binding limit of {} bytes \
                 (fewer particles, or --backend cpu)",
                self.label, ctx.max_binding
            )));
        }
        if bytes <= self.capacity {
            return Ok(false);
        }
        let mut cap = (bytes + bytes / 4).next_multiple_of(256);
        if binding {
            cap = cap.min(ctx.max_binding.max(bytes));
        }
        self.buf = create(ctx, self.label, self.usage, cap);
        self.capacity = cap;
        Ok(true)
    }

    /// Writes `data` at the start of the buffer (which must have room).
    pub fn upload<T: bytemuck::Pod>(&self, ctx: &GpuContext, data: &[T]) {
        if !data.is_empty() {
            ctx.queue.write_buffer(&self.buf, 0, bytemuck::cast_slice(data));
        }
    }
}

fn create(ctx: &GpuContext, label: &str, usage: wgpu::BufferUsages, size: u64) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false })
}

/// Usage of a storage buffer the host writes and reads back.
pub const STORAGE: wgpu::BufferUsages =
    wgpu::BufferUsages::STORAGE.union(wgpu::BufferUsages::COPY_DST).union(wgpu::BufferUsages::COPY_SRC);

/// Usage of a host-readable staging buffer.
pub const READBACK: wgpu::BufferUsages = wgpu::BufferUsages::MAP_READ.union(wgpu::BufferUsages::COPY_DST);

/// Maps every buffer of `bufs` for reading (their first `len` bytes), waits
/// for the device, and hands the bytes to `read`, then unmaps.
pub fn read_back(
    ctx: &GpuContext,
    bufs: &[(&wgpu::Buffer, u64)],
    mut read: impl FnMut(usize, &[u8]),
) -> Result<(), GpuError> {
    for &(b, len) in bufs {
        if len > 0 {
            b.map_async(wgpu::MapMode::Read, ..len, |r| {
                if let Err(e) = r {
                    eprintln!("porosph: GPU read-back failed: {e}");
                }
            });
        }
    }
    ctx.device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError(format!("GPU device lost while waiting for results: {e}")))?;
    for (k, &(b, len)) in bufs.iter().enumerate() {
        if len > 0 {
            let view = b.get_mapped_range(..len).map_err(|e| GpuError(format!("GPU read-back failed: {e}")))?;
            read(k, &view);
            drop(view);
            b.unmap();
        }
    }
    Ok(())
}
