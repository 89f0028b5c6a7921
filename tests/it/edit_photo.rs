//! `matedit edit`: a photo the test renders (a procedural shape under the built-in sky,
//! on a grey background), edited with a preset, a material file and another photo's
//! material, with the small nets of tests/data/nets and with the built-in ones; the
//! outputs exist and are sane, refinement lowers the loss and raises the PSNR of the
//! re-rendered photo, and bad inputs fail with one line, exit 2 and nothing written.

use std::path::{Path, PathBuf};

use crate::common;
use crate::photos::{photo, photo_on, red_blob, wide_photo};

use matedit::io;
use matedit::{Device, Renderer};

fn small_weights() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/nets/weights.safetensors")
}

pub(crate) fn edit(args: &[&std::ffi::OsStr]) -> assert_cmd::Command {
    let mut cmd = assert_cmd::cargo::cargo_bin_cmd!("matedit");
    cmd.arg("edit").args(args).args(["--device", "cpu"]);
    cmd
}

pub(crate) fn report(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("report.json")).unwrap()).unwrap()
}

#[test]
fn a_photo_on_black_is_taken_as_exposed_for_a_grey_card_and_says_so() {
    let tmp = tempfile::tempdir().unwrap();
    let (grey, grey_mask) = photo(tmp.path(), "grey", "blobby:seed=3", "plastic-red", 64);
    let (black, black_mask) = photo_on(tmp.path(), "black", "sphere", "gold", (64, 64), 0.0);
    let out = tmp.path().join("out");
    let run = edit(&[
        grey.as_os_str(),
        "--mask".as_ref(),
        grey_mask.as_os_str(),
        "--like".as_ref(),
        black.as_os_str(),
        "--like-mask".as_ref(),
        black_mask.as_os_str(),
        "-o".as_ref(),
        out.as_os_str(),
        "--steps".as_ref(),
        "2".as_ref(),
    ])
    .assert()
    .success();
    let stderr = String::from_utf8_lossy(&run.get_output().stderr).into_owned();
    let r = report(&out);
    assert_eq!(r["light_level_from"], "background", "{r}");
    assert_eq!(r["like_light_level_from"], "grey card", "{r}");
    let notices: Vec<&str> = stderr.lines().filter(|l| l.contains("grey card")).collect();
    assert_eq!(notices.len(), 1, "{stderr}");
    assert!(
        notices[0].contains("--like") && notices[0].contains("black.png"),
        "{stderr}"
    );
}

#[test]
fn a_photo_edited_with_a_preset_a_file_and_another_photo() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, a_mask) = photo(tmp.path(), "a", "blobby:seed=3", "plastic-red", 96);
    let (b, _) = photo(tmp.path(), "b", "torus:seed=2", "gold", 80);
    let out = tmp.path().join("out");
    edit(&[
        a.as_os_str(),
        "--mask".as_ref(),
        a_mask.as_os_str(),
        "--material".as_ref(),
        "gold".as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
        "--steps".as_ref(),
        "40".as_ref(),
        "--normal-steps".as_ref(),
        "20".as_ref(),
    ])
    .assert()
    .success();
    for f in [
        "edit.png",
        "normals.png",
        "mask.png",
        "light.exr",
        "material.json",
        "sphere.png",
        "compare.png",
        "report.json",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    let r = report(&out);
    assert_eq!(r["size"], serde_json::json!([96, 96]));
    assert_eq!(r["steps"], 40);
    // the normals' refinement takes steps that lower its loss, at most the 20 asked for
    let taken = r["normal_steps"].as_u64().unwrap();
    assert!((1..=20).contains(&taken), "{r}");
    assert!(
        r["normal_loss_last"].as_f64().unwrap() < r["normal_loss_first"].as_f64().unwrap(),
        "{r}"
    );
    // refinement lowers the loss and brings the re-rendered photo closer
    assert!(
        r["loss_last"].as_f64().unwrap() < r["loss_first"].as_f64().unwrap(),
        "{r}"
    );
    assert!(
        r["psnr_refined_db"].as_f64().unwrap() > r["psnr_predicted_db"].as_f64().unwrap(),
        "{r}"
    );
    // the edit keeps the background and changes the object
    let photo_img = io::load_image(&a).unwrap();
    let edited = io::load_image(&out.join("edit.png")).unwrap();
    let (_, _, mask) = io::load_mask(&a_mask).unwrap();
    let blurred_edge = |i: usize| {
        let (x, y) = ((i % 96) as i64, (i / 96) as i64);
        (-1..=1).any(|dy| {
            (-1..=1).any(|dx| {
                let (xx, yy) = (x + dx, y + dy);
                (0..96).contains(&xx) && (0..96).contains(&yy) && mask[(yy * 96 + xx) as usize]
            })
        })
    };
    let mut changed = 0;
    for (i, (p, e)) in photo_img.pixels.iter().zip(&edited.pixels).enumerate() {
        if !blurred_edge(i) {
            assert!(
                (0..3).all(|k| (p[k] - e[k]).abs() < 1e-6),
                "background pixel {i} changed"
            );
        } else if mask[i] && (0..3).any(|k| (p[k] - e[k]).abs() > 0.02) {
            changed += 1;
        }
    }
    let on = mask.iter().filter(|&&m| m).count();
    assert!(changed > on / 2, "{changed} of {on} object pixels changed");

    // a material file, the small nets, no refinement
    let gold = tmp.path().join("gold.json");
    std::fs::write(
        &gold,
        io::json::encode_material(&matedit::presets::lookup("gold").unwrap(), None),
    )
    .unwrap();
    let out2 = tmp.path().join("out2");
    edit(&[
        a.as_os_str(),
        "--material".as_ref(),
        gold.as_os_str(),
        "-o".as_ref(),
        out2.as_os_str(),
        "--no-refine".as_ref(),
        "--weights".as_ref(),
        small_weights().as_os_str(),
        "--mask".as_ref(),
        a_mask.as_os_str(),
    ])
    .assert()
    .success();
    let r2 = report(&out2);
    assert_eq!(r2["steps"], 0);
    assert_eq!(r2["psnr_refined_db"], r2["psnr_predicted_db"]);
    // with the same material and no refinement the edit is the same picture
    assert_eq!(
        std::fs::read(out.join("mask.png")).unwrap(),
        std::fs::read(out2.join("mask.png")).unwrap()
    );

    // another photo's material (the nets find b's object: no mask)
    let out3 = tmp.path().join("out3");
    edit(&[
        a.as_os_str(),
        "--like".as_ref(),
        b.as_os_str(),
        "-o".as_ref(),
        out3.as_os_str(),
        "--steps".as_ref(),
        "10".as_ref(),
        "--mask".as_ref(),
        a_mask.as_os_str(),
    ])
    .assert()
    .success();
    assert!(report(&out3)["seconds"]["like"].as_f64().unwrap() > 0.0);

    // the grid from photos: row i keeps photo i, column j brings photo j's material
    let grid = tmp.path().join("grid.png");
    let mut cmd = assert_cmd::cargo::cargo_bin_cmd!("matedit");
    cmd.arg("grid")
        .args([&a, &b])
        .args(["--cell", "32", "--steps", "5", "--device", "cpu", "-o"])
        .arg(&grid);
    cmd.assert().success();
    let g = io::load_image(&grid).unwrap();
    assert_eq!((g.width, g.height), (2 * 32 + 3 * 4, 2 * 32 + 3 * 4)); // cells and 4-pixel gaps
}

