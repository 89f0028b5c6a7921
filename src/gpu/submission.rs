//! One call's submission: the renderer's buffers (held for the call), the uploads, the
//! command encoder, every compute pass (each timed by GPU timestamps where the adapter
//! has them), the dispatches made, and the readback.

use std::sync::MutexGuard;

use super::buffers::{Entry, ParamsTable, Pool, Readback, Readout, Slot};
use super::layout::{DispatchParams, Pixel};
use super::pipelines::Pass;
use super::pixels::Selection;
use super::plan::Dispatch;
use super::{GpuRenderer, PassTiming};
use crate::error::{Error, Result};

/// What a call recorded: per-pass timings (empty without timestamps) and the dispatches.
#[derive(Clone, Debug, Default)]
pub struct LastRun {
    /// Per pass, in the order of first use.
    pub timings: Vec<PassTiming>,
    /// Every dispatch, in order.
    pub dispatches: Vec<Dispatch>,
}

/// A compute pass encoded: its pass, pixel-texel pairs and timestamp query set.
struct Encoded {
    pass: Pass,
    pairs: u64,
    queries: Option<wgpu::QuerySet>,
}

/// Commands of one submission.
pub struct Submission<'a> {
    r: &'a GpuRenderer,
    pool: MutexGuard<'a, Pool>,
    /// Copies from the staging buffers, submitted before `enc`.
    uploads: wgpu::CommandEncoder,
    enc: wgpu::CommandEncoder,
    readback: Readback,
    /// Pixel records uploaded in this call: usage, bytes and the selections' keys.
    pixel_uploads: Vec<(wgpu::BufferUsages, u64, Vec<[usize; 4]>, wgpu::Buffer)>,
    passes: Vec<Encoded>,
    dispatches: Vec<Dispatch>,
}

