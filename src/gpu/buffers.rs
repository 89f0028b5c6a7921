//! The buffers of a renderer, kept between calls: device buffers by role (a call's n-th
//! buffer of a label gets the same buffer as the last call's, grown where it is too
//! small), bind groups over them, staging buffers that large uploads are written straight
//! into, and one readback buffer that every result of a call is copied to and read from
//! where it is mapped. A call allocates nothing on the device once the shapes fit.

use std::collections::HashMap;
use std::sync::MutexGuard;

use super::layout::DispatchParams;
use super::layout::PARAMS_STRIDE;
use crate::error::{Error, Result};

/// Smallest buffer made: bindings cannot be empty, and a binding must hold at least one
/// element of the shader's array (a `Texel` is 256 bytes): a scene with no foreground
/// pixels, no lit texels or no pixel with an upstream gradient still binds a valid buffer.
/// tests/it/gpu_bindings.rs checks every binding of every pass against it.
pub const MIN_BYTES: u64 = 256;

/// Alignment of every upload and readback region: a multiple of wgpu's copy and map
/// alignments and of the storage and uniform offset alignments.
const ALIGN: u64 = 256;

/// One binding of a bind group: binding index, buffer, offset and size (`None`: the rest).
pub type Entry<'a> = (u32, &'a wgpu::Buffer, u64, Option<u64>);

/// A buffer's label and usage, and which of the call's buffers of both it is.
type Role = (&'static str, wgpu::BufferUsages, u32);

/// A bind group's pass and bindings.
type GroupKey = (&'static str, Vec<(u32, wgpu::Buffer, u64, Option<u64>)>);

/// The buffers and bind groups a renderer keeps.
#[derive(Default)]
pub struct Pool {
    kept: HashMap<Role, wgpu::Buffer>,
    uses: HashMap<(&'static str, wgpu::BufferUsages), u32>,
    groups: HashMap<GroupKey, wgpu::BindGroup>,
    readback: Option<wgpu::Buffer>,
}

/// `bytes` made a valid buffer size: at least [`MIN_BYTES`], whole [`ALIGN`]s.
fn buffer_size(bytes: u64) -> u64 {
    bytes.max(MIN_BYTES).next_multiple_of(ALIGN)
}

/// A buffer of at least `bytes` for `usage`: `old` where it fits, else a new one with a
/// quarter more room than `old` had, so that slowly growing inputs do not make one every
/// call.
fn fit(
    device: &wgpu::Device,
    old: Option<&wgpu::Buffer>,
    label: &str,
    usage: wgpu::BufferUsages,
    bytes: u64,
    mapped: bool,
) -> (wgpu::Buffer, bool) {
    let need = buffer_size(bytes);
    match old {
        Some(b) if b.size() >= need && b.usage() == usage => (b.clone(), false),
        _ => {
            let grown = old.map_or(0, |b| (b.size() + b.size() / 4).next_multiple_of(ALIGN));
            let b = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: need.max(grown),
                usage,
                mapped_at_creation: mapped,
            });
            (b, true)
        }
    }
}

impl Pool {
    /// Starts a call: the n-th buffer of each label is again the first one's.
    pub fn begin(&mut self) {
        self.uses.clear();
    }

    /// The role of the call's next buffer of `label` and `usage`.
    fn role(&mut self, label: &'static str, usage: wgpu::BufferUsages) -> Role {
        let n = self.uses.entry((label, usage)).or_default();
        *n += 1;
        (label, usage, *n - 1)
    }

    /// The call's next buffer of `label`, of at least `bytes`, for `usage` (plus
    /// `COPY_DST`, so that uploads can reach it). Its contents are whatever the last
    /// call left: every pass writes what it reads back.
    pub fn buffer(
        &mut self,
        device: &wgpu::Device,
        label: &'static str,
        usage: wgpu::BufferUsages,
        bytes: u64,
    ) -> wgpu::Buffer {
        let usage = usage | wgpu::BufferUsages::COPY_DST;
        let key = self.role(label, usage);
        let (b, new) = fit(device, self.kept.get(&key), label, usage, bytes, false);
        if new {
            // groups over the old buffer would keep it alive
            self.groups.clear();
            self.kept.insert(key, b.clone());
        }
        b
    }

    /// A bind group of `layout` (pass `pass`) over `entries`, made once per set of
    /// buffers and ranges.
    pub fn bind(
        &mut self,
        device: &wgpu::Device,
        pass: &'static str,
        layout: &wgpu::BindGroupLayout,
        entries: &[Entry<'_>],
    ) -> wgpu::BindGroup {
        let key = (
            pass,
            entries
                .iter()
                .map(|&(i, b, o, s)| (i, b.clone(), o, s))
                .collect::<Vec<_>>(),
        );
        if let Some(g) = self.groups.get(&key) {
            return g.clone();
        }
        let bindings: Vec<wgpu::BindGroupEntry<'_>> = entries
            .iter()
            .map(|&(binding, buffer, offset, size)| wgpu::BindGroupEntry {
                binding,
                resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding {
                    buffer,
                    offset,
                    size: size.and_then(wgpu::BufferSize::new),
                }),
            })
            .collect();
        let g = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(pass),
            layout,
            entries: &bindings,
        });
        self.groups.insert(key, g.clone());
        g
    }

    /// The call's next staging buffer of `label` for an upload of `bytes`, mapped for
    /// writing.
    pub fn staging(
        &mut self,
        device: &wgpu::Device,
        label: &'static str,
        bytes: u64,
    ) -> Result<wgpu::Buffer> {
        let usage = wgpu::BufferUsages::MAP_WRITE | wgpu::BufferUsages::COPY_SRC;
        let key = self.role(label, usage);
        let (b, new) = fit(device, self.kept.get(&key), label, usage, bytes, true);
        if new {
            self.kept.insert(key, b.clone());
        } else if let Err(e) = map(device, &b, wgpu::MapMode::Write) {
            // left mapped by a call that failed, or lost: the next call makes a new one
            self.kept.remove(&key);
            return Err(e);
        }
        Ok(b)
    }

    /// The readback buffer, unmapped, of at least `bytes`.
    pub fn readback(&mut self, device: &wgpu::Device, bytes: u64) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let (b, new) = fit(
            device,
            self.readback.as_ref(),
            "readback",
            usage,
            bytes,
            false,
        );
        if new {
            self.readback = Some(b.clone());
        }
        b
    }
}

