//! Reading and writing files: normal maps, environment maps, materials, upstream gradients
//! and rendered images in EXR, NPY, PNG and JSON; scene descriptions and batch manifests;
//! atomic output.
//!
//! Every loader checks what it reads and returns an [`Error::File`] naming the file, the
//! item and what is wrong (`normals.npy: pixel (3, 7) is NaN`, pixel = (column, row));
//! nothing here panics on user input. Outputs are written to a temporary file in the
//! destination folder and renamed into place, so a failed run leaves no partial file.
//! docs/FORMATS.md describes every format.
//!
//! Files: the formats ([`exr`], [`npy`], [`png`], [`jpeg`], [`json`]) and [`resample`] (env
//! map sizes) beneath the loaders here; scenes in: [`source`] (where normals and materials
//! come from) and [`manifest`] (batch files); results out: [`outputs`] (images and gradient
//! folders) on [`write`](mod@write) (checks before work, atomic writes).

pub mod exr;
pub mod jpeg;
pub mod json;
pub mod manifest;
pub mod npy;
pub mod outputs;
pub mod png;
pub mod resample;
pub mod source;
pub mod write;

use std::path::Path;

use crate::envmap::{Convention, EnvMap, MAX_RADIANCE};
use crate::error::{Error, Result};
use crate::material::Material;
use crate::scene::{BACKGROUND_EPS, Image, NormalMap};

pub use png::{Preview, Tonemap};
pub use resample::EnvSize;
pub use write::{
    Staged, check_output, check_parent, commit_all, create_dirs, encode_image, encode_mask,
    encode_normals, remove_created, stage, write_atomic, write_env,
};

/// A 3-channel float raster as read from a file, row-major, row 0 at the top, kept in f64
/// so that checks see the file's values.
#[derive(Clone, Debug, PartialEq)]
pub struct Raster {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Three values per pixel.
    pub pixels: Vec<[f64; 3]>,
}

/// A file format, known by the file's extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Format {
    /// OpenEXR (`.exr`).
    Exr,
    /// NumPy array (`.npy`).
    Npy,
    /// PNG (`.png`).
    Png,
    /// JSON (`.json`).
    Json,
    /// JPEG (`.jpg`, `.jpeg`): photos, read only.
    Jpeg,
}

impl Format {
    /// The format of `path` by its extension (case-insensitive), if known.
    pub fn of(path: &Path) -> Option<Format> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        match ext.as_str() {
            "exr" => Some(Format::Exr),
            "npy" => Some(Format::Npy),
            "png" => Some(Format::Png),
            "json" => Some(Format::Json),
            "jpg" | "jpeg" => Some(Format::Jpeg),
            _ => None,
        }
    }

    /// The extension, e.g. `.exr`.
    pub fn ext(self) -> &'static str {
        match self {
            Format::Exr => ".exr",
            Format::Npy => ".npy",
            Format::Png => ".png",
            Format::Json => ".json",
            Format::Jpeg => ".jpg",
        }
    }
}

/// The format of `path` if it is one of `allowed`; else an error saying which are.
pub fn format_of(path: &Path, what: &str, allowed: &[Format]) -> Result<Format> {
    let exts = allowed.iter().map(|f| f.ext()).collect::<Vec<_>>();
    let list = match exts.as_slice() {
        [one] => one.to_string(),
        [init @ .., last] => format!("{} or {last}", init.join(", ")),
        [] => String::new(),
    };
    match Format::of(path) {
        Some(f) if allowed.contains(&f) => Ok(f),
        _ => Err(Error::file(
            path,
            format!("{what} must be a {list} file (known by its extension)"),
        )),
    }
}

/// Reads a whole file, with an error that says plainly what is wrong.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    if path.is_dir() {
        return Err(Error::file(path, "is a folder, not a file"));
    }
    std::fs::read(path).map_err(|e| {
        let why = match e.kind() {
            std::io::ErrorKind::NotFound => "no such file".to_string(),
            std::io::ErrorKind::PermissionDenied => "permission denied".to_string(),
            _ => format!("cannot read: {e}"),
        };
        Error::file(path, why)
    })
}

/// Reads a whole file whose extension is one of `allowed` (checked first).
fn read_as(path: &Path, what: &str, allowed: &[Format]) -> Result<Vec<u8>> {
    format_of(path, what, allowed)?;
    read_bytes(path)
}

