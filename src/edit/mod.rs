//! Material editing by inverse rendering: the material (and, if asked, a low-resolution
//! environment map) that makes the layer reproduce an image, found with Adam through the
//! layer's own backward pass on whichever backend the [`Renderer`] holds; then transfer
//! (one image's shape and light with another's material) and the grid of transfers.
//!
//! Parameterisation: every scale control point is `sign * exp(u)` with its sign taken
//! from the initial material, every exponent control point `exp(u)`, every env texel
//! channel `exp(w)`: exponents stay >= 0 and radiance > 0 without constraints, and Adam's
//! steps are relative changes, which suits numbers that span 1e-3 to 1e3.
//!
//! Loss, on the masked pixels: the mean over pixels and channels of
//! `(g(I) - g(T))^2 / c^2` with `g(x) = c ln(1 + x / c)` (`g(x) = x` below 0) and `c` the
//! target's mean over the mask: linear, so like the PSNR it is judged by, for the body of
//! the object, and logarithmic above it, so that a highlight that is not yet in its place
//! does not drown the gradient of everything else.
//!
//! Material and light are ambiguous (a brighter light and a darker material give the same
//! image). With `Light::Fit` two priors on the map's log radiance resolve it: smoothness
//! (squared differences between neighbouring texels, which also fills the directions that
//! no pixel sees) and a level: each channel's mean log radiance is held near the level at
//! which the initial material renders the target's mean brightness under a uniform light,
//! so the light's mean colour stays neutral, the material takes the object's colour and
//! keeps about the brightness of the preset it starts from, and the light takes the rest.

pub mod adam;
pub mod dir;
pub mod plot;

use std::time::Instant;

use crate::envmap::{Convention, EnvMap, MAX_RADIANCE};
use crate::error::{Error, Result, invalid};
use crate::material::{MAX_ABS_SCALE, MAX_EXPONENT, N_COEFS, N_LOBES, N_PARAMS, idx};
use crate::spline::N_CTRL_POINTS;
use crate::{Accuracy, Batch, Camera, Image, Material, NormalMap, Renderer, Scene, Wanted};

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

/// What is fitted to: normals, the image, and which pixels count.
#[derive(Clone, Debug)]
pub struct Inputs {
    /// The object's normals (background pixels never count).
    pub normals: NormalMap,
    /// The image, linear RGB.
    pub target: Image,
    /// Pixels that count: inside the mask and not background.
    pub mask: Vec<bool>,
}

impl Inputs {
    /// Inputs of one size; `mask` (true = counts) defaults to every non-background pixel.
    pub fn new(normals: NormalMap, target: Image, mask: Option<Vec<bool>>) -> Result<Self> {
        normals.validate()?;
        if (target.width, target.height) != (normals.width, normals.height) {
            return Err(invalid!(
                "image: size {}x{} differs from the normals' {}x{}",
                target.width,
                target.height,
                normals.width,
                normals.height
            ));
        }
        if let Some(i) = target
            .pixels
            .iter()
            .position(|p| p.iter().any(|v| !v.is_finite()))
        {
            return Err(invalid!(
                "image: pixel (column {}, row {}) is not finite",
                i % target.width,
                i / target.width
            ));
        }
        let n = normals.normals.len();
        let given = mask.unwrap_or_else(|| vec![true; n]);
        if given.len() != n {
            return Err(invalid!(
                "mask: {} pixels for a {}x{} image",
                given.len(),
                target.width,
                target.height
            ));
        }
        let mask: Vec<bool> = (0..n)
            .map(|i| given[i] && !normals.is_background(i))
            .collect();
        if !mask.iter().any(|&m| m) {
            return Err(invalid!(
                "mask: no pixel is both in the mask and on the object"
            ));
        }
        Ok(Inputs {
            normals,
            target,
            mask,
        })
    }

