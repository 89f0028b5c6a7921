//! A material edit of an object in a photo (`matedit edit`; the paper's "approach with
//! post-optimization"): the nets ([`crate::nets`]) predict the object's mask, normals,
//! light and material on a square crop around the object; a fit through the layer
//! ([`super::fit`]) refines the material and the light from those predictions until the
//! layer re-renders the photo, and, if asked, the normals with those fixed
//! (`refine_normals`, an experiment: docs/edit.md); the object is then rendered with another material under the
//! refined light and normals, at the photo's resolution, and composited over the untouched
//! background with a soft mask.
//!
//! The crop: the square around the mask's bounding box with the margin the nets were
//! trained with (the object fills the frame but 5% on each side), padded with black where
//! it leaves the photo, box-filtered to the nets' input size. Without a mask, passes on the
//! whole photo (padded to a square) find the object: the first on the photo normalised by
//! its mean, each next on the photo normalised by the mean over the mask found before (as
//! the nets were trained); the last pass's mask probability, bilinear at the photo's
//! pixels, above one half. The soft mask of the composite is the
//! mask averaged over each pixel's 3 x 3 neighbourhood.

use std::time::Instant;

use super::fit::fit;
use super::inputs::Inputs;
use super::loss::psnr;
use super::options::{Light, Options};
use crate::error::{Result, invalid};

use crate::nets::Nets;
use crate::{Batch, Camera, EnvMap, Image, Material, NormalMap, Renderer, Scene};

/// The largest photo: pixels in all (16.8 million, 4096 x 4096).
pub const MAX_PIXELS: usize = 4096 * 4096;
/// The largest side of a photo, in pixels.
pub const MAX_SIDE: usize = 8192;
/// The smallest side of a photo, in pixels.
pub const MIN_SIDE: usize = 16;
/// The fewest pixels an object may cover.
pub const MIN_OBJECT_PIXELS: usize = 16;
/// Passes of the normals net that find the mask again on the image normalised by the
/// mask of the pass before (see `decompose`).
const MASK_PASSES: usize = 3;
/// The normals' refinement's first step moves the normal with the largest gradient by
/// this many radians (about 3 degrees).
const NORMAL_MOVE: f64 = 0.05;
/// Halvings of a step that raised the loss before the normals' refinement ends.
const NORMAL_HALVINGS: usize = 8;
/// The margin of the nets' training images: the object fills the frame but this fraction
/// of the half-size on each side (`matedit normals --margin`).
const MARGIN: f64 = 0.05;

/// How to edit.
#[derive(Clone, Debug)]
pub struct PhotoOptions {
    /// Refinement steps of material and light (0: the predictions as they are).
    pub steps: usize,
    /// Refinement steps of the normals after them, material and light fixed (0: none, the
    /// default: an experiment, docs/edit.md).
    pub normal_steps: usize,
    /// Weight of the normals' smoothness prior (the mean squared difference between
    /// neighbouring normals on the object).
    pub normal_smoothness: f64,
    /// Weight of the normals' anchor to the nets' (the mean squared difference between a
    /// refined normal and the predicted one over the object).
    pub normal_anchor: f64,
    /// The refinement runs on the crop box-filtered to at most this many pixels a side.
    pub work_size: usize,
    /// The nets' input size (square; a multiple of 2^(levels - 1)).
    pub net_size: usize,
}

impl Default for PhotoOptions {
    fn default() -> Self {
        PhotoOptions {
            steps: 20,
            normal_steps: 0,
            normal_smoothness: 0.05,
            normal_anchor: 0.0,
            work_size: 128,
            net_size: 64,
        }
    }
}

/// A square in photo pixels: columns x0 .. x0 + size, rows y0 .. y0 + size; it may reach
/// past the photo's edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crop {
    /// First column (may be negative).
    pub x0: i64,
    /// First row (may be negative).
    pub y0: i64,
    /// Side in pixels.
    pub size: usize,
}

