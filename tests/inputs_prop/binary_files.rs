//! Valid NPY, EXR, PNG and MERL files, and ones whose header fields are odd.

use std::io::Cursor;

use exr::prelude::{self as ex, WritableImage};
use matedit::io::npy;
use proptest::prelude::*;
use proptest::sample::select;

use crate::mutations::{exr_attr, patch_ihdr, put, value};

pub(crate) fn npy_bytes(version: u8, header: &str, data: &[u8]) -> Vec<u8> {
    let prefix = if version == 1 { 10 } else { 12 };
    let mut h = header.to_string();
    h.push_str(&" ".repeat((64 - (prefix + h.len() + 1) % 64) % 64));
    h.push('\n');
    let mut out = b"\x93NUMPY".to_vec();
    out.extend([version, 0]);
    if version == 1 {
        out.extend((h.len() as u16).to_le_bytes());
    } else {
        out.extend((h.len() as u32).to_le_bytes());
    }
    out.extend(h.as_bytes());
    out.extend(data);
    out
}

pub(crate) fn npy_header(descr: &str, fortran: &str, shape: &str) -> String {
    format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}")
}

pub(crate) fn npy_data(descr: &str, values: &[f64]) -> Vec<u8> {
    values
        .iter()
        .flat_map(|&v| match descr {
            "<f4" => (v as f32).to_le_bytes().to_vec(),
            ">f4" => (v as f32).to_be_bytes().to_vec(),
            ">f8" => v.to_be_bytes().to_vec(),
            _ => v.to_le_bytes().to_vec(),
        })
        .collect()
}

/// A valid .npy file: float32 or float64, either byte order, C or Fortran order, format
/// version 1 to 3, shape (H, W, 3), (H, W) or another.
pub(crate) fn npy_file() -> impl Strategy<Value = Vec<u8>> {
    let shape = prop_oneof![
        (1usize..5, 1usize..5).prop_map(|(h, w)| vec![h, w, 3]),
        (1usize..5, 1usize..5).prop_map(|(h, w)| vec![h, w]),
        prop::collection::vec(0usize..4, 0..4),
    ];
    let descr = select(&["<f4", ">f4", "<f8", ">f8"][..]);
    (shape, descr, any::<bool>(), 1u8..=3).prop_flat_map(|(shape, descr, fortran, version)| {
        let n = shape.iter().product::<usize>();
        prop::collection::vec(value(), n).prop_map(move |v| {
            let f = if fortran { "True" } else { "False" };
            let header = npy_header(descr, f, &npy::shape_str(&shape));
            npy_bytes(version, &header, &npy_data(descr, &v))
        })
    })
}

/// A .npy file whose header fields are odd: sizes up to usize::MAX, malformed tuples,
/// unknown dtypes and versions, a wrong header length.
pub(crate) fn npy_mutant() -> impl Strategy<Value = Vec<u8>> {
    let size = prop_oneof![
        0usize..5,
        select(&[3, 1 << 20, 1 << 31, 1 << 40, 1 << 62, usize::MAX][..])
    ];
    let shape = prop_oneof![
        prop::collection::vec(size, 0..5).prop_map(|s| npy::shape_str(&s)),
        Just(format!("({})", "1, ".repeat(100))),
        select(
            &[
                "()",
                "(",
                "(3,",
                "(-1, 3)",
                "(1L, 2L, 3L)",
                "[2, 2]",
                "(2 2)",
                "(,)",
                "(99999999999999999999999,)",
                "",
            ][..]
        )
        .prop_map(String::from),
    ];
    let descr = select(&["<f4", ">f8", "<f2", "<i4", "|u1", "O", "", "f4", "<f4'"][..]);
    let fortran = select(&["True", "False", "1", "'True'", ""][..]);
    (
        shape,
        descr,
        fortran,
        0u8..5,
        prop::collection::vec(any::<u8>(), 0..200),
        prop::option::of(any::<u32>()),
    )
        .prop_map(|(shape, descr, fortran, version, data, len)| {
            let mut b = npy_bytes(version, &npy_header(descr, fortran, &shape), &data);
            if let Some(len) = len {
                put(
                    &mut b,
                    8,
                    &len.to_le_bytes()[..if version == 1 { 2 } else { 4 }],
                );
            }
            b
        })
}

