//! The GPU path: WGSL compute shaders through wgpu.

use crate::scene::{Batch, Gradients, Image};
use crate::{Backend, Error, Result};

/// Placeholder until the GPU path lands.
pub struct GpuRenderer;

impl GpuRenderer {
    /// A renderer on the best adapter.
    pub fn new() -> Result<Self> {
        Err(Error::NoAdapter { detail: String::new() })
    }
}

impl Backend for GpuRenderer {
    fn describe(&self) -> String {
        "gpu".into()
    }
    fn render(&self, _batch: &Batch) -> Result<Vec<Image>> {
        Err(Error::Gpu("not yet".into()))
    }
    fn backward(&self, _batch: &Batch, _upstream: &[Image]) -> Result<Vec<Gradients>> {
        Err(Error::Gpu("not yet".into()))
    }
}