const RASTERS: &[Format] = &[Format::Exr, Format::Npy];
const IMAGES: &[Format] = &[Format::Exr, Format::Npy, Format::Png];
/// Images to fit to, to edit, or to show behind an object: photos too.
const PHOTOS: &[Format] = &[Format::Exr, Format::Npy, Format::Png, Format::Jpeg];

/// Reads an H x W x 3 float raster from an EXR or NPY file.
pub fn read_raster(path: &Path, what: &str) -> Result<Raster> {
    raster_from_bytes(path, &read_as(path, what, RASTERS)?, what)
}

/// [`read_raster`] on a file's bytes: `path` names the file in errors and its extension
/// says the format.
pub fn raster_from_bytes(path: &Path, bytes: &[u8], what: &str) -> Result<Raster> {
    match format_of(path, what, RASTERS)? {
        Format::Exr => exr::decode_rgb(path, bytes),
        _ => npy_raster(path, npy::parse(bytes).map_err(|m| Error::file(path, m))?),
    }
}

/// An NPY array of shape (H, W, 3) as a raster.
pub fn npy_raster(path: &Path, a: npy::NpyArray) -> Result<Raster> {
    let [height, width, 3] = a.shape[..] else {
        return Err(Error::file(
            path,
            format!(
                "shape {} is not (height, width, 3)",
                npy::shape_str(&a.shape)
            ),
        ));
    };
    if height == 0 || width == 0 {
        return Err(Error::file(
            path,
            format!("shape {} is empty", npy::shape_str(&a.shape)),
        ));
    }
    let pixels = a.data.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
    Ok(Raster {
        width,
        height,
        pixels,
    })
}

const CHANNELS: [&str; 3] = ["R", "G", "B"];

/// The first non-finite value of a raster: (pixel index, channel, "NaN" or "infinite").
fn first_non_finite(pixels: &[[f64; 3]]) -> Option<(usize, usize, &'static str)> {
    pixels.iter().enumerate().find_map(|(i, p)| {
        p.iter().enumerate().find_map(|(c, v)| {
            (!v.is_finite()).then_some((i, c, if v.is_nan() { "NaN" } else { "infinite" }))
        })
    })
}

/// Normalises raw normals: background (|n| < 1e-6) becomes [0, 0, 0], the rest unit length.
/// Errors name the first non-finite pixel as (column, row).
fn normalise(path: &Path, width: usize, raw: &[[f64; 3]]) -> Result<Vec<[f32; 3]>> {
    if let Some((i, _, what)) = first_non_finite(raw) {
        return Err(Error::file(
            path,
            format!("pixel ({}, {}) is {what}", i % width, i / width),
        ));
    }
    Ok(raw
        .iter()
        .map(|n| {
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if len < BACKGROUND_EPS {
                [0.0; 3]
            } else if len.is_finite() {
                n.map(|v| (v / len) as f32)
            } else {
                // components beyond 1e154 (float64 files): the squares overflow, so
                // normalise the vector divided by its largest component
                let big = n.iter().fold(0.0f64, |a, v| a.max(v.abs()));
                let s = n.map(|v| v / big);
                let len = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                s.map(|v| (v / len) as f32)
            }
        })
        .collect())
}

/// Loads a normal map (EXR, NPY or PNG): channels (n.x, n.y, n.z), normalised, background
/// where |n| < 1e-6 (and, in PNG files, where alpha is 0 or R = G = B = 0).
pub fn load_normals(path: &Path) -> Result<NormalMap> {
    normals_from_bytes(path, &read_as(path, "a normal map", IMAGES)?)
}

/// [`load_normals`] on a file's bytes: `path` names the file in errors and its extension
/// says the format.
pub fn normals_from_bytes(path: &Path, bytes: &[u8]) -> Result<NormalMap> {
    let (width, height, raw) = match format_of(path, "a normal map", IMAGES)? {
        Format::Png => png::normals_of(path, &png::decode_bytes(path, bytes)?)?,
        _ => {
            let r = raster_from_bytes(path, bytes, "a normal map")?;
            (r.width, r.height, r.pixels)
        }
    };
    let normals = normalise(path, width, &raw)?;
    NormalMap::new(width, height, normals).map_err(|e| Error::file(path, e.to_string()))
}

/// An environment map as loaded, with how many negative values were clamped to 0.
#[derive(Clone, Debug, PartialEq)]
pub struct LoadedEnv {
    /// The map at the file's size.
    pub env: EnvMap,
    /// Channel values that were negative and are now 0.
    pub clamped: usize,
}

