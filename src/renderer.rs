//! The [`Renderer`]: one API over the backends, which [`Device`] picks; the levels of
//! detail of [`crate::lod`] run under an [`Accuracy`], and every output is checked finite.

use crate::backend::{Backend, PassTiming};
use crate::error::{Error, Result};
use crate::scene::{Batch, Gradients, Image, Wanted};
use crate::{cpu, gpu, lod, reference};

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

/// The backend a [`Device`] picks, not yet boxed: [`Renderer::new`] boxes it, and
/// `synth::Engine` also names its samples after it.
pub(crate) enum Picked {
    /// A wgpu adapter.
    Gpu(Box<gpu::GpuRenderer>),
    /// The fast f32 CPU path.
    Cpu(cpu::FastCpu),
    /// The f64 CPU reference.
    Reference(reference::Reference),
}

impl Device {
    /// The backend this device names: the one place where `Auto` chooses (a hardware GPU,
    /// else the fast CPU path, which outruns a software adapter such as lavapipe; ask for
    /// that with `Device::Gpu`).
    pub(crate) fn pick(self) -> Result<Picked> {
        Ok(match self {
            Device::Cpu => Picked::Cpu(cpu::FastCpu::new()?),
            Device::Reference => Picked::Reference(reference::Reference),
            Device::Gpu => Picked::Gpu(Box::new(gpu::GpuRenderer::new()?)),
            Device::Auto => match gpu::GpuContext::new_hardware() {
                Ok(ctx) => Picked::Gpu(Box::new(gpu::GpuRenderer::with_context(ctx)?)),
                Err(_) => Picked::Cpu(cpu::FastCpu::new()?),
            },
        })
    }
}

impl Picked {
    /// The backend, boxed for a [`Renderer`].
    pub(crate) fn into_backend(self) -> Box<dyn Backend> {
        match self {
            Picked::Gpu(g) => g,
            Picked::Cpu(c) => Box::new(c),
            Picked::Reference(r) => Box::new(r),
        }
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
        Ok(Renderer {
            backend: device.pick()?.into_backend(),
        })
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
    pub fn last_timings(&self) -> Vec<PassTiming> {
        self.backend.last_timings()
    }

    /// The backend, for the functions of [`lod`].
    pub fn backend(&self) -> &dyn Backend {
        self.backend.as_ref()
    }

    /// One image per scene of the batch.
    ///
    /// Valid inputs keep every value far inside f32 (see docs/CONVENTIONS.md), but an
    /// output that still overflows is an error naming it, never a silent inf or NaN.
    pub fn render(&self, batch: &Batch) -> Result<Vec<Image>> {
        Ok(self.render_with(batch, &Accuracy::Exact)?.0)
    }

    /// dLoss/dL, dLoss/dn and dLoss/dctrl per scene, given dLoss/dImage per scene.
    pub fn backward(&self, batch: &Batch, upstream: &[Image]) -> Result<Vec<Gradients>> {
        Ok(self
            .backward_with(batch, upstream, &Accuracy::Exact, Wanted::ALL)?
            .0)
    }

    /// [`Renderer::render`] under `accuracy`; with a tolerance, each scene's choice too.
    pub fn render_with(
        &self,
        batch: &Batch,
        accuracy: &Accuracy,
    ) -> Result<(Vec<Image>, Vec<Option<lod::Choice>>)> {
        let (images, choices) = match accuracy {
            Accuracy::Exact => (
                self.backend.render(batch.into())?,
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

    /// [`Renderer::backward`] under `accuracy`, computing only the gradients `wanted` asks
    /// for; the others are zeros. The exact layer skips their work (see [`Wanted`]); the
    /// levels of detail compute all three and zero the others. With a tolerance, each
    /// scene's choice too.
    pub fn backward_with(
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
                self.backend.backward(batch.into(), upstream, wanted)?,
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
