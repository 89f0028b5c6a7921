//! Buffer helpers: uploads, per-dispatch params, and the one place that reads results back
//! (staging buffer, map_async, poll).

use wgpu::util::DeviceExt;

use super::layout::{CHUNK_BYTES, PARAMS_STRIDE, Params};
use super::pipelines::Tiles;
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::{Error, Result};

/// Smallest buffer made: bindings cannot be empty.
const MIN_BYTES: u64 = 16;

/// A buffer holding `bytes` (at least [`MIN_BYTES`]), for `usage`.
pub fn upload(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    if (bytes.len() as u64) < MIN_BYTES {
        let mut padded = bytes.to_vec();
        padded.resize(MIN_BYTES as usize, 0);
        return device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: &padded,
            usage,
        });
    }
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytes,
        usage,
    })
}

/// A read-only storage buffer holding `records`.
pub fn storage<T: bytemuck::Pod>(
    device: &wgpu::Device,
    label: &str,
    records: &[T],
) -> wgpu::Buffer {
    upload(
        device,
        label,
        bytemuck::cast_slice(records),
        wgpu::BufferUsages::STORAGE,
    )
}

/// The looped-over records of one inner range of a gather pass, as it reads them: a
/// storage buffer ([`Tiles::Workgroup`]) or one uniform chunk, padded ([`Tiles::Uniform`]).
pub fn tiled<T: bytemuck::Pod + Default>(
    r: &GpuRenderer,
    label: &str,
    records: &[T],
) -> wgpu::Buffer {
    let device = &r.ctx.device;
    match r.planner.tiles {
        Tiles::Workgroup => storage(device, label, records),
        Tiles::Uniform => {
            let mut padded = records.to_vec();
            padded.resize(CHUNK_BYTES as usize / size_of::<T>(), T::default());
            upload(
                device,
                label,
                bytemuck::cast_slice(&padded),
                wgpu::BufferUsages::UNIFORM,
            )
        }
    }
}

/// A zeroed read-write storage buffer of `bytes` that can be copied out.
pub fn output(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes.max(MIN_BYTES),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
        mapped_at_creation: false,
    })
}

/// Per-dispatch [`Params`], [`PARAMS_STRIDE`] bytes apart, bound with a dynamic offset.
#[derive(Default)]
pub struct ParamsTable {
    bytes: Vec<u8>,
}

impl ParamsTable {
    /// Appends `p`; returns its dynamic offset.
    pub fn push(&mut self, p: Params) -> u32 {
        self.push_scenes(&[p])
    }

    /// Appends `scenes` as one array (a batched dispatch's, one per scene); returns its
    /// dynamic offset.
    pub fn push_scenes(&mut self, scenes: &[Params]) -> u32 {
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(bytemuck::cast_slice(scenes));
        let end = self.bytes.len().next_multiple_of(PARAMS_STRIDE as usize);
        self.bytes.resize(end, 0);
        offset as u32
    }

    /// The buffer (uniform, or storage for the batched gather passes).
    pub fn upload(&self, device: &wgpu::Device, label: &str) -> wgpu::Buffer {
        upload(
            device,
            label,
            &self.bytes,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::STORAGE,
        )
    }
}

/// A binding of the whole of `buffer`.
pub fn whole(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

/// A binding of the first `size` bytes of `buffer` (for dynamic offsets).
pub fn window(binding: u32, buffer: &wgpu::Buffer, size: u64) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
            buffer,
            offset: 0,
            size: wgpu::BufferSize::new(size),
        }),
    }
}

/// Buffers to read back after one submission.
#[derive(Default)]
pub struct Readback {
    staging: Vec<(wgpu::Buffer, u64)>,
}

impl Readback {
    /// Copies the first `bytes` of `src` to a new staging buffer; returns its slot.
    pub fn copy(
        &mut self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        src: &wgpu::Buffer,
        bytes: u64,
    ) -> usize {
        self.copy_at(device, enc, src, 0, bytes)
    }

    /// Copies `bytes` of `src` from byte `offset` (a multiple of 4) to a new staging
    /// buffer; returns its slot.
    pub fn copy_at(
        &mut self,
        device: &wgpu::Device,
        enc: &mut wgpu::CommandEncoder,
        src: &wgpu::Buffer,
        offset: u64,
        bytes: u64,
    ) -> usize {
        let size = bytes
            .max(MIN_BYTES)
            .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // the padding past a short source's end is not copied (nothing at all for a scene
        // of no records at the end of a batch)
        let size = size.min(src.size().saturating_sub(offset));
        if size > 0 {
            enc.copy_buffer_to_buffer(src, offset, &staging, 0, size);
        }
        self.staging.push((staging, bytes));
        self.staging.len() - 1
    }

    /// Waits for the device and returns every slot's f32 values.
    pub fn finish(self, device: &wgpu::Device) -> Result<Vec<Vec<f32>>> {
        let (tx, rx) = std::sync::mpsc::channel();
        for (i, (buf, _)) in self.staging.iter().enumerate() {
            let tx = tx.clone();
            buf.map_async(wgpu::MapMode::Read, .., move |r| {
                let _ = tx.send((i, r));
            });
        }
        drop(tx);
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))?;
        for (i, r) in rx.iter() {
            r.map_err(|e| Error::Gpu(format!("reading back buffer {i}: {e}")))?;
        }
        let mut out = Vec::with_capacity(self.staging.len());
        for (buf, bytes) in &self.staging {
            let view = buf
                .get_mapped_range(..)
                .map_err(|e| Error::Gpu(format!("mapping a readback buffer: {e}")))?;
            out.push(bytemuck::pod_collect_to_vec::<u8, f32>(
                &view[..*bytes as usize],
            ));
            drop(view);
            buf.unmap();
        }
        Ok(out)
    }
}

/// A bind group of `pass`'s layout: `params` at binding 0 (one [`Params`] at a dynamic
/// offset), then the whole of each of `buffers` in order.
pub fn bind(
    r: &GpuRenderer,
    pass: Pass,
    params: &wgpu::Buffer,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    bind_scenes(r, pass, params, 1, buffers)
}

/// [`bind`] with `scenes` [`Params`] at binding 0 (a batched dispatch's).
pub fn bind_scenes(
    r: &GpuRenderer,
    pass: Pass,
    params: &wgpu::Buffer,
    scenes: usize,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let mut entries = vec![window(0, params, (scenes * size_of::<Params>()) as u64)];
    entries.extend(
        buffers
            .iter()
            .enumerate()
            .map(|(k, b)| whole(k as u32 + 1, b)),
    );
    r.ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(pass.name()),
        layout: &r.pipeline(pass).layout,
        entries: &entries,
    })
}

/// Encodes reduce_slices over `parts` (`slices` slices of `elements` vec4 elements each);
/// returns the buffer of the sums.
pub fn reduce_slices(
    r: &GpuRenderer,
    sub: &mut Submission<'_>,
    base: Params,
    parts: &wgpu::Buffer,
    elements: usize,
    slices: u32,
) -> wgpu::Buffer {
    let device = &r.ctx.device;
    let mut table = ParamsTable::default();
    let offset = table.push(Params {
        n_pixels: elements as u32,
        n_slices: slices,
        ..base
    });
    let params = table.upload(device, "reduce_slices params");
    let total = output(device, "slice sums", elements as u64 * 16);
    let bg = bind(r, Pass::ReduceSlices, &params, &[parts, &total]);
    sub.compute(
        Pass::ReduceSlices,
        0,
        &[(&bg, offset, r.planner.reduce_groups(elements))],
    );
    total
}