/// Loads a lat-long environment map (EXR or NPY, row 0 = top) under `convention`.
/// Negative values are clamped to 0 and counted; NaN, infinite or huge values are errors.
pub fn load_env(path: &Path, convention: Convention) -> Result<LoadedEnv> {
    let what = "an environment map";
    env_from_bytes(path, &read_as(path, what, RASTERS)?, convention)
}

/// [`load_env`] on a file's bytes: `path` names the file in errors and its extension says
/// the format.
pub fn env_from_bytes(path: &Path, bytes: &[u8], convention: Convention) -> Result<LoadedEnv> {
    let r = raster_from_bytes(path, bytes, "an environment map")?;
    if let Some((i, c, what)) = first_non_finite(&r.pixels) {
        return Err(Error::file(
            path,
            format!(
                "texel (row {}, column {}) channel {} is {what}",
                i / r.width,
                i % r.width,
                CHANNELS[c]
            ),
        ));
    }
    let mut texels: Vec<[f32; 3]> = r.pixels.iter().map(|p| p.map(|v| v as f32)).collect();
    let clamped = EnvMap::clamp_negative(&mut texels);
    if let Some((i, c)) = texels
        .iter()
        .enumerate()
        .find_map(|(i, t)| t.iter().position(|&v| v > MAX_RADIANCE).map(|c| (i, c)))
    {
        return Err(Error::file(
            path,
            format!(
                "texel (row {}, column {}) channel {} is {:e}, above the largest radiance accepted ({MAX_RADIANCE:e})",
                i / r.width,
                i % r.width,
                CHANNELS[c],
                r.pixels[i][c]
            ),
        ));
    }
    let env = EnvMap::new(r.height, r.width, convention, texels)
        .map_err(|e| Error::file(path, e.to_string()))?;
    Ok(LoadedEnv { env, clamped })
}

/// Loads an image to fit to: EXR or NPY (linear RGB, H x W x 3, every value finite), PNG
/// (8 or 16 bits) or JPEG, both sRGB-decoded to linear (grey is replicated, alpha ignored).
pub fn load_image(path: &Path) -> Result<Image> {
    image_from_bytes(path, &read_as(path, "an image", PHOTOS)?)
}

/// The width and height of a photo's bytes (JPEG, PNG or EXR, which `path`'s extension
/// says), read from its headers without decoding its pixels: a size check before the cost.
pub fn image_dimensions(path: &Path, bytes: &[u8]) -> Result<(usize, usize)> {
    match format_of(path, "an image", &[Format::Png, Format::Jpeg, Format::Exr])? {
        Format::Png => {
            const SIGNATURE: &[u8] = b"\x89PNG\r\n\x1a\n";
            if bytes.len() < 24 || &bytes[..8] != SIGNATURE || &bytes[12..16] != b"IHDR" {
                return Err(Error::file(path, "not a readable PNG: no IHDR header"));
            }
            let be =
                |i: usize| u32::from_be_bytes([bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]]);
            Ok((be(16) as usize, be(20) as usize))
        }
        Format::Jpeg => jpeg::dimensions(path, bytes),
        _ => exr::dimensions(path, bytes),
    }
}

/// A PNG's alpha as the object's mask (a pixel counts above half the largest sample), where
/// it has alpha that is not opaque everywhere; None for other formats (by `path`'s
/// extension) and PNGs without transparency.
pub fn png_alpha_mask(path: &Path, bytes: &[u8]) -> Result<Option<Vec<bool>>> {
    if Format::of(path) != Some(Format::Png) {
        return Ok(None);
    }
    let d = png::decode_bytes(path, bytes)?;
    if d.channels != 2 && d.channels != 4 {
        return Ok(None);
    }
    let max = d.max_value();
    let alpha: Vec<bool> = d
        .samples
        .chunks_exact(d.channels)
        .map(|p| f64::from(p[d.channels - 1]) > max / 2.0)
        .collect();
    Ok(alpha.iter().any(|&a| !a).then_some(alpha))
}

