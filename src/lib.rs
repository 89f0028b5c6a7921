//! matedit renders and differentiates the physically based rendering layer of Liu et al.,
//! "Material Editing Using a Physically Based Rendering Network" (ICCV 2017): per-pixel
//! normals lit by an HDR environment map through a Directional Statistics BRDF.
//!
//! Scenes, materials and environment maps are plain types ([`Scene`], [`Batch`],
//! [`Material`], [`EnvMap`]); a [`Renderer`] runs the forward pass ([`Renderer::render`])
//! and the vector-Jacobian product ([`Renderer::backward`]) on whichever backend it holds:
//! WGSL compute shaders through wgpu ([`gpu`]), the fast f32 SIMD CPU path ([`cpu`]) or
//! the f64 CPU reference ([`reference`]) that the other two are tested against.
//!
//! ```no_run
//! use matedit::{Batch, Camera, Device, EnvMap, Material, NormalMap, Renderer, Scene};
//! let scene = Scene {
//!     normals: NormalMap::sphere(64),
//!     env: EnvMap::constant(64, 128, Default::default(), [1.0; 3])?,
//!     material: Material::constant("plastic", [(0.5, 1.0), (2.0, 50.0), (0.0, 0.0)])?,
//!     camera: Camera::Orthographic,
//! };
//! let batch = Batch::single(scene)?;
//! let renderer = Renderer::new(Device::Auto)?;
//! let image = &renderer.render(&batch)?[0];
//! # Ok::<(), matedit::Error>(())
//! ```

#![allow(
    clippy::needless_range_loop,
    reason = "loops mirror the WGSL shaders index for index"
)]

pub mod brdf;
pub mod camera;
pub mod cpu;
pub mod defaults;
pub mod edit;
pub mod envmap;
pub mod error;
pub mod fit;
pub mod gpu;
pub mod io;
pub mod lod;
pub mod material;
pub mod prepare;
pub mod presets;
pub mod reference;
pub mod scene;
pub mod spline;
pub mod splitmix;
pub mod synth;

pub use camera::Camera;
pub use envmap::{Convention, EnvMap};
pub use error::{Error, Result};
pub use material::{Material, N_PARAMS};
use prepare::Prepared;
pub use scene::{Batch, Gradients, Image, NormalMap, Scene, Wanted};

/// Which backend a [`Renderer`] should use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Device {
    /// A hardware GPU (discrete or integrated adapter) if there is one, else the fast CPU
    /// path; never fails for lack of a GPU, and never picks a software adapter.
    #[default]
    Auto,
    /// Any wgpu adapter (a hardware GPU first, else a software one such as lavapipe); an
    /// error if there is none.
    Gpu,
    /// The fast f32 CPU path: SIMD (AVX-512, AVX2 + FMA or portable, chosen at run time)
    /// on rayon's threads.
    Cpu,
    /// The f64 CPU reference, the ground truth the other paths are tested against.
    Reference,
}

impl std::str::FromStr for Device {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "auto" => Ok(Device::Auto),
            "gpu" => Ok(Device::Gpu),
            "cpu" => Ok(Device::Cpu),
            "reference" => Ok(Device::Reference),
            _ => Err(format!(
                "unknown device '{s}': expected auto, gpu, cpu or reference"
            )),
        }
    }
}

