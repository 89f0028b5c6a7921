//! A photo to its [`Decomposition`]: the object found (or given), the nets on the square
//! around it, then material and light refined through the layer from their predictions,
//! and, if asked, the normals after them; known normals and a known light
//! ([`PhotoOptions`]) take the nets' place.

use std::time::Instant;

use super::check::{check_mask, check_photo, single_object};
use super::composite::{RENDER_SIZE, render};
use super::crop::{
    crop_around, crop_image, mask_image, paste_scalar, render_grid, upsample_normals,
};
use super::light::{EDIT_LIGHT_BLUR, Factors, REFINED_BIAS, blur, match_background, relabel};
use super::pointing::segment_object;
use super::refine::refine_normals;
use super::{Decomposition, Object, PhotoOptions, Stage};
use crate::edit::fit::fit;
use crate::edit::inputs::Inputs;
use crate::edit::loss::psnr;
use crate::edit::options::{Light, Options};
use crate::error::{Result, invalid};
use crate::nets::{Frame, Nets};
use crate::raster::{self, Crop};
use crate::{Accuracy, EnvMap, Image, Material, NormalMap, Renderer};

/// Passes of the normals net that find the mask again on the image normalised by the
/// mask of the pass before (see [`find_object`]).
const MASK_PASSES: usize = 3;

/// Predicts and refines the decomposition of `photo` (linear RGB); `object` says where the
/// object is ([`Object`]: `None` or a mask converts into one). `progress` is called as each stage starts and after
/// each refinement step (`&mut |_| {}` for none).
pub fn decompose<'a>(
    renderer: &Renderer,
    nets: &Nets,
    photo: &Image,
    object: impl Into<Object<'a>>,
    options: &PhotoOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<Decomposition> {
    check_photo(photo)?;
    let (w, h) = (photo.width, photo.height);
    let n = match options.net_size {
        0 => nets.image_size(),
        n => n,
    };
    let mut t = Instant::now();
    let found;
    let mut stages = Vec::new();
    let mask = match object.into() {
        Object::Mask(m) => {
            check_mask(m, w, h)?;
            m
        }
        Object::Find => {
            found = find_object(nets, photo, n, progress)?;
            &found
        }
        Object::Pointed(p) => {
            progress(Stage::Segment);
            found = segment_object(nets, photo, p, n)?;
            stages.push(("segment", t.elapsed().as_secs_f64()));
            t = Instant::now();
            &found
        }
    };
    progress(Stage::Predict);
    let crop = crop_around(mask, w, h);
    let input = crop_image(photo, crop, n);
    let crop_mask = raster::crop_values(mask, w, h, crop, false);
    let small_mask: Vec<bool> = raster::resize(&mask_image(&crop_mask, crop.size, crop.size), n, n)
        .pixels
        .iter()
        .map(|p| p[0] > 0.5)
        .collect();
    let mut p = nets.predict(&input, Some(&small_mask))?;
    let light_factors = match &options.env {
        Some(env) => {
            p.env = known_light(env, p.env.height, p.env.width)?;
            Factors::GIVEN
        }
        None if options.background_light => match_background(&mut p.env, photo, mask),
        None => Factors::ONE,
    };
    let alpha = raster::blur3(mask, w, h);
    let mut normals = upsample_normals(&p.normals, crop, &crop_mask);
    if let Some(known) = &options.normals {
        take_known_normals(&mut normals, known, w, h, crop)?;
    }
    let predict_s = t.elapsed().as_secs_f64();

    // refinement on the crop at the photo's resolution, box-filtered by a whole factor to
    // the working size and pixel budget
    let t = Instant::now();
    let target = raster::crop(photo, crop);
    let object_pixels = crop_mask.iter().filter(|&&m| m).count();
    let inputs = Inputs::new(normals.clone(), target, Some(crop_mask.clone()))?;
    let work = inputs.downsampled(work_factor(crop.size, object_pixels, n, options));
    drop(inputs);
    let light_known = options.env.is_some();
    let light = if light_known {
        Light::Fixed(p.env.clone())
    } else {
        Light::FitFrom(p.env.clone())
    };
    let mut fit_options = Options::new(p.material.clone(), light);
    fit_options.steps = options.steps;
    // `work` is at the working size already
    fit_options.work_size = 0;
    // I' against the photo over the object, at the working size, with the given normals
    let judge = |normals: &NormalMap, m: &Material, e: &EnvMap| -> Result<f64> {
        let img = render(renderer, normals, e, m, Accuracy::Exact, false)?;
        Ok(psnr(&img, &work.target, &work.mask))
    };
    let psnr_predicted = judge(&work.normals, &p.material, &p.env)?;
    let (material, env, losses) = if options.steps == 0 {
        (p.material.clone(), p.env.clone(), Vec::new())
    } else {
        let steps = options.steps;
        progress(Stage::Refine { step: 0, steps });
        let f = fit(renderer, &work, &fit_options, &mut |step, _| {
            progress(Stage::Refine {
                step: (step + 1).min(steps),
                steps,
            })
        })?;
        let mut env = f.env;
        // the bias is the refinement's split of the gap between light and material
        let material = if light_known {
            f.material
        } else {
            relabel(&f.material, &mut env, REFINED_BIAS)
        };
        (material, env, f.losses)
    };
    let mut normal_losses = Vec::new();
    let mut work_normals = work.normals.clone();
    if options.steps > 0 && options.normal_steps > 0 {
        let (refined, l) = refine_normals(renderer, &work, &material, &env, options, progress)?;
        normal_losses = l;
        normals = upsample_normals(&refined, crop, &crop_mask);
        work_normals = refined;
    }
    let psnr_refined = judge(&work_normals, &material, &env)?;
    // a known light's detail is real; the refined light's below its broad shape is not
    let env = if light_known {
        env
    } else {
        blur(&env, EDIT_LIGHT_BLUR)
    };
    let (render_normals, coverage) = render_grid(&normals, &crop_mask, crop.size.min(RENDER_SIZE));
    let mut d = Decomposition {
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
        light_factors,
        render_normals: NormalMap {
            width: 0,
            height: 0,
            normals: Vec::new(),
        },
        coverage: Vec::new(),
        reference: Image::zeros(0, 0),
        detail: options.detail,
        stages: {
            stages.push(("predict", predict_s));
            stages.push(("refine", t.elapsed().as_secs_f64()));
            stages
        },
    };
    let t = Instant::now();
    d.set_render_normals(renderer, render_normals, coverage, false)?;
    d.stages.push(("reference", t.elapsed().as_secs_f64()));
    Ok(d)
}

