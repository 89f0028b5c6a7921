//! Round trips and error messages of the file readers and writers in `matedit::io`, on
//! small files made here (nothing from ../shared).

use std::path::{Path, PathBuf};

use exr::prelude::*;
use matedit::io::{self, EnvSize, Preview, Tonemap};
use matedit::{Convention, Error, Image};

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn msg(e: Error) -> String {
    e.to_string()
}

/// A small image with varied values, negative ones included.
fn image(w: usize, h: usize) -> Image {
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
fn write_exr(path: &Path, img: &Image, compression: Compression) {
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
fn patch_compression(path: &Path, code: u8) {
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

#[test]
fn npy_round_trip() {
    let d = dir();
    let p = d.path().join("a.npy");
    let img = image(5, 3);
    io::write_atomic(&p, &io::npy::encode_rgb(5, 3, &img.pixels)).unwrap();
    let r = io::read_raster(&p, "test").unwrap();
    assert_eq!((r.width, r.height), (5, 3));
    for (a, b) in r.pixels.iter().zip(&img.pixels) {
        assert_eq!(a.map(|v| v as f32), *b);
    }
    // The upstream loader keeps the values as they are.
    assert_eq!(io::load_upstream(&p).unwrap(), img);
}

#[test]
fn npy_shape_and_dtype_errors() {
    let d = dir();
    let p = d.path().join("bad.npy");
    std::fs::write(&p, io::npy::encode_f32(&[4, 3], &[0.0; 12])).unwrap();
    let e = msg(io::load_normals(&p).unwrap_err());
    assert!(
        e.contains("bad.npy") && e.contains("(4, 3)") && e.contains("(height, width, 3)"),
        "{e}"
    );
    std::fs::write(&p, b"not numpy").unwrap();
    let e = msg(io::load_normals(&p).unwrap_err());
    assert!(e.contains("not a NumPy"), "{e}");
}

#[test]
fn exr_round_trip_and_f16() {
    let d = dir();
    let p = d.path().join("a.exr");
    let img = image(7, 4);
    io::write_atomic(&p, &io::exr::encode_rgb(7, 4, &img.pixels).unwrap()).unwrap();
    assert_eq!(io::load_upstream(&p).unwrap(), img);

    // Half-float channels are widened.
    let p16 = d.path().join("half.exr");
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let v = (pos.x() + 10 * pos.y()) as f32 * 0.5;
        (f16::from_f32(v), f16::from_f32(-v), f16::from_f32(1.0))
    });
    exr::prelude::Image::from_channels((3, 2), channels)
        .write()
        .to_file(&p16)
        .unwrap();
    let r = io::read_raster(&p16, "test").unwrap();
    assert_eq!(r.pixels[4], [5.5, -5.5, 1.0]); // x = 1, y = 1
}

#[test]
fn exr_without_rgb_is_refused() {
    let d = dir();
    let p = d.path().join("depth.exr");
    let channels = SpecificChannels::build()
        .with_channel("Z")
        .with_pixel_fn(|_pos| (1.0f32,));
    exr::prelude::Image::from_channels((2, 2), channels)
        .write()
        .to_file(&p)
        .unwrap();
    let e = msg(io::load_env(&p, Convention::Equirect).unwrap_err());
    assert!(
        e.contains("depth.exr") && e.contains("R, G, B") && e.contains("Z"),
        "{e}"
    );
}

#[test]
fn exr_unsupported_compressions_are_named_with_a_fix() {
    let d = dir();
    let img = image(4, 2);
    for (code, name) in [
        (10u8, "HTJ2K256"),
        (11, "HTJ2K32"),
        (42, "unknown (code 42)"),
    ] {
        let p = d.path().join(format!("c{code}.exr"));
        write_exr(&p, &img, Compression::ZIP16);
        patch_compression(&p, code);
        for e in [
            msg(io::load_env(&p, Convention::Equirect).unwrap_err()),
            msg(io::load_normals(&p).unwrap_err()),
            msg(io::exr::read_info(&p).unwrap_err()),
        ] {
            assert!(e.contains(&format!("c{code}.exr")), "{e}");
            assert!(e.contains(name), "{e}");
            assert!(e.contains("oiiotool"), "{e}");
        }
    }
}

#[test]
fn exr_dwa_files_decode() {
    // exr 1.74 decodes (and writes) DWAA and DWAB: such files are read, not refused.
    let d = dir();
    // A smooth image: DWA is a lossy DCT, fine on smooth content, rough on noise.
    let img = Image {
        width: 8,
        height: 40,
        pixels: (0..8 * 40)
            .map(|i| {
                [
                    0.5 + 0.01 * (i % 8) as f32,
                    1.0 + 0.02 * (i / 8) as f32,
                    2.0,
                ]
            })
            .collect(),
    };
    for c in [Compression::DWAA(None), Compression::DWAB(None)] {
        let p = d.path().join("dwa.exr");
        write_exr(&p, &img, c);
        let got = io::load_upstream(&p).unwrap();
        for (a, b) in got.pixels.iter().zip(&img.pixels) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() <= 1e-2 * b[k], "{a:?} vs {b:?}");
            }
        }
    }
}

