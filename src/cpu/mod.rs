//! The fast f32 CPU path (work in progress: delegates to the reference).

use crate::scene::{Batch, Gradients, Image};
use crate::{Backend, Result};

/// The fast CPU path as a [`Backend`].
#[derive(Clone, Copy, Debug, Default)]
pub struct FastCpu;

impl FastCpu {
    /// The fast path at the widest instruction set this CPU has.
    pub fn new() -> Self {
        FastCpu
    }
}

impl Backend for FastCpu {
    fn describe(&self) -> String {
        crate::reference::Reference.describe()
    }
    fn render(&self, batch: &Batch) -> Result<Vec<Image>> {
        crate::reference::Reference.render(batch)
    }
    fn backward(&self, batch: &Batch, upstream: &[Image]) -> Result<Vec<Gradients>> {
        crate::reference::Reference.backward(batch, upstream)
    }
}