    /// Box-filtered by `factor` per axis (the size rounded down): normals averaged and
    /// normalised, the image averaged, a pixel kept in the mask when all of its block is.
    pub fn downsampled(&self, factor: usize) -> Inputs {
        if factor <= 1 {
            return self.clone();
        }
        let (w, h) = (self.target.width / factor, self.target.height / factor);
        let (w, h) = (w.max(1), h.max(1));
        let src_w = self.target.width;
        let mut normals = Vec::with_capacity(w * h);
        let mut pixels = Vec::with_capacity(w * h);
        let mut mask = Vec::with_capacity(w * h);
        for y in 0..h {
            for x in 0..w {
                let (mut n, mut p, mut all) = ([0.0f64; 3], [0.0f64; 3], true);
                let mut count = 0.0;
                for yy in y * factor..((y + 1) * factor).min(self.target.height) {
                    for xx in x * factor..((x + 1) * factor).min(src_w) {
                        let i = yy * src_w + xx;
                        for k in 0..3 {
                            n[k] += f64::from(self.normals.normals[i][k]);
                            p[k] += f64::from(self.target.pixels[i][k]);
                        }
                        all &= self.mask[i];
                        count += 1.0;
                    }
                }
                let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let keep = all && len > 1e-6;
                normals.push(if keep {
                    n.map(|v| (v / len) as f32)
                } else {
                    [0.0; 3]
                });
                pixels.push(p.map(|v| (v / count) as f32));
                mask.push(keep);
            }
        }
        Inputs {
            normals: NormalMap {
                width: w,
                height: h,
                normals,
            },
            target: Image {
                width: w,
                height: h,
                pixels,
            },
            mask,
        }
    }
}

/// A fit's result.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// The fitted material.
    pub material: Material,
    /// The light: the given map, or the fitted one.
    pub env: EnvMap,
    /// The loss after each step (data term and priors).
    pub losses: Vec<f64>,
    /// Steps taken.
    pub steps: usize,
    /// Wall-clock seconds of the fit.
    pub seconds: f64,
    /// The size the fit ran at (width, height).
    pub work_size: (usize, usize),
}

/// PSNR of `render` against `target` over the mask, with the target's largest value there
/// as the peak: 10 log10(peak^2 / MSE), over the three channels.
pub fn psnr(render: &Image, target: &Image, mask: &[bool]) -> f64 {
    let (mut se, mut n, mut peak) = (0.0f64, 0usize, 0.0f64);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        for k in 0..3 {
            let (a, b) = (
                f64::from(render.pixels[i][k]),
                f64::from(target.pixels[i][k]),
            );
            se += (a - b) * (a - b);
            peak = peak.max(b);
            n += 1;
        }
    }
    10.0 * (peak * peak / (se / n.max(1) as f64).max(1e-300)).log10()
}

const SCALE_FLOOR: f64 = 1e-4;
const EXPONENT_FLOOR: f64 = 1e-2;

/// The material as free parameters: (u, signs) with ctrl = sign exp(u) for scales and
/// exp(u) for exponents. A lobe whose scales are all 0 starts as a faint lobe (m0 1e-4,
/// exponent 1) that the fit may grow.
fn encode_material(m: &Material) -> (Vec<f64>, [f64; N_PARAMS]) {
    let mut u = vec![0.0; N_PARAMS];
    let mut signs = [1.0; N_PARAMS];
    for k in 0..3 {
        for s in 0..N_LOBES {
            let unused = (0..N_CTRL_POINTS).all(|j| m.ctrl[idx(k, s, 0, j)] == 0.0);
            for j in 0..N_CTRL_POINTS {
                let (a, b) = (idx(k, s, 0, j), idx(k, s, 1, j));
                let scale = m.ctrl[a];
                signs[a] = if scale < 0.0 { -1.0 } else { 1.0 };
                u[a] = scale.abs().max(SCALE_FLOOR).ln();
                u[b] = if unused {
                    0.0
                } else {
                    m.ctrl[b].max(EXPONENT_FLOOR).ln()
                };
            }
        }
    }
    (u, signs)
}

/// Control points from parameters, and d ctrl / d u (0 where a bound clamps).
fn decode_material(u: &[f64], signs: &[f64; N_PARAMS]) -> ([f64; N_PARAMS], [f64; N_PARAMS]) {
    let mut ctrl = [0.0; N_PARAMS];
    let mut d = [0.0; N_PARAMS];
    for i in 0..N_PARAMS {
        let is_exponent = (i / N_CTRL_POINTS) % N_COEFS == 1;
        let bound = if is_exponent {
            MAX_EXPONENT
        } else {
            MAX_ABS_SCALE
        };
        let v = u[i].exp();
        if v >= bound {
            ctrl[i] = signs[i] * bound;
        } else {
            ctrl[i] = signs[i] * v;
            d[i] = ctrl[i];
        }
    }
    (ctrl, d)
}

