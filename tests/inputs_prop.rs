//! Property tests (proptest) of every loader and validator:
//! - arbitrary bytes, and valid files with truncations, byte flips and header fields set to
//!   odd values, never panic: each loader gives Ok or one line naming the file;
//! - what the writers write (NPY, EXR, PNG, material JSON) reads back exactly;
//! - the validators accept a material, normals, env map or camera exactly when the limits
//!   of docs/CONVENTIONS.md hold, the loaders accept exactly the values they document, and
//!   what is accepted renders finite (fast CPU path and reference, tiny scenes);
//! - no loader allocates what a header claims before checking it against the file
//!   (a counting allocator watches the largest request).
//!
//! Failures proptest finds are kept in tests/inputs_prop.proptest-regressions and, as plain
//! tests, near the end of this file, with the inputs the fuzz targets (fuzz/) found, as
//! bytes. The last (ignored) test writes the fuzz targets' seeds.

use std::alloc::{GlobalAlloc, Layout, System};
use std::io::Cursor;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

use exr::prelude::{self as ex, WritableImage};
use matedit::brdf::{merl, nbrdf};
use matedit::envmap::MAX_RADIANCE;
use matedit::fit_brdf::job::Bundle;
use matedit::io::{self, EnvSize, npy};
use matedit::scene::MAX_NORMAL_LENGTH;
use matedit::{
    Batch, Camera, Convention, Device, EnvMap, Error, Material, NormalMap, Renderer, Scene,
};
use proptest::prelude::*;
use proptest::sample::{Index, select};
use proptest::test_runner::TestCaseError;
use serde_json::{Value, json};

// ---------------------------------------------------------------------------------------
// The loaders and what a clean result is

type Load = fn(&Path, &[u8]) -> matedit::Result<()>;

fn raster(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::raster_from_bytes(p, b, "a raster").map(drop)
}
fn normals(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::normals_from_bytes(p, b).map(drop)
}
/// As the command line loads a map: both conventions, brought to 1 x 1 (always a divisor)
/// and to the default size.
fn env(p: &Path, b: &[u8]) -> matedit::Result<()> {
    for c in [Convention::Paper, Convention::Equirect] {
        let e = io::env_from_bytes(p, b, c)?.env;
        io::resample::fit(
            e.clone(),
            EnvSize::Size {
                height: 1,
                width: 1,
            },
            p,
        )?;
        if c == Convention::Equirect {
            io::resample::fit(e, EnvSize::default(), p)?;
        }
    }
    Ok(())
}
fn png_image(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::png::decode_bytes(p, b).map(drop)
}
fn material(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::json::parse_material(p, b).map(drop)
}
fn manifest(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::manifest::parse(p, b, None).map(drop)
}
/// As `nbrdf::read` does after reading the file.
fn nbrdf_nets(p: &Path, b: &[u8]) -> matedit::Result<()> {
    let text = std::str::from_utf8(b).map_err(|e| Error::file(p, format!("cannot read: {e}")))?;
    nbrdf::parse(text).map(drop).map_err(|m| Error::file(p, m))
}
fn bundle(p: &Path, b: &[u8]) -> matedit::Result<()> {
    let text = std::str::from_utf8(b).map_err(|e| Error::file(p, format!("cannot read: {e}")))?;
    Bundle::parse(text).map(drop).map_err(|m| Error::file(p, m))
}
/// As `merl::read` does after reading the file.
fn merl_table(p: &Path, b: &[u8]) -> matedit::Result<()> {
    merl::parse(b, "t").map(drop).map_err(|m| Error::file(p, m))
}

/// Every loader on bytes, by the name of the file it is given (the extension picks the
/// format, as on the command line).
const LOADERS: &[(&str, Load)] = &[
    ("in/a.npy", raster),
    ("in/a.exr", raster),
    ("in/a.npy", normals),
    ("in/a.exr", normals),
    ("in/a.png", normals),
    ("in/a.npy", env),
    ("in/a.exr", env),
    ("in/a.png", png_image),
    ("in/a.json", material),
    ("in/a.json", manifest),
    ("in/a.json", nbrdf_nets),
    ("in/a.json", bundle),
    ("in/a.binary", merl_table),
];

/// Ok, or an [`Error::File`] naming `path` whose message is one line.
fn clean<T>(path: &Path, r: matedit::Result<T>) -> Result<Option<T>, TestCaseError> {
    match r {
        Ok(v) => Ok(Some(v)),
        Err(e) => {
            let m = e.to_string();
            prop_assert!(
                matches!(&e, Error::File { path: p, .. } if p == path),
                "not an error naming {}: {m}",
                path.display()
            );
            prop_assert!(!m.contains(['\n', '\r']), "more than one line: {m:?}");
            prop_assert!(m.len() > path.as_os_str().len() + 2, "no message: {m:?}");
            Ok(None)
        }
    }
}

/// Runs every loader for files ending in `ext` on `bytes`.
fn load_all(ext: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    for (name, load) in LOADERS.iter().filter(|(n, _)| n.ends_with(ext)) {
        let path = Path::new(name);
        clean(path, load(path, bytes))?;
    }
    Ok(())
}

/// Every path-based loader on a real file `name` holding `bytes`: the command line's way in.
fn load_file(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).expect("write");
    clean(&p, io::read_raster(&p, "a raster"))?;
    clean(&p, io::load_normals(&p))?;
    clean(&p, io::load_env(&p, Convention::Equirect))?;
    clean(&p, io::load_image(&p))?;
    clean(&p, io::load_mask(&p))?;
    clean(&p, io::load_upstream(&p))?;
    clean(&p, io::load_material(&p))?;
    clean(&p, io::manifest::read(&p, None))?;
    clean(&p, merl::read(&p))?;
    clean(&p, nbrdf::read(&p))?;
    info_is_clean(&p)?;
    Ok(())
}

/// `matedit info` on `path` (the report is the command line's): a report, or as [`clean`]
/// asks of an error, through the command's exit code 2 (bad input) and its one-line stderr
/// `error: PATH: MESSAGE`.
fn info_is_clean(path: &Path) -> Result<(), TestCaseError> {
    let out = assert_cmd::cargo::cargo_bin_cmd!("matedit")
        .arg("info")
        .arg(path)
        .output()
        .expect("runs matedit");
    if out.status.success() {
        return Ok(());
    }
    let m = String::from_utf8_lossy(&out.stderr);
    let m = m.strip_suffix('\n').unwrap_or(&m);
    let named = format!("error: {}: ", path.display());
    prop_assert_eq!(out.status.code(), Some(2), "not an input error: {}", m);
    prop_assert!(
        m.starts_with(&named),
        "not an error naming {}: {m}",
        path.display()
    );
    prop_assert!(!m.contains(['\n', '\r']), "more than one line: {m:?}");
    prop_assert!(m.len() > named.len(), "no message: {m:?}");
    Ok(())
}

// ---------------------------------------------------------------------------------------
// Values and corruptions

