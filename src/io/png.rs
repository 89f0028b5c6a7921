//! PNG files: 8-bit (or 16-bit) normal maps in, 8-bit sRGB previews of linear renders out,
//! 8-bit normal maps (RGBA, alpha the mask) and masks out.
//!
//! Normal maps: channel value v (0..=255, or 0..=65535 for 16-bit files) encodes
//! n = 2 v / max - 1. A pixel with alpha 0, or with R = G = B = 0, is background.
//!
//! Previews: each linear channel value v becomes `v * 2^exposure`, then the tonemap
//! (`clamp`: unchanged; `reinhard`: x / (1 + x)), then it is clamped to [0, 1], encoded
//! with the sRGB transfer function and rounded to 8 bits.

use std::io::Cursor;
use std::path::Path;

use rayon::prelude::*;

use crate::error::{Error, Result};
use crate::scene::{Image, NormalMap};

/// How linear radiance is mapped to display values in a preview.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Tonemap {
    /// Values above 1 (after exposure) clip to white.
    #[default]
    Clamp,
    /// x / (1 + x) per channel: nothing clips, highlights compress.
    Reinhard,
}

impl std::str::FromStr for Tonemap {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "clamp" => Ok(Tonemap::Clamp),
            "reinhard" => Ok(Tonemap::Reinhard),
            _ => Err(format!(
                "unknown tonemap '{s}': expected 'clamp' or 'reinhard'"
            )),
        }
    }
}

/// Settings for 8-bit previews.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Preview {
    /// Exposure in stops: values are multiplied by 2^exposure before the tonemap.
    pub exposure: f32,
    /// The tonemap applied after the exposure.
    pub tonemap: Tonemap,
}

