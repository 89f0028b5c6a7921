//! Camera effects and the true edit (`"camera_effects"`, `"edit"`): off by default (a
//! spec without them writes the bytes it wrote before), deterministic and shardable,
//! images on the 8-bit sRGB grid, the edit equal to the image off the object, bad values
//! refused in one line.
//!
//! Tiny datasets: 16 x 16 spheres over the map seen through the camera, 8 samples.

use std::path::{Path, PathBuf};

use matedit::synth::camera_effects::srgb8_table;
use matedit::synth::{self, Engine, tar};
use matedit::{Batch, Device};

use super::{data, dir, npy_rgb, synth_cmd, write_sky};

const ALL: &str = r#""camera_effects": {"exposure": [-1, 1], "noise": [0.02, 0.05],
    "jpeg": [40, 90], "defocus": [0.5, 2], "vignette": [0, 0.3]},
    "edit": {"materials": [{"preset": "clay"}, {"random": "merl", "perturb": true}]}"#;

/// A spec over a sky, with `extra` keys (JSON members, or "") added.
fn spec(root: &Path, name: &str, extra: &str) -> PathBuf {
    if !root.join("sky.exr").exists() {
        write_sky(&root.join("sky.exr"), 16, 32);
    }
    let path = root.join(name);
    let sep = if extra.is_empty() { "" } else { "," };
    std::fs::write(
        &path,
        format!(
            r#"{{"count": 8, "seed": 4, "image_size": 16, "env_size": "8x16", "chunk_size": 4,
  "normals": [{{"sphere": 16}}], "envs": ["sky.exr"], "backgrounds": ["env"],
  "materials": [{{"preset": "gold"}}, {{"random": "merl"}}]{sep} {extra}}}"#
        ),
    )
    .unwrap();
    path
}

fn engine() -> Engine {
    Engine::new(Device::Cpu).unwrap()
}

/// Chunk `c`'s samples: each a list of (suffix, bytes).
fn samples(spec: &synth::Spec, c: u64) -> Vec<Vec<(String, Vec<u8>)>> {
    let bytes = synth::render_chunk(spec, &engine(), c, &|_| {}).unwrap();
    let mut out: Vec<Vec<(String, Vec<u8>)>> = Vec::new();
    let mut key = String::new();
    for (name, b) in tar::decode(&bytes).unwrap() {
        let (k, suffix) = name.split_once('.').unwrap();
        if k != key {
            out.push(Vec::new());
            key = k.to_string();
        }
        out.last_mut().unwrap().push((suffix.to_string(), b));
    }
    out
}

fn get<'a>(sample: &'a [(String, Vec<u8>)], suffix: &str) -> &'a [u8] {
    &sample.iter().find(|(s, _)| s == suffix).unwrap().1
}

fn params(sample: &[(String, Vec<u8>)]) -> serde_json::Value {
    serde_json::from_slice(get(sample, "params.json")).unwrap()
}

#[test]
fn without_the_keys_a_sample_is_written_as_before() {
    let t = dir();
    let sp = synth::Spec::load(&spec(t.path(), "spec.json", "")).unwrap();
    assert_eq!(sp.members(), tar::MEMBERS);
    // the old path: render, compose over the background, the six members
    let e = engine();
    let old: Vec<tar::Keyed> = (4..8)
        .map(|k| {
            let sample = sp.sample(k).unwrap();
            let batch = Batch::single(sample.scene.clone()).unwrap();
            let image = sample.compose(e.renderer.render(&batch).unwrap().remove(0));
            (format!("{k:08}"), tar::members(&sample, &image, &e.label))
        })
        .collect();
    let bytes = synth::render_chunk(&sp, &e, 1, &|_| {}).unwrap();
    assert!(
        bytes == tar::encode(&old).unwrap(),
        "other bytes without the keys"
    );

    // with them, the scene's members and draws are those of the spec without them, the
    // light scaled by the exposure's gain
    let with = synth::Spec::load(&spec(t.path(), "with.json", ALL)).unwrap();
    let (a, b) = (samples(&sp, 1), samples(&with, 1));
    for (x, y) in a.iter().zip(&b) {
        for m in ["mask.npy", "material.json", "normals.npy"] {
            assert!(get(x, m) == get(y, m), "{m}");
        }
        let gain = params(y)["camera_effects"]["gain"].as_f64().unwrap() as f32;
        let (_, _, env_x) = npy_rgb(get(x, "env.npy"));
        let (_, _, env_y) = npy_rgb(get(y, "env.npy"));
        let scaled: Vec<[f32; 3]> = env_x.iter().map(|p| p.map(|v| v * gain)).collect();
        assert_eq!(env_y, scaled);
        let mut p = params(y);
        let o = p.as_object_mut().unwrap();
        assert!(o.remove("camera_effects").is_some() && o.remove("edit").is_some());
        assert_eq!(p, params(x));
        assert_ne!(get(x, "image.npy"), get(y, "image.npy"));
    }
}

