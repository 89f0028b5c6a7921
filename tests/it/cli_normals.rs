//! `matedit normals` end to end: its outputs read back against the library's normals, a
//! round trip through `matedit render --normals`, and bad input (exit code 2, one line
//! naming the file and the element, no output left behind).

use std::path::Path;

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::io;
use matedit::shapes::{self, Rotation, Shape, View};

fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// The library's normals for `--shape blobby --seed 3 --size 24x32`.
fn expected() -> (matedit::NormalMap, Vec<bool>) {
    let mesh = "blobby".parse::<Shape>().unwrap().mesh(3);
    let view = View {
        rotation: Rotation::random(3),
        ..View::new(32, 24)
    };
    shapes::render_normals(&mesh, &view).unwrap()
}

fn normals_cmd(out: &Path) -> assert_cmd::Command {
    let mut cmd = matedit();
    cmd.args([
        "normals",
        "--shape",
        "blobby",
        "--seed",
        "3",
        "--size",
        "24x32",
        "-o",
        s(out),
    ]);
    cmd
}

#[test]
fn npy_and_exr_outputs_are_the_library_normals() {
    let dir = tempfile::tempdir().unwrap();
    let (want, want_mask) = expected();
    for name in ["n.npy", "n.exr"] {
        let out = dir.path().join(name);
        let mask = dir.path().join(format!("{name}.mask.npy"));
        normals_cmd(&out)
            .args(["--mask", s(&mask)])
            .assert()
            .success();
        // the loader normalises; the stored normals survive that bit for bit
        assert_eq!(io::load_normals(&out).unwrap(), want, "{name}");
        let (w, h, m) = io::load_mask(&mask).unwrap();
        assert_eq!((w, h), (32, 24));
        assert_eq!(m, want_mask, "{name}");
    }
}

#[test]
fn png_output_renders_through_render() {
    let dir = tempfile::tempdir().unwrap();
    let (want, want_mask) = expected();
    let out = dir.path().join("n.png");
    let mask = dir.path().join("mask.png");
    normals_cmd(&out)
        .args(["--mask", s(&mask)])
        .assert()
        .success();
    let got = io::load_normals(&out).unwrap();
    assert_eq!(io::load_mask(&mask).unwrap().2, want_mask);
    for (i, (g, e)) in got.normals.iter().zip(&want.normals).enumerate() {
        // alpha is the mask; 8 bits hold each component to 1/255
        assert_eq!(got.is_background(i), !want_mask[i], "pixel {i}");
        for c in 0..3 {
            assert!((g[c] - e[c]).abs() < 0.01, "pixel {i}: {g:?} vs {e:?}");
        }
    }
    let image = dir.path().join("render.npy");
    matedit()
        .args(["render", "--normals", s(&out), "-o", s(&image)])
        .args(["--env-size", "8x16", "--device", "cpu"])
        .assert()
        .success();
    let rendered = io::load_upstream(&image).unwrap();
    assert_eq!((rendered.width, rendered.height), (32, 24));
    for (i, p) in rendered.pixels.iter().enumerate() {
        if want_mask[i] {
            assert!(p.iter().sum::<f32>() > 0.0, "object pixel {i} is black");
        } else {
            assert_eq!(*p, [0.0; 3], "background pixel {i}");
        }
    }
}

#[test]
fn a_mesh_file_with_options() {
    let dir = tempfile::tempdir().unwrap();
    let mesh = dir.path().join("tri.off");
    std::fs::write(
        &mesh,
        "OFF\n4 2 0\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n3 0 1 2\n3 0 2 3\n",
    )
    .unwrap();
    let out = dir.path().join("sq.npy");
    matedit()
        .args(["normals", "--mesh", s(&mesh), "-o", s(&out), "--size", "16"])
        .args([
            "--fov", "30", "--rotate", "-20,10,5", "--flat", "--margin", "0.1",
        ])
        .assert()
        .success();
    let map = io::load_normals(&out).unwrap();
    // one flat square: every pixel on it has the same normal, the square's, facing the camera
    let fg: Vec<[f32; 3]> = (0..256)
        .filter(|&i| !map.is_background(i))
        .map(|i| map.normals[i])
        .collect();
    assert!(fg.len() > 100, "{} pixels", fg.len());
    let r = Rotation {
        yaw: -20.0,
        pitch: 10.0,
        roll: 5.0,
    }
    .matrix();
    let want = [r[0][2], r[1][2], r[2][2]];
    for n in fg {
        for c in 0..3 {
            assert!((n[c] as f64 - want[c]).abs() < 1e-6, "{n:?} vs {want:?}");
        }
    }
}

/// Runs `matedit normals ARGS -o OUT --mask MASK` expecting exit code 2 and one line on
/// stderr that contains `want`; neither file may exist afterwards.
fn fails(dir: &Path, args: &[&str], want: &str) {
    let out = dir.join("out.png");
    let mask = dir.join("mask.png");
    let assert = matedit()
        .arg("normals")
        .args(args)
        .args(["-o", s(&out), "--mask", s(&mask)])
        .assert()
        .code(2);
    let stderr = String::from_utf8_lossy(&assert.get_output().stderr).to_string();
    assert!(stderr.contains(want), "{args:?}: {stderr}");
    if !stderr.contains("try '--help'") {
        // the library's errors: one line (clap's usage errors have their own layout)
        assert_eq!(stderr.trim_end().lines().count(), 1, "{args:?}: {stderr}");
    }
    assert!(
        !out.exists() && !mask.exists(),
        "{args:?}: an output was left behind"
    );
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}

#[test]
fn bad_input_fails_cleanly() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let obj = d.join("bunny.obj");
    std::fs::write(&obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 900\n").unwrap();
    fails(
        d,
        &["--mesh", s(&obj)],
        "bunny.obj: line 5: face 1: vertex index 900 out of range (3 vertices)",
    );
    let stl = d.join("empty.stl");
    std::fs::write(&stl, [0u8; 84]).unwrap();
    fails(
        d,
        &["--mesh", s(&stl)],
        "empty.stl: the mesh has no triangles",
    );
    fails(
        d,
        &["--mesh", s(&d.join("none.ply"))],
        "none.ply: no such file",
    );
    fails(d, &["--shape", "blobbi"], "unknown kind 'blobbi'");
    fails(
        d,
        &["--shape", "torus", "--size", "0"],
        "each side must be between 1 and 8192",
    );
    fails(
        d,
        &["--shape", "torus", "--rotate", "1,2"],
        "YAW,PITCH,ROLL",
    );
    fails(d, &["--shape", "torus", "--fov", "180"], "180");
    fails(
        d,
        &["--shape", "torus", "--mesh", s(&obj)],
        "cannot be used with",
    );
    // an output format it cannot write: refused before any work
    let assert = matedit()
        .args(["normals", "--shape", "torus", "-o", s(&d.join("n.jpg"))])
        .assert()
        .code(2);
    assert!(
        String::from_utf8_lossy(&assert.get_output().stderr)
            .contains("n.jpg: the output must be a .exr, .npy or .png file")
    );
}
