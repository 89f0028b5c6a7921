//! Buffer helpers: uploads, uniform chunk tables, per-dispatch params, and the one place
//! that reads results back (staging buffer, map_async, poll).

use wgpu::util::DeviceExt;

use super::layout::{CHUNK_BYTES, PARAMS_STRIDE, Params};
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

/// Dispatches `groups` workgroups once per uniform chunk: params entry `offsets[c]` with
/// chunk `c` of the chunk buffer bound at binding 1.
pub fn dispatch_chunks(
    cp: &mut wgpu::ComputePass<'_>,
    bg: &wgpu::BindGroup,
    offsets: &[u32],
    groups: u32,
) {
    for (c, &off) in offsets.iter().enumerate() {
        cp.set_bind_group(0, bg, &[off, c as u32 * CHUNK_BYTES as u32]);
        cp.dispatch_workgroups(groups, 1, 1);
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

/// Records padded to whole uniform chunks of [`CHUNK_BYTES`]: returns the buffer and the
/// number of records in each chunk (one empty chunk for no records).
pub fn uniform_chunks<T: bytemuck::Pod + Default>(
    device: &wgpu::Device,
    label: &str,
    records: &[T],
    per_chunk: usize,
) -> (wgpu::Buffer, Vec<u32>) {
    let chunks = records.len().div_ceil(per_chunk).max(1);
    let mut padded = records.to_vec();
    padded.resize(chunks * per_chunk, T::default());
    let bytes: &[u8] = bytemuck::cast_slice(&padded);
    debug_assert_eq!(bytes.len() as u64, chunks as u64 * CHUNK_BYTES);
    // no records (an all-black map, a map whose texels all have zero solid angle, an
    // upstream gradient of zeros) is one empty chunk: the passes then write their zero
    // sums, instead of binding an empty table of dispatches (a validation error)
    let sizes = if records.is_empty() {
        vec![0]
    } else {
        records.chunks(per_chunk).map(|c| c.len() as u32).collect()
    };
    (
        upload(device, label, bytes, wgpu::BufferUsages::UNIFORM),
        sizes,
    )
}

/// Per-dispatch [`Params`], [`PARAMS_STRIDE`] bytes apart, bound with a dynamic offset.
#[derive(Default)]
pub struct ParamsTable {
    bytes: Vec<u8>,
}

impl ParamsTable {
    /// Appends `p`; returns its dynamic offset.
    pub fn push(&mut self, p: Params) -> u32 {
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(bytemuck::bytes_of(&p));
        self.bytes.resize(offset + PARAMS_STRIDE as usize, 0);
        offset as u32
    }

    /// One entry per uniform chunk of `sizes`, `first` set on chunk 0 (the start of each
    /// sum), built by `entry(chunk size)` from `base`; returns their dynamic offsets.
    pub fn push_chunks(
        &mut self,
        base: Params,
        sizes: &[u32],
        entry: impl Fn(u32) -> (u32, u32),
    ) -> Vec<u32> {
        sizes
            .iter()
            .enumerate()
            .map(|(c, &size)| {
                let (n_pixels, n_texels) = entry(size);
                self.push(Params {
                    n_pixels,
                    n_texels,
                    first: (c == 0) as u32,
                    ..base
                })
            })
            .collect()
    }

    /// The uniform buffer.
    pub fn upload(&self, device: &wgpu::Device, label: &str) -> wgpu::Buffer {
        upload(device, label, &self.bytes, wgpu::BufferUsages::UNIFORM)
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
        let size = bytes
            .max(MIN_BYTES)
            .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT);
        let staging = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        enc.copy_buffer_to_buffer(src, 0, &staging, 0, size);
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
