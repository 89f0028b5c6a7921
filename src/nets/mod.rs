//! The three networks of python/matedit/nets/model.py (normals and mask, material, light)
//! run on the CPU (matrix products by matrixmultiply), from the weights file `matedit.nets.save` writes: the
//! binary predicts without Python.
//!
//! ```no_run
//! use matedit::{Image, nets::Nets};
//! let nets = Nets::load("weights.safetensors".as_ref())?;
//! let image = Image::zeros(64, 64); // linear RGB
//! let p = nets.predict(&image, None)?;
//! let (normals, mask, env, material) = (p.normals, p.mask, p.env, p.material);
//! # Ok::<(), matedit::Error>(())
//! ```
//!
//! The conventions are model.py's (`Nets.predict`): an image is divided by its mean over
//! the object, s = mean(max(I, 0)) over the mask (s = 1 for a black object), and the nets
//! see slog(I / s) = sign(x) log(1 + |x|). Without a mask, the mask is where the normals
//! net's logit is > 0 on the image normalised by its whole mean; the nets then run on the
//! image normalised over that mask. The light is returned in the image's units (times s).

mod layers;
mod planes;
mod weights;

use std::path::Path;

use crate::envmap::{Convention, EnvMap};
use crate::error::{Result, invalid};
use crate::material::{Material, N_COEFS, N_PARAMS};
use crate::normals::NormalMap;
use crate::scene::Image;
use crate::spline::N_CTRL_POINTS;
use layers::{GlobalNet, NormalsNet};
use planes::{Planes, matmul};
use weights::Weights;
pub use weights::{FORMAT, Frame, NetsConfig};

/// The fitted MERL materials the material net mixes (model.py's `N_MERL`).
pub const N_MERL: usize = 90;

/// The shipped nets' weights file (data/nets/weights.safetensors), built into the library.
pub static BUILTIN_WEIGHTS: &[u8] = include_bytes!("../../data/nets/weights.safetensors");

/// Largest exponent of a predicted material: model.py clamps a mix to [0, 1e4].
const MAX_MIX_EXPONENT: f32 = 1e4;

/// The three nets, ready to predict.
pub struct Nets {
    cfg: NetsConfig,
    normals: NormalsNet,
    material: GlobalNet,
    /// The basis presets' control points (K, 108), a buffer of the weights file.
    presets: Vec<f32>,
    light: GlobalNet,
    /// Whether [`Nets::predict`] averages with the mirrored image ([`Nets::with_mirror`]).
    mirror: bool,
}

/// What the nets see in one image.
#[derive(Clone, Debug)]
pub struct Prediction {
    /// Unit normals in the camera frame, zero off the mask.
    pub normals: NormalMap,
    /// The object's pixels: the given mask, or the predicted one.
    pub mask: Vec<bool>,
    /// The normals net's foreground probability per pixel (sigmoid of its logit): of the
    /// pass that decided the mask without a given mask (mask = prob > 0.5), of the pass on
    /// the masked input with one.
    pub mask_prob: Vec<f32>,
    /// The light, equirect, the config's size, in the image's units.
    pub env: EnvMap,
    /// The material: a mix of the MERL presets' 108 control points.
    pub material: Material,
    /// The image's scale s: the mean of max(I, 0) over the mask (1 for a black object).
    pub scale: f32,
}

impl Nets {
    /// The nets of a weights file written by `matedit.nets.save`. A file that is not
    /// safetensors, not matedit nets, or misses a tensor or has one of the wrong shape for
    /// its config is an [`Error::File`] naming the file and the tensor.
    pub fn load(path: &Path) -> Result<Nets> {
        let (cfg, w) = Weights::read(path)?;
        Self::build(cfg, w)
    }

    /// The shipped nets (data/nets/weights.safetensors, built into the binary; their model
    /// card is docs/nets_card.md).
    pub fn builtin() -> Result<Nets> {
        Self::from_bytes(Path::new("data/nets/weights.safetensors"), BUILTIN_WEIGHTS)
    }

    /// [`Nets::load`] on a weights file's bytes; `path` names it in errors.
    pub fn from_bytes(path: &Path, bytes: &[u8]) -> Result<Nets> {
        let (cfg, w) = Weights::parse(path, bytes)?;
        Self::build(cfg, w)
    }

    /// The image side the nets were trained at; [`crate::edit::photo`] analyses photos at it.
    pub fn image_size(&self) -> usize {
        self.cfg.image_size
    }

    fn build(cfg: NetsConfig, mut w: Weights) -> Result<Nets> {
        let normals = NormalsNet::new(&mut w, &cfg)?;
        let material = GlobalNet::new(&mut w, "material.net", &cfg, cfg.basis)?;
        let presets = w.take("material.presets", &[cfg.basis, N_PARAMS])?;
        let light = GlobalNet::new(
            &mut w,
            "light.net",
            &cfg,
            cfg.env_height * cfg.env_width * 3,
        )?;
        // the mean light of training: not part of a prediction, but part of the file
        w.take("log_light_sum", &[cfg.env_height, cfg.env_width, 3])?;
        w.take("light_count", &[])?;
        w.finish()?;
        Ok(Nets {
            cfg,
            normals,
            material,
            presets,
            light,
            mirror: false,
        })
    }