const EXR_COMPRESSIONS: [ex::Compression; 10] = [
    ex::Compression::Uncompressed,
    ex::Compression::RLE,
    ex::Compression::ZIP1,
    ex::Compression::ZIP16,
    ex::Compression::PIZ,
    ex::Compression::PXR24,
    ex::Compression::B44,
    ex::Compression::B44A,
    ex::Compression::DWAA(None),
    ex::Compression::DWAB(None),
];

/// An RGB EXR written by the `exr` crate: f32 or f16 samples, scan lines or 2 x 2 tiles.
pub(crate) fn exr_bytes(
    w: usize,
    h: usize,
    px: &[[f32; 3]],
    compression: ex::Compression,
    half: bool,
    tiles: bool,
) -> Vec<u8> {
    let blocks = if tiles {
        ex::Blocks::Tiles(ex::Vec2(2, 2))
    } else {
        ex::Blocks::ScanLines
    };
    let encoding = ex::Encoding {
        compression,
        blocks,
        line_order: ex::LineOrder::Increasing,
    };
    let mut out = Cursor::new(Vec::new());
    let at = |p: ex::Vec2<usize>| px[p.y() * w + p.x()];
    let written = if half {
        let ch = ex::SpecificChannels::rgb(|p| at(p).map(ex::f16::from_f32).into());
        let layer = ex::Layer::new((w, h), ex::LayerAttributes::default(), encoding, ch);
        ex::Image::from_layer(layer).write().to_buffered(&mut out)
    } else {
        let ch = ex::SpecificChannels::rgb(|p| at(p).into());
        let layer = ex::Layer::new((w, h), ex::LayerAttributes::default(), encoding, ch);
        ex::Image::from_layer(layer).write().to_buffered(&mut out)
    };
    written.expect("write exr");
    out.into_inner()
}

pub(crate) fn pixels(n: usize) -> impl Strategy<Value = Vec<[f32; 3]>> {
    prop::collection::vec(prop::array::uniform3(-2.0f32..2.0), n)
}

/// A valid EXR: 1 to 6 pixels a side, every compression, f32 or f16, scan lines or tiles.
pub(crate) fn exr_file() -> impl Strategy<Value = Vec<u8>> {
    (
        1usize..7,
        1usize..7,
        0..EXR_COMPRESSIONS.len(),
        any::<bool>(),
        any::<bool>(),
    )
        .prop_flat_map(|(w, h, c, half, tiles)| {
            pixels(w * h).prop_map(move |px| exr_bytes(w, h, &px, EXR_COMPRESSIONS[c], half, tiles))
        })
}

const EXR_INTS: &[i32] = &[
    0,
    1,
    -1,
    2,
    5,
    255,
    4095,
    15999,
    16383,
    65535,
    1 << 20,
    i32::MAX,
    i32::MIN,
];

/// A valid EXR with odd header fields: data and display windows, compression, channel
/// types and sampling, line order, tile description.
pub(crate) fn exr_mutant() -> impl Strategy<Value = Vec<u8>> {
    let int = prop_oneof![select(EXR_INTS), any::<i32>()];
    (
        exr_file(),
        prop::option::of(prop::array::uniform4(int.clone())),
        any::<bool>(),
        prop::option::of(any::<u8>()),
        prop::option::of((0usize..3, int.clone(), 0usize..3)),
        prop::option::of(any::<u8>()),
        prop::option::of((int.clone(), int, any::<u8>())),
    )
        .prop_map(|(mut b, window, display, comp, chan, order, tile)| {
            if let Some(win) = window {
                let v: Vec<u8> = win.iter().flat_map(|i| i.to_le_bytes()).collect();
                let names: &[&str] = if display {
                    &["dataWindow", "displayWindow"]
                } else {
                    &["dataWindow"]
                };
                for name in names {
                    if let Some(at) = exr_attr(&b, name, "box2i") {
                        put(&mut b, at, &v);
                    }
                }
            }
            if let (Some(c), Some(at)) = (comp, exr_attr(&b, "compression", "compression")) {
                put(&mut b, at, &[c]);
            }
            // channel k's entry: "B\0" / "G\0" / "R\0", type i32, pLinear, 3 reserved,
            // x and y sampling i32
            if let (Some((k, v, field)), Some(at)) = (chan, exr_attr(&b, "channels", "chlist")) {
                put(
                    &mut b,
                    at + 18 * k + 2 + [0, 8, 12][field],
                    &v.to_le_bytes(),
                );
            }
            if let (Some(o), Some(at)) = (order, exr_attr(&b, "lineOrder", "lineOrder")) {
                put(&mut b, at, &[o]);
            }
            if let (Some((x, y, mode)), Some(at)) = (tile, exr_attr(&b, "tiles", "tiledesc")) {
                put(&mut b, at, &x.to_le_bytes());
                put(&mut b, at + 4, &y.to_le_bytes());
                put(&mut b, at + 8, &[mode]);
            }
            b
        })
}