#[test]
fn bad_inputs_fail_with_one_line_and_write_nothing() {
    let tmp = tempfile::tempdir().unwrap();
    let (a, a_mask) = photo(tmp.path(), "a", "capsule:seed=1", "plastic-red", 48);
    let not_image = tmp.path().join("notes.png");
    std::fs::write(&not_image, b"hello").unwrap();
    let empty = tmp.path().join("empty.png");
    std::fs::write(
        &empty,
        io::png::encode_mask(48, 48, &vec![false; 48 * 48]).unwrap(),
    )
    .unwrap();
    let full = tmp.path().join("full.png");
    std::fs::write(
        &full,
        io::png::encode_mask(48, 48, &vec![true; 48 * 48]).unwrap(),
    )
    .unwrap();
    let tiny = tmp.path().join("tiny.png");
    std::fs::write(
        &tiny,
        io::png::encode_rgb8(12, 12, &[100u8; 12 * 12 * 3]).unwrap(),
    )
    .unwrap();
    let huge = tmp.path().join("huge.png");
    std::fs::write(
        &huge,
        io::png::encode_rgb8(8200, 2, &vec![100u8; 8200 * 2 * 3]).unwrap(),
    )
    .unwrap();
    let out = tmp.path().join("out");
    let cases: Vec<(Vec<&std::ffi::OsStr>, &str)> = vec![
        (
            vec![
                not_image.as_os_str(),
                "--material".as_ref(),
                "gold".as_ref(),
            ],
            "notes.png",
        ),
        (
            vec![
                a.as_os_str(),
                "--mask".as_ref(),
                empty.as_os_str(),
                "--material".as_ref(),
                "gold".as_ref(),
            ],
            "0 pixels on the object",
        ),
        (
            vec![
                a.as_os_str(),
                "--mask".as_ref(),
                full.as_os_str(),
                "--material".as_ref(),
                "gold".as_ref(),
            ],
            "no background",
        ),
        (
            vec![tiny.as_os_str(), "--material".as_ref(), "gold".as_ref()],
            "too small to hold an object",
        ),
        (
            vec![huge.as_os_str(), "--material".as_ref(), "gold".as_ref()],
            "over the limit",
        ),
        (
            vec![
                a.as_os_str(),
                "--mask".as_ref(),
                a_mask.as_os_str(),
                "--material".as_ref(),
                "unobtainium".as_ref(),
            ],
            "not a preset",
        ),
        (
            vec![
                a.as_os_str(),
                "--mask".as_ref(),
                tiny.as_os_str(),
                "--material".as_ref(),
                "gold".as_ref(),
            ],
            "mask is 12x12",
        ),
    ];
    for (args, want) in cases {
        let mut all = args.clone();
        all.extend(["-o".as_ref(), out.as_os_str()]);
        let o = edit(&all).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{want}: {err}");
        assert!(err.contains(want), "{want}: {err}");
        assert_eq!(
            err.trim()
                .lines()
                .filter(|l| l.starts_with("error"))
                .count(),
            1,
            "{err}"
        );
        assert!(!out.exists(), "{want}: wrote {}", out.display());
    }
}

