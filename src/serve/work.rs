//! What the server computes, off the async threads: an upload decoded and checked, its
//! decomposition ([`photo::decompose`]) with the pictures the page shows, and edits
//! at full size or as a preview through the levels of detail.

use std::path::Path;
use std::sync::Arc;

use crate::edit::photo::{self, Crop, Decomposition, Object, PhotoOptions, Pointing, Stage};
use crate::error::{Error, Result};
use crate::io::png::{Preview, Tonemap};
use crate::nets::Nets;
use crate::raster;
use crate::{
    Accuracy, Batch, Camera, Convention, EnvMap, Image, Material, NormalMap, Renderer, Scene,
};

/// The longest side of a preview, in pixels.
pub const PREVIEW_SIDE: usize = 256;
/// The levels of detail's error budget for previews (relative, as `matedit render
/// --tolerance`).
pub const PREVIEW_TOLERANCE: f64 = 1e-2;
/// The side of a material's sphere picture.
pub const SPHERE_SIDE: usize = 96;

/// A decoded upload: the photo (linear RGB) and, for a PNG with transparency, its alpha as
/// the object's mask.
pub struct Upload {
    pub photo: Arc<Image>,
    pub mask: Option<Vec<bool>>,
}

/// Where the object is for an analysis: found by the nets, a mask (the photo's size), or
/// pointed at.
pub enum Target {
    Find,
    Mask(Vec<bool>),
    Pointed(Pointing),
}

impl Target {
    fn object(&self) -> Object<'_> {
        match self {
            Target::Find => Object::Find,
            Target::Mask(m) => Object::Mask(m),
            Target::Pointed(p) => Object::Pointed(p),
        }
    }
}

/// The object's mask from `pointing` ([`photo::segment_object`]) as a PNG of the photo's
/// size, with its count of pixels.
pub fn segment_png(nets: &Nets, photo: &Image, pointing: &Pointing) -> Result<(Vec<u8>, usize)> {
    let mask = photo::segment_object(nets, photo, pointing, nets.image_size())?;
    let count = mask.iter().filter(|&&m| m).count();
    Ok((
        crate::io::png::encode_mask(photo.width, photo.height, &mask)?,
        count,
    ))
}

/// A mask sent as a PNG (a pixel counts above half the largest sample of its first
/// channel) for a `width` x `height` photo; its size is read from the header first.
pub fn decode_mask(bytes: &[u8], width: usize, height: usize) -> Result<Vec<bool>> {
    let path = Path::new("mask.png");
    if sniff(bytes) != Some("photo.png") {
        return Err(Error::Invalid("mask: not a PNG".into()));
    }
    let (w, h) = crate::io::image_dimensions(path, bytes)?;
    if (w, h) != (width, height) {
        return Err(Error::Invalid(format!(
            "mask: {w}x{h}; the photo is {width}x{height}"
        )));
    }
    let d = crate::io::png::decode_bytes(path, bytes)?;
    let half = d.max_value() / 2.0;
    Ok(d.samples
        .chunks_exact(d.channels)
        .map(|p| f64::from(p[0]) > half)
        .collect())
}

/// The photo as the page shows it (PNG).
pub fn photo_png(photo: &Image) -> Result<Vec<u8>> {
    crate::io::png::encode_preview(photo, &Preview::default())
}

/// Why an upload was refused: too large (413), not a kind of file taken (415), or not a
/// readable photo (400).
#[derive(Debug)]
pub enum Refusal {
    TooLarge(String),
    Unsupported(String),
    Bad(String),
}

/// The format of an upload from its first bytes, as a file name for messages and loaders.
fn sniff(bytes: &[u8]) -> Option<&'static str> {
    if bytes.starts_with(&[0xFF, 0xD8, 0xFF]) {
        Some("photo.jpg")
    } else if bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        Some("photo.png")
    } else if bytes.starts_with(&[0x76, 0x2F, 0x31, 0x01]) {
        Some("photo.exr")
    } else {
        None
    }
}

