//! The GPU path: WGSL compute shaders through wgpu. Forward: one invocation per foreground
//! pixel and slice of the lit texels, the texels read in workgroup-memory tiles. Backward:
//! a per-texel gather (per slice of the pixels) for dLoss/dL and each texel's share of
//! dLoss/dctrl, a fixed-order reduction of the shares, and a per-pixel pass for dLoss/dn.
//! Slices are added in slice order by reduce_slices ([`plan`] chooses their number). Every
//! output element has one writer and every sum a fixed order, so two runs give bitwise
//! equal results.

mod backward;
mod buffers;
pub mod context;
mod forward;
pub mod layout;
pub mod pipelines;
pub mod plan;
mod submission;

use std::sync::Mutex;

pub use context::GpuContext;
pub use pipelines::{Pass, Tiles};
pub use plan::{Dispatch, Planner, Shape};

use crate::Backend;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Batch, Gradients, Image, Wanted};
use pipelines::Pipeline;
use submission::LastRun;

/// The GPU time of one pass in the last call, from timestamps written at the start and end
/// of each of its compute passes.
#[derive(Clone, Debug, PartialEq)]
pub struct PassTiming {
    /// The pass (the shader's name).
    pub pass: &'static str,
    /// Seconds, summed over its compute passes.
    pub seconds: f64,
    /// Pixel-texel pairs it covered (0 for the reductions).
    pub pairs: u64,
    /// Its compute passes (one per scene and range).
    pub compute_passes: usize,
}

impl PassTiming {
    /// Pairs per second; `None` for a reduction.
    pub fn pairs_per_second(&self) -> Option<f64> {
        (self.pairs > 0 && self.seconds > 0.0).then(|| self.pairs as f64 / self.seconds)
    }
}

/// The layer on a wgpu device, pipelines built once.
pub struct GpuRenderer {
    ctx: GpuContext,
    pipelines: Vec<Pipeline>,
    planner: Planner,
    last: Mutex<LastRun>,
}

impl GpuRenderer {
    /// A renderer on the best adapter (see [`GpuContext::new`]).
    pub fn new() -> Result<Self> {
        Self::with_context(GpuContext::new()?)
    }

    /// A renderer on an open device.
    pub fn with_context(ctx: GpuContext) -> Result<Self> {
        let planner = Planner::for_limits(&ctx.limits, ctx.is_software());
        let pipelines = build_pipelines(&ctx.device, planner.tiles)?;
        Ok(GpuRenderer {
            ctx,
            pipelines,
            planner,
            last: Mutex::new(LastRun::default()),
        })
    }

    /// Caps the bytes of any one storage binding below the adapter's limit, so that large
    /// inputs are split into more, smaller dispatches (to bound memory, and to test the
    /// split path on small inputs). At least one workgroup's worth of records is kept.
    pub fn with_binding_cap(mut self, bytes: u64) -> Self {
        self.planner.max_binding = self.planner.max_binding.min(bytes);
        self
    }

    /// Caps the workgroups per dispatch dimension below the adapter's limit, so that large
    /// inputs are split into more dispatches and the reductions spread over y (to test
    /// those paths on small inputs). At least 1.
    pub fn with_workgroup_cap(mut self, groups: u32) -> Self {
        self.planner.max_groups = self.planner.max_groups.min(groups.max(1));
        self
    }

    /// Splits the looped-over records of every gather pass into `n` slices (fewer where
    /// the limits or the records allow fewer) instead of the automatic count.
    pub fn with_slices(mut self, n: u32) -> Self {
        self.planner = self.planner.with_slices(n);
        self
    }

    /// Reads the gather passes' looped-over records through `tiles` instead of the
    /// adapter's default ([`Tiles::Uniform`] on a software adapter, else
    /// [`Tiles::Workgroup`]); rebuilds the pipelines.
    pub fn with_tiles(mut self, tiles: Tiles) -> Result<Self> {
        self.pipelines = build_pipelines(&self.ctx.device, tiles)?;
        self.planner.tiles = tiles;
        Ok(self)
    }

    /// The plan this renderer follows.
    pub fn planner(&self) -> &Planner {
        &self.planner
    }

    /// GPU time per pass of the last render or backward call; empty where the adapter has
    /// no timestamp queries.
    pub fn last_timings(&self) -> Vec<PassTiming> {
        self.last
            .lock()
            .map(|l| l.timings.clone())
            .unwrap_or_default()
    }

    /// Every dispatch of the last render or backward call, in order.
    pub fn last_dispatches(&self) -> Vec<Dispatch> {
        self.last
            .lock()
            .map(|l| l.dispatches.clone())
            .unwrap_or_default()
    }

    fn record(&self, run: LastRun) {
        if let Ok(mut l) = self.last.lock() {
            *l = run;
        }
    }

    /// The device and adapter.
    pub fn context(&self) -> &GpuContext {
        &self.ctx
    }

    fn pipeline(&self, pass: Pass) -> &Pipeline {
        &self.pipelines[Pass::ALL.iter().position(|&p| p == pass).unwrap_or(0)]
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

/// Every pass's pipeline, the gather passes reading through `tiles`.
fn build_pipelines(device: &wgpu::Device, tiles: Tiles) -> Result<Vec<Pipeline>> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let pipelines = Pass::ALL
        .iter()
        .map(|&p| Pipeline::new(device, p, tiles))
        .collect();
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(Error::Gpu(format!("building the pipelines: {e}")));
    }
    Ok(pipelines)
}

impl Backend for GpuRenderer {
    fn describe(&self) -> String {
        self.ctx.describe()
    }

    fn last_timings(&self) -> Vec<PassTiming> {
        GpuRenderer::last_timings(self)
    }

    fn render_prepared(&self, preps: &[Prepared]) -> Result<Vec<Image>> {
        self.scoped("forward", || forward::forward(self, preps))
    }

    fn backward_prepared(&self, preps: &[Prepared], upstream: &[Image]) -> Result<Vec<Gradients>> {
        self.backward_prepared_wanted(preps, upstream, Wanted::ALL)
    }

    fn backward_prepared_wanted(
        &self,
        preps: &[Prepared],
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        self.scoped("backward", || {
            backward::backward(self, preps, upstream, wanted)
        })
    }

    // the whole batch in one submission
    fn render(&self, batch: &Batch) -> Result<Vec<Image>> {
        let preps: Vec<Prepared> = batch.scenes().iter().map(Prepared::new).collect();
        self.render_prepared(&preps)
    }

    fn backward_wanted(
        &self,
        batch: &Batch,
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        batch.check_upstream(upstream)?;
        let preps: Vec<Prepared> = batch.scenes().iter().map(Prepared::new).collect();
        self.backward_prepared_wanted(&preps, upstream, wanted)
    }
}