/// The photo's own material gives the photo back with all of its detail, and the render
/// alone (the object as the layer explains it) with none; the light takes the grey
/// background's level.
#[test]
fn the_photos_own_material_gives_it_back() {
    use matedit::edit::photo::{self, PhotoOptions};
    let tmp = tempfile::tempdir().unwrap();
    let (img, mask) = red_blob(tmp.path());
    let renderer = Renderer::new(Device::Cpu).unwrap();
    let nets = matedit::nets::Nets::builtin().unwrap();
    let options = PhotoOptions::default();
    let mut d = photo::decompose(
        &renderer,
        &nets,
        &img,
        Some(mask.as_slice()),
        &options,
        &mut |_| {},
    )
    .unwrap();
    assert!(
        d.light_factors.gains.iter().all(|&f| f != 1.0),
        "{:?}",
        d.light_factors
    );
    let psnr = |e: &matedit::Image| {
        let (mut se, mut n) = (0.0f64, 0usize);
        for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
            for k in 0..3 {
                se += f64::from(e.pixels[i][k] - img.pixels[i][k]).powi(2);
                n += 1;
            }
        }
        10.0 * (1.0 / (se / n as f64).max(1e-30)).log10()
    };
    let own = d
        .edit(&renderer, &img, &d.material, None, matedit::Accuracy::Exact)
        .unwrap();
    eprintln!("own material: {:.2} dB", psnr(&own));
    assert!(psnr(&own) > 60.0, "own material: {} dB", psnr(&own));
    d.detail = 0.0;
    let rendered = d
        .edit(&renderer, &img, &d.material, None, matedit::Accuracy::Exact)
        .unwrap();
    let object = d
        .render_object(&renderer, &d.material, None, matedit::Accuracy::Exact)
        .unwrap();
    let inside: Vec<usize> = (0..mask.len()).filter(|&i| d.alpha[i] == 1.0).collect();
    assert!(!inside.is_empty());
    for &i in &inside {
        for k in 0..3 {
            assert!(
                (rendered.pixels[i][k] - object.pixels[i][k]).abs() < 1e-5,
                "pixel {i}"
            );
        }
    }
    assert!(psnr(&rendered) < psnr(&own));
}

/// The built-in nets' weights with their metadata's `frame` set to "photo".
fn photo_frame_weights(dir: &Path) -> PathBuf {
    let out = dir.join("photo_frame.safetensors");
    common::rewritten_weights(matedit::nets::BUILTIN_WEIGHTS, &out, |_, meta| {
        let mut config: serde_json::Value = serde_json::from_str(&meta["config"]).unwrap();
        config["frame"] = "photo".into();
        meta.insert("config".into(), config.to_string());
    })
}

#[test]
fn nets_of_photo_frames_see_a_photo_at_its_own_shape() {
    // without a mask the nets find the object on the whole photo: nets whose weights say
    // they saw photo-like frames see it at its own shape, not padded to a square
    let tmp = tempfile::tempdir().unwrap();
    let weights = photo_frame_weights(tmp.path());
    for (name, shape, size) in [
        ("wide", "blobby:seed=3", (160, 96)),
        ("tall", "capsule:seed=1", (96, 160)),
    ] {
        let (p, p_mask) = wide_photo(tmp.path(), name, shape, "plastic-red", size);
        let (_, _, truth) = io::load_mask(&p_mask).unwrap();
        let found = |out: &Path, extra: &[&str]| {
            let run = edit(&[p.as_os_str(), "--material".as_ref(), "gold".as_ref()])
                .args(["-o".as_ref(), out.as_os_str()])
                .args(["--steps", "2"])
                .args(extra)
                .output()
                .unwrap();
            run.status
                .success()
                .then(|| io::load_mask(&out.join("mask.png")).unwrap().2)
        };
        let framed = found(
            &tmp.path().join(format!("{name}_photo")),
            &["--weights", weights.to_str().unwrap()],
        )
        .expect("the object found");
        let both = framed
            .iter()
            .zip(&truth)
            .filter(|(a, b)| **a && **b)
            .count();
        let either = framed
            .iter()
            .zip(&truth)
            .filter(|(a, b)| **a || **b)
            .count();
        let iou = both as f64 / either as f64;
        assert!(iou > 0.9, "{name}: IoU {iou}");
        // the same nets as they are (square frames) see it otherwise
        let square = found(&tmp.path().join(format!("{name}_square")), &[]);
        assert!(square.as_ref() != Some(&framed), "{name}");
    }
}