/// Decodes and checks an upload; `name` is the client's name for it (messages only),
/// `max_pixels` the server's limit, checked on the headers before decoding.
pub fn decode_upload(
    name: &str,
    bytes: &[u8],
    max_pixels: usize,
) -> std::result::Result<Upload, Refusal> {
    let Some(file) = sniff(bytes) else {
        return Err(Refusal::Unsupported(format!(
            "{name}: not a JPEG, PNG or EXR image"
        )));
    };
    let path = Path::new(file);
    let named = |e: Error| match e {
        Error::File { message, .. } => format!("{name}: {message}"),
        e => format!("{name}: {e}"),
    };
    let (w, h) = crate::io::image_dimensions(path, bytes).map_err(|e| Refusal::Bad(named(e)))?;
    if w.saturating_mul(h) > max_pixels || w > photo::MAX_SIDE || h > photo::MAX_SIDE {
        return Err(Refusal::TooLarge(format!(
            "{name}: {w}x{h} is over the limit of {max_pixels} pixels ({} a side); downscale it",
            photo::MAX_SIDE
        )));
    }
    let image = crate::io::image_from_bytes(path, bytes).map_err(|e| Refusal::Bad(named(e)))?;
    photo::check_photo(&image).map_err(|e| Refusal::Bad(format!("{name}: {e}")))?;
    let mask = crate::io::png_alpha_mask(path, bytes).map_err(|e| Refusal::Bad(named(e)))?;
    Ok(Upload {
        photo: Arc::new(image),
        mask,
    })
}

/// A decomposition with everything an edit and the page need.
pub struct Analysed {
    pub photo: Arc<Image>,
    pub d: Decomposition,
    /// The decomposition and photo scaled to at most [`PREVIEW_SIDE`] a side.
    pub small: Decomposition,
    pub small_photo: Image,
    /// The pictures of the decomposition: file name, content type, bytes.
    pub files: Vec<(&'static str, &'static str, Vec<u8>)>,
    pub report: serde_json::Value,
}

/// A stage as (stage, done, total, message) for the page.
pub fn describe(stage: Stage) -> (&'static str, usize, usize, String) {
    match stage {
        Stage::Mask { pass, passes } => (
            "mask",
            pass,
            passes,
            format!("Finding the object (pass {pass} of {passes})"),
        ),
        Stage::Segment => (
            "segment",
            0,
            1,
            "Cutting out the object pointed at".to_string(),
        ),
        Stage::Predict => (
            "predict",
            0,
            1,
            "Predicting shape, light and material".into(),
        ),
        Stage::Refine { step, steps } => (
            "refine",
            step,
            steps,
            format!("Refining material and light: step {step} of {steps}"),
        ),
        Stage::Normals { step, steps } => (
            "normals",
            step,
            steps,
            format!("Refining the normals: step {step} of {steps}"),
        ),
    }
}

/// Decomposes a photo with its object at `target` and makes its pictures.
pub fn analyse(
    renderer: &Renderer,
    nets: &Nets,
    photo: Arc<Image>,
    target: &Target,
    options: &PhotoOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<Analysed> {
    let d = photo::decompose(renderer, nets, &photo, target.object(), options, progress)?;
    let factor = photo.width.max(photo.height).div_ceil(PREVIEW_SIDE).max(1);
    let (mut small, small_photo) = scaled(&d, &photo, factor);
    let coverage = small
        .normals
        .normals
        .iter()
        .map(|n| f32::from(u8::from(n != &[0.0; 3])))
        .collect();
    small.set_render_normals(renderer, small.normals.clone(), coverage, true)?;
    let crop_mask: Vec<bool> = d.normals.normals.iter().map(|n| n != &[0.0; 3]).collect();
    let files = vec![
        ("photo.png", "image/png", photo_png(&photo)?),
        (
            "mask.png",
            "image/png",
            crate::io::png::encode_mask(d.width, d.height, &d.mask)?,
        ),
        (
            "normals.png",
            "image/png",
            crate::io::png::encode_normals(&d.normals, &crop_mask)?,
        ),
        ("light.png", "image/png", light_png(&d.env)?),
        (
            "light.exr",
            "image/x-exr",
            crate::io::exr::encode_rgb(d.env.width, d.env.height, &d.env.texels)?,
        ),
        (
            "sphere.png",
            "image/png",
            sphere_png(renderer, &d.material)?,
        ),
        (
            "material.json",
            "application/json",
            crate::io::json::encode_material(
                &d.material,
                Some("the material matedit serve found in a photo"),
            ),
        ),
    ];
    let seconds: serde_json::Map<String, serde_json::Value> = d
        .stages
        .iter()
        .map(|(k, v)| ((*k).to_string(), serde_json::json!(v)))
        .collect();
    let report = serde_json::json!({
        "width": d.width,
        "height": d.height,
        "crop": {"x0": d.crop.x0, "y0": d.crop.y0, "size": d.crop.size},
        "object_pixels": d.mask.iter().filter(|&&m| m).count(),
        "steps": d.losses.len(),
        "loss_first": d.losses.first(),
        "loss_last": d.losses.last(),
        "psnr_predicted_db": d.psnr_predicted,
        "psnr_refined_db": d.psnr_refined,
        "seconds": seconds,
    });
    Ok(Analysed {
        photo,
        d,
        small,
        small_photo,
        files,
        report,
    })
}

/// What an edit asks for.
pub struct EditRequest<'a> {
    pub material: &'a Material,
    /// Degrees the light turns about the vertical axis.
    pub turn: f64,
    /// Stops the light is scaled by.
    pub exposure: f64,
    /// At most [`PREVIEW_SIDE`] a side, through the levels of detail.
    pub preview: bool,
}

