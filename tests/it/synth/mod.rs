//! `matedit synth`: the spec of docs/synth.md as written, the same chunk files (bit for
//! bit) from a whole run and from shards run in any order, a killed run resumed, every
//! sample's image against a render of its recorded inputs (through the library and
//! `matedit render`), and bad specs failing before anything is written.
//!
//! Datasets are tiny (16 x 16 images, 8 x 16 maps, 12 samples in chunks of 4, `--device
//! cpu`), except the spec of the documentation (64 x 64, 12 samples).

mod camera_effects;
mod clutter;
mod photo;
mod refusals;
mod renders;
mod shards;
mod sources;
mod spec;

use std::path::{Path, PathBuf};

use crate::common;
use common::{npy_rgb, synth_cmd};

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::io::{self, npy};
use matedit::synth;
use matedit::{Convention, NormalMap};

fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn s(p: &Path) -> &str {
    p.to_str().expect("UTF-8 path")
}

/// The procedural sky, `h` x `w`, as an EXR file.
fn write_sky(path: &Path, h: usize, w: usize) {
    let env = matedit::builtin_sky::procedural_env(h, w, Convention::Equirect);
    let bytes = io::exr::encode_rgb(w, h, &env.texels).expect("encode");
    std::fs::write(path, bytes).expect("write sky");
}

/// A folder with every kind of source: a normal map file, two env maps in a folder, a
/// material file; and the spec drawing from them.
fn small_spec(root: &Path) -> PathBuf {
    std::fs::create_dir_all(root.join("envs")).unwrap();
    write_sky(&root.join("envs/a.exr"), 16, 32);
    let texels: Vec<[f32; 3]> = (0..8 * 16)
        .map(|i| [0.2 + (i % 7) as f32 * 0.3, 0.5, 1.0 + (i / 16) as f32])
        .collect();
    std::fs::write(root.join("envs/b.npy"), npy::encode_rgb(16, 8, &texels)).unwrap();
    let bumpy = NormalMap::bumpy(16, 16, 99);
    std::fs::write(
        root.join("face.npy"),
        npy::encode_rgb(16, 16, &bumpy.normals),
    )
    .unwrap();
    let clay = matedit::presets::lookup("clay").unwrap();
    std::fs::write(
        root.join("clay.json"),
        io::json::encode_material(&clay, None),
    )
    .unwrap();
    let spec = root.join("spec.json");
    std::fs::write(
        &spec,
        r#"{
  "count": 12, "seed": 3, "image_size": 16, "env_size": "8x16", "chunk_size": 4,
  "normals": [{"sphere": 16}, {"bumpy": 16, "weight": 2}, "face.npy"],
  "envs": [{"folder": "envs"}, {"file": "envs/a.exr", "rotate": false}],
  "materials": [{"preset": "gold"}, {"random": "merl"}, {"file": "clay.json"},
                {"random": "merl", "mix": 2}]
}"#,
    )
    .unwrap();
    spec
}

/// Every data file (chunk tars and records) of a dataset folder with its bytes.
fn data(dir: &Path) -> Vec<(String, Vec<u8>)> {
    synth::data_files(dir)
        .unwrap()
        .into_iter()
        .map(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            (name, std::fs::read(&p).unwrap())
        })
        .collect()
}

fn names(d: &[(String, Vec<u8>)]) -> Vec<&str> {
    d.iter().map(|(n, _)| n.as_str()).collect()
}

fn manifest(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("manifest.json")).unwrap()).unwrap()
}

/// Pixels of a normal map that face the viewer (the object, not the background).
fn foreground(n: &matedit::NormalMap) -> usize {
    n.normals.iter().filter(|v| v[2] > 0.0).count()
}

/// Runs `spec` whole into `root/whole` and as `order.len()` shards, in that order, into
/// `root/split`, and checks that both wrote the same data files, byte for byte.
fn assert_shards_agree(spec: &Path, root: &Path, order: &[usize]) {
    let whole = root.join("whole");
    synth_cmd(spec, &whole, &[]).assert().success();
    let split = root.join("split");
    for i in order {
        synth_cmd(spec, &split, &["--shard", &format!("{i}/{}", order.len())])
            .assert()
            .success();
    }
    assert!(data(&whole) == data(&split), "the shards wrote other bytes");
}
