//! JPEG photos: baseline and progressive, grey, RGB and CMYK/YCCK decoded to 8-bit RGB
//! (zune-jpeg), then sRGB-decoded to linear by the callers.

use std::path::Path;

use zune_core::bytestream::ZCursor;
use zune_core::colorspace::ColorSpace;
use zune_core::options::DecoderOptions;
use zune_jpeg::JpegDecoder;

use crate::error::{Error, Result};
use crate::io::source::MAX_IMAGE_SIDE;

/// A decoded JPEG: width, height and 8-bit RGB samples, row-major, row 0 at the top.
pub type Rgb8 = (usize, usize, Vec<u8>);

/// A JPEG's width and height, from its headers alone.
pub fn dimensions(path: &Path, bytes: &[u8]) -> Result<(usize, usize)> {
    let mut decoder = JpegDecoder::new(ZCursor::new(bytes));
    decoder
        .decode_headers()
        .map_err(|e| Error::file(path, format!("not a readable JPEG: {e}")))?;
    decoder
        .dimensions()
        .ok_or_else(|| Error::file(path, "not a readable JPEG: no header"))
}

/// Decodes a JPEG file's bytes to 8-bit RGB; `path` names the file in errors.
pub fn decode_bytes(path: &Path, bytes: &[u8]) -> Result<Rgb8> {
    let options = DecoderOptions::default()
        .jpeg_set_out_colorspace(ColorSpace::RGB)
        .set_max_width(MAX_IMAGE_SIDE)
        .set_max_height(MAX_IMAGE_SIDE);
    let mut decoder = JpegDecoder::new_with_options(ZCursor::new(bytes), options);
    let pixels = decoder
        .decode()
        .map_err(|e| Error::file(path, format!("not a readable JPEG: {e}")))?;
    let info = decoder
        .info()
        .ok_or_else(|| Error::file(path, "not a readable JPEG: no header"))?;
    let (w, h) = (usize::from(info.width), usize::from(info.height));
    if w == 0 || h == 0 || pixels.len() != w * h * 3 {
        return Err(Error::file(
            path,
            format!(
                "not a readable JPEG: {} samples for {w} x {h} RGB pixels",
                pixels.len()
            ),
        ));
    }
    Ok((w, h, pixels))
}

/// 8-bit RGB through a JPEG of quality `q` (jpeg-encoder: 4:2:0 below 90, 4:4:4 from 90)
/// and back (zune-jpeg, the decoder photos go through).
pub fn round_trip(rgb: &[u8], w: usize, h: usize, q: u8) -> Result<Vec<u8>> {
    let fail = |m: String| Error::Invalid(format!("JPEG round trip: {m}"));
    let (w16, h16) = match (u16::try_from(w), u16::try_from(h)) {
        (Ok(a), Ok(b)) => (a, b),
        _ => return Err(fail(format!("{w} x {h} is larger than JPEG allows"))),
    };
    let mut bytes = Vec::new();
    jpeg_encoder::Encoder::new(&mut bytes, q)
        .encode(rgb, w16, h16, jpeg_encoder::ColorType::Rgb)
        .map_err(|e| fail(e.to_string()))?;
    let (dw, dh, out) = decode_bytes(std::path::Path::new("camera_effects.jpeg"), &bytes)?;
    if (dw, dh) != (w, h) {
        return Err(fail(format!("decoded {dw} x {dh} for {w} x {h}")));
    }
    Ok(out)
}