/// What the nets and the refinement made of a photo.
#[derive(Clone, Debug)]
pub struct Decomposition {
    /// The photo's columns.
    pub width: usize,
    /// The photo's rows.
    pub height: usize,
    /// The crop the nets saw.
    pub crop: Crop,
    /// The object's normals at the crop's pixels (crop.size square; zero off the object).
    pub normals: NormalMap,
    /// The object at the photo's pixels.
    pub mask: Vec<bool>,
    /// The soft mask at the photo's pixels, in [0, 1].
    pub alpha: Vec<f32>,
    /// The nets' material.
    pub predicted_material: Material,
    /// The nets' light, in the photo's units.
    pub predicted_env: EnvMap,
    /// The refined material (the prediction without refinement).
    pub material: Material,
    /// The refined light (the prediction without refinement).
    pub env: EnvMap,
    /// PSNR (dB) of I' = R(n', m', L') against the photo over the object, with the
    /// predictions and after refinement, at the refinement's working size.
    pub psnr_predicted: f64,
    /// As `psnr_predicted`, after refinement.
    pub psnr_refined: f64,
    /// The refinement's loss per step (material and light).
    pub losses: Vec<f64>,
    /// The normals' refinement's loss (data term and smoothness prior) at its start and
    /// after each step taken (empty without it).
    pub normal_losses: Vec<f64>,
    /// Seconds per stage: "predict", "refine".
    pub stages: Vec<(&'static str, f64)>,
}

/// Checks that `photo` is one the edit takes: its size within the limits, every value finite.
pub fn check_photo(photo: &Image) -> Result<()> {
    let (w, h) = (photo.width, photo.height);
    if w > MAX_SIDE || h > MAX_SIDE || w * h > MAX_PIXELS {
        return Err(invalid!(
            "image: {w}x{h} is over the limit of {MAX_PIXELS} pixels ({MAX_SIDE} a side); downscale it"
        ));
    }
    if w < MIN_SIDE || h < MIN_SIDE {
        return Err(invalid!(
            "image: {w}x{h} is too small to hold an object (at least {MIN_SIDE} pixels a side)"
        ));
    }
    if let Some((x, y)) = photo.non_finite_pixel() {
        return Err(invalid!("image: pixel (column {x}, row {y}) is not finite"));
    }
    Ok(())
}

/// Checks a mask for `photo`: its size, at least [`MIN_OBJECT_PIXELS`] on the object, and
/// some background.
pub fn check_mask(mask: &[bool], width: usize, height: usize) -> Result<()> {
    if mask.len() != width * height {
        return Err(invalid!(
            "mask: {} pixels for a {width}x{height} image",
            mask.len()
        ));
    }
    let n = mask.iter().filter(|&&m| m).count();
    if n < MIN_OBJECT_PIXELS {
        return Err(invalid!(
            "mask: {n} pixels on the object; at least {MIN_OBJECT_PIXELS} are needed"
        ));
    }
    if n == mask.len() {
        return Err(invalid!(
            "mask: every pixel is on the object; there is no background to keep"
        ));
    }
    Ok(())
}

/// Predicts and refines the decomposition of `photo` (linear RGB); `mask`, if given, is
/// the object (else the nets find it).
pub fn decompose(
    renderer: &Renderer,
    nets: &Nets,
    photo: &Image,
    mask: Option<&[bool]>,
    options: &PhotoOptions,
) -> Result<Decomposition> {
    decompose_with(renderer, nets, photo, mask, options, &mut |_| {})
}

/// A stage of [`decompose_with`], for a progress display.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Finding the object: pass `pass` of `passes` of the normals net on the whole photo.
    Mask { pass: usize, passes: usize },
    /// The nets on the crop around the object.
    Predict,
    /// Refining material and light: `step` of `steps` done.
    Refine { step: usize, steps: usize },
    /// Refining the normals: `step` of `steps` done.
    Normals { step: usize, steps: usize },
}

