//! End-to-end runs of the `matedit` binary: every subcommand's happy path, every output
//! format read back with `matedit::io` and compared with a render done through the library
//! on the same (fast CPU) path, the devices and thread counts against each other, and every
//! kind of bad input (exit code 2, a one-line error naming the file, no output left behind,
//! no panic).
//!
//! Scenes are tiny (16 x 16 sphere, 8 x 16 environment, `--device cpu`).

mod devices;
mod errors;
mod grad;
mod info;
mod lod;
mod render;

use std::path::Path;

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::io;
use matedit::{
    Batch, Camera, Convention, Device, EnvMap, Image, Material, NormalMap, Renderer, Scene,
};

/// The small scene options every test uses.
pub(super) const SMALL: [&str; 6] = ["--sphere", "16", "--env-size", "8x16", "--device", "cpu"];

pub(super) fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

/// `matedit render -o OUT` of an 8-pixel sphere against a 4x8 map: the smallest real render.
pub(super) fn tiny_render(out: &Path) -> assert_cmd::Command {
    let mut cmd = matedit();
    cmd.args([
        "render",
        "-o",
        path_str(out),
        "--sphere",
        "8",
        "--env-size",
        "4x8",
    ]);
    cmd
}

pub(super) fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

pub(super) fn cpu() -> Renderer {
    Renderer::new(Device::Cpu).expect("CPU renderer")
}

pub(super) fn default_material() -> Material {
    matedit::presets::lookup(matedit::presets::DEFAULT).expect("default preset")
}

pub(super) fn procedural(h: usize, w: usize) -> EnvMap {
    matedit::builtin_sky::procedural_env(h, w, Convention::Equirect)
}

/// The scene that `SMALL` with no other option describes.
pub(super) fn small_scene() -> Scene {
    Scene {
        normals: NormalMap::sphere(16),
        env: procedural(8, 16),
        material: default_material(),
        camera: Camera::Orthographic,
    }
}

pub(super) fn render_lib(scenes: Vec<Scene>) -> Vec<Image> {
    cpu().render(&Batch::new(scenes).unwrap()).unwrap()
}

/// Same CPU code on both sides, so only float formatting could differ: demand 1e-6.
pub(super) fn assert_close(actual: &[[f32; 3]], expected: &[[f32; 3]]) {
    assert_eq!(actual.len(), expected.len(), "pixel counts");
    let mut worst = (0.0f32, 0);
    for (i, (a, e)) in actual.iter().zip(expected).enumerate() {
        for k in 0..3 {
            let err = (a[k] - e[k]).abs() / e[k].abs().max(1.0);
            if err > worst.0 || err.is_nan() {
                worst = (err, i);
            }
        }
    }
    assert!(
        worst.0 <= 1e-6,
        "pixel {}: {:?} vs {:?}",
        worst.1,
        actual[worst.1],
        expected[worst.1]
    );
}

/// Files in `d`, temporary files included.
pub(super) fn listing(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Runs a command that must fail on bad input: exit code 2, one line on stderr that starts
/// with "error: " and contains every string of `want`, no panic, and `d` unchanged.
pub(super) fn fails_with(cmd: &mut assert_cmd::Command, d: &Path, want: &[&str]) -> String {
    let before = listing(d);
    let out = cmd.output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr).into_owned();
    assert_eq!(out.status.code(), Some(2), "stderr: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let lines: Vec<&str> = stderr.lines().collect();
    assert_eq!(lines.len(), 1, "one line expected: {stderr}");
    assert!(lines[0].starts_with("error: "), "{stderr}");
    for w in want {
        assert!(stderr.contains(w), "'{w}' not in: {stderr}");
    }
    assert_eq!(listing(d), before, "the failed run left files behind");
    stderr
}

pub(super) fn write_npy(path: &Path, w: usize, h: usize, data: &[[f32; 3]]) {
    std::fs::write(path, io::npy::encode_rgb(w, h, data)).unwrap();
}

pub(super) fn write_exr(path: &Path, w: usize, h: usize, data: &[[f32; 3]]) {
    std::fs::write(path, io::exr::encode_rgb(w, h, data).unwrap()).unwrap();
}

/// A 16 x 32 environment with structure, a bright spot and some negative texels.
pub(super) fn env_texels() -> Vec<[f32; 3]> {
    (0..16 * 32)
        .map(|i| {
            let (r, c) = (i / 32, i % 32);
            let mut t = [
                0.2 + 0.05 * c as f32,
                1.0 - 0.05 * r as f32,
                0.5 + 0.3 * ((r + c) % 3) as f32,
            ];
            if (r, c) == (4, 6) {
                t = [200.0, 150.0, 100.0];
            }
            if i % 37 == 0 {
                t[1] = -0.01;
            }
            t
        })
        .collect()
}

pub(super) fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

pub(super) fn write_manifest(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}