/// The factor the refinement box-filters the crop (`size` pixels a side, `object` of them
/// on the object) by: the smallest whole one that leaves at most
/// [`PhotoOptions::work_size`] pixels a side and [`PhotoOptions::work_pixels`] on the
/// object (a pixel counts when its whole block is on the object, at most `object` / f^2),
/// but never fewer than `n` (the nets' size) a side for the pixel budget: a crop the nets
/// see at full resolution is refined at it.
fn work_factor(size: usize, object: usize, n: usize, options: &PhotoOptions) -> usize {
    let side = match options.work_size {
        0 => 1,
        w => size.div_ceil(w),
    };
    let pixels = match options.work_pixels {
        0 => 1,
        b => ((object as f64 / b as f64).sqrt().ceil() as usize).min(size / n.max(1)),
    };
    side.max(pixels).max(1)
}

/// A known light brought to the nets' light size (`height` x `width`): an error when that
/// does not divide it.
fn known_light(env: &EnvMap, height: usize, width: usize) -> Result<EnvMap> {
    if (env.height, env.width) == (height, width) {
        return Ok(env.clone());
    }
    crate::io::resample::downsample(env, height, width)
        .map_err(|e| invalid!("env (the known light): {e}"))
}

/// `normals` (the crop's, at its pixels, zero off the object) take the known normals of the
/// `w` x `h` photo at each pixel on the object where it has one (not zero): an error when
/// the map is not the photo's size.
fn take_known_normals(
    normals: &mut NormalMap,
    known: &NormalMap,
    w: usize,
    h: usize,
    crop: Crop,
) -> Result<()> {
    if (known.width, known.height) != (w, h) {
        return Err(invalid!(
            "the normals are {}x{}, the photo {w}x{h}",
            known.width,
            known.height
        ));
    }
    let at = raster::crop_values(&known.normals, w, h, crop, [0.0; 3]);
    for (n, k) in normals.normals.iter_mut().zip(at) {
        if *n != [0.0; 3] && k != [0.0; 3] {
            *n = k;
        }
    }
    Ok(())
}