#[test]
fn exr_mislabelled_dwa_is_an_error_not_garbage() {
    // ZIP data whose header claims DWAA: the decoder must fail cleanly.
    let d = dir();
    let p = d.path().join("liar.exr");
    write_exr(&p, &image(8, 40), Compression::ZIP16);
    patch_compression(&p, 8);
    let e = msg(io::load_upstream(&p).unwrap_err());
    assert!(e.contains("liar.exr"), "{e}");
}

#[test]
fn normals_are_normalised_with_background() {
    let d = dir();
    let p = d.path().join("n.npy");
    let data = [
        [0.0, 0.0, 2.0],
        [0.0, 0.0, 0.0],
        [3.0, 4.0, 0.0],
        [1e-9, 0.0, 0.0],
    ];
    std::fs::write(&p, io::npy::encode_rgb(2, 2, &data)).unwrap();
    let n = io::load_normals(&p).unwrap();
    assert_eq!(
        n.normals,
        vec![[0.0, 0.0, 1.0], [0.0; 3], [0.6, 0.8, 0.0], [0.0; 3]]
    );
}

#[test]
fn nan_normal_names_the_pixel() {
    let d = dir();
    let p = d.path().join("normals.npy");
    let mut data = vec![[0.0f32, 0.0, 1.0]; 8 * 10];
    data[7 * 8 + 3][1] = f32::NAN; // column 3, row 7
    std::fs::write(&p, io::npy::encode_rgb(8, 10, &data)).unwrap();
    let e = msg(io::load_normals(&p).unwrap_err());
    assert!(e.ends_with("normals.npy: pixel (3, 7) is NaN"), "{e}");
}

#[test]
fn png_normals() {
    let d = dir();
    let p = d.path().join("n.png");
    // RGBA: an up-facing normal, a transparent pixel, a black pixel, a right-facing one.
    let rgba: Vec<u8> = vec![
        128, 255, 128, 255, //
        128, 128, 255, 0, //
        0, 0, 0, 255, //
        255, 128, 128, 255,
    ];
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, 2, 2);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&rgba).unwrap();
    }
    std::fs::write(&p, bytes).unwrap();
    let n = io::load_normals(&p).unwrap();
    assert_eq!(n.normals[1], [0.0; 3]);
    assert_eq!(n.normals[2], [0.0; 3]);
    let up = n.normals[0];
    assert!(up[1] > 0.999 && up[0].abs() < 0.01, "{up:?}");
    let right = n.normals[3];
    assert!(right[0] > 0.999, "{right:?}");
}

#[test]
fn png_preview_values() {
    let d = dir();
    let p = d.path().join("p.png");
    let img = Image {
        width: 3,
        height: 1,
        pixels: vec![[0.0, 0.5, 1.0], [2.0, -1.0, 0.25], [f32::NAN, 1e9, 0.01]],
    };
    let preview = Preview {
        exposure: 1.0,
        tonemap: Tonemap::Reinhard,
    };
    io::write_atomic(&p, &io::encode_image(&p, &img, &preview).unwrap()).unwrap();
    let dec = io::png::decode(&p).unwrap();
    assert_eq!(
        (dec.width, dec.height, dec.channels, dec.bit_depth),
        (3, 1, 3, 8)
    );
    let want: Vec<u16> = img
        .pixels
        .iter()
        .flatten()
        .map(|&v| io::png::display_value(v, &preview) as u16)
        .collect();
    assert_eq!(dec.samples, want);
    // 0.5 * 2 = 1 -> reinhard 0.5 -> sRGB 188
    assert_eq!(dec.samples[1], 188);
}

#[test]
fn env_negatives_are_clamped_and_counted() {
    let d = dir();
    let p = d.path().join("env.npy");
    let mut data = vec![[1.0f32, 2.0, 3.0]; 4 * 8];
    data[5] = [-0.5, 1.0, -0.1];
    data[9][2] = -1e-6;
    std::fs::write(&p, io::npy::encode_rgb(8, 4, &data)).unwrap();
    let l = io::load_env(&p, Convention::Paper).unwrap();
    assert_eq!(l.clamped, 3);
    assert_eq!(l.env.texels[5], [0.0, 1.0, 0.0]);
    assert_eq!((l.env.height, l.env.width), (4, 8));
    assert_eq!(l.env.convention, Convention::Paper);

    data[10][1] = f32::INFINITY; // row 1, column 2
    std::fs::write(&p, io::npy::encode_rgb(8, 4, &data)).unwrap();
    let e = msg(io::load_env(&p, Convention::Equirect).unwrap_err());
    assert!(
        e.contains("env.npy: texel (row 1, column 2) channel G is infinite"),
        "{e}"
    );
}