/// A backend: something that runs the layer's forward and backward passes.
///
/// A backend works on [`prepare::Prepared`] scenes: the levels of detail in [`lod`] hand
/// it reduced scenes (a downsampled map, a table's nodes as pixels), so every backend runs
/// every approximation.
pub trait Backend: Send + Sync {
    /// A one-line description: which backend and adapter.
    fn describe(&self) -> String;
    /// Device time per pass of the last call: GPU timestamps on the GPU backend where the
    /// adapter has them; empty elsewhere.
    fn last_timings(&self) -> Vec<gpu::PassTiming> {
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
    fn normal_jacobians(&self, preps: &[Prepared]) -> Result<Vec<Vec<[[f32; 3]; 3]>>> {
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

/// Renders and differentiates batches on one backend.
pub struct Renderer {
    backend: Box<dyn Backend>,
}

impl Renderer {
    /// A renderer on the given device.
    ///
    /// `Device::Auto` takes a hardware GPU, else the fast CPU path (which outruns a
    /// software adapter such as lavapipe; ask for that with `Device::Gpu`).
    pub fn new(device: Device) -> Result<Self> {
        let backend: Box<dyn Backend> = match device {
            Device::Cpu => Box::new(cpu::FastCpu::new()?),
            Device::Reference => Box::new(reference::Reference),
            Device::Gpu => Box::new(gpu::GpuRenderer::new()?),
            Device::Auto => match gpu::GpuContext::new_hardware() {
                Ok(ctx) => Box::new(gpu::GpuRenderer::with_context(ctx)?),
                Err(_) => Box::new(cpu::FastCpu::new()?),
            },
        };
        Ok(Renderer { backend })
    }

    /// A renderer over any backend.
    pub fn with_backend(backend: Box<dyn Backend>) -> Self {
        Renderer { backend }
    }

    /// Which backend and adapter this renderer runs on.
    pub fn describe(&self) -> String {
        self.backend.describe()
    }

    /// Device time per pass of the last call (see [`Backend::last_timings`]).
    pub fn last_timings(&self) -> Vec<gpu::PassTiming> {
        self.backend.last_timings()
    }

    /// The backend, for the functions of [`lod`].
    pub fn backend(&self) -> &dyn Backend {
        self.backend.as_ref()
    }

    /// One image per scene, under `accuracy`; with a tolerance, each scene's choice too.
    pub fn render_with(
        &self,
        batch: &Batch,
        accuracy: &Accuracy,
    ) -> Result<(Vec<Image>, Vec<Option<lod::Choice>>)> {
        let (images, choices) = match accuracy {
            Accuracy::Exact => (
                self.backend.render(batch)?,
                vec![None; batch.scenes().len()],
            ),
            _ => {
                let mut images = Vec::new();
                let mut choices = Vec::new();
                for s in batch.scenes() {
                    let (image, choice) = match *accuracy {
                        Accuracy::Method(m) => (lod::render(self.backend(), s, &m)?, None),
                        _ => {
                            let (i, c) =
                                lod::render_within(self.backend(), s, accuracy.tolerance())?;
                            (i, Some(c))
                        }
                    };
                    images.push(image);
                    choices.push(choice);
                }
                (images, choices)
            }
        };
        for (b, img) in images.iter().enumerate() {
            check_finite("image", b, img.width, &img.pixels)?;
        }
        Ok((images, choices))
    }

    /// Gradients per scene under `accuracy`; with a tolerance, each scene's choice too.
    pub fn backward_with(
        &self,
        batch: &Batch,
        upstream: &[Image],
        accuracy: &Accuracy,
    ) -> Result<(Vec<Gradients>, Vec<Option<lod::Choice>>)> {
        self.backward_wanted_with(batch, upstream, accuracy, Wanted::ALL)
    }

    /// As [`Renderer::backward_with`], computing only the gradients `wanted` asks for; the
    /// others are zeros. The exact layer skips their work (see [`Wanted`]); the levels of
    /// detail compute all three and zero the others.
    pub fn backward_wanted_with(
        &self,
        batch: &Batch,
        upstream: &[Image],
        accuracy: &Accuracy,
        wanted: Wanted,
    ) -> Result<(Vec<Gradients>, Vec<Option<lod::Choice>>)> {
        batch.check_upstream(upstream)?;
        let (mut grads, choices) = match accuracy {
            // nothing wanted: zeros, without a pass
            _ if !wanted.any() => (
                batch
                    .scenes()
                    .iter()
                    .map(|s| Gradients::zeros(s.env.texels.len(), s.normals.normals.len()))
                    .collect(),
                vec![None; batch.scenes().len()],
            ),
            Accuracy::Exact => (
                self.backend.backward_wanted(batch, upstream, wanted)?,
                vec![None; batch.scenes().len()],
            ),
            _ => {
                let mut grads = Vec::new();
                let mut choices = Vec::new();
                for (s, u) in batch.scenes().iter().zip(upstream) {
                    let (g, choice) = match *accuracy {
                        Accuracy::Method(m) => (lod::backward(self.backend(), s, u, &m)?, None),
                        _ => {
                            let (g, c) =
                                lod::backward_within(self.backend(), s, u, accuracy.tolerance())?;
                            (g, Some(c))
                        }
                    };
                    grads.push(g);
                    choices.push(choice);
                }
                (grads, choices)
            }
        };
        for g in &mut grads {
            g.keep(wanted);
        }
        check_gradients(batch, &grads)?;
        Ok((grads, choices))
    }

    /// One image per scene of the batch.
    ///
    /// Valid inputs keep every value far inside f32 (see docs/CONVENTIONS.md), but an
    /// output that still overflows is an error naming it, never a silent inf or NaN.
    pub fn render(&self, batch: &Batch) -> Result<Vec<Image>> {
        let images = self.backend.render(batch)?;
        for (b, img) in images.iter().enumerate() {
            check_finite("image", b, img.width, &img.pixels)?;
        }
        Ok(images)
    }

    /// dLoss/dL, dLoss/dn and dLoss/dctrl per scene, given dLoss/dImage per scene.
    pub fn backward(&self, batch: &Batch, upstream: &[Image]) -> Result<Vec<Gradients>> {
        batch.check_upstream(upstream)?;
        let grads = self.backend.backward(batch, upstream)?;
        check_gradients(batch, &grads)?;
        Ok(grads)
    }
}

/// How exactly to evaluate the layer.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Accuracy {
    /// The layer itself.
    #[default]
    Exact,
    /// A given level of detail.
    Method(lod::Method),
    /// The cheapest level of detail whose estimated relative error is within this.
    Tolerance(f64),
}

impl Accuracy {
    fn tolerance(&self) -> f64 {
        match *self {
            Accuracy::Tolerance(t) => t,
            _ => 0.0,
        }
    }
}

/// An error naming the first non-finite gradient.
fn check_gradients(batch: &Batch, grads: &[Gradients]) -> Result<()> {
    {
        let env_w = batch.scenes()[0].env.width;
        for (b, g) in grads.iter().enumerate() {
            check_finite("d_env", b, env_w, &g.d_env)?;
            check_finite("d_normals", b, batch.image_size().0, &g.d_normals)?;
            if let Some(i) = g.d_ctrl.iter().position(|v| !v.is_finite()) {
                return Err(Error::Invalid(format!(
                    "d_ctrl: scene {b} control point {i} overflowed f32; scale the upstream gradient down"
                )));
            }
        }
        Ok(())
    }
}

/// An error naming the first non-finite element of an output.
fn check_finite(what: &str, scene: usize, width: usize, v: &[[f32; 3]]) -> Result<()> {
    match v.iter().position(|p| p.iter().any(|x| !x.is_finite())) {
        None => Ok(()),
        Some(i) => Err(Error::Invalid(format!(
            "{what}: scene {scene} element (column {}, row {}) overflowed f32; scale the radiance, \
             the material's scales or the upstream gradient down",
            i % width.max(1),
            i / width.max(1)
        ))),
    }
}
