//! What a sample shows behind its object, as a photo would: black, the sample's own
//! environment map seen through the camera, or a photo from a folder. The object is opaque:
//! a sample's image is the layer's render where its mask is set and the background
//! elsewhere.
//!
//! - `env`: each background pixel shows the map along its camera ray (a perspective
//!   camera's ray through the pixel; an orthographic camera, whose rays are all -z, shows
//!   the map as a [`ORTHO_FOV`]-degree perspective view down -z would), bilinear in the
//!   map, then blurred by a Gaussian of `blur` degrees (default 0 for a perspective camera,
//!   [`ORTHO_BLUR`] for an orthographic one: a far background out of focus).
//! - photos (`file`, `folder`: PNG, JPEG, EXR or NPY; 8-bit files are sRGB-decoded to
//!   linear): a random crop of the photo's aspect-corrected frame (60-100% of the largest
//!   crop of the image's aspect ratio, anywhere in the photo, mirrored half the time),
//!   resampled bilinearly to the image size, scaled so that its mean luminance is the
//!   environment map's mean radiance times 2^e with e uniform in `exposure` (stops,
//!   default [-1, 1]): a background as bright as the light that falls on the object.

use std::path::Path;

use serde::Deserialize;
use serde_json::{Value, json};
use sha2::Sha256;

use super::files::{files_of, hash_file};
use super::sources::{serde_message, weight_of};
use crate::camera::Camera;
use crate::envgen::colour::luminance;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::raster::{self, Columns};
use crate::splitmix::SplitMix;

/// The vertical field of view through which an orthographic camera sees an `env`
/// background, degrees.
pub const ORTHO_FOV: f64 = 30.0;
/// The default blur of an `env` background behind an orthographic camera, degrees.
pub const ORTHO_BLUR: f64 = 1.5;
/// The smallest crop of a photo, as a share of the largest of the image's aspect ratio.
const MIN_CROP: f64 = 0.6;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBackground {
    black: Option<bool>,
    env: Option<bool>,
    file: Option<String>,
    folder: Option<String>,
    blur: Option<f64>,
    exposure: Option<[f64; 2]>,
    weight: Option<f64>,
}

/// A photo kept for backgrounds: linear RGB, box-filtered down to at most twice the image
/// size.
#[derive(Clone, Debug)]
pub struct Photo {
    width: usize,
    height: usize,
    pixels: Vec<[f32; 3]>,
}

/// Where a sample's background comes from.
#[derive(Clone, Debug)]
pub enum Background {
    /// Black (the render as it is).
    Black,
    /// The sample's map seen through the camera, blurred by a Gaussian of this many
    /// degrees.
    Env {
        /// Gaussian sigma, degrees.
        blur: f64,
    },
    /// Photos, each with its name as the spec gives it.
    Photos {
        /// The photos.
        photos: Vec<(String, Photo)>,
        /// Exposure range, stops about the map's mean radiance.
        exposure: [f64; 2],
    },
}

