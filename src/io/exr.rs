//! OpenEXR files through the `exr` crate: RGB reading (any sample type, the first layer,
//! channels `R`, `G`, `B`), header inspection, and float32 RGB writing (ZIP compressed).
//!
//! The compression is checked before any pixel is decoded, so that a file in a
//! compression the decoder lacks (HTJ2K, or a code it does not know) gets an error that
//! names the compression and says how to convert the file, never a panic or garbage.

use std::io::Cursor;
use std::path::Path;

use exr::meta::MetaData;
use exr::meta::attribute::{Compression, SampleType};
use exr::prelude::*;

use super::Raster;
use crate::error::{Error, Result};

/// Largest image read, in pixels (16384 x 16384): a guard against headers that claim
/// sizes no memory can hold.
pub const MAX_PIXELS: usize = 1 << 28;

/// What the header of one layer (part) of an EXR file says.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerInfo {
    /// The layer name, if any.
    pub name: Option<String>,
    /// Data window width.
    pub width: usize,
    /// Data window height.
    pub height: usize,
    /// The compression, as the `exr` crate names it.
    pub compression: String,
    /// Channel names and sample types (`f16`, `f32`, `u32`).
    pub channels: Vec<(String, &'static str)>,
    /// Whether the layer holds deep data (not readable by matedit).
    pub deep: bool,
}

/// The OpenEXR name of compression code `code` (the byte in the header).
pub fn compression_name(code: u8) -> String {
    match code {
        0 => "NONE".into(),
        1 => "RLE".into(),
        2 => "ZIPS".into(),
        3 => "ZIP".into(),
        4 => "PIZ".into(),
        5 => "PXR24".into(),
        6 => "B44".into(),
        7 => "B44A".into(),
        8 => "DWAA".into(),
        9 => "DWAB".into(),
        10 => "HTJ2K256".into(),
        11 => "HTJ2K32".into(),
        c => format!("unknown (code {c})"),
    }
}

/// Whether the decoder can read pixels stored with compression `code`.
pub fn compression_supported(code: u8) -> bool {
    code <= 9
}

fn unsupported_compression(path: &Path, code: u8) -> Error {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "in".into());
    let file = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "in.exr".into());
    Error::file(
        path,
        format!(
            "EXR compression {} is not supported (matedit reads NONE, RLE, ZIPS, ZIP, PIZ, \
             PXR24, B44, B44A, DWAA, DWAB); convert the file first, e.g. \
             `oiiotool {file} --compression zip -o {stem}-zip.exr`",
            compression_name(code)
        ),
    )
}

/// The compression code of the first header, read straight from the bytes, so that it is
/// known even where the `exr` crate refuses the header. `None` if the bytes are not an
/// EXR header or have no compression attribute.
pub fn raw_compression_code(bytes: &[u8]) -> Option<u8> {
    if bytes.len() < 8 || bytes[..4] != [0x76, 0x2f, 0x31, 0x01] {
        return None;
    }
    let mut pos = 8;
    let cstr = |pos: &mut usize| -> Option<&[u8]> {
        let start = *pos;
        let len = bytes.get(start..)?.iter().take(256).position(|&b| b == 0)?;
        *pos = start + len + 1;
        Some(&bytes[start..start + len])
    };
    loop {
        let name = cstr(&mut pos)?;
        if name.is_empty() {
            return None;
        }
        let ty = cstr(&mut pos)?;
        let size = i32::from_le_bytes(bytes.get(pos..pos + 4)?.try_into().ok()?);
        pos += 4;
        let size = usize::try_from(size).ok()?;
        if name == b"compression" && ty == b"compression" && size == 1 {
            return bytes.get(pos).copied();
        }
        pos = pos.checked_add(size)?;
    }
}

fn sample_type_name(t: SampleType) -> &'static str {
    match t {
        SampleType::F16 => "f16",
        SampleType::F32 => "f32",
        SampleType::U32 => "u32",
    }
}

