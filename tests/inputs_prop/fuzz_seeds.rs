//! Seeds for the fuzz targets.

use std::path::Path;

use exr::prelude::{self as ex};
use matedit::brdf::nbrdf;
use matedit::io::{self, npy};
use serde_json::json;

use crate::binary_files::{exr_bytes, npy_bytes, npy_data, npy_header};

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