#[test]
fn env_downsampling() {
    let d = dir();
    let p = d.path().join("env.npy");
    let data: Vec<[f32; 3]> = (0..8 * 16).map(|i| [i as f32, 1.0, 0.0]).collect();
    std::fs::write(&p, io::npy::encode_rgb(16, 8, &data)).unwrap();
    let env = io::load_env(&p, Convention::Equirect).unwrap().env;
    let small = io::resample::fit(env.clone(), "4x4".parse().unwrap(), &p).unwrap();
    assert_eq!((small.height, small.width), (4, 4));
    // Top-left block: rows 0-1, columns 0-3; weights sin(theta) per row.
    let w = |r: usize| Convention::Equirect.texel(r, 0, 8, 16).1;
    let want = (0..2)
        .map(|r| (0..4).map(|c| (r * 16 + c) as f64 * w(r)).sum::<f64>())
        .sum::<f64>()
        / (4.0 * (w(0) + w(1)));
    assert!(
        (small.texels[0][0] as f64 - want).abs() < 1e-4,
        "{:?} vs {want}",
        small.texels[0]
    );
    assert!(small.texels.iter().all(|t| (t[1] - 1.0).abs() < 1e-6));
    assert_eq!(
        io::resample::fit(env.clone(), EnvSize::Full, &p).unwrap(),
        env
    );
    let e = msg(io::resample::fit(env, "3x16".parse().unwrap(), &p).unwrap_err());
    assert!(
        e.contains("env.npy") && e.contains("1, 2, 4, 8") && e.contains("4x8"),
        "{e}"
    );
}