/// Maps the whole of `buffer` and waits for it.
pub fn map(device: &wgpu::Device, buffer: &wgpu::Buffer, mode: wgpu::MapMode) -> Result<()> {
    let (tx, rx) = std::sync::mpsc::channel();
    buffer.map_async(mode, .., move |r| {
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| Error::Gpu(format!("waiting for the device: {e}")))?;
    rx.recv()
        .map_err(|e| Error::Gpu(format!("mapping a buffer: {e}")))?
        .map_err(|e| Error::Gpu(format!("mapping a buffer: {e}")))
}

/// Per-dispatch [`DispatchParams`], [`PARAMS_STRIDE`] bytes apart, bound with a dynamic offset.
#[derive(Default)]
pub struct ParamsTable {
    /// The table's bytes.
    pub bytes: Vec<u8>,
}

impl ParamsTable {
    /// Appends `p`; returns its dynamic offset.
    pub fn push(&mut self, p: DispatchParams) -> u32 {
        self.push_scenes(&[p])
    }

    /// Appends `scenes` as one array (a batched dispatch's, one per scene); returns its
    /// dynamic offset.
    pub fn push_scenes(&mut self, scenes: &[DispatchParams]) -> u32 {
        let offset = self.bytes.len();
        self.bytes.extend_from_slice(bytemuck::cast_slice(scenes));
        let end = self.bytes.len().next_multiple_of(PARAMS_STRIDE as usize);
        self.bytes.resize(end, 0);
        offset as u32
    }
}

/// Results to read back after one submission: regions of device buffers, copied one
/// after another into the pool's readback buffer.
#[derive(Default)]
pub struct Readback {
    requests: Vec<(wgpu::Buffer, u64, u64)>,
    bytes: u64,
}

/// A readback slot: where a region lies in the readback buffer.
#[derive(Clone, Copy, Debug)]
pub struct Slot {
    at: u64,
    bytes: u64,
}

impl Readback {
    /// Asks for `bytes` of `src` from byte `offset` (both multiples of 4); returns its
    /// slot. Slots asked for one after another lie one after another.
    pub fn request(&mut self, src: &wgpu::Buffer, offset: u64, bytes: u64) -> Slot {
        let slot = Slot {
            at: self.bytes,
            bytes,
        };
        self.requests.push((src.clone(), offset, bytes));
        self.bytes += bytes;
        slot
    }

    /// Encodes the copies into `readback` (at least as large as every region together).
    pub fn encode(&self, enc: &mut wgpu::CommandEncoder, readback: &wgpu::Buffer) {
        let mut at = 0;
        for (src, offset, bytes) in &self.requests {
            if *bytes > 0 {
                enc.copy_buffer_to_buffer(src, *offset, readback, at, *bytes);
            }
            at += bytes;
        }
    }

    /// Bytes of every region together.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }
}

/// The readback buffer, mapped: every slot's values. Holds the renderer's buffers until
/// it is dropped, then unmaps.
pub struct Readout<'a> {
    view: Option<wgpu::BufferView>,
    buffer: wgpu::Buffer,
    _pool: MutexGuard<'a, Pool>,
}

impl<'a> Readout<'a> {
    /// Maps `buffer` (after the submission that fills it), holding `pool`.
    pub fn map(
        device: &wgpu::Device,
        buffer: wgpu::Buffer,
        pool: MutexGuard<'a, Pool>,
    ) -> Result<Self> {
        map(device, &buffer, wgpu::MapMode::Read)?;
        let view = buffer
            .get_mapped_range(..)
            .map_err(|e| Error::Gpu(format!("mapping the readback buffer: {e}")))?;
        Ok(Readout {
            view: Some(view),
            buffer,
            _pool: pool,
        })
    }

    /// The f32 values from the start of `first` to the end of `last` (slots asked for one
    /// after another).
    pub fn span(&self, first: Slot, last: Slot) -> &[f32] {
        let bytes = match &self.view {
            Some(v) => &v[first.at as usize..(last.at + last.bytes) as usize],
            None => &[],
        };
        bytemuck::cast_slice(bytes)
    }

    /// The f32 values of `slot`.
    pub fn get(&self, slot: Slot) -> &[f32] {
        self.span(slot, slot)
    }
}

impl Drop for Readout<'_> {
    fn drop(&mut self) {
        self.view = None;
        self.buffer.unmap();
    }
}