/// [`decompose`], calling `progress` as each stage starts and after each refinement step.
pub fn decompose_with(
    renderer: &Renderer,
    nets: &Nets,
    photo: &Image,
    mask: Option<&[bool]>,
    options: &PhotoOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<Decomposition> {
    check_photo(photo)?;
    let (w, h) = (photo.width, photo.height);
    let n = options.net_size;
    let t = Instant::now();
    // the object: given, or found on the whole photo padded to a square
    let found;
    let mask = match mask {
        Some(m) => {
            check_mask(m, w, h)?;
            m
        }
        None => {
            let whole = Crop {
                x0: (w as i64 - w.max(h) as i64) / 2,
                y0: (h as i64 - w.max(h) as i64) / 2,
                size: w.max(h),
            };
            let input = crop_image(photo, whole, n);
            let passes = MASK_PASSES + 1;
            progress(Stage::Mask { pass: 1, passes });
            let mut prob = nets.predict(&input, None)?.mask_prob;
            // the nets were trained on images normalised by the object's mean, and the first
            // pass can only normalise by the whole image's: normalise by the mask found
            // and find it again, a few times
            for pass in 2..=passes {
                let m: Vec<bool> = prob.iter().map(|&a| a > 0.5).collect();
                if !m.iter().any(|&x| x) {
                    break;
                }
                progress(Stage::Mask { pass, passes });
                prob = nets.predict(&input, Some(&m))?.mask_prob;
            }
            found = paste_scalar(&prob, n, whole, w, h)
                .iter()
                .map(|&a| a > 0.5)
                .collect::<Vec<_>>();
            let lit = found
                .iter()
                .zip(&photo.pixels)
                .any(|(&m, p)| m && p.iter().any(|&v| v > 0.0));
            check_mask(&found, w, h)
                .ok()
                .filter(|_| lit)
                .ok_or_else(|| {
                    invalid!("image: no object found (the nets' mask is empty, full, a speck or black); give one with --mask")
                })?;
            &found
        }
    };
    progress(Stage::Predict);
    let crop = crop_around(mask, w, h);
    let input = crop_image(photo, crop, n);
    let small_mask: Vec<bool> = crop_image(&mask_image(mask, w, h), crop, n)
        .pixels
        .iter()
        .map(|p| p[0] > 0.5)
        .collect();
    let p = nets.predict(&input, Some(&small_mask))?;
    let alpha = blur3(mask, w, h);
    let normals = upsample_normals(&p.normals, crop, mask, w, h);
    let predict_s = t.elapsed().as_secs_f64();

    // refinement on the crop at the photo's resolution, box-filtered to the working size
    let t = Instant::now();
    let target = crop_pixels(photo, crop);
    let crop_mask: Vec<bool> = crop_pixels(&mask_image(mask, w, h), crop)
        .pixels
        .iter()
        .map(|p| p[0] > 0.5)
        .collect();
    let inputs = Inputs::new(normals.clone(), target, Some(crop_mask))?;
    let mut fit_options = Options::new(p.material.clone(), Light::FitFrom(p.env.clone()));
    fit_options.steps = options.steps;
    fit_options.work_size = options.work_size;
    let work = inputs.at_work_size(options.work_size);
    // I' against the photo over the object, at the working size, with the given normals
    let judge = |normals: &NormalMap, m: &Material, e: &EnvMap| -> Result<f64> {
        let img = render(renderer, normals, e, m)?;
        Ok(psnr(&img, &work.target, &work.mask))
    };
    let psnr_predicted = judge(&work.normals, &p.material, &p.env)?;
    let (material, env, losses) = if options.steps == 0 {
        (p.material.clone(), p.env.clone(), Vec::new())
    } else {
        let steps = options.steps;
        progress(Stage::Refine { step: 0, steps });
        let f = fit(renderer, &inputs, &fit_options, &mut |step, _| {
            progress(Stage::Refine {
                step: (step + 1).min(steps),
                steps,
            })
        })?;
        (f.material, f.env, f.losses)
    };
    let mut normals = normals;
    let mut normal_losses = Vec::new();
    let mut work_normals = work.normals.clone();
    if options.steps > 0 && options.normal_steps > 0 {
        let (refined, l) = refine_normals(renderer, &work, &material, &env, options, progress)?;
        normal_losses = l;
        normals = upsample_normals(&refined, crop, mask, w, h);
        work_normals = refined;
    }
    let psnr_refined = judge(&work_normals, &material, &env)?;
    Ok(Decomposition {
        width: w,
        height: h,
        crop,
        normals,
        mask: mask.to_vec(),
        alpha,
        predicted_material: p.material,
        predicted_env: p.env,
        material,
        env,
        psnr_predicted,
        psnr_refined,
        losses,
        normal_losses,
        stages: vec![
            ("predict", predict_s),
            ("refine", t.elapsed().as_secs_f64()),
        ],
    })
}

/// The normals of `work` refined with the material and light fixed, on the fit's data term
/// plus `normal_smoothness` times the mean squared difference between neighbouring normals
/// on the object and `normal_anchor` times the mean squared difference from `work`'s: projected gradient descent with a backtracking line search. Each step
/// moves every object pixel's normal against its gradient's part tangent to the sphere,
/// renormalises it (kept facing the camera), and is taken only if the loss falls; the step
/// length starts where the largest move is [`NORMAL_MOVE`] radians, halves on a rise (up to
/// [`NORMAL_HALVINGS`] times, then the refinement ends) and grows by half after a success.
/// The loss never rises: the normals returned are the last taken, with the loss of the
/// start and after each step taken.
fn refine_normals(
    renderer: &Renderer,
    work: &Inputs,
    material: &Material,
    env: &EnvMap,
    options: &PhotoOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<(NormalMap, Vec<f64>)> {
    use super::loss::data_term;
    let (w, h) = (work.normals.width, work.normals.height);
    let on: Vec<usize> = (0..w * h).filter(|&i| work.mask[i]).collect();
    let n = (3 * on.len()) as f64;
    let c = on
        .iter()
        .map(|&i| {
            work.target.pixels[i]
                .iter()
                .map(|&v| f64::from(v).max(0.0))
                .sum::<f64>()
        })
        .sum::<f64>()
        / n;
    if c <= 0.0 || on.is_empty() {
        return Ok((work.normals.clone(), Vec::new()));
    }
    // neighbouring pairs on the object, right and down
    let mut pairs = Vec::new();
    for &i in &on {
        if i % w + 1 < w && work.mask[i + 1] {
            pairs.push((i, i + 1));
        }
        if i + w < w * h && work.mask[i + w] {
            pairs.push((i, i + w));
        }
    }
    let lambda = options.normal_smoothness / pairs.len().max(1) as f64;
    let mu = options.normal_anchor / on.len() as f64;
    let start = &work.normals;
    let sq = |a: [f32; 3], b: [f32; 3]| (0..3).map(|k| f64::from(a[k] - b[k]).powi(2)).sum::<f64>();
    let smoothness = |m: &NormalMap| -> f64 {
        lambda
            * pairs
                .iter()
                .map(|&(a, b)| sq(m.normals[a], m.normals[b]))
                .sum::<f64>()
            + mu * on
                .iter()
                .map(|&i| sq(m.normals[i], start.normals[i]))
                .sum::<f64>()
    };
    let scene = |m: &NormalMap| {
        Batch::single(Scene {
            normals: m.clone(),
            env: env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        })
    };
    let loss_of = |m: &NormalMap| -> Result<f64> {
        let img = renderer.render(&scene(m)?)?.remove(0);
        Ok(data_term(&img, work, c, n).0 + smoothness(m))
    };
    let wanted = crate::Wanted {
        env: false,
        normals: true,
        ctrl: false,
    };
    // dLoss/dn at the object's pixels, tangent to the sphere at each normal
    let gradient = |m: &NormalMap| -> Result<Vec<[f64; 3]>> {
        let batch = scene(m)?;
        let img = renderer.render(&batch)?.remove(0);
        let (_, up) = data_term(&img, work, c, n);
        let (mut grads, _) =
            renderer.backward_with(&batch, &[up], &crate::Accuracy::Exact, wanted)?;
        let d_n = grads.remove(0).d_normals;
        let mut g: Vec<[f64; 3]> = vec![[0.0; 3]; w * h];
        for &i in &on {
            g[i] = d_n[i].map(f64::from);
        }
        for &(a, b) in &pairs {
            for k in 0..3 {
                let d = 2.0 * lambda * f64::from(m.normals[a][k] - m.normals[b][k]);
                g[a][k] += d;
                g[b][k] -= d;
            }
        }
        for &i in &on {
            for k in 0..3 {
                g[i][k] += 2.0 * mu * f64::from(m.normals[i][k] - start.normals[i][k]);
            }
        }
        for &i in &on {
            let nv = m.normals[i].map(f64::from);
            let along = (0..3).map(|k| g[i][k] * nv[k]).sum::<f64>();
            for k in 0..3 {
                g[i][k] -= along * nv[k];
            }
        }
        Ok(g)
    };
    let moved = |m: &NormalMap, g: &[[f64; 3]], alpha: f64| -> NormalMap {
        let mut out = m.clone();
        for &i in &on {
            let mut v: [f64; 3] =
                std::array::from_fn(|k| f64::from(m.normals[i][k]) - alpha * g[i][k]);
            v[2] = v[2].max(0.02);
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            out.normals[i] = v.map(|x| (x / len) as f32);
        }
        out
    };
    let mut current = work.normals.clone();
    let mut loss = loss_of(&current)?;
    let mut losses = vec![loss];
    let mut g = gradient(&current)?;
    let largest = |g: &[[f64; 3]]| {
        on.iter()
            .map(|&i| (g[i][0] * g[i][0] + g[i][1] * g[i][1] + g[i][2] * g[i][2]).sqrt())
            .fold(0.0, f64::max)
    };
    let mut alpha = NORMAL_MOVE / largest(&g).max(1e-30);
    'steps: for step in 0..options.normal_steps {
        progress(Stage::Normals {
            step,
            steps: options.normal_steps,
        });
        for _ in 0..=NORMAL_HALVINGS {
            let trial = moved(&current, &g, alpha);
            let l = loss_of(&trial)?;
            if l.is_finite() && l < loss {
                (current, loss) = (trial, l);
                losses.push(loss);
                g = gradient(&current)?;
                if g.iter().flatten().any(|v| !v.is_finite()) {
                    break 'steps;
                }
                alpha *= 1.5;
                continue 'steps;
            }
            alpha /= 2.0;
        }
        break;
    }
    Ok((current, losses))
}

/// The object of `d` rendered with `material` under the refined light, at the photo's
/// pixels (black off the crop).
pub fn render_object(renderer: &Renderer, d: &Decomposition, material: &Material) -> Result<Image> {
    render_object_under(renderer, d, material, &d.env)
}

/// [`render_object`] under the light `env` (the refined light turned or exposed, say).
pub fn render_object_under(
    renderer: &Renderer,
    d: &Decomposition,
    material: &Material,
    env: &EnvMap,
) -> Result<Image> {
    let img = render(renderer, &d.normals, env, material)?;
    Ok(place(d, &img))
}

/// An image of the crop of `d` (as its normals) at the photo's pixels, black off the crop.
pub fn place(d: &Decomposition, img: &Image) -> Image {
    let mut out = Image::zeros(d.width, d.height);
    for (i, p) in img.pixels.iter().enumerate() {
        let (x, y) = (
            d.crop.x0 + (i % d.crop.size) as i64,
            d.crop.y0 + (i / d.crop.size) as i64,
        );
        if (0..d.width as i64).contains(&x) && (0..d.height as i64).contains(&y) {
            out.pixels[y as usize * d.width + x as usize] = *p;
        }
    }
    out
}

/// The square of `image` (the photo's size) that the nets saw, black past its edges.
pub fn crop_of(d: &Decomposition, image: &Image) -> Image {
    crop_pixels(image, d.crop)
}

/// `object` over `photo` with the soft mask `alpha`.
pub fn composite(photo: &Image, object: &Image, alpha: &[f32]) -> Image {
    let mut out = photo.clone();
    for ((o, p), &a) in out.pixels.iter_mut().zip(&object.pixels).zip(alpha) {
        for k in 0..3 {
            o[k] = (1.0 - a) * o[k] + a * p[k];
        }
    }
    out
}

fn render(
    renderer: &Renderer,
    normals: &NormalMap,
    env: &EnvMap,
    material: &Material,
) -> Result<Image> {
    let batch = Batch::single(Scene {
        normals: normals.clone(),
        env: env.clone(),
        material: material.clone(),
        camera: Camera::Orthographic,
    })?;
    Ok(renderer.render(&batch)?.remove(0))
}

/// The square around the mask's bounding box, with the nets' margin.
fn crop_around(mask: &[bool], w: usize, h: usize) -> Crop {
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        let (x, y) = (i % w, i / w);
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x + 1), y0.min(y), y1.max(y + 1));
    }
    let side = (x1 - x0).max(y1 - y0) as f64 / (1.0 - MARGIN);
    let size = side.ceil() as usize;
    let cx = (x0 + x1) as f64 / 2.0;
    let cy = (y0 + y1) as f64 / 2.0;
    Crop {
        x0: (cx - size as f64 / 2.0).round() as i64,
        y0: (cy - size as f64 / 2.0).round() as i64,
        size,
    }
}