fn compression_code(c: Compression) -> u8 {
    match c {
        Compression::Uncompressed => 0,
        Compression::RLE => 1,
        Compression::ZIP1 => 2,
        Compression::ZIP16 => 3,
        Compression::PIZ => 4,
        Compression::PXR24 => 5,
        Compression::B44 => 6,
        Compression::B44A => 7,
        Compression::DWAA(_) => 8,
        Compression::DWAB(_) => 9,
        Compression::HTJ2K256 => 10,
        Compression::HTJ2K32 => 11,
    }
}

/// Reads the headers of an EXR file held in `bytes` (no pixels), as the `exr` crate has them
/// and as [`LayerInfo`]s. Errors if a layer uses a compression the decoder lacks.
fn headers(path: &Path, bytes: &[u8]) -> Result<(MetaData, Vec<LayerInfo>)> {
    if let Some(code) = raw_compression_code(bytes)
        && !compression_supported(code)
    {
        return Err(unsupported_compression(path, code));
    }
    let meta = MetaData::read_from_buffered(Cursor::new(bytes), false)
        .map_err(|e| Error::file(path, format!("not a readable EXR file: {e}")))?;
    let mut layers = Vec::new();
    for h in &meta.headers {
        let code = compression_code(h.compression);
        if !compression_supported(code) {
            return Err(unsupported_compression(path, code));
        }
        layers.push(LayerInfo {
            name: h.own_attributes.layer_name.as_ref().map(|t| t.to_string()),
            width: h.layer_size.width(),
            height: h.layer_size.height(),
            compression: compression_name(code),
            channels: h
                .channels
                .list
                .iter()
                .map(|c| (c.name.to_string(), sample_type_name(c.sample_type)))
                .collect(),
            deep: h.deep,
        });
    }
    Ok((meta, layers))
}

/// The layers of an EXR file, from its headers alone.
pub fn read_info(path: &Path) -> Result<Vec<LayerInfo>> {
    let bytes = super::read_bytes(path)?;
    Ok(headers(path, &bytes)?.1)
}

/// Reads channels R, G, B of the first layer of an EXR file as a raster (row 0 at the
/// top). A layer named like `diffuse` with channels `diffuse.R` ... is accepted too.
pub fn read_rgb(path: &Path) -> Result<Raster> {
    decode_rgb(path, &super::read_bytes(path)?)
}

/// The most decoded bytes one byte of a file can hold under compression `code`: a bound
/// on the compressors' ratios, so that a header's size can be checked against the file's
/// before anything is allocated for it. NONE stores samples as they are; RLE codes at
/// most 127 bytes in 2; zlib (ZIPS, ZIP, and PXR24 after dropping a quarter of each
/// float32) at most 1032 bytes in 1, PIZ's Huffman coding less; B44 and B44A 32 bytes in
/// 3 at best; DWA keeps at least one zlib-coded 2-byte DC value per 8 x 8 block of halves
/// (64 x 1032), doubled for its other streams' slack.
fn max_expansion(code: u8) -> u64 {
    match code {
        0 => 1,
        1 => 64,
        2..=4 => 1032,
        5 => 1376,
        6 | 7 => 11,
        _ => 2 * 64 * 1032,
    }
}

