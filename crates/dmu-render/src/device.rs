//! A headless device for captures, tests and benchmarks, and buffer readback.

use crate::RenderError;

/// The optional features the renderer uses when a device has them: timestamp
/// queries (GPU times in the stats), multiview (stereo pairs in one pass),
/// indirect draws with a first instance (`hzb` culling, and chunk draws
/// batched into multi-draws) and with a count buffer (hzb's second pass
/// compacted). Request `adapter.features() &
/// OPTIONAL_FEATURES`.
pub const OPTIONAL_FEATURES: wgpu::Features = wgpu::Features::TIMESTAMP_QUERY
    .union(wgpu::Features::MULTIVIEW)
    .union(wgpu::Features::INDIRECT_FIRST_INSTANCE)
    .union(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT);

/// How wgpu should size the memory blocks it suballocates buffers from on
/// `adapter`. On a CPU device (lavapipe) GPU memory is process memory, and
/// wgpu's default blocks (64-256 MiB) stay resident once touched, though
/// mostly free (short-lived upload buffers go through them): small blocks
/// there keep a memory budget a promise. Elsewhere wgpu's default.
pub fn memory_hints(adapter: &wgpu::AdapterInfo) -> wgpu::MemoryHints {
    if adapter.device_type == wgpu::DeviceType::Cpu {
        wgpu::MemoryHints::MemoryUsage
    } else {
        wgpu::MemoryHints::Performance
    }
}

/// The instance `descriptor` with wgpu's check of indirect draw arguments
/// off in release builds: every draw's arguments come from the geometry
/// pool's slots (written by the CPU, or by hzb's compute pass from them),
/// and the check costs a compute pass and a buffer of its own per indirect
/// round (33.6 MB for the 500M plant's overview, docs/measurements.md).
/// Debug builds, so the test suite, keep it, and
/// `WGPU_VALIDATION_INDIRECT_CALL=1` turns it back on.
pub fn instance_descriptor(mut descriptor: wgpu::InstanceDescriptor) -> wgpu::InstanceDescriptor {
    if !cfg!(debug_assertions) {
        descriptor
            .flags
            .remove(wgpu::InstanceFlags::VALIDATION_INDIRECT_CALL);
        descriptor.flags = descriptor.flags.with_env();
    }
    descriptor
}

/// A device and queue with no surface, with the [`OPTIONAL_FEATURES`] the
/// adapter has. Honours `WGPU_BACKEND` and the other `wgpu` environment
/// variables.
pub fn headless_device() -> Result<(wgpu::Device, wgpu::Queue, wgpu::AdapterInfo), RenderError> {
    let instance = wgpu::Instance::new(instance_descriptor(
        wgpu::InstanceDescriptor::new_without_display_handle_from_env(),
    ));
    let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        compatible_surface: None,
        ..Default::default()
    }))
    .map_err(|e| RenderError::NoAdapter {
        reason: e.to_string(),
    })?;
    let info = adapter.get_info();
    let required_features = adapter.features() & OPTIONAL_FEATURES;
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("dmu headless"),
        required_features,
        required_limits: adapter.limits(),
        memory_hints: memory_hints(&info),
        ..Default::default()
    }))
    .map_err(|e| RenderError::RequestDevice {
        adapter: info.name.clone(),
        reason: e.to_string(),
    })?;
    Ok((device, queue, info))
}

/// Maps `buffer[..size]` for reading, waits, and hands the bytes to `read`.
pub(crate) fn map_read<T>(
    device: &wgpu::Device,
    buffer: &wgpu::Buffer,
    size: u64,
    what: &'static str,
    read: impl FnOnce(&[u8]) -> T,
) -> Result<T, RenderError> {
    let fail = |reason: String| RenderError::Readback { what, reason };
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(wgpu::MapMode::Read, ..size, move |r| {
        // The receiver outlives the poll below; a send error cannot happen.
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| fail(e.to_string()))?;
    rx.recv()
        .map_err(|e| fail(e.to_string()))?
        .map_err(|e| fail(e.to_string()))?;
    let result = {
        let view = buffer
            .get_mapped_range(..size)
            .map_err(|e| fail(e.to_string()))?;
        read(&view)
    };
    buffer.unmap();
    Ok(result)
}
