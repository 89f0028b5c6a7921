//! The backend trait, beneath every backend: what the reference, the fast CPU path and the
//! GPU path each implement, on the scenes [`crate::prepare`] makes, and what the levels of
//! detail in [`crate::lod`] and the [`crate::Renderer`] above them call.

use crate::error::Result;
use crate::prepare::{self, Prepared};
use crate::scene::{Batch, Gradients, Image, Wanted};

/// The device time of one pass in the last call, as the GPU backend measures it: from
/// timestamps written at the start and end of each of its compute passes.
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

/// dI^k/dn of one pixel, `[k][axis]`: a row of the normals' Jacobian per channel.
pub type Jacobian = [[f32; 3]; 3];

/// A backend: something that runs the layer's forward and backward passes.
///
/// A backend works on [`prepare::Prepared`] scenes: the levels of detail in [`crate::lod`] hand
/// it reduced scenes (a downsampled map, a table's nodes as pixels), so every backend runs
/// every approximation.
pub trait Backend: Send + Sync {
    /// A one-line description: which backend and adapter.
    fn describe(&self) -> String;
    /// Device time per pass of the last call: GPU timestamps on the GPU backend where the
    /// adapter has them; empty elsewhere.
    fn last_timings(&self) -> Vec<PassTiming> {
        Vec::new()
    }
    /// One image per prepared scene (`width` x `height`, 0 off its pixels).
    fn render_prepared(&self, preps: &[Prepared]) -> Result<Vec<Image>>;
    /// One set of gradients per prepared scene, for upstream dLoss/dImage `upstream` (one
    /// `width` x `height` image per scene); dLoss/dL in its `env_height` x `env_width` grid.
    fn backward_prepared(&self, preps: &[Prepared], upstream: &[Image]) -> Result<Vec<Gradients>>;
    /// As [`Backend::backward_prepared`], for the gradients `wanted` asks for; the others
    /// may be left out (the caller zeroes them). By default all three are computed.
    fn backward_prepared_wanted(
        &self,
        preps: &[Prepared],
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        let _ = wanted;
        self.backward_prepared(preps, upstream)
    }
    /// dI^k/dn per pixel of each prepared scene (in `pixels` order), `[k][axis]`: what a
    /// normal table interpolates for dLoss/dn. By default three backward passes, one per
    /// channel, over the pixels.
    fn normal_jacobians(&self, preps: &[Prepared]) -> Result<Vec<Vec<Jacobian>>> {
        let mut copies = Vec::with_capacity(preps.len());
        let mut ups = Vec::with_capacity(preps.len());
        for p in preps {
            let n = p.pixels.len();
            let pixels = (0..3 * n)
                .map(|i| prepare::PixelRec {
                    index: i,
                    ..p.pixels[i % n]
                })
                .collect();
            copies.push(p.with_pixels(3 * n, 1, pixels));
            let mut up = vec![[0.0f32; 3]; 3 * n];
            for (i, u) in up.iter_mut().enumerate() {
                u[i / n.max(1)] = 1.0;
            }
            ups.push(Image {
                width: 3 * n,
                height: 1,
                pixels: up,
            });
        }
        let grads = self.backward_prepared(&copies, &ups)?;
        Ok(grads
            .iter()
            .zip(preps)
            .map(|(g, p)| {
                let n = p.pixels.len();
                (0..n)
                    .map(|i| std::array::from_fn(|k| g.d_normals[k * n + i]))
                    .collect()
            })
            .collect())
    }
    /// [`Backend::backward_prepared_wanted`] and [`Backend::normal_jacobians`] of the
    /// same scenes: what a normal table's nodes need for every gradient. By default the
    /// two calls.
    fn backward_with_jacobians(
        &self,
        preps: &[Prepared],
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<(Gradients, Vec<Jacobian>)>> {
        let grads = self.backward_prepared_wanted(preps, upstream, wanted)?;
        let jacs = self.normal_jacobians(preps)?;
        Ok(grads.into_iter().zip(jacs).collect())
    }
    /// One image per scene. By default scene by scene, so that one scene's preparation is
    /// in memory at a time.
    fn render(&self, batch: &Batch) -> Result<Vec<Image>> {
        batch
            .scenes()
            .iter()
            .map(|s| Ok(self.render_prepared(&[Prepared::new(s)])?.remove(0)))
            .collect()
    }
    /// One set of gradients per scene, for upstream dLoss/dImage `upstream` (one image per
    /// scene).
    fn backward(&self, batch: &Batch, upstream: &[Image]) -> Result<Vec<Gradients>> {
        self.backward_wanted(batch, upstream, Wanted::ALL)
    }
    /// As [`Backend::backward`], for the gradients `wanted` asks for (see
    /// [`Backend::backward_prepared_wanted`]).
    fn backward_wanted(
        &self,
        batch: &Batch,
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        batch.check_upstream(upstream)?;
        batch
            .scenes()
            .iter()
            .zip(upstream)
            .map(|(s, u)| {
                Ok(self
                    .backward_prepared_wanted(&[Prepared::new(s)], std::slice::from_ref(u), wanted)?
                    .remove(0))
            })
            .collect()
    }
}