fn mask_image(mask: &[bool], w: usize, h: usize) -> Image {
    Image {
        width: w,
        height: h,
        pixels: mask.iter().map(|&m| [f32::from(u8::from(m)); 3]).collect(),
    }
}

/// The crop's pixels at the photo's resolution, black past the photo's edges.
fn crop_pixels(photo: &Image, crop: Crop) -> Image {
    let mut out = Image::zeros(crop.size, crop.size);
    for (i, p) in out.pixels.iter_mut().enumerate() {
        let (x, y) = (
            crop.x0 + (i % crop.size) as i64,
            crop.y0 + (i / crop.size) as i64,
        );
        if (0..photo.width as i64).contains(&x) && (0..photo.height as i64).contains(&y) {
            *p = photo.pixels[y as usize * photo.width + x as usize];
        }
    }
    out
}

/// The crop box-filtered (or, when it is smaller, enlarged by nearest pixels) to `n` x `n`.
fn crop_image(photo: &Image, crop: Crop, n: usize) -> Image {
    super::transfer::resize(&crop_pixels(photo, crop), n, n)
}

/// Values at `n` x `n` over `crop`, bilinear at the photo's pixels (0 off the crop).
fn paste_scalar(values: &[f32], n: usize, crop: Crop, w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0; w * h];
    let f = n as f64 / crop.size as f64;
    for (i, o) in out.iter_mut().enumerate() {
        let u = ((i % w) as i64 - crop.x0) as f64 + 0.5;
        let v = ((i / w) as i64 - crop.y0) as f64 + 0.5;
        if u < 0.0 || v < 0.0 || u >= crop.size as f64 || v >= crop.size as f64 {
            continue;
        }
        *o = bilinear(values, n, u * f - 0.5, v * f - 0.5);
    }
    out
}