/// Ordinary values, and the ones validators exist for: NaN, infinities, negatives, huge
/// and tiny values, the limits and just past them.
const SPECIAL: &[f64] = &[
    0.0,
    -0.0,
    1.0,
    -1.0,
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    40.0,
    -40.0,
    40.000_001,
    1.0e4,
    10_000.000_1,
    1.0e12,
    1.000_000_1e12,
    3.5e38,
    -3.5e38,
    1.0e200,
    -1.0e200,
    f64::MAX,
    f64::MIN_POSITIVE,
    5.0e-324,
    1.0e-7,
    -1.0e-7,
];

fn value() -> impl Strategy<Value = f64> + Clone {
    prop_oneof![3 => -2.0..2.0f64, 1 => select(SPECIAL)]
}

/// A corruption of a valid file.
#[derive(Clone, Debug)]
enum Mutation {
    None,
    Truncate(Index),
    Flip(Vec<(Index, u8)>),
    Overwrite(Index, Vec<u8>),
}

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        1 => Just(Mutation::None),
        2 => any::<Index>().prop_map(Mutation::Truncate),
        3 => prop::collection::vec((any::<Index>(), 1u8..), 1..8).prop_map(Mutation::Flip),
        2 => (any::<Index>(), prop::collection::vec(any::<u8>(), 1..16))
            .prop_map(|(i, b)| Mutation::Overwrite(i, b)),
    ]
}

fn mutate(mut bytes: Vec<u8>, m: &Mutation) -> Vec<u8> {
    if bytes.is_empty() {
        return bytes;
    }
    let n = bytes.len();
    match m {
        Mutation::None => {}
        Mutation::Truncate(i) => bytes.truncate(i.index(n)),
        Mutation::Flip(flips) => {
            for (i, x) in flips {
                bytes[i.index(n)] ^= x;
            }
        }
        Mutation::Overwrite(i, b) => {
            for (d, v) in bytes[i.index(n)..].iter_mut().zip(b) {
                *d = *v;
            }
        }
    }
    bytes
}

/// Where the value of EXR header attribute `name` of type `ty` starts.
fn exr_attr(bytes: &[u8], name: &str, ty: &str) -> Option<usize> {
    let key = format!("{name}\0{ty}\0");
    let at = bytes.windows(key.len()).position(|w| w == key.as_bytes())?;
    Some(at + key.len() + 4)
}

fn put(bytes: &mut [u8], at: usize, v: &[u8]) {
    if let Some(d) = bytes.get_mut(at..at + v.len()) {
        d.copy_from_slice(v);
    }
}

fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Sets a PNG's IHDR fields (width, height, bit depth, colour type, interlace) and its CRC.
fn patch_ihdr(bytes: &mut [u8], w: u32, h: u32, depth: u8, colour: u8, interlace: u8) {
    put(bytes, 16, &w.to_be_bytes());
    put(bytes, 20, &h.to_be_bytes());
    put(bytes, 24, &[depth, colour]);
    put(bytes, 28, &[interlace]);
    let crc = crc32(&bytes[12..29]);
    put(bytes, 29, &crc.to_be_bytes());
}

// ---------------------------------------------------------------------------------------
// Valid files