impl<'a> Submission<'a> {
    /// An empty submission on `r`'s device; holds `r`'s buffers until it is finished.
    pub fn new(r: &'a GpuRenderer, label: &str) -> Result<Self> {
        let mut pool = r
            .pool
            .lock()
            .map_err(|_| Error::Gpu("a call on this renderer failed mid-way".into()))?;
        pool.begin();
        let encoder = |l: &str| {
            r.ctx
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(l) })
        };
        Ok(Submission {
            r,
            pool,
            uploads: encoder("uploads"),
            enc: encoder(label),
            readback: Readback::default(),
            pixel_uploads: Vec::new(),
            passes: Vec::new(),
            dispatches: Vec::new(),
        })
    }

    /// A zeroed-or-reused read-write storage buffer of at least `bytes` that can be
    /// copied out: every element a pass reads back it writes first.
    pub fn output(&mut self, label: &'static str, bytes: u64) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC;
        self.pool.buffer(&self.r.ctx.device, label, usage, bytes)
    }

    /// [`Submission::output`] cleared to zeros first, for an output that the call's
    /// passes may leave unwritten (no records to reduce).
    pub fn zeroed(&mut self, label: &'static str, bytes: u64) -> wgpu::Buffer {
        let b = self.output(label, bytes);
        self.enc.clear_buffer(&b, 0, None);
        b
    }

    /// A buffer for `usage` holding `bytes` (a multiple of 4), through the queue.
    pub fn upload(
        &mut self,
        label: &'static str,
        usage: wgpu::BufferUsages,
        bytes: &[u8],
    ) -> wgpu::Buffer {
        let b = self
            .pool
            .buffer(&self.r.ctx.device, label, usage, bytes.len() as u64);
        if !bytes.is_empty() {
            self.r.ctx.queue.write_buffer(&b, 0, bytes);
        }
        b
    }

    /// A buffer for `usage` of `bytes` (a multiple of 16), written by `fill` straight into
    /// a kept staging buffer (no copy on the host), then copied on the device.
    pub fn upload_with(
        &mut self,
        label: &'static str,
        usage: wgpu::BufferUsages,
        bytes: u64,
        fill: impl FnOnce(wgpu::WriteOnly<'_, [u8]>),
    ) -> Result<wgpu::Buffer> {
        let device = &self.r.ctx.device;
        let dst = self.pool.buffer(device, label, usage, bytes);
        let staging = self.pool.staging(device, "staging", bytes)?;
        {
            let mut view = staging
                .get_mapped_range_mut(..)
                .map_err(|e| Error::Gpu(format!("mapping a staging buffer: {e}")))?;
            fill(view.slice(..bytes as usize));
        }
        staging.unmap();
        if bytes > 0 {
            self.uploads
                .copy_buffer_to_buffer(&staging, 0, &dst, 0, bytes);
        }
        Ok(dst)
    }

    /// A buffer for `usage` of `bytes` (at least the records') holding the records of
    /// `sels`, one scene after another, computed on all cores straight into the staging
    /// buffer; the call's earlier upload of the same records where there is one (the
    /// backward's two passes, where every foreground pixel has a gradient).
    pub fn upload_pixels(
        &mut self,
        label: &'static str,
        usage: wgpu::BufferUsages,
        sels: &[Selection<'_>],
        bytes: u64,
    ) -> Result<wgpu::Buffer> {
        let keys: Vec<[usize; 4]> = sels.iter().map(Selection::key).collect();
        let same = |(u, b, k, _): &&(wgpu::BufferUsages, u64, Vec<[usize; 4]>, wgpu::Buffer)| {
            *u == usage && *b == bytes && *k == keys
        };
        if let Some((.., buffer)) = self.pixel_uploads.iter().find(same) {
            return Ok(buffer.clone());
        }
        let buffer = self.upload_with(label, usage, bytes, |out| {
            let mut out = out;
            for sel in sels {
                let (head, tail) = out.split_at(sel.len() * size_of::<Pixel>());
                sel.write(head);
                out = tail;
            }
        })?;
        self.pixel_uploads
            .push((usage, bytes, keys, buffer.clone()));
        Ok(buffer)
    }

    /// The params buffer of `table` (uniform, or storage for the batched gather passes).
    pub fn params(&mut self, table: &ParamsTable) -> wgpu::Buffer {
        let usage = wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::STORAGE;
        self.upload("params", usage, &table.bytes)
    }

    /// A bind group of `pass`'s layout: `scenes` [`DispatchParams`] of `params` at binding 0 (at a
    /// dynamic offset), then each of `buffers` (buffer, offset, size or the rest) in order.
    pub fn bind(
        &mut self,
        pass: Pass,
        params: &wgpu::Buffer,
        scenes: usize,
        buffers: &[(&wgpu::Buffer, u64, Option<u64>)],
    ) -> wgpu::BindGroup {
        let mut entries: Vec<Entry<'_>> = vec![(
            0,
            params,
            0,
            Some((scenes * size_of::<DispatchParams>()) as u64),
        )];
        entries.extend(
            buffers
                .iter()
                .enumerate()
                .map(|(k, &(b, o, s))| (k as u32 + 1, b, o, s)),
        );
        let layout = &self.r.pipeline(pass).layout;
        self.pool
            .bind(&self.r.ctx.device, pass.name(), layout, &entries)
    }

    /// Asks for `bytes` of `src` from byte `offset` to be read back.
    pub fn read(&mut self, src: &wgpu::Buffer, offset: u64, bytes: u64) -> Slot {
        self.readback.request(src, offset, bytes)
    }

    /// One compute pass of `pass`'s pipeline: for each `(bind group, params offset,
    /// workgroups)`, binds the group at that dynamic offset and dispatches. `pairs`:
    /// pixel-texel pairs it covers.
    pub fn compute(
        &mut self,
        pass: Pass,
        pairs: u64,
        dispatches: &[(&wgpu::BindGroup, u32, [u32; 3])],
    ) {
        let device = &self.r.ctx.device;
        let queries = self.r.ctx.timestamps.then(|| {
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some(pass.name()),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            })
        });
        {
            let mut cp = self.enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(pass.name()),
                timestamp_writes: queries.as_ref().map(|q| wgpu::ComputePassTimestampWrites {
                    query_set: q,
                    beginning_of_pass_write_index: Some(0),
                    end_of_pass_write_index: Some(1),
                }),
            });
            cp.set_pipeline(&self.r.pipeline(pass).pipeline);
            for &(bg, offset, [x, y, z]) in dispatches {
                cp.set_bind_group(0, bg, &[offset]);
                cp.dispatch_workgroups(x, y, z);
                self.dispatches.push(Dispatch {
                    pass,
                    workgroups: [x, y, z],
                });
            }
        }
        self.passes.push(Encoded {
            pass,
            pairs,
            queries,
        });
    }

    /// Encodes reduce_slices over `parts` (`slices` slices of `elements` vec4 elements
    /// each); returns the buffer of the sums.
    pub fn reduce_slices(
        &mut self,
        base: DispatchParams,
        parts: &wgpu::Buffer,
        elements: usize,
        slices: u32,
    ) -> wgpu::Buffer {
        let mut table = ParamsTable::default();
        let offset = table.push(DispatchParams {
            n_pixels: elements as u32,
            n_slices: slices,
            ..base
        });
        let params = self.params(&table);
        let total = self.output("slice sums", elements as u64 * 16);
        let bg = self.bind(
            Pass::ReduceSlices,
            &params,
            1,
            &[(parts, 0, None), (&total, 0, None)],
        );
        let groups = self.r.planner.reduce_groups(elements);
        self.compute(Pass::ReduceSlices, 0, &[(&bg, offset, groups)]);
        total
    }

    /// Submits, waits, and returns the values read back and what the call recorded.
    pub fn finish(mut self) -> Result<(Readout<'a>, LastRun)> {
        let device = &self.r.ctx.device;
        let stride = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
        let timed: Vec<&Encoded> = self.passes.iter().filter(|p| p.queries.is_some()).collect();
        let mut ts_slot = None;
        if !timed.is_empty() {
            let usage = wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC;
            let bytes = stride * timed.len() as u64;
            let resolve = self.pool.buffer(device, "timestamps", usage, bytes);
            for (k, p) in timed.iter().enumerate() {
                if let Some(q) = &p.queries {
                    self.enc
                        .resolve_query_set(q, 0..2, &resolve, stride * k as u64);
                }
            }
            ts_slot = Some(self.readback.request(&resolve, 0, bytes));
        }
        let readback = self.pool.readback(device, self.readback.bytes());
        self.readback.encode(&mut self.enc, &readback);
        self.r
            .ctx
            .queue
            .submit([self.uploads.finish(), self.enc.finish()]);
        let out = Readout::map(device, readback, self.pool)?;
        let mut timings: Vec<PassTiming> = Vec::new();
        if let Some(slot) = ts_slot {
            let period_ns = self.r.ctx.queue.get_timestamp_period() as f64;
            let v = out.get(slot);
            // the u64 ticks, read back as pairs of f32 bit patterns (little-endian)
            let tick = |k: usize, end: usize| {
                let f = (stride as usize / 4) * k + 2 * end;
                v[f].to_bits() as u64 | (v[f + 1].to_bits() as u64) << 32
            };
            for (k, p) in timed.iter().enumerate() {
                let seconds = tick(k, 1).saturating_sub(tick(k, 0)) as f64 * period_ns * 1e-9;
                match timings.iter_mut().find(|t| t.pass == p.pass.name()) {
                    Some(t) => {
                        t.seconds += seconds;
                        t.pairs += p.pairs;
                        t.compute_passes += 1;
                    }
                    None => timings.push(PassTiming {
                        pass: p.pass.name(),
                        seconds,
                        pairs: p.pairs,
                        compute_passes: 1,
                    }),
                }
            }
        }
        Ok((
            out,
            LastRun {
                timings,
                dispatches: self.dispatches,
            },
        ))
    }
}