/// The photo with the object made of `req.material`, as a PNG.
pub fn edit_png(renderer: &Renderer, a: &Analysed, req: &EditRequest) -> Result<Vec<u8>> {
    let (d, photo) = if req.preview {
        (&a.small, &a.small_photo)
    } else {
        (&a.d, a.photo.as_ref())
    };
    let mut env = if req.turn == 0.0 {
        d.env.clone()
    } else {
        crate::envgen::turn(&d.env, req.turn)?
    };
    if req.exposure != 0.0 {
        let k = 2f32.powf(req.exposure as f32);
        for t in &mut env.texels {
            *t = t.map(|v| v * k);
        }
    }
    let accuracy = if req.preview {
        Accuracy::Tolerance(PREVIEW_TOLERANCE)
    } else {
        Accuracy::Exact
    };
    let edit = d.edit(renderer, photo, req.material, Some(&env), accuracy)?;
    crate::io::png::encode_preview(&edit, &Preview::default())
}

/// A material on a sphere under the built-in sky, as a PNG.
pub fn sphere_png(renderer: &Renderer, material: &Material) -> Result<Vec<u8>> {
    let batch = Batch::single(Scene {
        normals: NormalMap::sphere(SPHERE_SIDE),
        env: crate::builtin_sky::procedural_env(32, 64, Convention::Equirect),
        material: material.clone(),
        camera: Camera::Orthographic,
    })?;
    // a sharp lobe shows the sky's texels as dots under the layer's point lights: the
    // continuous light with sub-texels from the sky at 4 times the size
    let detail = crate::builtin_sky::procedural_env(128, 256, Convention::Equirect);
    let light = crate::continuous_light::Integration::Tolerance(photo::LIGHT_TOLERANCE);
    let image = crate::continuous_light::render(
        renderer,
        &batch,
        &Accuracy::Exact,
        light,
        &[Some(detail)],
    )?
    .0
    .remove(0);
    crate::io::png::encode_preview(&image, &Preview::default())
}

/// A light as a 256 x 128 lat-long picture (bilinear between texels), exposed for its mean
/// and Reinhard-mapped.
fn light_png(env: &EnvMap) -> Result<Vec<u8>> {
    let n = env.texels.len().max(1) as f64;
    let mean = env
        .texels
        .iter()
        .map(|t| f64::from(t[0] + t[1] + t[2]) / 3.0)
        .sum::<f64>()
        / n;
    // bilinear between texel centres, wrapping in longitude
    let (w, h) = (env.width, env.height);
    let mut big = Image::zeros(256, 128);
    for y in 0..128 {
        let v = ((y as f64 + 0.5) * h as f64 / 128.0 - 0.5).clamp(0.0, (h - 1) as f64);
        let (y0, fy) = (v.floor() as usize, (v - v.floor()) as f32);
        let y1 = (y0 + 1).min(h - 1);
        for x in 0..256 {
            let u = ((x as f64 + 0.5) * w as f64 / 256.0 - 0.5).rem_euclid(w as f64);
            let (x0, fx) = (u.floor() as usize % w, (u - u.floor()) as f32);
            let x1 = (x0 + 1) % w;
            let t = |xx: usize, yy: usize| env.texels[yy * w + xx];
            big.pixels[y * 256 + x] = std::array::from_fn(|k| {
                let top = t(x0, y0)[k] * (1.0 - fx) + t(x1, y0)[k] * fx;
                let bottom = t(x0, y1)[k] * (1.0 - fx) + t(x1, y1)[k] * fx;
                top * (1.0 - fy) + bottom * fy
            });
        }
    }
    let preview = Preview {
        exposure: if mean > 0.0 {
            (0.5 / mean).log2() as f32
        } else {
            0.0
        },
        tonemap: Tonemap::Reinhard,
    };
    crate::io::png::encode_preview(&big, &preview)
}