/// Largest log radiance of a fitted map: keeps every texel far inside the accepted range.
fn max_log_radiance() -> f64 {
    (f64::from(MAX_RADIANCE) * 1e-3).ln()
}

fn decode_env(w: &[f64]) -> Vec<[f32; 3]> {
    let top = max_log_radiance();
    w.chunks_exact(3)
        .map(|c| std::array::from_fn(|k| c[k].min(top).exp() as f32))
        .collect()
}

/// The data term's c ln(1 + x / c), extended linearly below 0, and its derivative.
fn compress(x: f64, c: f64) -> (f64, f64) {
    if x <= 0.0 {
        (x, 1.0)
    } else {
        (c * (x / c).ln_1p(), 1.0 / (1.0 + x / c))
    }
}

/// The map priors for log radiance `w` (height x width x 3): value and gradient (added to
/// `g`). Smoothness: mean squared difference of neighbours (columns wrap around); level:
/// the squared distance of each channel's mean log radiance from `level`.
fn priors(
    w: &[f64],
    height: usize,
    width: usize,
    options: &Options,
    level: f64,
    g: &mut [f64],
) -> f64 {
    let mut pairs = Vec::with_capacity(2 * height * width);
    for r in 0..height {
        for c in 0..width {
            let i = r * width + c;
            pairs.push((i, r * width + (c + 1) % width));
            if r + 1 < height {
                pairs.push((i, i + width));
            }
        }
    }
    let n_pairs = (pairs.len() * 3) as f64;
    let mut value = 0.0;
    for &(a, b) in &pairs {
        for k in 0..3 {
            let d = w[3 * a + k] - w[3 * b + k];
            value += options.smoothness * d * d / n_pairs;
            let gd = 2.0 * options.smoothness * d / n_pairs;
            g[3 * a + k] += gd;
            g[3 * b + k] -= gd;
        }
    }
    // per channel: the light's mean colour is held neutral, so that colour goes to the
    // material (a grey light and a green material, not a magenta light and a greener one)
    let texels = (w.len() / 3) as f64;
    for k in 0..3 {
        let mean = w.iter().skip(k).step_by(3).sum::<f64>() / texels;
        let d = mean - level;
        value += options.level * d * d;
        for gi in g.iter_mut().skip(k).step_by(3) {
            *gi += 2.0 * options.level * d / texels;
        }
    }
    value
}

/// The data term and its dLoss/dImage.
fn data_term(render: &Image, inputs: &Inputs, c: f64, n: f64) -> (f64, Image) {
    let mut up = Image::zeros(render.width, render.height);
    let mut loss = 0.0;
    for (i, _) in inputs.mask.iter().enumerate().filter(|(_, m)| **m) {
        for k in 0..3 {
            let (gi, di) = compress(f64::from(render.pixels[i][k]), c);
            let (gt, _) = compress(f64::from(inputs.target.pixels[i][k]), c);
            let r = (gi - gt) / c;
            loss += r * r / n;
            up.pixels[i][k] = (2.0 * r * di / (c * n)) as f32;
        }
    }
    (loss, up)
}

/// Halve the step when the loss has not improved by this much (relatively) for
/// [`PATIENCE`] steps; stop when the step is [`MIN_STEP_RATIO`] of the first.
const MIN_GAIN: f64 = 1e-3;
const PATIENCE: usize = 20;
const MIN_STEP_RATIO: f64 = 1.0 / 64.0;