/// Colour type and bit depth pairs PNG allows.
const PNG_KINDS: &[(png::ColorType, png::BitDepth)] = &[
    (png::ColorType::Grayscale, png::BitDepth::One),
    (png::ColorType::Grayscale, png::BitDepth::Four),
    (png::ColorType::Grayscale, png::BitDepth::Eight),
    (png::ColorType::Grayscale, png::BitDepth::Sixteen),
    (png::ColorType::GrayscaleAlpha, png::BitDepth::Eight),
    (png::ColorType::Rgb, png::BitDepth::Eight),
    (png::ColorType::Rgb, png::BitDepth::Sixteen),
    (png::ColorType::Rgba, png::BitDepth::Eight),
    (png::ColorType::Rgba, png::BitDepth::Sixteen),
    (png::ColorType::Indexed, png::BitDepth::Two),
    (png::ColorType::Indexed, png::BitDepth::Eight),
];

/// A valid PNG of every colour type (palettes of 4 entries, so that 8-bit indices can
/// point past them).
pub(crate) fn png_file() -> impl Strategy<Value = Vec<u8>> {
    (1u32..7, 1u32..7, select(PNG_KINDS)).prop_flat_map(|(w, h, (colour, depth))| {
        let row = (w as usize * colour.samples() * depth as usize).div_ceil(8);
        prop::collection::vec(any::<u8>(), row * h as usize).prop_map(move |data| {
            let mut out = Vec::new();
            let mut enc = png::Encoder::new(&mut out, w, h);
            enc.set_color(colour);
            enc.set_depth(depth);
            if colour == png::ColorType::Indexed {
                enc.set_palette(vec![0, 0, 0, 255, 0, 0, 0, 255, 0, 0, 0, 255]);
            }
            let mut wr = enc.write_header().expect("png header");
            wr.write_image_data(&data).expect("png data");
            wr.finish().expect("png end");
            out
        })
    })
}

/// A valid PNG whose header says another size, depth, colour type or interlacing (with
/// the header's CRC fixed, so that the decoder reads it).
pub(crate) fn png_mutant() -> impl Strategy<Value = Vec<u8>> {
    let side = prop_oneof![
        0u32..8,
        select(&[1000, 16384, 30000, (1 << 31) - 1, 1 << 31, u32::MAX][..]),
        any::<u32>(),
    ];
    (
        png_file(),
        side.clone(),
        side,
        select(&[0u8, 1, 2, 3, 4, 8, 16, 255][..]),
        select(&[0u8, 1, 2, 3, 4, 5, 6, 7][..]),
        0u8..3,
    )
        .prop_map(|(mut b, w, h, depth, colour, interlace)| {
            patch_ihdr(&mut b, w, h, depth, colour, interlace);
            b
        })
}

/// A valid MERL table of 1 to 3 cells per axis, some cells unmeasured (negative).
pub(crate) fn merl_file() -> impl Strategy<Value = Vec<u8>> {
    (1i32..4, 1i32..4, 1i32..4).prop_flat_map(|(a, b, c)| {
        prop::collection::vec(
            prop_oneof![0.0..5.0f64, Just(-1.0)],
            3 * (a * b * c) as usize,
        )
        .prop_map(move |v| {
            let mut out: Vec<u8> = [a, b, c].iter().flat_map(|d| d.to_le_bytes()).collect();
            out.extend(v.iter().flat_map(|x| (x * 1500.0).to_le_bytes()));
            out
        })
    })
}

/// A valid MERL table whose header claims other dimensions.
pub(crate) fn merl_mutant() -> impl Strategy<Value = Vec<u8>> {
    let dim = prop_oneof![
        select(&[0, 1, 2, 90, 180, 1024, 1025, -1, i32::MAX, i32::MIN][..]),
        any::<i32>()
    ];
    (merl_file(), 0usize..3, dim).prop_map(|(mut b, k, d)| {
        put(&mut b, 4 * k, &d.to_le_bytes());
        b
    })
}