    /// These nets, whose [`Nets::predict`] also sees each image mirrored left to right
    /// and averages the two answers (see [`Nets::predict_with`]) when `mirror` is true.
    pub fn with_mirror(self, mirror: bool) -> Nets {
        Nets { mirror, ..self }
    }

    /// Whether [`Nets::predict`] averages with the mirrored image.
    pub fn mirror(&self) -> bool {
        self.mirror
    }

    /// The sizes the nets were built with.
    pub fn config(&self) -> NetsConfig {
        self.cfg
    }

    /// Normals, mask, light and material of `image` (linear RGB, width and height
    /// multiples of 2^(levels - 1)); `mask` (one per pixel, row-major) or `None` to
    /// predict it. Mirrored as [`Nets::with_mirror`] set (by default not).
    pub fn predict(&self, image: &Image, mask: Option<&[bool]>) -> Result<Prediction> {
        self.predict_with(image, mask, self.mirror)
    }

    /// The normals net's foreground probability per pixel, as [`Prediction::mask_prob`]
    /// (mirrored as [`Nets::with_mirror`] set), without the material and light nets: what
    /// finding an object needs.
    pub fn mask_prob(&self, image: &Image, mask: Option<&[bool]>) -> Result<Vec<f32>> {
        self.check(image, mask)?;
        let all;
        let mask = match mask {
            Some(m) => m,
            None => {
                all = vec![true; image.pixels.len()];
                &all
            }
        };
        let (_, logits) = self.normals_net(&prepare(image, mask).0, self.mirror);
        Ok(logits.into_iter().map(sigmoid).collect())
    }

    /// An image the nets can see (sides multiples of 2^(levels - 1), finite pixels) and a
    /// mask of its size, or the error naming what is wrong.
    fn check(&self, image: &Image, mask: Option<&[bool]>) -> Result<()> {
        let (w, h) = (image.width, image.height);
        let k = 1usize << (self.cfg.levels - 1);
        if w == 0 || h == 0 || w % k != 0 || h % k != 0 {
            return Err(invalid!(
                "image: size {w}x{h} is not a non-zero multiple of {k} ({} levels)",
                self.cfg.levels
            ));
        }
        if image.pixels.len() != w * h {
            return Err(invalid!("image: {} pixels for {w}x{h}", image.pixels.len()));
        }
        if let Some((x, y)) = image.non_finite_pixel() {
            return Err(invalid!(
                "image: pixel ({x}, {y}) is {:?}",
                image.pixels[y * w + x]
            ));
        }
        if let Some(m) = mask
            && m.len() != w * h
        {
            return Err(invalid!(
                "mask: {} values, expected {} ({w}x{h})",
                m.len(),
                w * h
            ));
        }
        Ok(())
    }