/// Fits the material (and, with [`Light::Fit`], the light) so that the layer renders
/// `inputs.target`, calling `progress(step, loss)` after each step. Returns the best
/// parameters seen.
pub fn fit(
    renderer: &Renderer,
    inputs: &Inputs,
    options: &Options,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Fitted> {
    let start = Instant::now();
    options.init.validate()?;
    options.camera.validate()?;
    let side = inputs.target.width.max(inputs.target.height);
    let factor = if options.work_size == 0 {
        1
    } else {
        side.div_ceil(options.work_size).max(1)
    };
    let work = inputs.downsampled(factor);
    let n = (3 * work.mask.iter().filter(|&&m| m).count()) as f64;
    if n == 0.0 {
        return Err(invalid!(
            "mask: no pixel of the object is left at the working size {}x{}; use a larger work size",
            work.target.width,
            work.target.height
        ));
    }
    let c = work
        .mask
        .iter()
        .zip(&work.target.pixels)
        .filter(|(m, _)| **m)
        .map(|(_, p)| p.iter().map(|&v| f64::from(v).max(0.0)).sum::<f64>())
        .sum::<f64>()
        / n;
    if c <= 0.0 {
        return Err(invalid!("image: the masked pixels are all black"));
    }

    let (mut u, signs) = encode_material(&options.init);
    let n_mat = u.len();
    // the light: fixed, or log radiance at the level where the initial material renders
    // the target's mean brightness under a uniform map
    let (fixed_env, env_size) = match &options.light {
        Light::Fixed(env) => (Some(env.clone()), (env.height, env.width)),
        Light::Fit { height, width } => (None, (*height, *width)),
    };
    let level = match &fixed_env {
        Some(_) => 0.0,
        None => {
            let uniform = EnvMap::constant(env_size.0, env_size.1, options.convention, [1.0; 3])?;
            let image = render_one(renderer, &work, &options.init, &uniform, options.camera)?;
            let mean = work
                .mask
                .iter()
                .zip(&image.pixels)
                .filter(|(m, _)| **m)
                .map(|(_, p)| p.iter().map(|&v| f64::from(v)).sum::<f64>())
                .sum::<f64>()
                / n;
            if mean.is_nan() || mean <= 0.0 {
                return Err(invalid!(
                    "init: material '{}' renders black under a uniform light; start from another",
                    options.init.name
                ));
            }
            (c / mean).ln()
        }
    };
    if fixed_env.is_none() {
        u.extend(std::iter::repeat_n(level, 3 * env_size.0 * env_size.1));
    }
    let mut lr = vec![options.learning_rate; u.len()];
    let mut adam = adam::Adam::new(u.len());
    let mut lr_scale = 1.0;
    let (mut best, mut best_u) = (f64::INFINITY, u.clone());
    let mut last_gain_at = (f64::INFINITY, 0usize);
    let mut losses = Vec::new();
    let mut steps = 0;
    while steps < options.steps {
        let (ctrl, dctrl) = decode_material(&u[..n_mat], &signs);
        let material = Material {
            name: options.init.name.clone(),
            ctrl,
        };
        let env = match &fixed_env {
            Some(e) => e.clone(),
            None => EnvMap {
                height: env_size.0,
                width: env_size.1,
                convention: options.convention,
                texels: decode_env(&u[n_mat..]),
            },
        };
        let scene = Scene {
            normals: work.normals.clone(),
            env,
            material,
            camera: options.camera,
        };
        let batch = Batch::single(scene)?;
        let image = renderer.render(&batch)?.remove(0);
        let (mut loss, up) = data_term(&image, &work, c, n);
        // dLoss/dn is never used, dLoss/dL only when the light is fitted
        let wanted = Wanted {
            env: fixed_env.is_none(),
            normals: false,
            ctrl: true,
        };
        let (mut grads, _) =
            renderer.backward_wanted_with(&batch, &[up], &Accuracy::Exact, wanted)?;
        let grads = grads.remove(0);
        let mut g = vec![0.0; u.len()];
        for i in 0..n_mat {
            g[i] = f64::from(grads.d_ctrl[i]) * dctrl[i];
            if (i / N_CTRL_POINTS).is_multiple_of(N_COEFS) {
                // d|ctrl|/du = |ctrl| (0 where clamped)
                loss += options.sparsity * ctrl[i].abs();
                g[i] += options.sparsity * dctrl[i].abs();
            }
        }
        for coef in 0..n_mat / N_CTRL_POINTS {
            for j in 0..N_CTRL_POINTS - 1 {
                let (a, b) = (coef * N_CTRL_POINTS + j, coef * N_CTRL_POINTS + j + 1);
                let d = u[a] - u[b];
                loss += options.theta_d_smoothness * d * d;
                g[a] += 2.0 * options.theta_d_smoothness * d;
                g[b] -= 2.0 * options.theta_d_smoothness * d;
            }
        }
        if fixed_env.is_none() {
            let texels = &batch.scenes()[0].env.texels;
            for (t, (dl, l)) in grads.d_env.iter().zip(texels).enumerate() {
                for k in 0..3 {
                    g[n_mat + 3 * t + k] = f64::from(dl[k]) * f64::from(l[k]);
                }
            }
            loss += priors(
                &u[n_mat..],
                env_size.0,
                env_size.1,
                options,
                level,
                &mut g[n_mat..],
            );
        }
        if !loss.is_finite() || g.iter().any(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!(
                "fit: the loss or its gradient is not finite at step {steps}"
            )));
        }
        losses.push(loss);
        progress(steps, loss);
        if loss < best {
            best = loss;
            best_u.clone_from(&u);
        }
        if loss < last_gain_at.0 * (1.0 - MIN_GAIN) {
            last_gain_at = (loss, steps);
        } else if steps - last_gain_at.1 >= PATIENCE {
            lr_scale *= 0.5;
            last_gain_at = (best, steps);
            if lr_scale < MIN_STEP_RATIO {
                steps += 1;
                break;
            }
        }
        lr.fill(options.learning_rate * lr_scale);
        adam.step(&mut u, &g, &lr);
        steps += 1;
    }
    let (ctrl, _) = decode_material(&best_u[..n_mat], &signs);
    let material = Material::new(options.init.name.clone(), &ctrl)?;
    let env = match fixed_env {
        Some(e) => e,
        None => EnvMap::new(
            env_size.0,
            env_size.1,
            options.convention,
            decode_env(&best_u[n_mat..]),
        )?,
    };
    Ok(Fitted {
        material,
        env,
        losses,
        steps,
        seconds: start.elapsed().as_secs_f64(),
        work_size: (work.target.width, work.target.height),
    })
}