/// `d` and `photo` box-filtered by `f` (a pixel of the result covers f x f of the photo):
/// the photo and the soft mask averaged, the normals of a block averaged and renormalised
/// where most of the block is on the object, the crop scaled to cover the same photo pixels
/// (without its render grid: [`Decomposition::set_render_normals`]).
pub fn scaled(d: &Decomposition, photo: &Image, f: usize) -> (Decomposition, Image) {
    let (w, h) = (d.width.div_ceil(f), d.height.div_ceil(f));
    let reduced = raster::reduce((d.width, d.height), (f, f), (w, h), |block| {
        let (mut sum, mut a, mut count) = ([0f32; 3], 0f32, 0f32);
        for i in block {
            for k in 0..3 {
                sum[k] += photo.pixels[i][k];
            }
            a += d.alpha[i];
            count += 1.0;
        }
        (sum.map(|v| v / count), a / count)
    });
    let small = Image {
        width: w,
        height: h,
        pixels: reduced.iter().map(|r| r.0).collect(),
    };
    let alpha: Vec<f32> = reduced.iter().map(|r| r.1).collect();
    let x0 = d.crop.x0.div_euclid(f as i64);
    let y0 = d.crop.y0.div_euclid(f as i64);
    let end = |o: i64| (o + d.crop.size as i64 + f as i64 - 1).div_euclid(f as i64);
    let size = ((end(d.crop.x0) - x0).max(end(d.crop.y0) - y0)).max(1) as usize;
    let mut normals = NormalMap {
        width: size,
        height: size,
        normals: vec![[0.0; 3]; size * size],
    };
    let cs = d.crop.size as i64;
    for sy in 0..size {
        for sx in 0..size {
            let (mut sum, mut on) = ([0f32; 3], 0usize);
            for by in 0..f as i64 {
                for bx in 0..f as i64 {
                    // the crop-local pixel under this photo pixel
                    let cx = (x0 + sx as i64) * f as i64 + bx - d.crop.x0;
                    let cy = (y0 + sy as i64) * f as i64 + by - d.crop.y0;
                    if !(0..cs).contains(&cx) || !(0..cs).contains(&cy) {
                        continue;
                    }
                    let n = d.normals.normals[(cy * cs + cx) as usize];
                    if n != [0.0; 3] {
                        for k in 0..3 {
                            sum[k] += n[k];
                        }
                        on += 1;
                    }
                }
            }
            let len = (sum[0] * sum[0] + sum[1] * sum[1] + sum[2] * sum[2]).sqrt();
            if 2 * on >= f * f && len > 0.0 {
                normals.normals[sy * size + sx] = sum.map(|v| v / len);
            }
        }
    }
    let small_d = Decomposition {
        width: w,
        height: h,
        crop: Crop { x0, y0, size },
        normals,
        mask: alpha.iter().map(|&a| a > 0.5).collect(),
        alpha,
        predicted_material: d.predicted_material.clone(),
        predicted_env: d.predicted_env.clone(),
        material: d.material.clone(),
        env: d.env.clone(),
        psnr_predicted: d.psnr_predicted,
        psnr_refined: d.psnr_refined,
        losses: Vec::new(),
        normal_losses: Vec::new(),
        light_factors: d.light_factors,
        render_normals: NormalMap {
            width: 0,
            height: 0,
            normals: Vec::new(),
        },
        coverage: Vec::new(),
        reference: Image::zeros(0, 0),
        detail: d.detail,
        stages: Vec::new(),
    };
    (small_d, small)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sniffs_the_three_kinds() {
        assert_eq!(sniff(&[0xFF, 0xD8, 0xFF, 0xE0]), Some("photo.jpg"));
        assert_eq!(sniff(b"\x89PNG\r\n\x1a\n...."), Some("photo.png"));
        assert_eq!(sniff(&[0x76, 0x2F, 0x31, 0x01, 2]), Some("photo.exr"));
        assert_eq!(sniff(b"GIF89a"), None);
        assert_eq!(sniff(b""), None);
    }

    #[test]
    fn a_png_header_over_the_limit_is_refused_before_decoding() {
        // a PNG signature and an IHDR claiming 100000 x 100000, and nothing after it
        let mut bytes = b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR".to_vec();
        bytes.extend_from_slice(&100_000u32.to_be_bytes());
        bytes.extend_from_slice(&100_000u32.to_be_bytes());
        match decode_upload("big.png", &bytes, 1 << 24) {
            Err(Refusal::TooLarge(m)) => assert!(m.starts_with("big.png: 100000x100000"), "{m}"),
            _ => panic!("not refused as too large"),
        }
        match decode_upload("t.txt", b"hello", 1 << 24) {
            Err(Refusal::Unsupported(m)) => assert!(m.contains("t.txt"), "{m}"),
            _ => panic!("text taken for an image"),
        }
    }
}
