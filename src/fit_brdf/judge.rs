//! Judging fits by the images they make: a small sphere under a few built-in lights,
//! rendered with the measured BRDF (brute force, [`crate::brdf::render`]) and with each
//! candidate material (the f64 reference layer), compared by RMSE over the image's peak.
//!
//! The lights are the built-in procedural sky ([`crate::builtin_sky::procedural_env`]) with
//! its sun turned to four azimuths (front-left, right, behind, left), so that highlights
//! land at the centre, across and at the rim of the sphere, and (with [`Judge::broad`])
//! three broad procedural lights of [`crate::envgen`] (an overcast sky, a studio's area
//! lights, a room with a window), on which a fit's mid-range and grazing values count
//! more than under a sun. They are not the HDRIs the fit-quality report measures with, so
//! the report's figures are not fitted to.

use crate::brdf::Isotropic;
use crate::brdf::render::render_measured;
use crate::builtin_sky::procedural_env;
use crate::camera::Camera;
use crate::envgen::LightKind;
use crate::envmap::{Convention, EnvMap};
use crate::error::Result;
use crate::material::Material;
use crate::prepare::Prepared;
use crate::renderer::{Device, Renderer};
use crate::scene::{Batch, NormalMap, Scene};

/// The judging sphere's size and the lights' size.
const SPHERE: usize = 32;
const ENV: (usize, usize) = (32, 64);
/// The broad lights' kinds and the seed that draws them.
const BROAD: [LightKind; 3] = [LightKind::Overcast, LightKind::Studio, LightKind::Indoor];
const BROAD_SEED: u64 = 1;

/// Measured images to compare candidates with.
pub struct Judge {
    normals: NormalMap,
    envs: Vec<EnvMap>,
    /// Per light: the measured image (f64) and its largest value.
    measured: Vec<(Vec<[f64; 3]>, f64)>,
    /// Pixels on the sphere.
    mask: Vec<bool>,
    /// Candidates are rendered by the fast CPU path if set, else by the f64 reference.
    renderer: Option<Renderer>,
}

impl Judge {
    /// Renders `measured` under the four suns.
    pub fn new(measured: &dyn Isotropic) -> Result<Self> {
        Self::with_lights(measured, false)
    }

    /// Renders `measured` under the four suns and the three broad lights; candidates are
    /// rendered by the fast CPU path (f32, the path the fit-quality report renders fits
    /// with), several times faster than the f64 reference [`Judge::new`] uses.
    pub fn broad(measured: &dyn Isotropic) -> Result<Self> {
        Self::with_lights(measured, true)
    }

    fn with_lights(measured: &dyn Isotropic, broad: bool) -> Result<Self> {
        let normals = NormalMap::sphere(SPHERE);
        let base = procedural_env(ENV.0, ENV.1, Convention::Equirect);
        let mut envs: Vec<EnvMap> = (0..4)
            .map(|q| {
                let shift = q * ENV.1 / 4;
                let mut texels = base.texels.clone();
                for row in texels.chunks_exact_mut(ENV.1) {
                    row.rotate_right(shift);
                }
                EnvMap {
                    texels,
                    ..base.clone()
                }
            })
            .collect();
        if broad {
            for kind in BROAD {
                envs.push(crate::envgen::generate(kind, BROAD_SEED, ENV.0, ENV.1)?);
            }
        }
        let mask: Vec<bool> = normals.normals.iter().map(|n| n[2] > 0.0).collect();
        let mut images = Vec::with_capacity(envs.len());
        for env in &envs {
            let img = render_measured(measured, &normals, env, Camera::Orthographic)?;
            let px: Vec<[f64; 3]> = img.pixels.iter().map(|p| p.map(f64::from)).collect();
            let peak = px
                .iter()
                .zip(&mask)
                .filter(|(_, m)| **m)
                .flat_map(|(p, _)| p.iter().copied())
                .fold(0.0f64, f64::max);
            images.push((px, peak.max(1e-30)));
        }
        Ok(Judge {
            normals,
            envs,
            measured: images,
            mask,
            renderer: if broad {
                Some(Renderer::new(Device::Cpu)?)
            } else {
                None
            },
        })
    }

    /// The mean over the lights of RMSE / peak (10^(-PSNR/20)) of `material`'s images.
    pub fn error(&self, material: &Material) -> f64 {
        let scenes: Vec<Scene> = self
            .envs
            .iter()
            .map(|env| Scene {
                normals: self.normals.clone(),
                env: env.clone(),
                material: material.clone(),
                camera: Camera::Orthographic,
            })
            .collect();
        let images: Vec<Vec<[f64; 3]>> = match self.fast() {
            // a material that fails validation, which the fitter never makes, is infinitely bad
            Some(r) => match Batch::new(scenes).and_then(|b| r.render(&b)) {
                Ok(images) => images
                    .iter()
                    .map(|i| i.pixels.iter().map(|p| p.map(f64::from)).collect())
                    .collect(),
                Err(_) => return f64::INFINITY,
            },
            None => scenes
                .iter()
                .map(|s| crate::reference::forward(&Prepared::new(s)))
                .collect(),
        };
        let mut total = 0.0;
        for (img, (measured, peak)) in images.iter().zip(&self.measured) {
            let (mut se, mut n) = (0.0, 0usize);
            for ((a, b), &m) in img.iter().zip(measured).zip(&self.mask) {
                if m {
                    for k in 0..3 {
                        se += (a[k] - b[k]) * (a[k] - b[k]);
                    }
                    n += 3;
                }
            }
            total += (se / n.max(1) as f64).sqrt() / peak;
        }
        total / self.envs.len() as f64
    }

    /// The fast CPU renderer, for the broad judge.
    fn fast(&self) -> Option<&Renderer> {
        self.renderer.as_ref()
    }
}