/// Checks the first layer's size against the limit and against what `file_len` bytes in
/// its compression can hold, before the decoder allocates its samples (every channel at
/// the layer's size: the `exr` crate refuses subsampled channels).
fn check_size(path: &Path, header: &exr::meta::header::Header, file_len: usize) -> Result<()> {
    let (w, h) = (header.layer_size.width(), header.layer_size.height());
    if w.saturating_mul(h) > MAX_PIXELS {
        return Err(Error::file(
            path,
            format!(
                "the EXR image is {w} wide x {h} high, more than matedit reads ({MAX_PIXELS} pixels)"
            ),
        ));
    }
    let list = &header.channels.list;
    let per_pixel: u64 = list
        .iter()
        .map(|c| c.sample_type.bytes_per_sample() as u64)
        .sum();
    let stored = (w as u64 * h as u64).saturating_mul(per_pixel);
    let code = compression_code(header.compression);
    let most = (file_len as u64).saturating_mul(max_expansion(code));
    if stored > most {
        return Err(Error::file(
            path,
            format!(
                "the EXR header claims {w} wide x {h} high x {} channels ({stored} bytes of \
                 samples), more than a {file_len}-byte file in {} compression can hold",
                list.len(),
                compression_name(code)
            ),
        ));
    }
    Ok(())
}

/// The first layer's width and height, from the headers alone.
pub fn dimensions(path: &Path, bytes: &[u8]) -> Result<(usize, usize)> {
    let (_, layers) = headers(path, bytes)?;
    layers
        .first()
        .map(|l| (l.width, l.height))
        .ok_or_else(|| Error::file(path, "the EXR file has no layers"))
}

/// [`read_rgb`] on a file's bytes; `path` names the file in errors.
pub fn decode_rgb(path: &Path, bytes: &[u8]) -> Result<Raster> {
    let (meta, layers) = headers(path, bytes)?;
    let (Some(first), Some(header)) = (layers.first(), meta.headers.first()) else {
        return Err(Error::file(path, "the EXR file has no layers"));
    };
    if first.deep {
        return Err(Error::file(
            path,
            "the EXR file holds deep data; matedit reads flat images",
        ));
    }
    check_size(path, header, bytes.len())?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_buffered(Cursor::new(bytes))
        .map_err(|e| Error::file(path, format!("cannot decode the EXR pixels: {e}")))?;
    let layer = &image.layer_data;
    let (width, height) = (layer.size.width(), layer.size.height());
    let list = &layer.channel_data.list;
    let find = |suffix: &str| {
        list.iter().position(|c| {
            let name = c.name.to_string();
            name == suffix || name.ends_with(&format!(".{suffix}"))
        })
    };
    let (Some(r), Some(g), Some(b)) = (find("R"), find("G"), find("B")) else {
        let names: Vec<String> = list.iter().map(|c| c.name.to_string()).collect();
        return Err(Error::file(
            path,
            format!(
                "needs channels R, G, B; the file has {}",
                if names.is_empty() {
                    "none".to_string()
                } else {
                    names.join(", ")
                }
            ),
        ));
    };
    let n = width * height;
    let channel = |i: usize| -> Result<Vec<f32>> {
        let v: Vec<f32> = list[i].sample_data.values_as_f32().collect();
        if v.len() != n {
            return Err(Error::file(
                path,
                format!(
                    "channel {} has {} samples for a {width}x{height} image",
                    list[i].name,
                    v.len()
                ),
            ));
        }
        Ok(v)
    };
    let (rv, gv, bv) = (channel(r)?, channel(g)?, channel(b)?);
    let pixels = (0..n)
        .map(|i| [rv[i] as f64, gv[i] as f64, bv[i] as f64])
        .collect();
    Ok(Raster {
        width,
        height,
        pixels,
    })
}

/// Encodes a linear RGB float32 image as a ZIP-compressed scanline EXR.
pub fn encode_rgb(width: usize, height: usize, pixels: &[[f32; 3]]) -> Result<Vec<u8>> {
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = pixels[pos.y() * width + pos.x()];
        (p[0], p[1], p[2])
    });
    let encoding = Encoding {
        compression: Compression::ZIP16,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        (width, height),
        LayerAttributes::default(),
        encoding,
        channels,
    );
    let mut out = Cursor::new(Vec::new());
    Image::from_layer(layer)
        .write()
        .to_buffered(&mut out)
        .map_err(|e| Error::Invalid(format!("cannot encode EXR: {e}")))?;
    Ok(out.into_inner())
}
