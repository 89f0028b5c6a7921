//! A scene's inputs from files: normal maps (normalised, background, NaN, PNG), environment
//! maps (negatives clamped, downsampling, the procedural sky) and materials in JSON.

use std::path::{Path, PathBuf};

use matedit::Convention;
use matedit::io::{self, EnvSize};

use super::{dir, msg};

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
fn procedural_env_is_valid_in_both_conventions() {
    for c in [Convention::Equirect, Convention::Paper] {
        for (h, w) in [(1, 1), (8, 16), (64, 128)] {
            let e = matedit::builtin_sky::procedural_env(h, w, c);
            assert_eq!((e.height, e.width, e.convention), (h, w, c));
            e.validate().unwrap();
        }
    }
}
