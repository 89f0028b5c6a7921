//! Scenes and batches: per-pixel normals ([`crate::normals`]), an environment map, a
//! material and a camera; and what the layer returns (images, gradients).

use crate::camera::Camera;
use crate::envmap::EnvMap;
use crate::error::{Error, Result, invalid};
use crate::material::{Material, N_PARAMS};
pub use crate::normals::{BACKGROUND_EPS, MAX_NORMAL_LENGTH, NormalMap};

/// One scene: what one image is made of.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Per-pixel normals.
    pub normals: NormalMap,
    /// The lighting.
    pub env: EnvMap,
    /// The material.
    pub material: Material,
    /// The camera.
    pub camera: Camera,
}

impl Scene {
    /// Checks every part.
    pub fn validate(&self) -> Result<()> {
        self.normals.validate()?;
        self.env.validate()?;
        self.material.validate()?;
        self.camera.validate()
    }
}

/// B scenes rendered in one call. All share the image size, the environment-map size and
/// convention, and the camera; each has its own normals, lighting and material.
#[derive(Clone, Debug, PartialEq)]
pub struct Batch {
    scenes: Vec<Scene>,
}

impl Batch {
    /// A validated batch of at least one scene.
    pub fn new(scenes: Vec<Scene>) -> Result<Self> {
        let Some(first) = scenes.first() else {
            return Err(Error::Batch("a batch needs at least one scene".into()));
        };
        for (b, s) in scenes.iter().enumerate() {
            s.validate().map_err(|e| {
                if scenes.len() > 1 {
                    invalid!("scene {b}: {e}")
                } else {
                    e
                }
            })?;
            let same = s.normals.width == first.normals.width
                && s.normals.height == first.normals.height
                && s.env.width == first.env.width
                && s.env.height == first.env.height
                && s.env.convention == first.env.convention
                && s.camera == first.camera;
            if !same {
                return Err(Error::Batch(format!(
                    "scene {b} differs from scene 0 in image size, env size, convention or camera \
                     ({}x{} image, {}x{} {} env, {:?} vs {}x{} image, {}x{} {} env, {:?})",
                    s.normals.width,
                    s.normals.height,
                    s.env.height,
                    s.env.width,
                    s.env.convention.name(),
                    s.camera,
                    first.normals.width,
                    first.normals.height,
                    first.env.height,
                    first.env.width,
                    first.env.convention.name(),
                    first.camera
                )));
            }
        }
        Ok(Batch { scenes })
    }

    /// A batch of one scene.
    pub fn single(scene: Scene) -> Result<Self> {
        Batch::new(vec![scene])
    }

    /// The scenes.
    pub fn scenes(&self) -> &[Scene] {
        &self.scenes
    }

    /// Image (width, height), shared by all scenes.
    pub fn image_size(&self) -> (usize, usize) {
        (self.scenes[0].normals.width, self.scenes[0].normals.height)
    }

    /// Checks that `upstream` holds one image per scene of the batch's image size, all finite.
    pub fn check_upstream(&self, upstream: &[Image]) -> Result<()> {
        if upstream.len() != self.scenes.len() {
            return Err(invalid!(
                "upstream: {} images given for a batch of {}",
                upstream.len(),
                self.scenes.len()
            ));
        }
        let (w, h) = self.image_size();
        for (b, g) in upstream.iter().enumerate() {
            if g.width != w || g.height != h || g.pixels.len() != w * h {
                return Err(invalid!(
                    "upstream: image {b} is {}x{} ({} pixels); the batch renders {w}x{h}",
                    g.width,
                    g.height,
                    g.pixels.len()
                ));
            }
            if let Some((x, y)) = g.non_finite_pixel() {
                return Err(invalid!(
                    "upstream: image {b} pixel ({x}, {y}) is not finite"
                ));
            }
        }
        Ok(())
    }
}

/// A linear RGB image, row-major, row 0 at the top.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// RGB per pixel.
    pub pixels: Vec<[f32; 3]>,
}

impl Image {
    /// An all-zero image.
    pub fn zeros(width: usize, height: usize) -> Self {
        Image {
            width,
            height,
            pixels: vec![[0.0; 3]; width * height],
        }
    }

    /// The first pixel (column, row) with a NaN or infinite channel.
    pub fn non_finite_pixel(&self) -> Option<(usize, usize)> {
        let i = self
            .pixels
            .iter()
            .position(|p| p.iter().any(|v| !v.is_finite()))?;
        Some((i % self.width.max(1), i / self.width.max(1)))
    }

    /// The largest channel value.
    pub fn max_value(&self) -> f32 {
        self.pixels.iter().flatten().fold(0.0f32, |a, &b| a.max(b))
    }
}

/// The layer's vector-Jacobian product for one scene: dLoss/d(inputs) for an upstream
/// dLoss/dImage.
#[derive(Clone, Debug, PartialEq)]
pub struct Gradients {
    /// dLoss/dL, one RGB triple per env texel, the env map's layout.
    pub d_env: Vec<[f32; 3]>,
    /// dLoss/dn, one triple per pixel, the normal map's layout.
    pub d_normals: Vec<[f32; 3]>,
    /// dLoss/dctrl, the material's flat layout.
    pub d_ctrl: [f32; N_PARAMS],
}

/// Which of the three gradients a backward call computes. One that is not wanted comes
/// back as zeros (in its full shape), and a backend may skip the work for it: the GPU
/// path leaves out the per-pixel pass without dLoss/dn and the per-texel passes without
/// dLoss/dL and dLoss/dctrl; the fast CPU path drops dLoss/dn's and dLoss/dctrl's terms
/// from its pass over the pairs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Wanted {
    /// dLoss/dL.
    pub env: bool,
    /// dLoss/dn.
    pub normals: bool,
    /// dLoss/dctrl.
    pub ctrl: bool,
}

impl Wanted {
    /// All three gradients.
    pub const ALL: Wanted = Wanted {
        env: true,
        normals: true,
        ctrl: true,
    };

    /// No gradient.
    pub const NONE: Wanted = Wanted {
        env: false,
        normals: false,
        ctrl: false,
    };

    /// Whether any gradient is wanted.
    pub fn any(self) -> bool {
        self.env || self.normals || self.ctrl
    }
}

impl Default for Wanted {
    fn default() -> Self {
        Wanted::ALL
    }
}

impl Gradients {
    /// Zeros for a map of `texels` texels and an image of `pixels` pixels.
    pub fn zeros(texels: usize, pixels: usize) -> Self {
        Gradients {
            d_env: vec![[0.0; 3]; texels],
            d_normals: vec![[0.0; 3]; pixels],
            d_ctrl: [0.0; N_PARAMS],
        }
    }

    /// Sets the gradients `wanted` leaves out to zeros.
    pub fn keep(&mut self, wanted: Wanted) {
        if !wanted.env {
            self.d_env.iter_mut().for_each(|v| *v = [0.0; 3]);
        }
        if !wanted.normals {
            self.d_normals.iter_mut().for_each(|v| *v = [0.0; 3]);
        }
        if !wanted.ctrl {
            self.d_ctrl = [0.0; N_PARAMS];
        }
    }
}
