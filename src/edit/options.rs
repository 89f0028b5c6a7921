//! How to fit: the light (known, or fitted at a size) and the [`Options`] with their
//! defaults.

use std::path::Path;

use crate::camera::Camera;
use crate::envmap::{Convention, EnvMap};
use crate::error::Result;
use crate::io::{self, EnvSize};
use crate::material::Material;

/// What the fit does with the light.
#[derive(Clone, Debug, PartialEq)]
pub enum Light {
    /// The light is known: only the material is fitted.
    Fixed(EnvMap),
    /// The light is fitted too, as a `height` x `width` map.
    Fit {
        /// Rows.
        height: usize,
        /// Columns.
        width: usize,
    },
    /// The light is fitted too, starting from this map (a prediction, say): its size and
    /// convention; the level prior holds the mean log radiance near this map's.
    FitFrom(EnvMap),
}

impl Light {
    /// The size a fitted light has unless asked otherwise (rows, columns).
    pub const DEFAULT_FIT: (usize, usize) = (16, 32);

    /// A known light: the lat-long map at `path`, brought to `size`.
    pub fn load(path: &Path, size: EnvSize, convention: Convention) -> Result<Light> {
        let loaded = io::load_env(path, convention)?;
        Ok(Light::Fixed(io::resample::fit(loaded.env, size, path)?))
    }
}

/// How to fit.
#[derive(Clone, Debug)]
pub struct Options {
    /// The material the fit starts from (its scales' signs are kept).
    pub init: Material,
    /// Known or fitted light.
    pub light: Light,
    /// Texel convention of a fitted map.
    pub convention: Convention,
    /// The camera the image was taken with.
    pub camera: Camera,
    /// Most Adam steps.
    pub steps: usize,
    /// Adam's initial step (a relative change of each parameter).
    pub learning_rate: f64,
    /// Weight of the map's smoothness prior.
    pub smoothness: f64,
    /// Weight of the map's level prior.
    pub level: f64,
    /// Weight of the material's sparsity prior, the sum of the scales' magnitudes: a lobe
    /// (or a range of theta_d) that the image does not ask for fades instead of keeping
    /// whatever the initial material had there, which another light would show.
    pub sparsity: f64,
    /// Weight of the material's smoothness prior over theta_d: squared differences of
    /// neighbouring control points' log values, so that what the image says about the
    /// theta_d it sees carries over to the theta_d it does not.
    pub theta_d_smoothness: f64,
    /// The fit runs on the image box-filtered by a whole factor to at most this many pixels
    /// on its longer side (0: full size).
    pub work_size: usize,
}

impl Options {
    /// The defaults, from `init` and `light`.
    pub fn new(init: Material, light: Light) -> Self {
        Options {
            init,
            light,
            convention: Convention::default(),
            camera: Camera::Orthographic,
            steps: 600,
            learning_rate: 0.05,
            smoothness: 1e-3,
            level: 1e-2,
            sparsity: 1e-4,
            theta_d_smoothness: 1e-4,
            work_size: 128,
        }
    }
}
