//! The GPU path: WGSL compute shaders through wgpu. Forward: one invocation per foreground
//! pixel and slice of the lit texels, the texels read in workgroup-memory tiles. Backward:
//! a per-texel gather (per slice of the pixels) for dLoss/dL and each texel's share of
//! dLoss/dctrl, a fixed-order reduction of the shares, and a per-pixel pass for dLoss/dn.
//! Slices are added in slice order by reduce_slices ([`plan`] chooses their number). Every
//! output element has one writer and every sum a fixed order, so two runs give bitwise
//! equal results.

mod backward;
mod buffers;
pub mod cache;
pub mod context;
mod forward;
pub mod layout;
pub mod pipelines;
mod pixels;
pub mod plan;
mod submission;

use std::sync::Mutex;

pub use buffers::MIN_BYTES;
pub use context::GpuContext;
pub use pipelines::{Pass, Tiles};
pub use plan::{Dispatch, GatherShape, Planner};

use crate::Backend;
use crate::backend::Scenes;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Batch, Gradients, Image, Wanted};
use buffers::Pool;
use cache::DiskCache;
use forward::Input;
use pipelines::Pipeline;
use pixels::PixelSource;
use submission::LastRun;

pub use crate::backend::PassTiming;

/// The layer on a wgpu device, pipelines built once, buffers and bind groups kept
/// between calls (grown to the largest call's; calls on one renderer take turns).
pub struct GpuRenderer {
    ctx: GpuContext,
    cache: Option<DiskCache>,
    pipelines: Vec<Pipeline>,
    planner: Planner,
    pool: Mutex<Pool>,
    last: Mutex<LastRun>,
}

impl GpuRenderer {
    /// A renderer on the best adapter (see [`GpuContext::new`]).
    pub fn new() -> Result<Self> {
        Self::with_context(GpuContext::new()?)
    }

    /// A renderer on an open device, planned for its adapter; `MATEDIT_GPU_PLAN=large`
    /// plans as for a large GPU on any adapter (slices for [`plan::LARGE_GPU_RESIDENT`]
    /// invocations, batches in one dispatch, workgroup tiles) and `MATEDIT_GPU_TILES=
    /// workgroup|uniform` forces the tile kind, so that a software adapter runs the paths
    /// a hardware GPU takes.
    pub fn with_context(ctx: GpuContext) -> Result<Self> {
        let mut planner = Planner::for_limits(&ctx.limits, ctx.is_software());
        if env_choice("MATEDIT_GPU_PLAN", &["auto", "large"])?.as_deref() == Some("large") {
            planner = planner.as_large_gpu();
        }
        Self::planned(ctx, planner)
    }

    /// The same device planned as a large GPU whatever its adapter, as
    /// `MATEDIT_GPU_PLAN=large` plans it: slices for [`plan::LARGE_GPU_RESIDENT`]
    /// invocations, batches in one dispatch, workgroup tiles (the pipelines rebuilt for
    /// them), so that a software adapter runs the paths a hardware GPU takes. A hardware
    /// adapter is planned so already.
    pub fn as_large_gpu(self) -> Result<Self> {
        let planner = self.planner.clone().as_large_gpu();
        Self::planned(self.ctx, planner)
    }