/// Renders `inputs`' normals with a material and a map.
fn render_one(
    renderer: &Renderer,
    inputs: &Inputs,
    material: &Material,
    env: &EnvMap,
    camera: Camera,
) -> Result<Image> {
    let batch = Batch::single(Scene {
        normals: inputs.normals.clone(),
        env: env.clone(),
        material: material.clone(),
        camera,
    })?;
    Ok(renderer.render(&batch)?.remove(0))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_round_trip_and_keep_signs() {
        let mut m = crate::presets::lookup("plastic-red").unwrap_or_else(|| {
            Material::constant("m", [(0.5, 1.0), (2.0, 50.0), (0.0, 0.0)]).unwrap()
        });
        m.ctrl[idx(1, 1, 0, 2)] = -0.25;
        let (u, signs) = encode_material(&m);
        let (ctrl, d) = decode_material(&u, &signs);
        for i in 0..N_PARAMS {
            let want = m.ctrl[i];
            let is_exponent = (i / N_CTRL_POINTS) % N_COEFS == 1;
            if want != 0.0 && (!is_exponent || want >= EXPONENT_FLOOR) {
                assert!((ctrl[i] - want).abs() <= 1e-12 * want.abs(), "{i}");
                assert_eq!(d[i], ctrl[i]);
            }
            if !is_exponent {
                assert!(ctrl[i] * want >= 0.0, "{i}: sign lost");
            }
        }
    }

    #[test]
    fn priors_gradient_matches_differences() {
        let (h, w) = (3, 4);
        let opts = Options::new(
            Material::constant("m", [(0.5, 1.0), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
            Light::Fit {
                height: h,
                width: w,
            },
        );
        let x: Vec<f64> = (0..3 * h * w).map(|i| ((i * 7) % 5) as f64 * 0.3).collect();
        let mut g = vec![0.0; x.len()];
        let f0 = priors(&x, h, w, &opts, 0.2, &mut g);
        for i in [0, 5, 17, 35] {
            let mut xp = x.clone();
            xp[i] += 1e-6;
            let f1 = priors(&xp, h, w, &opts, 0.2, &mut vec![0.0; x.len()]);
            let fd = (f1 - f0) / 1e-6;
            assert!(
                (fd - g[i]).abs() < 1e-6 * (1.0 + g[i].abs()),
                "{i}: {fd} vs {}",
                g[i]
            );
        }
    }
}