#[test]
fn effects_and_edit_are_deterministic_and_shardable() {
    let t = dir();
    let path = spec(t.path(), "spec.json", ALL);
    let sp = synth::Spec::load(&path).unwrap();
    assert_eq!(samples(&sp, 0), samples(&sp, 0));
    let whole = t.path().join("whole");
    synth_cmd(&path, &whole, &[]).assert().success();
    let split = t.path().join("split");
    for i in [1, 0] {
        let shard = format!("{i}/2");
        synth_cmd(&path, &split, &["--shard", &shard, "--threads", "1"])
            .assert()
            .success();
    }
    assert!(data(&whole) == data(&split), "the shards wrote other bytes");
    let m: serde_json::Value =
        serde_json::from_slice(&std::fs::read(whole.join("manifest.json")).unwrap()).unwrap();
    assert_eq!(m["members"][0], "edit.npy");
    assert_eq!(m["members"][1], "edit_material.json");
    let members = tar::decode(&std::fs::read(whole.join("chunk-000000.tar")).unwrap()).unwrap();
    let first: Vec<&str> = members[..8].iter().map(|(n, _)| n.as_str()).collect();
    let mut sorted = first.clone();
    sorted.sort();
    assert_eq!(first, sorted);
    assert_eq!(first[0], "00000000.edit.npy");
}

#[test]
fn images_and_edits_lie_on_the_8_bit_srgb_grid() {
    let t = dir();
    let sp = synth::Spec::load(&spec(t.path(), "spec.json", ALL)).unwrap();
    let table = srgb8_table();
    for x in samples(&sp, 0) {
        for m in ["image.npy", "edit.npy"] {
            let (_, _, px) = npy_rgb(get(&x, m));
            assert!(px.iter().flatten().all(|v| table.contains(v)), "{m}");
        }
        let p = params(&x);
        let fx = &p["camera_effects"];
        let q = fx["jpeg_quality"].as_u64().unwrap();
        assert!((40..=90).contains(&q), "{fx}");
        assert!(fx["read_noise_std"].as_f64().unwrap() > 0.0, "{fx}");
        for k in [
            "exposure_stops",
            "defocus_sigma",
            "vignette",
            "noise_level",
            "noise_seed",
        ] {
            assert!(fx[k].is_number(), "{k}: {fx}");
        }
        assert!(p["edit"]["material_item"].is_number(), "{p}");
    }
}

#[test]
fn jpeg_quality_changes_the_bytes() {
    let t = dir();
    let q = |name: &str, q: u8| {
        let extra = format!(r#""camera_effects": {{"jpeg": [{q}, {q}]}}"#);
        synth::Spec::load(&spec(t.path(), name, &extra)).unwrap()
    };
    let (a, b) = (samples(&q("a.json", 20), 0), samples(&q("b.json", 95), 0));
    for (x, y) in a.iter().zip(&b) {
        assert_ne!(get(x, "image.npy"), get(y, "image.npy"));
        assert_eq!(get(x, "normals.npy"), get(y, "normals.npy"));
    }
}

#[test]
fn no_noise_no_jpeg_no_exposure_leaves_the_auto_exposure_and_8_bit_quantisation() {
    let t = dir();
    let plain = synth::Spec::load(&spec(t.path(), "plain.json", "")).unwrap();
    let extra = r#""camera_effects": {"noise": [0, 0], "exposure": [0, 0]}"#;
    let fx = synth::Spec::load(&spec(t.path(), "fx.json", extra)).unwrap();
    let table = srgb8_table();
    let preview = matedit::io::png::Preview::default();
    for (x, y) in samples(&plain, 0).iter().zip(&samples(&fx, 0)) {
        let (_, _, a) = npy_rgb(get(x, "image.npy"));
        let (_, _, b) = npy_rgb(get(y, "image.npy"));
        // the frame's mean luminance goes to middle grey, and the light with it
        let mean = a
            .iter()
            .map(|p| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64)
            .sum::<f64>()
            / a.len() as f64;
        let gain = (matedit::synth::camera_effects::MIDDLE_GREY / mean) as f32;
        let quantised: Vec<[f32; 3]> = a
            .iter()
            .map(|p| p.map(|v| table[matedit::io::png::display_value(v * gain, &preview) as usize]))
            .collect();
        assert_eq!(b, quantised);
        assert_ne!(a, b);
        let (_, _, env_a) = npy_rgb(get(x, "env.npy"));
        let (_, _, env_b) = npy_rgb(get(y, "env.npy"));
        let scaled: Vec<[f32; 3]> = env_a.iter().map(|p| p.map(|v| v * gain)).collect();
        assert_eq!(env_b, scaled);
    }
}

#[test]
fn the_edit_equals_the_image_off_the_object_and_differs_on_it() {
    let t = dir();
    // every effect but JPEG, whose 8 x 8 blocks mix the object's pixels into the rest
    let extra = r#""camera_effects": {"exposure": [-1, 1], "noise": [0.05, 0.05],
        "defocus": [1, 2], "vignette": [0.2, 0.4]},
        "edit": {"materials": [{"preset": "clay"}]}"#;
    let sp = synth::Spec::load(&spec(t.path(), "spec.json", extra)).unwrap();
    for x in samples(&sp, 1) {
        let (_, _, image) = npy_rgb(get(&x, "image.npy"));
        let (_, _, edit) = npy_rgb(get(&x, "edit.npy"));
        let mask = matedit::io::npy::parse(get(&x, "mask.npy")).unwrap().data;
        let (mut on, mut differ) = (0, 0);
        for ((a, b), m) in image.iter().zip(&edit).zip(&mask) {
            if *m == 0.0 {
                assert_eq!(a, b);
            } else {
                on += 1;
                differ += usize::from(a != b);
            }
        }
        assert!(
            on > 0 && differ * 2 > on,
            "{differ} of {on} object pixels differ"
        );
        let name = serde_json::from_slice::<serde_json::Value>(get(&x, "edit_material.json"))
            .unwrap()["name"]
            .clone();
        assert_eq!(name, "clay");
        assert_eq!(params(&x)["edit"]["material"]["preset"], "clay");
    }
}