/// The spec's `backgrounds` list (absent: black), loaded and hashed; errors name the item.
pub(super) fn backgrounds(
    items: Option<&[Value]>,
    (w, h): (usize, usize),
    camera: Camera,
    convention: Convention,
    base: &Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<super::sources::Weighted<Background>>> {
    let Some(items) = items else {
        return Ok(vec![super::sources::Weighted {
            weight: 1.0,
            source: Background::Black,
        }]);
    };
    if items.is_empty() {
        return Err(err(
            "backgrounds: the list is empty; leave it out for black".into(),
        ));
    }
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let at = |m: String| err(format!("backgrounds[{i}]: {m}"));
        let r: RawBackground = match item {
            Value::String(s) if s == "black" || s == "env" => {
                serde_json::from_value(json!({ s.as_str(): true }))
                    .map_err(|e| at(e.to_string()))?
            }
            Value::String(s) => {
                return Err(at(format!(
                    "'{s}': give \"black\", \"env\", {{\"file\": PATH}} or {{\"folder\": PATH}}"
                )));
            }
            _ => serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?,
        };
        let given = [
            r.black == Some(true),
            r.env == Some(true),
            r.file.is_some(),
            r.folder.is_some(),
        ];
        if given.iter().filter(|g| **g).count() != 1 {
            return Err(at(
                "give exactly one of \"black\": true, \"env\": true, \"file\", \"folder\"".into(),
            ));
        }
        if r.blur.is_some() && !given[1] {
            return Err(at("\"blur\" goes with \"env\" only".into()));
        }
        if r.exposure.is_some() && !(given[2] || given[3]) {
            return Err(at(
                "\"exposure\" goes with \"file\" or \"folder\" only".into()
            ));
        }
        let weight = weight_of(r.weight).map_err(at)?;
        let source = if given[0] {
            Background::Black
        } else if given[1] {
            if convention != Convention::Equirect {
                return Err(at(
                    "env: a map seen through the camera needs the equirect convention".into(),
                ));
            }
            let default = if camera.is_orthographic() {
                ORTHO_BLUR
            } else {
                0.0
            };
            let blur = r.blur.unwrap_or(default);
            if !(blur.is_finite() && (0.0..=30.0).contains(&blur)) {
                return Err(at(format!("blur: {blur} degrees must be in [0, 30]")));
            }
            Background::Env { blur }
        } else {
            let exposure = r.exposure.unwrap_or([-1.0, 1.0]);
            if !(exposure.iter().all(|e| e.is_finite() && e.abs() <= 20.0)
                && exposure[0] <= exposure[1])
            {
                return Err(at(format!(
                    "exposure: {exposure:?} must be a range of stops within [-20, 20] with lo <= hi"
                )));
            }
            let exts = ["png", "jpg", "jpeg", "exr", "npy"];
            let files = files_of(base, r.file, r.folder, &exts).map_err(at)?;
            let mut photos = Vec::with_capacity(files.len());
            for f in files {
                let bytes = crate::io::read_bytes(&f.path).map_err(|e| at(e.to_string()))?;
                let image =
                    crate::io::image_from_bytes(&f.path, &bytes).map_err(|e| at(e.to_string()))?;
                hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                photos.push((f.label, Photo::reduced(image, w.max(h) * 2)));
            }
            Background::Photos { photos, exposure }
        };
        out.push(super::sources::Weighted { weight, source });
    }
    Ok(out)
}

impl Photo {
    /// `image` box-filtered by the largest whole factor that keeps its shorter side at
    /// least `side` (or as it is, if smaller).
    fn reduced(image: crate::scene::Image, side: usize) -> Photo {
        let f = (image.width.min(image.height) / side.max(1)).max(1);
        let (w, h) = (image.width / f, image.height / f);
        let norm = 1.0 / (f * f) as f32;
        let pixels = raster::reduce((image.width, image.height), (f, f), (w, h), |block| {
            let mut s = [0.0f32; 3];
            for i in block {
                for k in 0..3 {
                    s[k] += image.pixels[i][k];
                }
            }
            s.map(|v| v * norm)
        });
        Photo {
            width: w,
            height: h,
            pixels,
        }
    }

    /// Bilinear sample at continuous pixel coordinates (pixel centres at +0.5), clamped.
    fn sample(&self, x: f64, y: f64) -> [f32; 3] {
        raster::bilinear(
            &self.pixels,
            self.width,
            self.height,
            x - 0.5,
            y - 0.5,
            Columns::Clamp,
        )
    }
}

/// The radiance of an equirect map along direction `d` (unit), bilinear.
pub fn env_along(env: &EnvMap, d: [f64; 3]) -> [f32; 3] {
    let theta = d[1].clamp(-1.0, 1.0).acos();
    let phi = d[2].atan2(d[0]).rem_euclid(std::f64::consts::TAU);
    let x = phi / std::f64::consts::TAU * env.width as f64 - 0.5;
    let y = theta / std::f64::consts::PI * env.height as f64 - 0.5;
    raster::bilinear(&env.texels, env.width, env.height, x, y, Columns::Wrap)
}