    /// [`Nets::predict`]; with `mirror`, each net also sees the image mirrored left to
    /// right and the two answers are averaged, the mirrored one mirrored back: the
    /// normals (renormalised), the mask logits, the material's weights and the light's
    /// log (model.py's `Nets.forward(x, mask, mirror=True)`). Twice the time; on
    /// held-out photo-like samples the normals are 0.8 degrees closer (docs/nets.md).
    pub fn predict_with(
        &self,
        image: &Image,
        mask: Option<&[bool]>,
        mirror: bool,
    ) -> Result<Prediction> {
        self.check(image, mask)?;
        let (w, h) = (image.width, image.height);
        let (mask, first_prob) = match mask {
            Some(m) => (m.to_vec(), None),
            None => {
                let all = vec![true; w * h];
                let (_, logits) = self.normals_net(&prepare(image, &all).0, mirror);
                let m = logits.iter().map(|&l| l > 0.0).collect();
                (m, Some(logits.into_iter().map(sigmoid).collect()))
            }
        };
        let (x, s) = prepare(image, &mask);
        let m = Planes::new(
            1,
            h,
            w,
            mask.iter().map(|&b| f32::from(u8::from(b))).collect(),
        );
        let (n, logits) = self.normals_net(&x, mirror);
        let mask_prob = match first_prob {
            Some(p) => p,
            None => logits.into_iter().map(sigmoid).collect(),
        };

        let normals = n
            .iter()
            .zip(&mask)
            .map(|(&v, &on)| if on { v } else { [0.0; 3] })
            .collect();
        let normals = NormalMap::new(w, h, normals)?;

        // MaterialNet: softmax(logits) @ presets, exponents clamped to [0, 1e4]
        let mirrored = mirror.then(|| (x.mirrored(), m.mirrored()));
        let mut weights = softmax(&self.material.forward(&x, &m));
        if let Some((xm, mm)) = &mirrored {
            let other = softmax(&self.material.forward(xm, mm));
            average_into(&mut weights, other);
        }
        let ctrl = matmul(&weights, false, &self.presets, 1, self.cfg.basis, N_PARAMS);
        let ctrl: Vec<f64> = ctrl
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let is_exponent = (i / N_CTRL_POINTS) % N_COEFS == 1;
                f64::from(if is_exponent {
                    v.clamp(0.0, MAX_MIX_EXPONENT)
                } else {
                    v
                })
            })
            .collect();
        let material = Material::new("predicted", &ctrl)?;

        // LightNet: exp of its output clamped to [-20, 20], times s
        let clamp = |v: Vec<f32>| v.into_iter().map(|v| v.clamp(-20.0, 20.0)).collect();
        let mut log_env: Vec<f32> = clamp(self.light.forward(&x, &m));
        if let Some((xm, mm)) = &mirrored {
            let other = mirror_env(&clamp(self.light.forward(xm, mm)), self.cfg.env_width);
            average_into(&mut log_env, other);
        }
        let texels = log_env
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]].map(|v| v.exp() * s))
            .collect();
        let env = EnvMap::new(
            self.cfg.env_height,
            self.cfg.env_width,
            Convention::Equirect,
            texels,
        )?;
        Ok(Prediction {
            normals,
            mask,
            mask_prob,
            env,
            material,
            scale: s,
        })
    }

    /// The normals net's (normals, mask logits) of x; with `mirror`, averaged with those of
    /// the mirrored image (mirrored back: x negated, normals renormalised).
    fn normals_net(&self, x: &Planes, mirror: bool) -> (Vec<[f32; 3]>, Vec<f32>) {
        let (mut n, mut logits) = self.normals.forward(x);
        if mirror {
            let (nm, lm) = self.normals.forward(&x.mirrored());
            for (row, (rn, rl)) in n
                .chunks_exact_mut(x.w)
                .zip(logits.chunks_exact_mut(x.w))
                .enumerate()
            {
                let (mn, ml) = (&nm[row * x.w..][..x.w], &lm[row * x.w..][..x.w]);
                for (col, (a, l)) in rn.iter_mut().zip(rl.iter_mut()).enumerate() {
                    let b = mn[x.w - 1 - col];
                    let v = [a[0] - b[0], a[1] + b[1], a[2] + b[2]];
                    let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt().max(1e-6);
                    *a = v.map(|c| c / len);
                    *l = (*l + ml[x.w - 1 - col]) / 2.0;
                }
            }
        }
        (n, logits)
    }
}

/// The light (rows of `width` RGB texels, equirect) of an image mirrored left to right:
/// x -> -x takes the azimuth phi to pi - phi, column c to (width / 2 - 1 - c) mod width.
fn mirror_env(texels: &[f32], width: usize) -> Vec<f32> {
    let mut out = vec![0f32; texels.len()];
    for (src, dst) in texels
        .chunks_exact(3 * width)
        .zip(out.chunks_exact_mut(3 * width))
    {
        for c in 0..width {
            let to = (width / 2 + width - 1 - c) % width;
            dst[3 * to..3 * to + 3].copy_from_slice(&src[3 * c..3 * c + 3]);
        }
    }
    out
}

/// a = (a + b) / 2, element by element.
fn average_into(a: &mut [f32], b: Vec<f32>) {
    a.iter_mut().zip(b).for_each(|(a, b)| *a = (*a + b) / 2.0);
}

fn sigmoid(x: f32) -> f32 {
    1.0 / (1.0 + (-x).exp())
}

/// softmax of a vector.
fn softmax(x: &[f32]) -> Vec<f32> {
    let max = x.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let e: Vec<f32> = x.iter().map(|&v| (v - max).exp()).collect();
    let sum: f32 = e.iter().sum();
    e.into_iter().map(|v| v / sum).collect()
}

/// model.py's `prepare`: slog(I / s) as 3 planes, and s = the mean of max(I, 0) over
/// `mask` (1 where that is 0).
fn prepare(image: &Image, mask: &[bool]) -> (Planes, f32) {
    let (mut sum, mut count) = (0f64, 0usize);
    for (p, _) in image.pixels.iter().zip(mask).filter(|(_, on)| **on) {
        sum += p.iter().map(|&v| f64::from(v.max(0.0))).sum::<f64>();
        count += 1;
    }
    let s = (sum / (3 * count.max(1)) as f64) as f32;
    let s = if s > 0.0 { s } else { 1.0 };
    let inv = (1.0 / f64::from(s)) as f32;
    let n = image.pixels.len();
    let mut v = vec![0f32; 3 * n];
    for (i, p) in image.pixels.iter().enumerate() {
        for (ch, &c) in p.iter().enumerate() {
            // sign(x) log(1 + |x|), 0 at 0
            let x = c * inv;
            v[ch * n + i] = if x == 0.0 {
                0.0
            } else {
                x.signum() * x.abs().ln_1p()
            };
        }
    }
    (Planes::new(3, image.height, image.width, v), s)
}
