//! One submission: the command encoder, every compute pass (each timed by GPU timestamps
//! where the adapter has them), the dispatches made, and the readback.

use super::buffers::Readback;
use super::pipelines::Pass;
use super::plan::Dispatch;
use super::{GpuRenderer, PassTiming};
use crate::error::Result;

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
    /// The encoder, for copies.
    pub enc: wgpu::CommandEncoder,
    /// The buffers to read back.
    pub readback: Readback,
    passes: Vec<Encoded>,
    dispatches: Vec<Dispatch>,
}

impl<'a> Submission<'a> {
    /// An empty submission on `r`'s device.
    pub fn new(r: &'a GpuRenderer, label: &str) -> Self {
        let enc = r
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
        Submission {
            r,
            enc,
            readback: Readback::default(),
            passes: Vec::new(),
            dispatches: Vec::new(),
        }
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

    /// Submits, waits, and returns every readback slot's values and what the call recorded.
    pub fn finish(mut self) -> Result<(Vec<Vec<f32>>, LastRun)> {
        let device = &self.r.ctx.device;
        let stride = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;
        let timed: Vec<&Encoded> = self.passes.iter().filter(|p| p.queries.is_some()).collect();
        let mut ts_slot = None;
        if !timed.is_empty() {
            let resolve = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: stride * timed.len() as u64,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            for (k, p) in timed.iter().enumerate() {
                if let Some(q) = &p.queries {
                    self.enc
                        .resolve_query_set(q, 0..2, &resolve, stride * k as u64);
                }
            }
            ts_slot = Some(self.readback.copy(
                device,
                &mut self.enc,
                &resolve,
                stride * timed.len() as u64,
            ));
        }
        self.r.ctx.queue.submit([self.enc.finish()]);
        let data = self.readback.finish(device)?;
        let mut timings: Vec<PassTiming> = Vec::new();
        if let Some(slot) = ts_slot {
            let period_ns = self.r.ctx.queue.get_timestamp_period() as f64;
            // the u64 ticks, read back as pairs of f32 bit patterns (little-endian)
            let tick = |k: usize, end: usize| {
                let f = (stride as usize / 4) * k + 2 * end;
                let v = &data[slot];
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
            data,
            LastRun {
                timings,
                dispatches: self.dispatches,
            },
        ))
    }
}
