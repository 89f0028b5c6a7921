//! The GPU path: WGSL compute shaders through wgpu. Forward: one invocation per foreground
//! pixel, looping over uniform chunks of lit texels. Backward: a per-texel gather for
//! dLoss/dL and each texel's share of dLoss/dctrl, a fixed-order reduction of the shares,
//! and a per-pixel pass for dLoss/dn. Every output element has one writer and every sum a
//! fixed order, so two runs give bitwise equal results.

mod backward;
mod buffers;
pub mod context;
mod forward;
pub mod layout;
pub mod pipelines;

pub use context::GpuContext;
pub use pipelines::Pass;

use crate::Backend;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Batch, Gradients, Image};
use pipelines::Pipeline;

/// The layer on a wgpu device, pipelines built once.
pub struct GpuRenderer {
    ctx: GpuContext,
    pipelines: Vec<Pipeline>,
    binding_cap: Option<u64>,
}

impl GpuRenderer {
    /// A renderer on the best adapter (see [`GpuContext::new`]).
    pub fn new() -> Result<Self> {
        Self::with_context(GpuContext::new()?)
    }

    /// A renderer on an open device.
    pub fn with_context(ctx: GpuContext) -> Result<Self> {
        let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipelines = Pass::ALL
            .iter()
            .map(|&p| Pipeline::new(&ctx.device, p))
            .collect();
        if let Some(e) = pollster::block_on(scope.pop()) {
            return Err(Error::Gpu(format!("building the pipelines: {e}")));
        }
        Ok(GpuRenderer {
            ctx,
            pipelines,
            binding_cap: None,
        })
    }

    /// Caps the bytes of any one storage binding below the adapter's limit, so that large
    /// inputs are split into more, smaller dispatches (to bound memory, and to test the
    /// split path on small inputs). At least one workgroup's worth of records is kept.
    pub fn with_binding_cap(mut self, bytes: u64) -> Self {
        self.binding_cap = Some(bytes);
        self
    }

    /// The device and adapter.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn pipeline(&self, pass: Pass) -> &Pipeline {
        &self.pipelines[Pass::ALL.iter().position(|&p| p == pass).unwrap_or(0)]
    }

    /// Most records one storage binding (and one dispatch of 64-thread workgroups) may
    /// hold, for records of `bytes` bytes: inputs beyond it are split into ranges.
    fn max_records(&self, bytes: u64) -> usize {
        let limit = self.ctx.limits.max_storage_buffer_binding_size;
        let by_binding = limit.min(self.binding_cap.unwrap_or(u64::MAX)) / bytes;
        let by_buffer = self.ctx.limits.max_buffer_size / bytes;
        let by_dispatch =
            self.ctx.limits.max_compute_workgroups_per_dimension as u64 * layout::WG as u64;
        let n = by_binding.min(by_buffer).min(by_dispatch) as usize;
        // whole workgroups, so that range offsets stay aligned
        (n / layout::WG * layout::WG).max(layout::WG)
    }

    /// Runs `f` inside validation and out-of-memory error scopes.
    fn scoped<T>(&self, what: &str, f: impl FnOnce() -> Result<T>) -> Result<T> {
        let oom = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::OutOfMemory);
        let val = self
            .ctx
            .device
            .push_error_scope(wgpu::ErrorFilter::Validation);
        let r = f();
        let v = pollster::block_on(val.pop());
        let o = pollster::block_on(oom.pop());
        if let Some(e) = o.or(v) {
            return Err(Error::Gpu(format!("{what}: {e}")));
        }
        r
    }
}

impl Backend for GpuRenderer {
    fn describe(&self) -> String {
        self.ctx.describe()
    }

    fn render_prepared(&self, preps: &[Prepared]) -> Result<Vec<Image>> {
        self.scoped("forward", || forward::forward(self, preps))
    }

    fn backward_prepared(&self, preps: &[Prepared], upstream: &[Image]) -> Result<Vec<Gradients>> {
        self.scoped("backward", || backward::backward(self, preps, upstream))
    }

    // the whole batch in one submission
    fn render(&self, batch: &Batch) -> Result<Vec<Image>> {
        let preps: Vec<Prepared> = batch.scenes().iter().map(Prepared::new).collect();
        self.render_prepared(&preps)
    }

    fn backward(&self, batch: &Batch, upstream: &[Image]) -> Result<Vec<Gradients>> {
        batch.check_upstream(upstream)?;
        let preps: Vec<Prepared> = batch.scenes().iter().map(Prepared::new).collect();
        self.backward_prepared(&preps, upstream)
    }
}