/// [`load_image`] on a file's bytes: `path` names the file in errors and its extension
/// says the format.
pub fn image_from_bytes(path: &Path, bytes: &[u8]) -> Result<Image> {
    let (width, height, pixels) = match format_of(path, "an image", PHOTOS)? {
        Format::Png => {
            let d = png::decode_bytes(path, bytes)?;
            let max = d.max_value();
            let pixels = d
                .samples
                .chunks_exact(d.channels)
                .map(|p| {
                    let rgb = if d.channels >= 3 {
                        [p[0], p[1], p[2]]
                    } else {
                        [p[0]; 3]
                    };
                    rgb.map(|v| png::srgb_decode(v as f32 / max as f32))
                })
                .collect();
            (d.width, d.height, pixels)
        }
        Format::Jpeg => {
            let (w, h, rgb) = jpeg::decode_bytes(path, bytes)?;
            let lut: Vec<f32> = (0..=255u8)
                .map(|v| png::srgb_decode(f32::from(v) / 255.0))
                .collect();
            let pixels = rgb
                .chunks_exact(3)
                .map(|p| [lut[p[0] as usize], lut[p[1] as usize], lut[p[2] as usize]])
                .collect();
            (w, h, pixels)
        }
        _ => {
            let r = raster_from_bytes(path, bytes, "an image")?;
            let pixels = to_f32(path, &r, |c, row| format!("pixel (column {c}, row {row})"))?;
            (r.width, r.height, pixels)
        }
    };
    Ok(Image {
        width,
        height,
        pixels,
    })
}

/// Loads a mask (EXR, NPY or PNG, any channels): a pixel counts where its first channel is
/// above half (PNG: half the largest sample; EXR and NPY: 0.5).
pub fn load_mask(path: &Path) -> Result<(usize, usize, Vec<bool>)> {
    let format = format_of(path, "a mask", IMAGES)?;
    if format == Format::Png {
        let d = png::decode(path)?;
        let half = d.max_value() / 2.0;
        let mask = d
            .samples
            .chunks_exact(d.channels)
            .map(|p| f64::from(p[0]) > half)
            .collect();
        return Ok((d.width, d.height, mask));
    }
    let r = match format {
        Format::Exr => exr::read_rgb(path)?,
        _ => {
            let a = npy::read(path)?;
            match a.shape[..] {
                [h, w] if h > 0 && w > 0 => Raster {
                    width: w,
                    height: h,
                    pixels: a.data.iter().map(|&v| [v; 3]).collect(),
                },
                _ => npy_raster(path, a)?,
            }
        }
    };
    if let Some((i, _, what)) = first_non_finite(&r.pixels) {
        return Err(Error::file(
            path,
            format!(
                "pixel (column {}, row {}) is {what}",
                i % r.width,
                i / r.width
            ),
        ));
    }
    Ok((
        r.width,
        r.height,
        r.pixels.iter().map(|p| p[0] > 0.5).collect(),
    ))
}

/// Loads an upstream gradient dLoss/dImage (EXR or NPY, H x W x 3, every value finite).
pub fn load_upstream(path: &Path) -> Result<Image> {
    let r = read_raster(path, "an upstream gradient")?;
    Ok(Image {
        width: r.width,
        height: r.height,
        pixels: to_f32(path, &r, |c, row| format!("pixel ({c}, {row})"))?,
    })
}

/// A raster's values in float32; the error names the first value that is not finite or is
/// beyond float32's range (float64 files), with the pixel as `at(column, row)` writes it.
fn to_f32(path: &Path, r: &Raster, at: impl Fn(usize, usize) -> String) -> Result<Vec<[f32; 3]>> {
    let bad = |i: usize, c: usize, why: String| {
        let at = at(i % r.width, i / r.width);
        Error::file(path, format!("{at} channel {} is {why}", CHANNELS[c]))
    };
    if let Some((i, c, what)) = first_non_finite(&r.pixels) {
        return Err(bad(i, c, what.to_string()));
    }
    if let Some((i, c)) = r.pixels.iter().enumerate().find_map(|(i, p)| {
        p.iter()
            .position(|v| v.abs() > f32::MAX as f64)
            .map(|c| (i, c))
    }) {
        return Err(bad(
            i,
            c,
            format!("{:e}, beyond float32 range", r.pixels[i][c]),
        ));
    }
    Ok(r.pixels.iter().map(|p| p.map(|v| v as f32)).collect())
}

/// Loads a material JSON file (`{"name": ..., "ctrl": [108 numbers]}`).
pub fn load_material(path: &Path) -> Result<Material> {
    format_of(path, "a material", &[Format::Json])?;
    json::read_material(path)
}