fn write_material(d: &Path, name: &str, ctrl: &[f64]) -> PathBuf {
    let p = d.join(name);
    let text = format!(
        "{{\"name\": \"m\", \"ctrl\": [{}]}}",
        ctrl.iter()
            .map(|v| v.to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    std::fs::write(&p, text).unwrap();
    p
}

#[test]
fn material_json() {
    let d = dir();
    let gold = matedit::presets::lookup("gold").unwrap();
    let p = d.path().join("gold.json");
    std::fs::write(&p, io::json::encode_material(&gold, None)).unwrap();
    assert_eq!(io::load_material(&p).unwrap(), gold);

    let mut ctrl = gold.ctrl.to_vec();
    ctrl[6 + 2] = -1.0; // channel R, lobe 0, exponent, point 2
    let p = write_material(d.path(), "neg.json", &ctrl);
    let e = msg(io::load_material(&p).unwrap_err());
    assert!(
        e.contains("neg.json: ctrl[8] (channel R, lobe 0, exponent m1, point 2) is -1"),
        "{e}"
    );

    let p = write_material(d.path(), "short.json", &gold.ctrl[..107]);
    let e = msg(io::load_material(&p).unwrap_err());
    assert!(
        e.contains("short.json: 'ctrl' has 107 numbers") && e.contains("108"),
        "{e}"
    );

    std::fs::write(d.path().join("typo.json"), r#"{"ctlr": []}"#).unwrap();
    let e = msg(io::load_material(&d.path().join("typo.json")).unwrap_err());
    assert!(e.contains("typo.json") && e.contains("ctlr"), "{e}");

    // a type error names where it is
    std::fs::write(d.path().join("type.json"), r#"{"ctrl": [1, "x"]}"#).unwrap();
    let e = msg(io::load_material(&d.path().join("type.json")).unwrap_err());
    assert!(
        e.contains("type.json: not a material file: ctrl[1]: invalid type: string"),
        "{e}"
    );
}

#[test]
fn missing_files_and_unknown_extensions() {
    let d = dir();
    let e = msg(io::load_normals(&d.path().join("nope.npy")).unwrap_err());
    assert!(e.ends_with("nope.npy: no such file"), "{e}");
    let e = msg(io::load_env(&d.path().join("sky.hdr"), Convention::Equirect).unwrap_err());
    assert!(e.contains("sky.hdr") && e.contains(".exr or .npy"), "{e}");
    let e = msg(
        io::check_output(&d.path().join("no/such/dir/out.exr"), &[io::Format::Exr]).unwrap_err(),
    );
    assert!(e.contains("does not exist"), "{e}");
}

#[test]
fn staged_writes_leave_nothing_when_dropped() {
    let d = dir();
    let p = d.path().join("out.npy");
    let s = io::stage(&p, b"data").unwrap();
    assert!(!p.exists());
    drop(s);
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 0);
    let s = io::stage(&p, b"data").unwrap();
    io::commit_all(vec![s]).unwrap();
    assert_eq!(std::fs::read(&p).unwrap(), b"data");
    assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
}

#[test]
fn manifest_validation() {
    let d = dir();
    let p = d.path().join("batch.json");
    let write = |text: &str| std::fs::write(&p, text).unwrap();

    write(
        r#"{"env_size": "8x16", "scenes": [{"output": "a.exr", "sphere": 16, "preset": "gold"}, {"output": "b.npy", "normals": "n.npy", "env": "/abs/sky.exr"}]}"#,
    );
    let m = io::manifest::read(&p, None).unwrap();
    assert_eq!(m.scenes.len(), 2);
    assert_eq!(m.scenes[0].output, d.path().join("a.exr"));
    assert_eq!(m.scenes[1].env, Some(PathBuf::from("/abs/sky.exr")));
    let out = d.path().join("out");
    let m = io::manifest::read(&p, Some(&out)).unwrap();
    assert_eq!(m.scenes[1].output, out.join("b.npy"));

    let cases = [
        (r#"{"scenes": []}"#, "'scenes' is empty"),
        (
            r#"{"scenes": [{"output": "a.exr", "sphere": 4, "normals": "n.npy"}]}"#,
            "scenes[0]: give 'normals' or 'sphere'",
        ),
        (
            r#"{"scenes": [{"output": "a.exr", "preset": "unobtainium"}]}"#,
            "unknown preset 'unobtainium'",
        ),
        (
            r#"{"scenes": [{"output": "a.exr", "sphre": 4}]}"#,
            "scenes[0].sphre: unknown field `sphre`",
        ),
        (
            r#"{"scenes": [{"output": "a.exr"}, {"output": 5}]}"#,
            "scenes[1].output: invalid type: integer `5`",
        ),
        (r#"{"scenes": [{"sphere": 4}]}"#, "missing field `output`"),
        (
            r#"{"scenes": [{"output": "a.exr"}, {"output": "a.exr"}]}"#,
            "scenes[1]: output",
        ),
        (
            r#"{"env_size": "7", "scenes": [{"output": "a.exr"}]}"#,
            "env_size",
        ),
        (r#"{"fov": 200, "scenes": [{"output": "a.exr"}]}"#, "fov"),
        (r#"{"scenes": "#, "not a valid manifest"),
    ];
    for (text, want) in cases {
        write(text);
        let e = msg(io::manifest::read(&p, None).unwrap_err());
        assert!(e.contains("batch.json") && e.contains(want), "{text}: {e}");
    }
}

#[test]
fn procedural_env_is_valid_in_both_conventions() {
    for c in [Convention::Equirect, Convention::Paper] {
        for (h, w) in [(1, 1), (8, 16), (64, 128)] {
            let e = matedit::builtin_sky::procedural_env(h, w, c);
            assert_eq!((e.height, e.width, e.convention), (h, w, c));
            e.validate().unwrap();
        }
    }
}

/// `matedit info FILE`'s report on stdout (the report is the command line's).
fn info(path: &Path) -> String {
    let out = assert_cmd::cargo::cargo_bin_cmd!("matedit")
        .arg("info")
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn info_reports() {
    let d = dir();
    let p = d.path().join("env.npy");
    let mut data = vec![[0.5f32, 0.25, 2.0]; 4 * 8];
    data[3] = [-1.0, f32::NAN, 0.0];
    std::fs::write(&p, io::npy::encode_rgb(8, 4, &data)).unwrap();
    let r = info(&p);
    assert!(r.contains("8 wide x 4 high"), "{r}");
    assert!(
        r.contains("NaN values: 1") && r.contains("negative values: 1"),
        "{r}"
    );
    assert!(
        r.contains("env       no: pixel (3, 0) is not finite"),
        "{r}"
    );

    let m = d.path().join("m.json");
    std::fs::write(
        &m,
        io::json::encode_material(&matedit::presets::lookup("clay").unwrap(), None),
    )
    .unwrap();
    let r = info(&m);
    assert!(r.contains("material  yes"), "{r}");

    let x = d.path().join("x.exr");
    write_exr(&x, &image(4, 2), Compression::ZIP16);
    patch_compression(&x, 10);
    let r = info(&x);
    assert!(
        r.contains("cannot be used") && r.contains("HTJ2K256"),
        "{r}"
    );
}
