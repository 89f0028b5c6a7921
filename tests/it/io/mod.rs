//! Round trips and error messages of the file readers and writers in `matedit::io`, on
//! small files made here (nothing from ../shared).

mod files;
mod formats;
mod info;
mod inputs;

use std::path::Path;

use exr::prelude::*;
use matedit::{Error, Image};

pub(super) fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

pub(super) fn msg(e: Error) -> String {
    e.to_string()
}

/// A small image with varied values, negative ones included.
pub(super) fn image(w: usize, h: usize) -> Image {
    Image {
        width: w,
        height: h,
        pixels: (0..w * h)
            .map(|i| {
                let t = i as f32;
                [t * 0.25 - 1.0, (t * 0.37).sin() * 3.0, 1.0e3 + t]
            })
            .collect(),
    }
}

/// Writes an EXR with the exr crate: RGB f32 in the given compression.
pub(super) fn write_exr(path: &Path, img: &Image, compression: Compression) {
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let p = img.pixels[pos.y() * img.width + pos.x()];
        (p[0], p[1], p[2])
    });
    let encoding = Encoding {
        compression,
        blocks: Blocks::ScanLines,
        line_order: LineOrder::Increasing,
    };
    let layer = Layer::new(
        (img.width, img.height),
        LayerAttributes::default(),
        encoding,
        channels,
    );
    exr::prelude::Image::from_layer(layer)
        .write()
        .to_file(path)
        .expect("write exr");
}

/// Sets the compression byte of an EXR file's first header to `code`.
pub(super) fn patch_compression(path: &Path, code: u8) {
    let mut bytes = std::fs::read(path).unwrap();
    let key = b"compression\0compression\0";
    let at = bytes
        .windows(key.len())
        .position(|w| w == key)
        .expect("compression attribute");
    let value = at + key.len() + 4; // after the i32 size
    bytes[value] = code;
    std::fs::write(path, bytes).unwrap();
}