#[test]
fn bad_camera_effects_and_edits_are_refused_in_one_line() {
    for (extra, expect) in [
        (
            r#""camera_effects": {"jpeg": [95, 20]}"#,
            "spec.json: camera_effects.jpeg: [95, 20]: expected LO <= HI",
        ),
        (
            r#""camera_effects": {"noise": [-1, 0]}"#,
            "spec.json: camera_effects.noise: [-1, 0]: expected levels >= 0",
        ),
        (
            r#""camera_effects": {"defocus": [-1, 1]}"#,
            "spec.json: camera_effects.defocus: [-1, 1]: expected sigmas",
        ),
        (
            r#""edit": {"materials": []}"#,
            "spec.json: edit.materials: the list is empty",
        ),
        (
            r#""edit": {"materials": [{"preset": "golden"}]}"#,
            "spec.json: edit.materials[0]: unknown preset 'golden'",
        ),
        (
            r#""edit": {"material": []}"#,
            "spec.json: edit.material: unknown field",
        ),
    ] {
        let t = dir();
        let path = spec(t.path(), "spec.json", extra);
        let out = t.path().join("ds");
        let o = synth_cmd(&path, &out, &[])
            .assert()
            .code(2)
            .get_output()
            .clone();
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.contains(expect) && err.trim_end().lines().count() == 1,
            "{extra}: {err}"
        );
        assert!(!out.exists());
    }
}

/// CPU seconds of one 128 x 128 sample, with and without the effects and the edit
/// (`cargo test --test it camera_effects_cost -- --ignored --nocapture`; a debug build).
#[test]
#[ignore = "a timing, not a check"]
fn camera_effects_cost() {
    let t = dir();
    write_sky(&t.path().join("sky.exr"), 64, 128);
    let write = |name: &str, extra: &str| {
        let path = t.path().join(name);
        std::fs::write(
            &path,
            format!(
                r#"{{"count": 16, "image_size": 128, "env_size": "32x64", "chunk_size": 16,
  "normals": [{{"sphere": 128}}], "envs": ["sky.exr"], "backgrounds": ["env"],
  "materials": [{{"random": "merl"}}]{extra}}}"#
            ),
        )
        .unwrap();
        synth::Spec::load(&path).unwrap()
    };
    let e = engine();
    for (name, extra) in [
        ("plain", ""),
        (
            "effects",
            r#", "camera_effects": {"exposure": [-1, 1], "noise": [0.01, 0.05], "jpeg": [60, 95], "defocus": [1, 3], "vignette": [0, 0.3]}"#,
        ),
        ("edit", r#", "edit": {"materials": [{"random": "merl"}]}"#),
        ("both", &format!(", {ALL}")),
    ] {
        let sp = write(&format!("{name}.json"), extra);
        let _ = synth::render_chunk(&sp, &e, 0, &|_| {}).unwrap();
        let start = std::time::Instant::now();
        let cpu = cpu_seconds();
        let _ = synth::render_chunk(&sp, &e, 0, &|_| {}).unwrap();
        let (wall, cpu) = (start.elapsed().as_secs_f64(), cpu_seconds() - cpu);
        println!(
            "{name:8} {:.1} ms CPU, {:.1} ms wall per sample",
            cpu / 16.0 * 1e3,
            wall / 16.0 * 1e3
        );
    }
}

/// This process's user + system CPU seconds (Linux; 0 elsewhere).
fn cpu_seconds() -> f64 {
    let stat = std::fs::read_to_string("/proc/self/stat").unwrap_or_default();
    let after = stat.rsplit_once(')').map(|(_, r)| r).unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let field = |n: usize| {
        f.get(n - 3)
            .and_then(|v| v.parse::<f64>().ok())
            .unwrap_or(0.0)
    };
    // utime and stime, fields 14 and 15, in clock ticks of 1/100 s
    (field(14) + field(15)) / 100.0
}
