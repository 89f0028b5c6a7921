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

/// The scenes a backend runs: a batch as the user gives it, or scenes already prepared.
///
/// A batch lets a backend take its own fast path (the GPU reads the pixels from the normal
/// maps and runs the whole batch in one submission; the fast CPU path prepares each scene on
/// its own thread); prepared scenes are what the levels of detail in [`crate::lod`] and
/// [`crate::continuous_light`] hand a backend (a downsampled map, a table's nodes as pixels).
#[derive(Clone, Copy, Debug)]
pub enum Scenes<'a> {
    /// A batch's scenes, prepared by the backend as it runs them.
    Batch(&'a Batch),
    /// Prepared scenes, their pixels listed.
    Prepared(&'a [Prepared]),
}

impl<'a> From<&'a Batch> for Scenes<'a> {
    fn from(batch: &'a Batch) -> Self {
        Scenes::Batch(batch)
    }
}

impl<'a> From<&'a [Prepared]> for Scenes<'a> {
    fn from(preps: &'a [Prepared]) -> Self {
        Scenes::Prepared(preps)
    }
}

impl<'a> From<&'a Vec<Prepared>> for Scenes<'a> {
    fn from(preps: &'a Vec<Prepared>) -> Self {
        Scenes::Prepared(preps)
    }
}

impl<'a> From<&'a Prepared> for Scenes<'a> {
    fn from(prep: &'a Prepared) -> Self {
        Scenes::Prepared(std::slice::from_ref(prep))
    }
}

/// A backend: something that runs the layer's forward and backward passes.
///
/// Every backend runs both kinds of [`Scenes`]: the levels of detail in [`crate::lod`] hand
/// it reduced scenes, so every backend runs every approximation.
pub trait Backend: Send + Sync {
    /// A one-line description: which backend and adapter.
    fn describe(&self) -> String;
    /// Device time per pass of the last call: GPU timestamps on the GPU backend where the
    /// adapter has them; empty elsewhere.
    fn last_timings(&self) -> Vec<PassTiming> {
        Vec::new()
    }
    /// One image per scene (`width` x `height`, 0 off its pixels).
    fn render(&self, scenes: Scenes<'_>) -> Result<Vec<Image>>;
    /// One set of gradients per scene, for upstream dLoss/dImage `upstream` (one `width` x
    /// `height` image per scene; checked against a batch); dLoss/dL in its `env_height` x
    /// `env_width` grid. Only the gradients `wanted` asks for need be computed: the others
    /// may be left out (the caller zeroes them).
    fn backward(
        &self,
        scenes: Scenes<'_>,
        upstream: &[Image],
        wanted: Wanted,
    ) -> Result<Vec<Gradients>>;
    /// dI^k/dn per pixel of each prepared scene (in `pixels` order), `[k][axis]`: what a
    /// normal table interpolates for dLoss/dn. With `backward` (upstream and wanted), the
    /// scenes' [`Backend::backward`] too, which a backend may compute in the same pass.
    ///
    /// By default three backward passes, one per channel, over the pixels, and the backward
    /// call on its own.
    fn normal_jacobians(
        &self,
        preps: &[Prepared],
        backward: Option<(&[Image], Wanted)>,
    ) -> Result<Vec<(Vec<Jacobian>, Option<Gradients>)>> {
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
        let grads = match backward {
            Some((upstream, wanted)) => {
                Some(self.backward(Scenes::Prepared(preps), upstream, wanted)?)
            }
            None => None,
        };
        let channels = self.backward(Scenes::Prepared(&copies), &ups, Wanted::ALL)?;
        let jacs = channels.iter().zip(preps).map(|(g, p)| {
            let n = p.pixels.len();
            (0..n)
                .map(|i| std::array::from_fn(|k| g.d_normals[k * n + i]))
                .collect()
        });
        Ok(match grads {
            Some(grads) => jacs.zip(grads.into_iter().map(Some)).collect(),
            None => jacs.map(|j| (j, None)).collect(),
        })
    }
}