fn bilinear(values: &[f32], n: usize, x: f64, y: f64) -> f32 {
    let (x, y) = (x.clamp(0.0, (n - 1) as f64), y.clamp(0.0, (n - 1) as f64));
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(n - 1), (y0 + 1).min(n - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let at = |xx: usize, yy: usize| values[yy * n + xx];
    (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x1, y0))
        + fy * ((1.0 - fx) * at(x0, y1) + fx * at(x1, y1))
}

/// The nets' normals (n x n over the crop) at the crop's pixels: bilinear, renormalised,
/// on the photo's mask only (facing the camera where the nets saw background).
fn upsample_normals(small: &NormalMap, crop: Crop, mask: &[bool], w: usize, h: usize) -> NormalMap {
    let n = small.width;
    let channel = |k: usize| -> Vec<f32> { small.normals.iter().map(|v| v[k]).collect() };
    let comps = [channel(0), channel(1), channel(2)];
    let f = n as f64 / crop.size as f64;
    let normals = (0..crop.size * crop.size)
        .map(|i| {
            let (u, v) = (i % crop.size, i / crop.size);
            let (x, y) = (crop.x0 + u as i64, crop.y0 + v as i64);
            let inside = (0..w as i64).contains(&x) && (0..h as i64).contains(&y);
            if !inside || !mask[y as usize * w + x as usize] {
                return [0.0; 3];
            }
            let (sx, sy) = ((u as f64 + 0.5) * f - 0.5, (v as f64 + 0.5) * f - 0.5);
            let c: [f32; 3] = std::array::from_fn(|k| bilinear(&comps[k], n, sx, sy));
            let len = c.iter().map(|a| a * a).sum::<f32>().sqrt();
            if len > 1e-3 {
                c.map(|a| a / len)
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect();
    NormalMap {
        width: crop.size,
        height: crop.size,
        normals,
    }
}

/// The mask as 0/1, averaged over each pixel's 3 x 3 neighbourhood (inside the photo).
fn blur3(mask: &[bool], w: usize, h: usize) -> Vec<f32> {
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            let (mut s, mut c) = (0.0f32, 0.0f32);
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let (xx, yy) = (x + dx, y + dy);
                    if (0..w as i64).contains(&xx) && (0..h as i64).contains(&yy) {
                        s += f32::from(u8::from(mask[yy as usize * w + xx as usize]));
                        c += 1.0;
                    }
                }
            }
            s / c
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_crop_holds_the_object_with_the_margin() {
        let (w, h) = (40, 30);
        let mask: Vec<bool> = (0..w * h)
            .map(|i| (10..20).contains(&(i % w)) && (5..25).contains(&(i / w)))
            .collect();
        let c = crop_around(&mask, w, h);
        assert_eq!(c.size, 22); // 20 / 0.95 = 21.05, rounded up
        assert!(
            c.x0 <= 10 && c.x0 + c.size as i64 >= 20 && c.y0 <= 5 && c.y0 + c.size as i64 >= 25
        );
        let img = crop_pixels(&mask_image(&mask, w, h), c);
        assert_eq!(img.pixels.iter().filter(|p| p[0] > 0.5).count(), 200);
    }

    #[test]
    fn masks_are_checked() {
        assert!(
            check_mask(&[false; 100], 10, 10)
                .unwrap_err()
                .to_string()
                .contains("0 pixels on the object")
        );
        assert!(
            check_mask(&[true; 100], 10, 10)
                .unwrap_err()
                .to_string()
                .contains("no background")
        );
        assert!(
            check_mask(&[true; 10], 10, 10)
                .unwrap_err()
                .to_string()
                .contains("10 pixels for a 10x10")
        );
    }

    #[test]
    fn photos_are_checked() {
        assert!(
            check_photo(&Image::zeros(8, 40))
                .unwrap_err()
                .to_string()
                .contains("too small")
        );
        assert!(
            check_photo(&Image::zeros(8193, 16))
                .unwrap_err()
                .to_string()
                .contains("over the limit")
        );
        let mut img = Image::zeros(16, 16);
        img.pixels[17][1] = f32::NAN;
        assert!(
            check_photo(&img)
                .unwrap_err()
                .to_string()
                .contains("(column 1, row 1)")
        );
    }
}