/// The sRGB transfer function (linear [0, 1] to encoded [0, 1]).
pub fn srgb_encode(x: f32) -> f32 {
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// The inverse of [`srgb_encode`]: an sRGB-encoded value in [0, 1] to linear.
pub fn srgb_decode(x: f32) -> f32 {
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// The 8-bit display value of linear channel value `v` under `preview`.
pub fn display_value(v: f32, preview: &Preview) -> u8 {
    code_of(tonemapped(v, preview))
}

/// `v` after the exposure and the tonemap, in [0, 1].
fn tonemapped(v: f32, preview: &Preview) -> f32 {
    tonemapped_scaled(v * preview.exposure.exp2(), preview.tonemap)
}

/// [`tonemapped`] of `v` whose exposure `x = v 2^exposure` is given.
fn tonemapped_scaled(x: f32, tonemap: Tonemap) -> f32 {
    let y = match tonemap {
        Tonemap::Clamp => x,
        Tonemap::Reinhard => x / (1.0 + x),
    };
    // NaN fails both comparisons in clamp's guard, so map it to 0 explicitly.
    if y.is_nan() { 0.0 } else { y.clamp(0.0, 1.0) }
}

/// The 8-bit sRGB code of a display value `y` in [0, 1].
fn code_of(y: f32) -> u8 {
    (srgb_encode(y) * 255.0).round() as u8
}

/// The smallest display value of each code 1 to 255 ([`code_of`] is non-decreasing: a
/// test sweeps it), found by bisection on the bits of the f32s in [0, 1], which order as
/// their values.
fn code_steps() -> &'static [f32; 255] {
    static STEPS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    STEPS.get_or_init(|| {
        std::array::from_fn(|c| {
            let (mut lo, mut hi) = (0u32, 1.0f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if usize::from(code_of(f32::from_bits(mid))) > c {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            f32::from_bits(lo)
        })
    })
}

/// Encodes an 8-bit sRGB RGB preview of a linear image.
pub fn encode_preview(image: &Image, preview: &Preview) -> Result<Vec<u8>> {
    encode_rgb8(image.width, image.height, &display_bytes(image, preview))
}

/// Buckets of [`code_start`]: [0, 1] cut into this many equal parts.
const CODE_BUCKETS: usize = 4096;

/// The code of each bucket's lower end: the code of a value in bucket i is at least
/// `code_start()[i]`, and one or two steps of [`code_steps`] more at most (the steepest part
/// of the sRGB curve, near 0, spans 0.8 codes a bucket).
fn code_start() -> &'static [u8; CODE_BUCKETS + 1] {
    static START: std::sync::OnceLock<[u8; CODE_BUCKETS + 1]> = std::sync::OnceLock::new();
    START.get_or_init(|| {
        let steps = code_steps();
        std::array::from_fn(|i| {
            let lo = i as f32 / CODE_BUCKETS as f32;
            steps.partition_point(|&t| t <= lo) as u8
        })
    })
}

/// The 8-bit display values of a linear image's pixels, 3 bytes a pixel (rows in
/// parallel: a 12-megapixel photo has 36 million values).
pub fn display_bytes(image: &Image, preview: &Preview) -> Vec<u8> {
    let mut out = vec![0u8; 3 * image.pixels.len()];
    let row = 3 * image.width.max(1);
    let scale = preview.exposure.exp2();
    out.par_chunks_mut(row)
        .zip(image.pixels.par_chunks(image.width.max(1)))
        .for_each(|(o, p)| {
            // the code is how many steps the value reaches, found from its bucket's first
            // code: no powf and no search per value
            let (steps, start) = (code_steps(), code_start());
            for (o, v) in o.iter_mut().zip(p.iter().flatten()) {
                let y = tonemapped_scaled(*v * scale, preview.tonemap);
                let mut c = usize::from(start[(y * CODE_BUCKETS as f32) as usize]);
                while c < steps.len() && steps[c] <= y {
                    c += 1;
                }
                *o = c as u8;
            }
        });
    out
}

/// Encodes 8-bit RGB data (row-major, 3 bytes a pixel) as a PNG tagged sRGB.
pub fn encode_rgb8(width: usize, height: usize, data: &[u8]) -> Result<Vec<u8>> {
    encode8(width, height, png::ColorType::Rgb, data, true)
}

/// Encodes a normal map as 8-bit RGBA, v = round((n + 1) / 2 * 255) per channel (the
/// inverse of the loader's n = 2 v / 255 - 1), alpha 255 where `mask` is set; background
/// pixels are [0, 0, 0, 0]. Not tagged sRGB: the values are vectors, not colours.
pub fn encode_normals(map: &NormalMap, mask: &[bool]) -> Result<Vec<u8>> {
    let data: Vec<u8> = map
        .normals
        .iter()
        .zip(mask)
        .flat_map(|(n, &fg)| {
            if fg {
                let v = n.map(|c| ((c.clamp(-1.0, 1.0) + 1.0) / 2.0 * 255.0).round() as u8);
                [v[0], v[1], v[2], 255]
            } else {
                [0; 4]
            }
        })
        .collect();
    encode8(map.width, map.height, png::ColorType::Rgba, &data, false)
}

/// Encodes a mask as an 8-bit greyscale PNG: 255 where set, 0 elsewhere.
pub fn encode_mask(width: usize, height: usize, mask: &[bool]) -> Result<Vec<u8>> {
    let data: Vec<u8> = mask.iter().map(|&m| if m { 255 } else { 0 }).collect();
    encode8(width, height, png::ColorType::Grayscale, &data, false)
}

fn encode8(
    width: usize,
    height: usize,
    color: png::ColorType,
    data: &[u8],
    srgb: bool,
) -> Result<Vec<u8>> {
    let (w, h) = (
        u32::try_from(width)
            .map_err(|_| Error::Invalid(format!("PNG width {width} is too large")))?,
        u32::try_from(height)
            .map_err(|_| Error::Invalid(format!("PNG height {height} is too large")))?,
    );
    let mut out = Vec::new();
    let mut enc = png::Encoder::new(&mut out, w, h);
    enc.set_color(color);
    enc.set_depth(png::BitDepth::Eight);
    // fdeflate's PNG-tuned DEFLATE: a 12-megapixel mask or a photo-sized picture in a
    // fraction of the default level's time, files a little larger
    enc.set_compression(png::Compression::Fast);
    if srgb {
        enc.set_source_srgb(png::SrgbRenderingIntent::Perceptual);
    }
    let mut writer = enc
        .write_header()
        .map_err(|e| Error::Invalid(format!("cannot encode PNG: {e}")))?;
    writer
        .write_image_data(data)
        .map_err(|e| Error::Invalid(format!("cannot encode PNG: {e}")))?;
    writer
        .finish()
        .map_err(|e| Error::Invalid(format!("cannot encode PNG: {e}")))?;
    Ok(out)
}

/// A decoded PNG: 8- or 16-bit samples widened to u16, with the maximum value.
#[derive(Clone, Debug, PartialEq)]
pub struct Decoded {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Channels per pixel after palette expansion: 1 (grey), 2 (grey, alpha), 3 (RGB) or
    /// 4 (RGBA).
    pub channels: usize,
    /// 8 or 16.
    pub bit_depth: u8,
    /// Samples, row-major, `channels` per pixel.
    pub samples: Vec<u16>,
}

impl Decoded {
    /// The largest sample value of the bit depth (255 or 65535).
    pub fn max_value(&self) -> f64 {
        if self.bit_depth == 16 { 65535.0 } else { 255.0 }
    }
}

/// Decodes a PNG file (palette and low bit depths expanded to 8 bits).
pub fn decode(path: &Path) -> Result<Decoded> {
    decode_bytes(path, &super::read_bytes(path)?)
}

/// The most bytes zlib can inflate one byte to (a 258-byte match in 2 bits).
const MAX_INFLATE: u64 = 1032;

/// [`decode`] on a file's bytes; `path` names the file in errors.
pub fn decode_bytes(path: &Path, bytes: &[u8]) -> Result<Decoded> {
    let bad = |e: png::DecodingError| Error::file(path, format!("not a readable PNG file: {e}"));
    // The default 64 MiB limit refuses 16-bit RGBA maps above ~2800 x 2800; allow 1 GiB.
    let limits = png::Limits { bytes: 1 << 30 };
    let mut dec = png::Decoder::new_with_limits(Cursor::new(bytes), limits);
    dec.set_transformations(png::Transformations::EXPAND);
    let mut reader = dec.read_info().map_err(bad)?;
    // The pixels are zlib data inside the file: a header that claims more than the file's
    // bytes can inflate to is refused before the image buffer is allocated.
    let info = reader.info();
    let bits = [
        info.color_type.samples() as u64,
        info.bit_depth as u64,
        u64::from(info.height),
    ]
    .into_iter()
    .fold(u64::from(info.width), u64::saturating_mul);
    if bits / 8 > bytes.len() as u64 * MAX_INFLATE {
        return Err(Error::file(
            path,
            format!(
                "the PNG header claims {} wide x {} high, more than a {}-byte file can hold",
                info.width,
                info.height,
                bytes.len()
            ),
        ));
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| Error::file(path, "PNG image is too large"))?;
    let mut buf = vec![0u8; size];
    let info = reader.next_frame(&mut buf).map_err(bad)?;
    let channels = info.color_type.samples();
    let (width, height) = (info.width as usize, info.height as usize);
    let bit_depth = match info.bit_depth {
        png::BitDepth::Sixteen => 16,
        _ => 8,
    };
    let mut samples = Vec::with_capacity(width * height * channels);
    for row in buf.chunks(info.line_size).take(height) {
        if bit_depth == 16 {
            samples.extend(
                row.chunks_exact(2)
                    .take(width * channels)
                    .map(|c| u16::from_be_bytes([c[0], c[1]])),
            );
        } else {
            samples.extend(row.iter().take(width * channels).map(|&v| v as u16));
        }
    }
    Ok(Decoded {
        width,
        height,
        channels,
        bit_depth,
        samples,
    })
}

/// Reads a PNG normal map: n = 2 v / max - 1 per channel, background (returned as
/// [0, 0, 0]) where alpha is 0 or R = G = B = 0. Normals are not yet normalised.
pub fn read_normals(path: &Path) -> Result<(usize, usize, Vec<[f64; 3]>)> {
    normals_of(path, &decode(path)?)
}

/// [`read_normals`] on a decoded PNG; `path` names the file in errors.
pub fn normals_of(path: &Path, d: &Decoded) -> Result<(usize, usize, Vec<[f64; 3]>)> {
    if d.channels < 3 {
        return Err(Error::file(
            path,
            "the PNG is greyscale; a normal map needs RGB channels (n.x, n.y, n.z)",
        ));
    }
    let max = d.max_value();
    let normals = d
        .samples
        .chunks_exact(d.channels)
        .map(|p| {
            let transparent = d.channels == 4 && p[3] == 0;
            if transparent || (p[0] == 0 && p[1] == 0 && p[2] == 0) {
                [0.0; 3]
            } else {
                [0, 1, 2].map(|c| 2.0 * p[c] as f64 / max - 1.0)
            }
        })
        .collect();
    Ok((d.width, d.height, normals))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn display_values() {
        let p = Preview::default();
        assert_eq!(display_value(0.0, &p), 0);
        assert_eq!(display_value(1.0, &p), 255);
        assert_eq!(display_value(7.0, &p), 255);
        assert_eq!(display_value(-1.0, &p), 0);
        assert_eq!(display_value(f32::NAN, &p), 0);
        // 0.5 linear is 0.7354 in sRGB: 188.
        assert_eq!(display_value(0.5, &p), 188);
        // one stop down: 1.0 -> 0.5
        let dark = Preview {
            exposure: -1.0,
            ..p
        };
        assert_eq!(display_value(1.0, &dark), 188);
        // Reinhard: 1.0 -> 0.5
        let r = Preview {
            tonemap: Tonemap::Reinhard,
            ..p
        };
        assert_eq!(display_value(1.0, &r), 188);
    }

    #[test]
    fn display_bytes_are_the_display_values() {
        // every 997th f32 in [0, 1] and the values around each code's step, in order:
        // the table needs the code to be non-decreasing in the value
        let mut values: Vec<f32> = (0..1.0f32.to_bits())
            .step_by(997)
            .map(f32::from_bits)
            .collect();
        for &t in code_steps() {
            values.extend((t.to_bits() - 2..=t.to_bits() + 2).map(f32::from_bits));
        }
        values.sort_by(f32::total_cmp);
        assert!(
            values
                .windows(2)
                .all(|w| code_of(w[0].min(1.0)) <= code_of(w[1].min(1.0)))
        );
        values.extend([-1.0, 2.0, f32::NAN, f32::INFINITY]);
        for preview in [
            Preview::default(),
            Preview {
                exposure: -1.5,
                tonemap: Tonemap::Reinhard,
            },
        ] {
            let image = Image {
                width: values.len().div_ceil(3),
                height: 1,
                pixels: values
                    .chunks(3)
                    .map(|c| std::array::from_fn(|k| c.get(k).copied().unwrap_or(0.0)))
                    .collect(),
            };
            let want: Vec<u8> = image
                .pixels
                .iter()
                .flat_map(|p| p.map(|v| display_value(v, &preview)))
                .collect();
            assert_eq!(display_bytes(&image, &preview), want);
        }
    }
}