/// The size (width, height) a `w` x `h` photo is shown to nets of input side `n` at: `n`
/// on its longer side, the shorter in proportion, rounded to a multiple of `k` (at least
/// `k`).
fn nets_shape(w: usize, h: usize, n: usize, k: usize) -> (usize, usize) {
    let short = |a: usize, b: usize| {
        let v = (n as f64 * a as f64 / b as f64 / k as f64).round() as usize * k;
        v.clamp(k, n)
    };
    if w >= h {
        (n, short(h, w))
    } else {
        (short(w, h), n)
    }
}

/// The object as the nets find it on the whole photo, shown to them as they saw photos in
/// training ([`Frame`]): padded to a square, `n` x `n`, or at its own shape with `n` pixels
/// on its longer side (the shorter a multiple of the nets' 2^(levels - 1)); photo-like nets
/// never saw black bands above and below a photo, and with them took the background beside
/// the object for it (docs/edit.md). [`MASK_PASSES`] + 1 passes, each after the first on the
/// photo normalised by the mask of the pass before; an error if what is found is empty,
/// full, a speck or black, or when no single object stands out ([`single_object`]).
fn find_object(
    nets: &Nets,
    photo: &Image,
    n: usize,
    progress: &mut dyn FnMut(Stage),
) -> Result<Vec<bool>> {
    let (w, h) = (photo.width, photo.height);
    let frame = nets.config().frame;
    let whole = Crop {
        x0: (w as i64 - w.max(h) as i64) / 2,
        y0: (h as i64 - w.max(h) as i64) / 2,
        size: w.max(h),
    };
    let input = match frame {
        Frame::Square => crop_image(photo, whole, n),
        Frame::Photo => {
            let (nw, nh) = nets_shape(w, h, n, 1 << (nets.config().levels - 1));
            raster::resize(photo, nw, nh)
        }
    };
    let passes = MASK_PASSES + 1;
    progress(Stage::Mask { pass: 1, passes });
    let mut prob = nets.mask_prob(&input, None)?;
    // the nets were trained on images normalised by the object's mean, and the first
    // pass can only normalise by the whole image's: normalise by the mask found
    // and find it again, a few times
    for pass in 2..=passes {
        let m: Vec<bool> = prob.iter().map(|&a| a > 0.5).collect();
        if !m.iter().any(|&x| x) {
            break;
        }
        progress(Stage::Mask { pass, passes });
        prob = nets.mask_prob(&input, Some(&m))?;
    }
    let prob = match frame {
        Frame::Square => paste_scalar(&prob, n, whole, w, h),
        Frame::Photo => raster::resample_scalar(&prob, input.width, input.height, w, h),
    };
    let found: Vec<bool> = prob.iter().map(|&a| a > 0.5).collect();
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
    single_object(&found, w, h)?;
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::nets_shape;

    #[test]
    fn the_nets_see_a_photo_at_its_shape() {
        assert_eq!(nets_shape(320, 240, 128, 8), (128, 96));
        assert_eq!(nets_shape(240, 320, 64, 8), (48, 64));
        assert_eq!(nets_shape(600, 400, 64, 8), (64, 40)); // 42.7 rounds to 40
        assert_eq!(nets_shape(500, 500, 64, 8), (64, 64));
        assert_eq!(nets_shape(8000, 16, 64, 8), (64, 8)); // never below 8
    }
}
