//! `matedit edit --box / --point / --not`: an object drawn on a cluttered background is
//! cut out from a box, a part of it is left out by points off it, and bad boxes and points
//! are refused with one line, exit 2 and nothing written.

use std::path::{Path, PathBuf};

use crate::common;

use matedit::Image;
use matedit::io::{self, Preview};
use matedit::splitmix::SplitMix;

/// A 240 x 180 PNG photo: tiles of random colours (6 pixels), a red disc of radius 50 at
/// (110, 90) shaded left to right, and a blue tab (x 160..190, y 80..100) joined to it;
/// the disc's and the tab's pixels.
fn photo(dir: &Path) -> (PathBuf, Vec<bool>, Vec<bool>) {
    let (w, h) = (240, 180);
    let mut rng = SplitMix(11);
    let tiles: Vec<[f32; 3]> = (0..40 * 30)
        .map(|_| {
            [
                0.05 + 0.4 * rng.uniform() as f32,
                0.1 + 0.5 * rng.uniform() as f32,
                0.05 + 0.3 * rng.uniform() as f32,
            ]
        })
        .collect();
    let mut img = Image::zeros(w, h);
    let (mut disc, mut tab) = (vec![false; w * h], vec![false; w * h]);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let dx = x as f64 + 0.5 - 110.0;
            disc[i] = dx.hypot(y as f64 + 0.5 - 90.0) < 50.0;
            tab[i] = !disc[i] && (150..190).contains(&x) && (80..100).contains(&y);
            img.pixels[i] = if disc[i] {
                let s = 0.6 + 0.3 * (dx / 50.0) as f32;
                [0.7 * s, 0.08 * s, 0.06 * s]
            } else if tab[i] {
                [0.05, 0.1, 0.8]
            } else {
                tiles[(y / 6) * 40 + x / 6]
            };
        }
    }
    let path = dir.join("clutter.png");
    std::fs::write(
        &path,
        io::png::encode_preview(&img, &Preview::default()).unwrap(),
    )
    .unwrap();
    (path, disc, tab)
}

fn test_weights() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/nets/weights.safetensors")
}

fn edit(photo: &Path, out: &Path, extra: &[&str]) -> assert_cmd::assert::Assert {
    edit_with(&test_weights(), photo, out, extra)
}

fn edit_with(
    weights: &Path,
    photo: &Path,
    out: &Path,
    extra: &[&str],
) -> assert_cmd::assert::Assert {
    assert_cmd::cargo::cargo_bin_cmd!("matedit")
        .arg("edit")
        .arg(photo)
        .args(["--material", "gold", "--no-refine", "--device", "cpu", "-o"])
        .arg(out)
        .arg("--weights")
        .arg(weights)
        .args(extra)
        .assert()
}

fn iou(a: &[bool], b: &[bool]) -> f64 {
    let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let any = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    both as f64 / any.max(1) as f64
}

fn mask(out: &Path) -> Vec<bool> {
    io::load_mask(&out.join("mask.png")).unwrap().2
}

#[test]
fn a_box_cuts_the_object_out_of_clutter() {
    let tmp = tempfile::tempdir().unwrap();
    let (p, disc, tab) = photo(tmp.path());
    let truth: Vec<bool> = disc.iter().zip(&tab).map(|(a, b)| *a || *b).collect();
    let out = tmp.path().join("box");
    edit(&p, &out, &["--box", "55,35,195,145"]).success();
    let j = iou(&mask(&out), &truth);
    assert!(j >= 0.9, "IoU {j}");
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out.join("report.json")).unwrap()).unwrap();
    assert_eq!(
        report["pointing"]["box"],
        serde_json::json!([55, 35, 195, 145])
    );
    assert!(report["seconds"]["segment"].as_f64().unwrap() > 0.0);
}

/// The test nets with the mask's bias at -100: they see no object anywhere.
fn blind_weights(dir: &Path) -> PathBuf {
    let bytes = std::fs::read(test_weights()).unwrap();
    common::rewritten_weights(&bytes, &dir.join("blind.safetensors"), |tensors, _| {
        let bias = tensors
            .iter_mut()
            .find(|(n, ..)| n == "normals.head.bias")
            .unwrap();
        assert_eq!((bias.1, &bias.2[..]), (safetensors::Dtype::F32, &[4][..]));
        bias.3[12..16].copy_from_slice(&(-100f32).to_le_bytes());
    })
}

#[test]
fn a_box_finds_the_object_where_the_nets_see_none() {
    // the nets' mask is a prior of the cut; where it leaves nothing in the box, the cut
    // goes by the photo's colours alone
    let tmp = tempfile::tempdir().unwrap();
    let (p, disc, tab) = photo(tmp.path());
    let truth: Vec<bool> = disc.iter().zip(&tab).map(|(a, b)| *a || *b).collect();
    let blind = blind_weights(tmp.path());
    let out = tmp.path().join("blind");
    edit_with(&blind, &p, &out, &["--box", "55,35,195,145"]).success();
    let j = iou(&mask(&out), &truth);
    assert!(j >= 0.9, "IoU {j}");
}

#[test]
fn points_off_the_object_leave_a_part_out() {
    let tmp = tempfile::tempdir().unwrap();
    let (p, disc, _) = photo(tmp.path());
    let out = tmp.path().join("not");
    edit(
        &p,
        &out,
        &[
            "--box",
            "55,35,195,145",
            "--point",
            "110,90",
            "--not",
            "180,90",
        ],
    )
    .success();
    let j = iou(&mask(&out), &disc);
    assert!(j >= 0.9, "IoU {j}");
    // points alone
    let out = tmp.path().join("points");
    edit(
        &p,
        &out,
        &["--point", "110,90", "--point", "90,70", "--not", "180,90"],
    )
    .success();
    let j = iou(&mask(&out), &disc);
    assert!(j >= 0.85, "IoU {j}");
}

#[test]
fn bad_boxes_and_points_are_refused() {
    let tmp = tempfile::tempdir().unwrap();
    let (p, _, _) = photo(tmp.path());
    let out = tmp.path().join("out");
    for (args, message) in [
        (
            vec!["--box", "10,10,900,50"],
            "--box 10,10,900,50: outside the 240x180 photo",
        ),
        (
            vec!["--point", "700,20"],
            "--point 700,20: outside the 240x180 photo",
        ),
        (
            vec!["--box", "10,10,12,50"],
            "--box 10,10,12,50: 2x40 pixels; at least 4 a side",
        ),
        (vec!["--box", "50,10,10,50"], "--box 50,10,10,50: empty"),
        (
            vec!["--box", "10,10,50"],
            "--box 10,10,50: 4 whole numbers of pixels expected",
        ),
        (
            vec!["--point", "-3,5"],
            "--point -3,5: 2 whole numbers of pixels expected",
        ),
        (
            vec!["--box", "10,10,100,100", "--point", "150,20"],
            "--point 150,20: outside the box 10,10,100,100",
        ),
        (
            vec!["--not", "20,20"],
            "--not: points off the object need a box or a point on it",
        ),
    ] {
        let a = edit(&p, &out, &args).code(2);
        let err = String::from_utf8(a.get_output().stderr.clone()).unwrap();
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(message), "{args:?}: {err}");
        assert!(!out.exists(), "{args:?} wrote {}", out.display());
    }
}