    /// A renderer on `ctx` following `planner` (`MATEDIT_GPU_TILES` may force the tiles).
    fn planned(ctx: GpuContext, mut planner: Planner) -> Result<Self> {
        if let Some(t) = env_choice("MATEDIT_GPU_TILES", &["workgroup", "uniform"])? {
            planner.tiles = if t == "workgroup" {
                Tiles::Workgroup
            } else {
                Tiles::Uniform
            };
        }
        let cache = DiskCache::open(&ctx);
        let pipelines = build_pipelines(&ctx.device, planner.tiles, cache.as_ref())?;
        Ok(GpuRenderer {
            ctx,
            cache,
            pipelines,
            planner,
            pool: Mutex::new(Pool::default()),
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
        self.pipelines = build_pipelines(&self.ctx.device, tiles, self.cache.as_ref())?;
        self.pool = Mutex::new(Pool::default());
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

/// The value of environment variable `var` where it is set and not empty: one of
/// `allowed`, else an error naming the variable.
fn env_choice(var: &str, allowed: &[&str]) -> Result<Option<String>> {
    match std::env::var(var) {
        Ok(v) if v.is_empty() => Ok(None),
        Ok(v) if allowed.contains(&v.as_str()) => Ok(Some(v)),
        Ok(v) => Err(Error::Invalid(format!(
            "{var}={v:?}: expected one of {}",
            allowed.join(", ")
        ))),
        Err(std::env::VarError::NotPresent) => Ok(None),
        Err(std::env::VarError::NotUnicode(_)) => {
            Err(Error::Invalid(format!("{var}: not valid UTF-8")))
        }
    }
}

/// Every pass's pipeline, the gather passes reading through `tiles`; through `cache`, which
/// is then saved, where there is one.
fn build_pipelines(
    device: &wgpu::Device,
    tiles: Tiles,
    cache: Option<&DiskCache>,
) -> Result<Vec<Pipeline>> {
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let pipelines = Pass::ALL
        .iter()
        .map(|&p| Pipeline::new(device, p, tiles, cache.map(DiskCache::cache)))
        .collect();
    if let Some(e) = pollster::block_on(scope.pop()) {
        return Err(Error::Gpu(format!("building the pipelines: {e}")));
    }
    if let Some(c) = cache {
        c.save();
    }
    Ok(pipelines)
}

impl Backend for GpuRenderer {
    fn describe(&self) -> String {
        let tiles = match self.planner.tiles {
            Tiles::Workgroup => "workgroup tiles",
            Tiles::Uniform => "uniform tiles",
        };
        let plan = if self.ctx.is_software() && !self.planner.software {
            ", large-GPU plan"
        } else {
            ""
        };
        format!("{}, {tiles}{plan}", self.ctx.describe())
    }

    fn last_timings(&self) -> Vec<PassTiming> {
        GpuRenderer::last_timings(self)
    }

    // a batch: the whole batch in one submission, the pixels read from the normal maps
    fn render(&self, scenes: Scenes<'_>) -> Result<Vec<Image>> {
        let lights;
        let inputs = match scenes {
            Scenes::Batch(batch) => {
                lights = lights_of(batch);
                mapped(batch, &lights)
            }
            Scenes::Prepared(preps) => listed(preps),
        };
        self.scoped("forward", || forward::forward(self, &inputs))
    }

    fn backward(
        &self,
        scenes: Scenes<'_>,
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        let lights;
        let inputs = match scenes {
            Scenes::Batch(batch) => {
                batch.check_upstream(upstream)?;
                lights = lights_of(batch);
                mapped(batch, &lights)
            }
            Scenes::Prepared(preps) => listed(preps),
        };
        self.scoped("backward", || {
            backward::backward(self, &inputs, upstream, wanted)
        })
    }
}

/// Prepared scenes as inputs, their listed pixels.
fn listed(preps: &[Prepared]) -> Vec<Input<'_>> {
    preps
        .iter()
        .map(|prep| Input {
            prep,
            source: PixelSource::Listed(&prep.pixels),
        })
        .collect()
}

/// A batch's scenes prepared without their pixels.
fn lights_of(batch: &Batch) -> Vec<Prepared> {
    batch
        .scenes()
        .iter()
        .map(Prepared::without_pixels)
        .collect()
}

/// A batch's scenes as inputs, their pixels read from the normal maps.
fn mapped<'a>(batch: &'a Batch, preps: &'a [Prepared]) -> Vec<Input<'a>> {
    batch
        .scenes()
        .iter()
        .zip(preps)
        .map(|(s, prep)| Input {
            prep,
            source: PixelSource::Map(&s.normals, s.camera),
        })
        .collect()
}