/// The map's mean luminance over the sphere (solid-angle weighted).
fn mean_luminance(env: &EnvMap) -> f64 {
    let (mut sum, mut total) = (0.0, 0.0);
    for r in 0..env.height {
        for c in 0..env.width {
            let (_, d_omega) = env.convention.texel(r, c, env.height, env.width);
            let t = env.texels[r * env.width + c];
            sum += d_omega * luminance(t.map(f64::from));
            total += d_omega;
        }
    }
    sum / total.max(1e-300)
}

impl Background {
    /// The background of a `w` x `h` image lit by `env` under `camera`, drawn from `rng`,
    /// with what the sample records of it; `None` for black.
    pub fn draw(
        &self,
        env: &EnvMap,
        camera: Camera,
        (w, h): (usize, usize),
        rng: &mut SplitMix,
    ) -> (Option<Vec<[f32; 3]>>, Value) {
        match self {
            Background::Black => (None, json!("black")),
            Background::Env { blur: deg } => {
                let (cam, fov) = match camera {
                    Camera::Orthographic => (
                        Camera::Perspective {
                            fov_y_deg: ORTHO_FOV,
                        },
                        ORTHO_FOV,
                    ),
                    Camera::Perspective { fov_y_deg } => (camera, fov_y_deg),
                };
                let mut px = Vec::with_capacity(w * h);
                for y in 0..h {
                    for x in 0..w {
                        let v = cam.view_dir(x, y, w, h);
                        px.push(env_along(env, [-v[0], -v[1], -v[2]]));
                    }
                }
                raster::gaussian_blur(&mut px, w, h, deg / fov * h as f64);
                (Some(px), json!({ "env": true, "blur": deg }))
            }
            Background::Photos { photos, exposure } => {
                let (label, photo) = &photos[rng.below(photos.len())];
                // the largest crop of the image's aspect ratio, then a share of it
                let aspect = w as f64 / h as f64;
                let (pw, ph) = (photo.width as f64, photo.height as f64);
                let (cw_max, ch_max) = if pw / ph > aspect {
                    (ph * aspect, ph)
                } else {
                    (pw, pw / aspect)
                };
                let share = MIN_CROP + (1.0 - MIN_CROP) * rng.uniform();
                let (cw, ch) = (cw_max * share, ch_max * share);
                let (x0, y0) = ((pw - cw) * rng.uniform(), (ph - ch) * rng.uniform());
                let mirror = rng.uniform() < 0.5;
                let stops = exposure[0] + (exposure[1] - exposure[0]) * rng.uniform();
                let mut px = Vec::with_capacity(w * h);
                for y in 0..h {
                    for x in 0..w {
                        let u = (x as f64 + 0.5) / w as f64;
                        let u = if mirror { 1.0 - u } else { u };
                        let v = (y as f64 + 0.5) / h as f64;
                        px.push(photo.sample(x0 + u * cw, y0 + v * ch));
                    }
                }
                let mean: f64 =
                    px.iter().map(|p| luminance(p.map(f64::from))).sum::<f64>() / px.len() as f64;
                let scale = if mean > 0.0 {
                    mean_luminance(env) * stops.exp2() / mean
                } else {
                    0.0
                };
                for p in &mut px {
                    *p = p.map(|v| (v as f64 * scale) as f32);
                }
                let record = json!({
                    "photo": label,
                    "crop": [x0, y0, cw, ch],
                    "mirror": mirror,
                    "exposure": stops,
                    "scale": scale,
                });
                (Some(px), record)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn env_lookup_finds_each_texel_centre() {
        let (h, w) = (4, 8);
        let texels: Vec<[f32; 3]> = (0..h * w).map(|i| [i as f32; 3]).collect();
        let env = EnvMap::new(h, w, Convention::Equirect, texels).unwrap();
        for r in 0..h {
            for c in 0..w {
                let (d, _) = Convention::Equirect.texel(r, c, h, w);
                let v = env_along(&env, d);
                assert!(
                    (v[0] - (r * w + c) as f32).abs() < 1e-3,
                    "({r}, {c}): {v:?}"
                );
            }
        }
    }
}