fn npy_bytes(version: u8, header: &str, data: &[u8]) -> Vec<u8> {
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

fn npy_header(descr: &str, fortran: &str, shape: &str) -> String {
    format!("{{'descr': '{descr}', 'fortran_order': {fortran}, 'shape': {shape}, }}")
}

fn npy_data(descr: &str, values: &[f64]) -> Vec<u8> {
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
fn npy_file() -> impl Strategy<Value = Vec<u8>> {
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
fn npy_mutant() -> impl Strategy<Value = Vec<u8>> {
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
fn exr_bytes(
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

fn pixels(n: usize) -> impl Strategy<Value = Vec<[f32; 3]>> {
    prop::collection::vec(prop::array::uniform3(-2.0f32..2.0), n)
}

/// A valid EXR: 1 to 6 pixels a side, every compression, f32 or f16, scan lines or tiles.
fn exr_file() -> impl Strategy<Value = Vec<u8>> {
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
fn exr_mutant() -> impl Strategy<Value = Vec<u8>> {
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
fn png_file() -> impl Strategy<Value = Vec<u8>> {
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
fn png_mutant() -> impl Strategy<Value = Vec<u8>> {
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

fn valid_ctrl() -> impl Strategy<Value = Vec<f64>> {
    prop::collection::vec(
        prop_oneof![-40.0..=40.0f64, select(&[0.0, -0.0, 40.0, -40.0][..])],
        108,
    )
    .prop_flat_map(|scales| {
        let exps = prop::collection::vec(
            prop_oneof![0.0..=1.0e4f64, select(&[0.0, 1.0e4, 5.0e-324][..])],
            108,
        );
        (Just(scales), exps)
    })
    .prop_map(|(scales, exps)| {
        (0..108)
            .map(|i| if (i / 6) % 2 == 1 { exps[i] } else { scales[i] })
            .collect()
    })
}

fn valid_material() -> impl Strategy<Value = Material> {
    (any::<String>(), valid_ctrl())
        .prop_map(|(name, ctrl)| Material::new(name, &ctrl).expect("a valid material"))
}

/// Any JSON value: leaves of every kind, arrays and objects up to 3 deep.
fn json_value() -> impl Strategy<Value = Value> {
    let leaf = prop_oneof![
        Just(Value::Null),
        any::<bool>().prop_map(Value::from),
        any::<i64>().prop_map(Value::from),
        any::<u64>().prop_map(Value::from),
        value().prop_map(|v| serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number)),
        ".{0,8}".prop_map(Value::from),
    ];
    leaf.prop_recursive(3, 64, 8, |inner| {
        prop_oneof![
            prop::collection::vec(inner.clone(), 0..8).prop_map(Value::Array),
            prop::collection::btree_map("[a-z0-9_]{0,6}", inner, 0..4)
                .prop_map(|m| Value::Object(m.into_iter().collect())),
        ]
    })
}

/// A change to a JSON document at the node reached by walking `path`: replace it, resize
/// it (an array: cut or repeat its last element) or drop one of its keys (an object).
#[derive(Clone, Debug)]
enum JsonEdit {
    Replace(Vec<Index>, Value),
    Resize(Vec<Index>, usize),
    DropKey(Vec<Index>, Index),
}

fn json_edit() -> impl Strategy<Value = JsonEdit> {
    let path = prop::collection::vec(any::<Index>(), 0..4);
    prop_oneof![
        (path.clone(), json_value()).prop_map(|(p, v)| JsonEdit::Replace(p, v)),
        (path.clone(), 0usize..300).prop_map(|(p, n)| JsonEdit::Resize(p, n)),
        (path, any::<Index>()).prop_map(|(p, k)| JsonEdit::DropKey(p, k)),
    ]
}

fn walk<'a>(v: &'a mut Value, path: &[Index]) -> &'a mut Value {
    let Some((i, rest)) = path.split_first() else {
        return v;
    };
    let len = match v {
        Value::Array(a) => a.len(),
        Value::Object(o) => o.len(),
        _ => 0,
    };
    if len == 0 {
        return v;
    }
    let k = i.index(len);
    match v {
        Value::Array(a) => walk(&mut a[k], rest),
        Value::Object(o) => walk(o.values_mut().nth(k).expect("k < len"), rest),
        _ => v,
    }
}

fn edit_json(mut doc: Value, e: &JsonEdit) -> Vec<u8> {
    match e {
        JsonEdit::Replace(p, new) => *walk(&mut doc, p) = new.clone(),
        JsonEdit::Resize(p, n) => {
            if let Value::Array(a) = walk(&mut doc, p) {
                let last = a.last().cloned().unwrap_or(Value::Null);
                a.resize(*n, last);
            }
        }
        JsonEdit::DropKey(p, k) => {
            if let Value::Object(o) = walk(&mut doc, p)
                && !o.is_empty()
            {
                let key = o.keys().nth(k.index(o.len())).cloned().expect("k < len");
                o.remove(&key);
            }
        }
    }
    serde_json::to_vec(&doc).expect("json")
}

fn material_json() -> impl Strategy<Value = Value> {
    valid_material().prop_map(|m| {
        serde_json::from_slice(&io::json::encode_material(&m, Some("d"))).expect("json")
    })
}

/// A manifest mixing valid and invalid entries of every key.
fn manifest_json() -> impl Strategy<Value = Value> {
    let names = matedit::presets::names();
    let preset = prop_oneof![select(names), select(&["", "no-such-preset"][..])];
    let scene = (
        select(&["out.png", "", "/abs/out.exr", "out.png", "o/x.npy"][..]),
        prop::option::of(select(&["n.npy", "n.png", "", "/abs/n.exr"][..])),
        prop::option::of(prop_oneof![
            0usize..300,
            select(&[8192, 8193, usize::MAX][..])
        ]),
        prop::option::of(select(&["sky.exr", ""][..])),
        prop::option::of(select(&["m.json"][..])),
        prop::option::of(preset),
        prop::option::of(select(&["up.npy"][..])),
    )
        .prop_map(
            |(output, normals, sphere, env, material, preset, upstream)| {
                let mut o = serde_json::Map::new();
                o.insert("output".into(), output.into());
                let opt = |o: &mut serde_json::Map<_, _>, k: &str, v: Option<Value>| {
                    if let Some(v) = v {
                        o.insert(k.into(), v);
                    }
                };
                opt(&mut o, "normals", normals.map(Value::from));
                opt(&mut o, "sphere", sphere.map(Value::from));
                opt(&mut o, "env", env.map(Value::from));
                opt(&mut o, "material", material.map(Value::from));
                opt(&mut o, "preset", preset.map(Value::from));
                opt(&mut o, "upstream", upstream.map(Value::from));
                Value::Object(o)
            },
        );
    (
        prop::collection::vec(scene, 0..4),
        prop::option::of(select(
            &["64x128", "full", "0x1", "8", "16384x16385", "3x4"][..],
        )),
        prop::option::of(select(&["equirect", "paper", "x"][..])),
        prop::option::of(select(&[40.0, 0.0, 180.0, -1.0, 1e300, 179.9][..])),
    )
        .prop_map(|(scenes, size, conv, fov)| {
            let mut o = json!({ "scenes": scenes });
            if let Some(s) = size {
                o["env_size"] = s.into();
            }
            if let Some(c) = conv {
                o["convention"] = c.into();
            }
            if let Some(f) = fov {
                o["fov"] = f.into();
            }
            o
        })
}

/// A valid NBRDF file of one or two networks.
fn nbrdf_json() -> impl Strategy<Value = Value> {
    let net = prop::collection::vec(-1.0..1.0f64, 6 * 21 + 21 + 21 * 21 + 21 + 21 * 3 + 3)
        .prop_map(|v| {
            let mut it = v.into_iter();
            let mut take = |r: usize, c: usize| -> Value {
                let rows: Vec<Vec<f64>> = (0..r).map(|_| it.by_ref().take(c).collect()).collect();
                if r == 1 { json!(rows[0]) } else { json!(rows) }
            };
            json!({"w1": take(6, 21), "b1": take(1, 21), "w2": take(21, 21),
                   "b2": take(1, 21), "w3": take(21, 3), "b3": take(1, 3)})
        });
    prop::collection::vec(net, 1..3).prop_map(|nets| {
        let materials: serde_json::Map<_, _> = nets
            .into_iter()
            .enumerate()
            .map(|(i, n)| (format!("m{i}"), n))
            .collect();
        json!({"format": nbrdf::FORMAT, "materials": materials})
    })
}

/// A valid MERL table of 1 to 3 cells per axis, some cells unmeasured (negative).
fn merl_file() -> impl Strategy<Value = Vec<u8>> {
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
fn merl_mutant() -> impl Strategy<Value = Vec<u8>> {
    let dim = prop_oneof![
        select(&[0, 1, 2, 90, 180, 1024, 1025, -1, i32::MAX, i32::MIN][..]),
        any::<i32>()
    ];
    (merl_file(), 0usize..3, dim).prop_map(|(mut b, k, d)| {
        put(&mut b, 4 * k, &d.to_le_bytes());
        b
    })
}

// ---------------------------------------------------------------------------------------
// (a) Nothing panics; errors are one line naming the file

/// The first bytes of each format.
const MAGICS: &[&[u8]] = &[
    b"\x93NUMPY\x01\x00",
    b"\x93NUMPY\x02\x00",
    b"\x76\x2f\x31\x01\x02\x00\x00\x00",
    b"\x89PNG\r\n\x1a\n",
    b"{\"ctrl\": ",
    b"{\"format\": \"nbrdf-6-21-21-3\", \"materials\": ",
];

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..512)) {
        for ext in [".npy", ".exr", ".png", ".json", ".binary"] {
            load_all(ext, &bytes)?;
        }
    }

    /// Arbitrary bytes behind each format's magic number, so that they reach the parsers.
    #[test]
    fn bytes_after_a_magic_number_never_panic(
        magic in select(MAGICS),
        tail in prop::collection::vec(any::<u8>(), 0..512),
    ) {
        let bytes = [magic, &tail[..]].concat();
        for ext in [".npy", ".exr", ".png", ".json"] {
            load_all(ext, &bytes)?;
        }
    }

    #[test]
    fn corrupted_npy_files_are_clean(b in npy_file(), m in mutation()) {
        load_all(".npy", &mutate(b, &m))?;
    }

    #[test]
    fn npy_header_fields_are_checked(b in npy_mutant(), m in mutation()) {
        load_all(".npy", &mutate(b, &m))?;
    }

    #[test]
    fn corrupted_png_files_are_clean(b in png_file(), m in mutation()) {
        load_all(".png", &mutate(b, &m))?;
    }

    #[test]
    fn png_header_fields_are_checked(b in png_mutant(), m in mutation()) {
        load_all(".png", &mutate(b, &m))?;
    }

    #[test]
    fn corrupted_json_files_are_clean(
        doc in prop_oneof![material_json(), manifest_json(), nbrdf_json()],
        e in prop::option::of(json_edit()),
        m in mutation(),
    ) {
        let bytes = match &e {
            Some(e) => edit_json(doc, e),
            None => serde_json::to_vec(&doc).expect("json"),
        };
        load_all(".json", &mutate(bytes, &m))?;
    }

    #[test]
    fn corrupted_merl_tables_are_clean(b in prop_oneof![merl_file(), merl_mutant()], m in mutation()) {
        load_all(".binary", &mutate(b, &m))?;
    }
}

proptest! {
    // EXR decoding is the slowest loader: fewer cases
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn corrupted_exr_files_are_clean(b in exr_file(), m in mutation()) {
        load_all(".exr", &mutate(b, &m))?;
    }

    #[test]
    fn exr_header_fields_are_checked(b in exr_mutant(), m in mutation()) {
        load_all(".exr", &mutate(b, &m))?;
    }
}

proptest! {
    // a temporary folder and 11 loaders per case
    #![proptest_config(ProptestConfig::with_cases(64))]

    /// Through the files the command line opens: every path-based loader on every kind of
    /// corrupted file, under each extension.
    #[test]
    fn path_loaders_are_clean(
        b in prop_oneof![
            npy_file(), exr_file(), png_file(), merl_file(),
            material_json().prop_map(|v| serde_json::to_vec(&v).expect("json")),
            prop::collection::vec(any::<u8>(), 0..64),
        ],
        m in mutation(),
        ext in select(&["npy", "exr", "png", "json", "binary"][..]),
    ) {
        load_file(&format!("in.{ext}"), &mutate(b, &m))?;
    }
}

// ---------------------------------------------------------------------------------------
// (b) Round trips

/// Equal bits, or both NaN (widening to f64 and back may quiet a signalling NaN).
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn npy_round_trips(
        (shape, data) in prop::collection::vec(0usize..5, 0..4).prop_flat_map(|s| {
            let n = s.iter().product::<usize>();
            (Just(s), prop::collection::vec(any::<f32>(), n))
        })
    ) {
        let a = npy::parse(&npy::encode_f32(&shape, &data)).expect("own file");
        prop_assert_eq!(&a.shape, &shape);
        prop_assert_eq!(a.dtype, npy::Dtype::F32);
        prop_assert_eq!(a.data.len(), data.len());
        for (x, y) in a.data.iter().zip(&data) {
            prop_assert!(same(*x as f32, *y), "{x} vs {y}");
        }
    }

    #[test]
    fn exr_round_trips(
        (w, h, px) in (1usize..9, 1usize..9).prop_flat_map(|(w, h)| {
            (Just(w), Just(h), prop::collection::vec(prop::array::uniform3(any::<f32>()), w * h))
        })
    ) {
        let p = Path::new("in/a.exr");
        let r = io::exr::decode_rgb(p, &io::exr::encode_rgb(w, h, &px).expect("encode"))
            .expect("own file");
        prop_assert_eq!((r.width, r.height), (w, h));
        for (a, b) in r.pixels.iter().zip(&px) {
            prop_assert!((0..3).all(|k| same(a[k] as f32, b[k])), "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn png_round_trips(
        (w, h, data) in (1usize..9, 1usize..9).prop_flat_map(|(w, h)| {
            (Just(w), Just(h), prop::collection::vec(any::<u8>(), 3 * w * h))
        })
    ) {
        let p = Path::new("in/a.png");
        let d = io::png::decode_bytes(p, &io::png::encode_rgb8(w, h, &data).expect("encode"))
            .expect("own file");
        prop_assert_eq!((d.width, d.height, d.channels, d.bit_depth), (w, h, 3, 8));
        prop_assert!(d.samples.iter().map(|&v| v as u8).eq(data.iter().copied()));
    }

    #[test]
    fn material_json_round_trips(m in valid_material(), description in prop::option::of(any::<String>())) {
        let p = Path::new("in/a.json");
        let bytes = io::json::encode_material(&m, description.as_deref());
        let back = io::json::parse_material(p, &bytes).expect("own file");
        prop_assert_eq!(&back.name, &m.name);
        prop_assert!(back.ctrl.iter().zip(&m.ctrl).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}

// ---------------------------------------------------------------------------------------
// (c) Validators accept exactly the valid inputs; what they accept renders finite

fn valid_scale(v: f64) -> bool {
    v.is_finite() && v.abs() <= 40.0
}
fn valid_exponent(v: f64) -> bool {
    v.is_finite() && (0.0..=1.0e4).contains(&v)
}
fn valid_normal(n: [f32; 3]) -> bool {
    n.iter().all(|v| v.is_finite())
        && n.iter()
            .map(|&v| f64::from(v) * f64::from(v))
            .sum::<f64>()
            .sqrt()
            <= MAX_NORMAL_LENGTH
}
fn valid_radiance(v: f32) -> bool {
    v.is_finite() && (0.0..=MAX_RADIANCE).contains(&v)
}
fn valid_fov(f: f64) -> bool {
    f.is_finite() && f > 0.0 && f < 180.0
}

/// A valid material with a few control points set to arbitrary values, and a length that
/// is sometimes not 108.
fn any_ctrl() -> impl Strategy<Value = Vec<f64>> {
    (
        valid_ctrl(),
        prop::collection::vec((any::<Index>(), value()), 0..3),
        prop_oneof![8 => Just(108usize), 1 => select(&[0usize, 107, 109][..])],
    )
        .prop_map(|(mut c, edits, len)| {
            for (i, v) in edits {
                let k = i.index(c.len());
                c[k] = v;
            }
            c.resize(len, 0.5);
            c
        })
}

/// A normal: unit, background, a hair longer than the limit or within it, or arbitrary.
fn any_normal() -> impl Strategy<Value = [f32; 3]> + Clone {
    let unit = (0.0..std::f64::consts::TAU, -1.0..1.0f64).prop_map(|(phi, z)| {
        let r = (1.0 - z * z).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    });
    prop_oneof![
        4 => (unit.clone(), select(&[1.0, 1.0 + 5e-6, 1.0 + 2e-5, 0.5, 100.0][..]))
            .prop_map(|(n, s)| n.map(|v| (v * s) as f32)),
        1 => Just([0.0f32; 3]),
        1 => prop::array::uniform3(value().prop_map(|v| v as f32)),
    ]
}

fn any_texel() -> impl Strategy<Value = [f32; 3]> + Clone {
    prop::array::uniform3(prop_oneof![
        4 => 0.0..10.0f32,
        1 => select(vec![0.0, -0.0, -1e-3, MAX_RADIANCE, MAX_RADIANCE.next_up(), f32::INFINITY, f32::NAN, f32::MAX]),
    ])
}

fn sized<T: std::fmt::Debug + Clone>(
    item: impl Strategy<Value = T> + Clone,
) -> impl Strategy<Value = (usize, usize, Vec<T>)> {
    (
        1usize..4,
        1usize..4,
        prop_oneof![6 => Just(0i32), 1 => -1i32..=1],
    )
        .prop_flat_map(move |(a, b, off)| {
            let n = ((a * b) as i32 + off).max(0) as usize;
            (Just(a), Just(b), prop::collection::vec(item.clone(), n))
        })
}

/// Renders `scene` on the fast CPU path and the reference; both must give finite images.
fn renders_finite(scene: Scene) -> Result<(), TestCaseError> {
    let batch = Batch::single(scene).expect("valid scene");
    for device in [Device::Cpu, Device::Reference] {
        let r = Renderer::new(device).expect("CPU renderer");
        let images = r.render(&batch);
        prop_assert!(images.is_ok(), "{device:?}: {}", images.unwrap_err());
        for img in images.expect("checked") {
            prop_assert!(
                img.pixels.iter().flatten().all(|v| v.is_finite()),
                "{device:?}"
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn validators_accept_exactly_the_valid_scenes(
        ctrl in any_ctrl(),
        (nw, nh, ns) in sized(any_normal()),
        (eh, ew, texels) in sized(any_texel()),
        conv in select(&[Convention::Equirect, Convention::Paper][..]),
        fov in prop::option::of(prop_oneof![1.0..179.0f64, select(&[0.0, 180.0, -1.0, 1e-9, 179.999, f64::NAN, f64::INFINITY][..])]),
    ) {
        let ctrl_ok = ctrl.len() == 108
            && ctrl.iter().enumerate().all(|(i, &v)| {
                if (i / 6) % 2 == 1 { valid_exponent(v) } else { valid_scale(v) }
            });
        let normals_ok = ns.len() == nw * nh && ns.iter().all(|&n| valid_normal(n));
        let env_ok = texels.len() == eh * ew && texels.iter().flatten().all(|&v| valid_radiance(v));
        let camera = fov.map_or(Camera::Orthographic, |f| Camera::Perspective { fov_y_deg: f });
        let camera_ok = fov.is_none_or(valid_fov);

        let m = Material::new("m", &ctrl);
        prop_assert_eq!(m.is_ok(), ctrl_ok, "material {:?}", m.as_ref().err());
        let from_json = io::json::material_from_ctrl("m".into(), &ctrl);
        prop_assert_eq!(from_json.is_ok(), ctrl_ok, "material file {:?}", from_json.err());
        let n = NormalMap::new(nw, nh, ns);
        prop_assert_eq!(n.is_ok(), normals_ok, "normals {:?}", n.as_ref().err());
        let e = EnvMap::new(eh, ew, conv, texels);
        prop_assert_eq!(e.is_ok(), env_ok, "env {:?}", e.as_ref().err());
        prop_assert_eq!(camera.validate().is_ok(), camera_ok);
        for err in [m.as_ref().err(), n.as_ref().err(), e.as_ref().err()].into_iter().flatten() {
            prop_assert!(err.is_input_error() && !err.to_string().contains('\n'), "{err}");
        }
        if let (Ok(material), Ok(normals), Ok(env), true) = (m, n, e, camera_ok) {
            renders_finite(Scene { normals, env, material, camera })?;
        }
    }
}

/// What the loaders must make of an H x W x 3 float64 array.
fn expect_loaded(values: &[[f64; 3]]) -> (bool, bool, bool) {
    let finite = values.iter().flatten().all(|v| v.is_finite());
    let env_ok = finite && values.iter().flatten().all(|&v| (v as f32) <= MAX_RADIANCE);
    let f32_ok = finite && values.iter().flatten().all(|v| v.abs() <= f32::MAX as f64);
    (finite, env_ok, f32_ok)
}

/// |n| (inf past f64's range) and n / |n| (zeros for a zero vector), without overflow in
/// the direction: the components are scaled by the largest first.
fn length(n: [f64; 3]) -> (f64, [f64; 3]) {
    let big = n.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if big == 0.0 {
        return (0.0, [0.0; 3]);
    }
    let s = n.map(|v| v / big);
    let l = s.iter().map(|v| v * v).sum::<f64>().sqrt();
    (big * l, s.map(|v| v / l))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Float64 files through the file loaders: normals, env maps, images, upstream
    /// gradients and masks are accepted exactly as docs/FORMATS.md says, with the values
    /// it says, and what is accepted renders finite.
    #[test]
    fn loaders_accept_exactly_the_documented_values(
        (h, w, values) in (1usize..4, 1usize..4).prop_flat_map(|(h, w)| {
            (Just(h), Just(w), prop::collection::vec(prop::array::uniform3(value()), h * w))
        }),
        m in valid_material(),
    ) {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = dir.path().join("a.npy");
        let header = npy_header("<f8", "False", &npy::shape_str(&[h, w, 3]));
        std::fs::write(&p, npy_bytes(1, &header, &npy_data("<f8", values.as_flattened())))
            .expect("write");
        let (finite, env_ok, f32_ok) = expect_loaded(&values);

        let n = clean(&p, io::load_normals(&p))?;
        prop_assert_eq!(n.is_some(), finite);
        if let Some(n) = &n {
            for (got, raw) in n.normals.iter().zip(&values) {
                let (len, dir) = length(*raw);
                let g = got.map(f64::from);
                if len < 1e-6 {
                    prop_assert_eq!(*got, [0.0; 3], "{:?}", raw);
                } else {
                    prop_assert!((length(g).0 - 1.0).abs() < 1e-6, "{:?} -> {:?}", raw, got);
                    prop_assert!((0..3).all(|k| (g[k] - dir[k]).abs() < 1e-6), "{:?} -> {:?}", raw, got);
                }
            }
        }
        let e = clean(&p, io::load_env(&p, Convention::Equirect))?;
        prop_assert_eq!(e.is_some(), env_ok);
        if let Some(e) = &e {
            let negative = values.iter().flatten().filter(|&&v| (v as f32) < 0.0).count();
            prop_assert_eq!(e.clamped, negative);
            for (t, raw) in e.env.texels.iter().zip(&values) {
                prop_assert!((0..3).all(|k| t[k].to_bits() == (raw[k] as f32).max(0.0).to_bits()
                    || (t[k] == 0.0 && raw[k] as f32 == 0.0)));
            }
        }
        for (what, r) in [("image", io::load_image(&p)), ("upstream", io::load_upstream(&p))] {
            let img = clean(&p, r)?;
            prop_assert_eq!(img.is_some(), f32_ok, "{}", what);
            if let Some(img) = img {
                prop_assert!(img.pixels.iter().flatten().all(|v| v.is_finite()), "{}", what);
            }
        }
        let mask = clean(&p, io::load_mask(&p))?;
        prop_assert_eq!(mask.is_some(), finite);
        if let Some((_, _, mask)) = mask {
            prop_assert!(mask.iter().zip(&values).all(|(&k, v)| k == (v[0] > 0.5)));
        }
        if let (Some(normals), Some(e)) = (n, e) {
            renders_finite(Scene { normals, env: e.env, material: m, camera: Camera::Orthographic })?;
        }
    }
}

// ---------------------------------------------------------------------------------------
// Header claims: no loader allocates for them before checking them against the file

/// The global allocator, counting the largest request since [`largest_since`] last reset.
struct Counting;

static LARGEST: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is passed to the system allocator unchanged.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LARGEST.fetch_max(new_size, Ordering::Relaxed);
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result with the largest allocation made meanwhile (by any
/// thread: the other tests here allocate kilobytes, far below what is checked).
fn largest_since<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.store(0, Ordering::Relaxed);
    let out = f();
    (out, LARGEST.load(Ordering::Relaxed))
}

/// Writes `bytes` as `name` in a temporary folder and loads it with `load`: the error must
/// say `says`, name the file, come within a second and allocate no more than 16 MiB at once.
fn refused_cheaply<T: std::fmt::Debug>(
    name: &str,
    bytes: &[u8],
    load: fn(&Path) -> matedit::Result<T>,
    says: &str,
) {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).expect("write");
    let start = std::time::Instant::now();
    let (r, largest) = largest_since(|| load(&p));
    let took = start.elapsed();
    let e = r
        .expect_err("a file claiming more than it holds")
        .to_string();
    assert!(
        e.starts_with(&p.display().to_string()) && !e.contains('\n'),
        "{e}"
    );
    assert!(e.contains(says), "{name}: {e}");
    assert!(
        largest <= 16 << 20,
        "{name}: allocated {largest} bytes at once: {e}"
    );
    assert!(took.as_secs_f64() < 1.0, "{name}: took {took:?}");
}

#[test]
fn headers_claiming_huge_sizes_are_refused_before_allocating() {
    // EXR: a 2 x 2 file whose data window says 16000 x 16000 (within MAX_PIXELS), its
    // chunk count to match (the decoder allocated 1 GB a channel before reading a chunk)
    for (comp, lines) in [
        (ex::Compression::Uncompressed, 1),
        (ex::Compression::ZIP16, 16),
        (ex::Compression::DWAA(None), 32),
    ] {
        let mut b = exr_bytes(2, 2, &[[0.5; 3]; 4], comp, false, false);
        let window: Vec<u8> = [0i32, 0, 15999, 15999]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        for name in ["dataWindow", "displayWindow"] {
            let at = exr_attr(&b, name, "box2i").expect("window");
            put(&mut b, at, &window);
        }
        let at = exr_attr(&b, "chunkCount", "int").expect("chunk count");
        put(&mut b, at, &(16000i32 / lines).to_le_bytes());
        refused_cheaply(
            "big.exr",
            &b,
            |p| io::read_raster(p, "a raster"),
            "more than a",
        );
    }

    // PNG: a 1 x 1 RGB file whose header says 16000 x 16000 (768 MB, within png's limit)
    let mut b = io::png::encode_rgb8(1, 1, &[1, 2, 3]).expect("png");
    patch_ihdr(&mut b, 16000, 16000, 8, 2, 0);
    refused_cheaply("big.png", &b, io::load_normals, "more than a");
    refused_cheaply("big.png", &b, io::load_image, "more than a");

    // NPY: shape (100000, 100000, 3) and no data
    let header = npy_header("<f4", "False", "(100000, 100000, 3)");
    let b = npy_bytes(1, &header, &[0; 16]);
    refused_cheaply("big.npy", &b, io::load_normals, "truncated");
    // and a shape of more axes than NumPy writes
    let header = npy_header("<f4", "True", &format!("({}2,)", "1, ".repeat(100)));
    let b = npy_bytes(1, &header, &[0; 8]);
    refused_cheaply("axes.npy", &b, npy::read, "axes");

    // MERL: 1024 x 1024 x 1024 cells claimed, none there
    let b: Vec<u8> = [1024i32; 3].iter().flat_map(|d| d.to_le_bytes()).collect();
    refused_cheaply(
        "big.binary",
        &b,
        merl::read,
        "header says 1024 x 1024 x 1024",
    );
}

// ---------------------------------------------------------------------------------------
// What the property tests found, kept as plain tests

/// An error quoting the file's text (a JSON key, a dtype, a format name) holding a
/// newline was two lines (found by `corrupted_json_files_are_clean`): control characters
/// are escaped.
#[test]
fn messages_quoting_the_file_stay_one_line() {
    let cases: [(&str, &[u8], Load); 4] = [
        ("in/a.json", b"{\"ctrl\": [], \"conv\\ntion\": 1}", material),
        ("in/a.json", b"{\"scenes\": [], \"a\\nb\": 1}", manifest),
        ("in/a.json", b"{\"format\": \"x\\ny\"}", nbrdf_nets),
        (
            "in/a.npy",
            b"\x93NUMPY\x01\x00\x1a\x00{'descr': '<\ni4', 'shape': ()}",
            raster,
        ),
    ];
    for (name, bytes, load) in cases {
        let e = load(Path::new(name), bytes)
            .expect_err("invalid")
            .to_string();
        assert!(!e.contains('\n') && e.contains("\\n"), "{e:?}");
    }
}

/// Float64 normals beyond 1e154 overflowed |n|^2 and loaded as background (found by
/// `loaders_accept_exactly_the_documented_values`); values beyond float32's range in an
/// image to fit loaded as infinities.
#[test]
fn float64_extremes_load_as_documented() {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join("a.npy");
    let header = npy_header("<f8", "False", "(1, 2, 3)");
    let values = [1e200, 0.0, 0.0, -1e300, 1e300, 0.0];
    std::fs::write(&p, npy_bytes(1, &header, &npy_data("<f8", &values))).expect("write");
    let n = io::load_normals(&p).expect("finite normals");
    let s = std::f32::consts::FRAC_1_SQRT_2;
    assert_eq!(n.normals, vec![[1.0, 0.0, 0.0], [-s, s, 0.0]]);
    let e = io::load_image(&p).expect_err("beyond float32").to_string();
    assert!(
        e.ends_with("a.npy: pixel (column 0, row 0) channel R is 1e200, beyond float32 range"),
        "{e}"
    );
}

// ---------------------------------------------------------------------------------------
// What the fuzz targets found, kept as bytes

/// A 3 x 6 B44A EXR (found by the `env` fuzz target) whose block makes the `exr` crate's
/// B44 decoder overflow u32 arithmetic that OpenEXR's C code lets wrap: with overflow
/// checks on (dev builds) it panicked in exr's decoder threads, which aborted the whole
/// process. Cargo.toml builds exr without them in every profile now.
const B44_OVERFLOW: &[u8] = &[
    0x76, 0x2f, 0x31, 0x01, 0x02, 0x00, 0x00, 0x00, 0x63, 0x68, 0x75, 0x6e, 0x6b, 0x43, 0x6f, 0x75,
    0x6e, 0x74, 0x00, 0x69, 0x6e, 0x74, 0x00, 0x04, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x63,
    0x68, 0x61, 0x6e, 0x6e, 0x65, 0x6c, 0x73, 0x00, 0x63, 0x68, 0x6c, 0x69, 0x73, 0x74, 0x00, 0x37,
    0x00, 0x00, 0x00, 0x42, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00,
    0x00, 0x01, 0x00, 0x00, 0x00, 0x47, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01,
    0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x52, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x63, 0x6f, 0x6d, 0x70, 0x72, 0x65,
    0x73, 0x73, 0x69, 0x6f, 0x6e, 0x00, 0x63, 0x6f, 0x6d, 0x70, 0x72, 0x65, 0x73, 0x73, 0x69, 0x6f,
    0x6e, 0x00, 0x01, 0x00, 0x00, 0x00, 0x07, 0x6c, 0x69, 0x6e, 0x65, 0x4f, 0x72, 0x64, 0x65, 0x72,
    0x00, 0x6c, 0x69, 0x6e, 0x65, 0x4f, 0x72, 0x64, 0x65, 0x72, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00,
    0x64, 0x69, 0x73, 0x70, 0x6c, 0x61, 0x79, 0x57, 0x69, 0x6e, 0x64, 0x6f, 0x77, 0x00, 0x62, 0x6f,
    0x78, 0x32, 0x69, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x70, 0x69, 0x78, 0x65, 0x6c, 0x41, 0x73, 0x70,
    0x65, 0x63, 0x74, 0x52, 0x61, 0x74, 0x69, 0x6f, 0x00, 0x66, 0x6c, 0x6f, 0x61, 0x74, 0x00, 0x04,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f, 0x73, 0x63, 0x72, 0x65, 0x65, 0x6e, 0x57, 0x69, 0x6e,
    0x64, 0x6f, 0x77, 0x43, 0x65, 0x6e, 0x74, 0x65, 0x72, 0x00, 0x76, 0x32, 0x66, 0x00, 0x08, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x73, 0x63, 0x65, 0x72, 0x6e, 0x65,
    0x57, 0x69, 0x6e, 0x64, 0x6f, 0x77, 0x57, 0x69, 0x64, 0x74, 0x68, 0x00, 0x66, 0x6c, 0x6f, 0x61,
    0x74, 0x00, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f, 0x64, 0x61, 0x74, 0x61, 0x57, 0x69,
    0x6e, 0x64, 0x6f, 0x77, 0x00, 0x62, 0x6f, 0x78, 0x32, 0x69, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x05, 0x00, 0x00, 0x00, 0x74,
    0x79, 0x70, 0x65, 0x00, 0x73, 0x74, 0x72, 0x69, 0x6e, 0x67, 0x00, 0x0d, 0x00, 0x00, 0x00, 0x73,
    0x63, 0x61, 0x6e, 0x6c, 0x69, 0x6e, 0x65, 0x69, 0x6d, 0x61, 0x67, 0x65, 0x00, 0x75, 0x01, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x14, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x74, 0xff, 0xfc, 0x81, 0x00, 0x27, 0xe8, 0x20, 0xf2, 0x28, 0xa2, 0x8a, 0x08, 0x20, 0x82, 0x08,
    0x20,
];

#[test]
fn b44_blocks_that_wrap_decode_or_fail_cleanly() {
    // a test binary that aborts here (SIGABRT) has exr built with overflow checks
    let path = Path::new("in/b44.exr");
    let r = io::exr::decode_rgb(path, B44_OVERFLOW);
    clean(path, r).expect("one line naming the file");
}

/// A 3 x 2 tiled B44 EXR (found by the `exr` fuzz target) with a chunk whose level index
/// (0, 16) is past the file's levels: the `exr` crate's debug assertion "line should have
/// been filtered" fired on it (dev and fuzz builds; a release build returns the decoder's
/// error). Cargo.toml builds exr without debug assertions in every profile now, so tests
/// and fuzzing run the decoder users get.
const TILE_LEVEL_PAST_END: &[u8] = &[
    0x76, 0x2f, 0x31, 0x01, 0x02, 0x02, 0x00, 0x00, 0x63, 0x68, 0x75, 0x6e, 0x6b, 0x43, 0x6f, 0x75,
    0x6e, 0x74, 0x00, 0x69, 0x6e, 0x74, 0x00, 0x04, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x63,
    0x68, 0x61, 0x6e, 0x6e, 0x65, 0x6c, 0x73, 0x00, 0x63, 0x68, 0x6c, 0x69, 0x73, 0x74, 0x00, 0x37,
    0x00, 0x00, 0x00, 0x42, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00,
    0x00, 0x01, 0x00, 0x00, 0x00, 0x47, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x01,
    0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x52, 0x00, 0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x01, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00, 0x63, 0x6f, 0x6d, 0x70, 0x72, 0x65,
    0x73, 0x73, 0x69, 0x6f, 0x6e, 0x00, 0x63, 0x6f, 0x6d, 0x70, 0x72, 0x65, 0x73, 0x73, 0x69, 0x6f,
    0x6e, 0x00, 0x01, 0x00, 0x00, 0x00, 0x06, 0x94, 0x96, 0x91, 0x65, 0x4f, 0x72, 0x64, 0x65, 0x72,
    0x00, 0x6c, 0x61, 0x6e, 0x65, 0x4f, 0x72, 0x64, 0x65, 0x72, 0x00, 0x01, 0x00, 0x00, 0x00, 0x00,
    0x64, 0x69, 0x73, 0x70, 0x6c, 0x61, 0x79, 0x57, 0x69, 0x6e, 0x64, 0x6f, 0x77, 0x00, 0x62, 0x6f,
    0x78, 0x32, 0x69, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x70, 0x69, 0x78, 0x65, 0x6c, 0x41, 0x73, 0x70,
    0x65, 0x63, 0x74, 0x74, 0x52, 0x6f, 0x61, 0x00, 0x66, 0x69, 0x6c, 0x6f, 0x61, 0x74, 0x00, 0x04,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f, 0x73, 0x63, 0x72, 0x65, 0x65, 0x56, 0x57, 0x69, 0x6e,
    0x64, 0x6f, 0x77, 0x43, 0x9b, 0x91, 0x8b, 0xa0, 0x72, 0x00, 0x62, 0x32, 0x66, 0x00, 0x08, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x73, 0x63, 0x72, 0x65, 0x65, 0x6e,
    0x57, 0x69, 0x6e, 0x64, 0x6f, 0x41, 0x57, 0x69, 0x64, 0x74, 0x68, 0x00, 0x66, 0x6c, 0x6f, 0x61,
    0x74, 0x00, 0x04, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f, 0x64, 0x61, 0x74, 0x61, 0x57, 0x69,
    0x6e, 0x64, 0x6f, 0x77, 0x00, 0x62, 0x6f, 0x78, 0x32, 0x69, 0x00, 0x10, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x74,
    0x79, 0x70, 0x65, 0x00, 0x73, 0x74, 0x72, 0x69, 0x6e, 0x67, 0x00, 0x0a, 0x00, 0x00, 0x00, 0x74,
    0x69, 0x6c, 0x65, 0x64, 0x69, 0x6d, 0x61, 0x67, 0x65, 0x74, 0x69, 0x6c, 0x65, 0x73, 0x00, 0x74,
    0x69, 0x6c, 0x65, 0x64, 0x65, 0x73, 0x63, 0x00, 0x09, 0x00, 0x00, 0x00, 0x02, 0x00, 0x00, 0x00,
    0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x96, 0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xda, 0x01,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x10, 0x00, 0x00, 0x00, 0x30, 0x00, 0x00, 0x00, 0x00, 0x00, 0x04, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x4c, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xff,
    0xff, 0xff, 0x75, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
    0x00, 0x02, 0x00, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x74, 0x79, 0x70, 0x65, 0x00, 0x73, 0x74,
    0x72, 0x69, 0x6e, 0x67, 0x00, 0x0a, 0x00, 0x00, 0x00, 0x74, 0x69, 0x52, 0x61, 0x74, 0x69, 0xff,
    0xff, 0xff, 0xff, 0x63, 0x65, 0x6c, 0x65, 0x73, 0x00, 0x74, 0x69, 0x6c, 0x65, 0x64, 0x65, 0x73,
    0x63, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x18, 0x00, 0x00,
    0x00, 0x00, 0x00, 0xc0, 0x3f, 0x00, 0x00, 0x80, 0xbe, 0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0xc0,
    0x3f, 0x00, 0x00, 0x80, 0xbe, 0x00, 0x00, 0x20, 0x40,
];

#[test]
fn tiles_of_levels_past_the_end_fail_cleanly() {
    let path = Path::new("in/levels.exr");
    let r = io::exr::decode_rgb(path, TILE_LEVEL_PAST_END);
    assert!(r.is_err(), "a chunk past the file's levels must not decode");
    clean(path, r).expect("one line naming the file");
}

// ---------------------------------------------------------------------------------------
// Seeds for the fuzz targets

/// Writes small valid files made by the library and the format crates to
/// fuzz/seeds/TARGET/: `cargo test --test inputs_prop -- --ignored`.
#[test]
#[ignore = "writes fuzz/seeds; run by hand"]
fn write_fuzz_seeds() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/seeds");
    let write = |target: &str, name: &str, bytes: &[u8]| {
        let dir = root.join(target);
        std::fs::create_dir_all(&dir).expect("seed folder");
        std::fs::write(dir.join(name), bytes).expect("seed");
    };
    let px: Vec<[f32; 3]> = (0..6).map(|i| [i as f32 * 0.5, -0.25, 1.5]).collect();
    let values: Vec<f64> = px.as_flattened().iter().map(|&v| f64::from(v)).collect();
    let npys = [
        ("c-f4.npy", npy::encode_f32(&[2, 3, 3], px.as_flattened())),
        (
            "fortran-f8-be.npy",
            npy_bytes(
                2,
                &npy_header(">f8", "True", "(3, 2, 3)"),
                &npy_data(">f8", &values),
            ),
        ),
        (
            "mask-v3.npy",
            npy_bytes(
                3,
                &npy_header("<f4", "False", "(2, 3)"),
                &npy_data("<f4", &values[..6]),
            ),
        ),
    ];
    for (name, b) in &npys {
        write("npy", name, b);
        write("env", name, &[&[11u8][..], b].concat());
    }
    let exrs = [
        ("zip.exr", io::exr::encode_rgb(2, 3, &px).expect("exr")),
        (
            "none.exr",
            exr_bytes(3, 2, &px, ex::Compression::Uncompressed, false, false),
        ),
        (
            "rle-half.exr",
            exr_bytes(2, 3, &px, ex::Compression::RLE, true, false),
        ),
        (
            "piz-tiles.exr",
            exr_bytes(3, 2, &px, ex::Compression::PIZ, false, true),
        ),
        (
            "pxr24.exr",
            exr_bytes(2, 3, &px, ex::Compression::PXR24, false, false),
        ),
        (
            "b44a-half.exr",
            exr_bytes(3, 2, &px, ex::Compression::B44A, true, false),
        ),
        (
            "dwaa-half.exr",
            exr_bytes(2, 3, &px, ex::Compression::DWAA(None), true, false),
        ),
    ];
    for (name, b) in &exrs {
        write("exr", name, b);
        write("env", name, &[&[8u8][..], b].concat());
    }
    let rgb: Vec<u8> = (0..12).map(|i| i * 20).collect();
    write(
        "png",
        "rgb8.png",
        &io::png::encode_rgb8(2, 2, &rgb).expect("png"),
    );
    let encode = |colour: png::ColorType, depth: png::BitDepth, data: &[u8]| {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, 2, 2);
        enc.set_color(colour);
        enc.set_depth(depth);
        if colour == png::ColorType::Indexed {
            enc.set_palette(vec![0, 0, 0, 255, 128, 0]);
        }
        let mut w = enc.write_header().expect("png header");
        w.write_image_data(data).expect("png data");
        w.finish().expect("png end");
        out
    };
    let rgba16: Vec<u8> = (0..32).map(|i| i * 7).collect();
    write(
        "png",
        "rgba16.png",
        &encode(png::ColorType::Rgba, png::BitDepth::Sixteen, &rgba16),
    );
    write(
        "png",
        "grey8.png",
        &encode(
            png::ColorType::Grayscale,
            png::BitDepth::Eight,
            &[0, 9, 99, 255],
        ),
    );
    write(
        "png",
        "indexed1.png",
        &encode(png::ColorType::Indexed, png::BitDepth::One, &[0x80, 0x40]),
    );
    let preset = matedit::presets::lookup(matedit::presets::DEFAULT).expect("preset");
    write(
        "material",
        "preset.json",
        &io::json::encode_material(&preset, Some("seed")),
    );
    let manifest = json!({
        "env_size": "8x16", "convention": "paper", "fov": 40,
        "scenes": [
            {"output": "a.png", "sphere": 16, "preset": matedit::presets::DEFAULT},
            {"output": "b.exr", "normals": "n.npy", "env": "sky.exr", "material": "m.json",
             "upstream": "up.npy"}
        ]
    });
    write("manifest", "batch.json", manifest.to_string().as_bytes());
    let table: Vec<u8> = [2i32, 1, 2]
        .iter()
        .flat_map(|d| d.to_le_bytes())
        .chain((0..12).flat_map(|i| (if i == 11 { -1.0 } else { i as f64 * 300.0 }).to_le_bytes()))
        .collect();
    write("merl", "tiny.binary", &table);
    let zeros = |r: usize, c: usize| vec![vec![0.0; c]; r];
    let mut w1 = zeros(6, 21);
    w1[2][0] = 1.0;
    let nets = json!({"format": nbrdf::FORMAT, "materials": {"m": {
        "w1": w1, "b1": vec![0.0; 21], "w2": zeros(21, 21), "b2": vec![0.5; 21],
        "w3": zeros(21, 3), "b3": vec![0.1; 3]}}});
    write("nbrdf", "one.json", nets.to_string().as_bytes());
}
