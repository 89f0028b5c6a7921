//! `matedit synth` as a photo's data: backgrounds (the map through the camera, photos from
//! a folder in PNG, JPEG and NPY), the mask of every sample, views of meshes and shapes,
//! lights turned by any angle, exposed and white-balanced, and perturbed materials. Every
//! sample's image is the layer's render of its recorded inputs where its mask is set and
//! its background elsewhere; shards write the whole run's bytes; bad items fail naming
//! themselves.

use std::path::Path;

use crate::common;
use common::{npy_rgb, synth_cmd};

use matedit::io::{self, npy};
use matedit::synth::{self, tar};
use matedit::{Batch, Convention, Device, EnvMap, NormalMap, Renderer, Scene};

/// A folder of three photos: the committed JPEG, a PNG and an NPY the test makes.
fn photos(root: &Path) {
    let dir = root.join("photos");
    std::fs::create_dir_all(&dir).unwrap();
    let jpeg = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gradient.jpg");
    std::fs::copy(jpeg, dir.join("a.jpg")).unwrap();
    let (w, h) = (48, 36);
    let rgb8: Vec<u8> = (0..w * h)
        .flat_map(|i| [(i % w * 5) as u8, 200, (i / w * 7) as u8])
        .collect();
    std::fs::write(
        dir.join("b.png"),
        io::png::encode_rgb8(w, h, &rgb8).unwrap(),
    )
    .unwrap();
    let px: Vec<[f32; 3]> = (0..40 * 30)
        .map(|i| [0.1, (i % 40) as f32 * 0.05, 2.0])
        .collect();
    std::fs::write(dir.join("c.npy"), npy::encode_rgb(40, 30, &px)).unwrap();
}

const SPEC: &str = r#"{
  "count": 12, "seed": 11, "image_size": 20, "env_size": "8x16", "chunk_size": 4,
  "normals": [{"shape": "capsule", "views": "upright"}, {"sphere": 20},
              {"shape": "torus", "views": [[0, 0, 0], [90, 20, 0]]}],
  "envs": [{"procedural": "sun-sky", "rotate": true, "exposure": [-1, 1]},
           {"procedural": "studio", "white_balance": [3000, 9000]}],
  "materials": [{"random": "merl", "perturb": true},
                {"preset": "gold", "perturb": {"brightness": [0.5, 0.6], "colour": 0.3}}],
  "backgrounds": ["env", {"folder": "photos", "exposure": [0, 0]}, "black"]
}"#;

#[test]
fn backgrounds_masks_views_and_perturbations() {
    let t = tempfile::tempdir().unwrap();
    photos(t.path());
    let spec = t.path().join("spec.json");
    std::fs::write(&spec, SPEC).unwrap();
    let whole = t.path().join("whole");
    synth_cmd(&spec, &whole, &[]).assert().success();
    let split = t.path().join("split");
    for i in [2, 0, 1] {
        synth_cmd(&spec, &split, &["--shard", &format!("{i}/3")])
            .assert()
            .success();
    }
    let data = |d: &Path| -> Vec<Vec<u8>> {
        synth::data_files(d)
            .unwrap()
            .iter()
            .map(|p| std::fs::read(p).unwrap())
            .collect()
    };
    assert!(data(&whole) == data(&split), "the shards wrote other bytes");

    let sp = synth::Spec::load(&spec).unwrap();
    let cpu = Renderer::new(Device::Cpu).unwrap();
    let mut backgrounds = std::collections::BTreeSet::new();
    let mut photos_seen = std::collections::BTreeSet::new();
    for tar_path in synth::data_files(&whole).unwrap() {
        if tar_path.extension().is_some_and(|e| e != "tar") {
            continue;
        }
        let members = tar::decode(&std::fs::read(&tar_path).unwrap()).unwrap();
        for sample in members.chunks(6) {
            let get = |suffix: &str| {
                sample
                    .iter()
                    .find(|(n, _)| n.ends_with(suffix))
                    .unwrap()
                    .1
                    .clone()
            };
            let params: serde_json::Value = serde_json::from_slice(&get("params.json")).unwrap();
            let k = params["index"].as_u64().unwrap();
            let (h, w, normals) = npy_rgb(&get("normals.npy"));
            let (eh, ew, texels) = npy_rgb(&get("env.npy"));
            let (_, _, image) = npy_rgb(&get("image.npy"));
            let mask: Vec<bool> = npy::parse(&get("mask.npy"))
                .unwrap()
                .data
                .iter()
                .map(|&m| m == 1.0)
                .collect();
            let mat_path = t.path().join(format!("m{k}.json"));
            std::fs::write(&mat_path, get("material.json")).unwrap();
            let scene = Scene {
                normals: NormalMap::new(w, h, normals.clone()).unwrap(),
                env: EnvMap::new(eh, ew, Convention::Equirect, texels).unwrap(),
                material: io::load_material(&mat_path).unwrap(),
                camera: matedit::Camera::Orthographic,
            };
            let render = cpu
                .render(&Batch::single(scene).unwrap())
                .unwrap()
                .remove(0);
            let drawn = sp.sample(k).unwrap();
            let bg = &params["background"];
            backgrounds.insert(params["background_item"].as_u64().unwrap());
            let fg = mask.iter().filter(|m| **m).count();
            assert!(fg > 20 && fg < w * h, "sample {k}: {fg} object pixels");
            for i in 0..w * h {
                assert_eq!(mask[i], normals[i] != [0.0; 3], "sample {k} pixel {i}");
                if mask[i] {
                    assert_eq!(image[i], render.pixels[i], "sample {k}: object pixel {i}");
                } else {
                    let expect = drawn.background.as_ref().map_or([0.0; 3], |b| b[i]);
                    assert_eq!(image[i], expect, "sample {k}: background pixel {i}");
                }
            }
            let outside: f32 = (0..w * h).filter(|i| !mask[*i]).map(|i| image[i][1]).sum();
            if *bg == "black" {
                assert_eq!(outside, 0.0, "sample {k}");
            } else {
                assert!(outside > 0.0, "sample {k}: {bg}");
            }
            if let Some(photo) = bg["photo"].as_str() {
                photos_seen.insert(photo.to_string());
                // exposure [0, 0]: the background's mean luminance is the map's mean
                assert_eq!(bg["exposure"], 0.0);
            }
            // the material: perturbed, recorded, valid
            let p = &params["material"]["perturb"];
            assert!(p["roughness"].is_f64() && p["gains"].is_array(), "{params}");
            let material = io::load_material(&mat_path).unwrap();
            material.validate().unwrap();
            if params["material"]["preset"] == "gold" {
                // drawn in its range; lowered only where a channel would reflect too much
                let (b, drawn) = (
                    p["brightness"].as_f64().unwrap(),
                    p["brightness_drawn"].as_f64().unwrap(),
                );
                assert!((0.5..=0.6).contains(&drawn) && b <= drawn, "{p}");
                let gold = matedit::presets::lookup("gold").unwrap();
                let cap = synth::perturb::albedo(&gold)
                    .into_iter()
                    .fold(0.95f64, f64::max);
                let a = synth::perturb::albedo(&material);
                assert!(a.iter().all(|v| *v <= cap * 1.001), "{a:?}");
                assert_ne!(
                    material.ctrl,
                    matedit::presets::lookup("gold").unwrap().ctrl
                );
            }
            // lights: the sun-sky turned and exposed, the studio white-balanced
            let e = &params["env"];
            match e["procedural"].as_str().unwrap() {
                "sun-sky" => {
                    assert!(
                        e["turn_degrees"].is_f64() && e["exposure_stops"].is_f64(),
                        "{e}"
                    )
                }
                _ => assert!(e["white_balance_kelvin"].is_f64() && e.get("turn_degrees").is_none()),
            }
            // views: upright capsules have no roll; the torus takes one of its two views
            let n = &params["normals"];
            if let Some(r) = n["rotation"].as_array() {
                let r: Vec<f64> = r.iter().map(|v| v.as_f64().unwrap()).collect();
                if n["shape"].as_str().unwrap().starts_with("capsule") {
                    assert!(r[2] == 0.0 && (0.0..=30.0).contains(&r[1]), "{r:?}");
                } else {
                    assert!(r == [0.0, 0.0, 0.0] || r == [90.0, 20.0, 0.0], "{r:?}");
                }
            }
        }
    }
    assert_eq!(backgrounds.len(), 3, "every kind of background drawn");
    assert!(!photos_seen.is_empty());
}

#[test]
fn an_env_background_is_the_map_along_each_ray() {
    // perspective: a background pixel shows the map along its camera ray
    let t = tempfile::tempdir().unwrap();
    let spec = t.path().join("spec.json");
    std::fs::write(
        &spec,
        r#"{"count": 2, "seed": 1, "image_size": 24, "env_size": "16x32", "fov": 50,
            "normals": [{"shape": "blobby"}], "envs": [{"procedural": "indoor"}],
            "materials": [{"preset": "clay"}], "backgrounds": ["env"]}"#,
    )
    .unwrap();
    let sp = synth::Spec::load(&spec).unwrap();
    let x = sp.sample(0).unwrap();
    let bg = x.background.as_ref().unwrap();
    let cam = x.scene.camera;
    for (y, px) in [(0usize, 0usize), (5, 17), (23, 23)] {
        let v = cam.view_dir(px, y, 24, 24);
        let along = synth::background::env_along(&x.scene.env, [-v[0], -v[1], -v[2]]);
        assert_eq!(bg[y * 24 + px], along);
    }
    // the map's top row is above the camera: the top of the frame sees a higher part of
    // the sky than its bottom, so the two differ
    assert_ne!(bg[0], bg[23 * 24]);
}

#[test]
fn jpeg_photos_load_as_linear_images() {
    let jpeg = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/gradient.jpg");
    let image = io::load_image(&jpeg).unwrap();
    assert_eq!((image.width, image.height), (40, 30));
    // a red ramp across, a green ramp down, blue at 128: sRGB-decoded, within JPEG's loss
    for (x, y) in [(0usize, 0usize), (20, 15), (39, 29)] {
        let p = image.pixels[y * 40 + x];
        let srgb = |v: f32| io::png::srgb_encode(v) * 255.0;
        let expect = [x as f32 * 255.0 / 39.0, y as f32 * 255.0 / 29.0, 128.0];
        for k in 0..3 {
            assert!((srgb(p[k]) - expect[k]).abs() < 12.0, "({x}, {y}): {p:?}");
        }
    }
    let t = tempfile::tempdir().unwrap();
    let bad = t.path().join("broken.jpg");
    std::fs::write(&bad, &std::fs::read(&jpeg).unwrap()[..200]).unwrap();
    let e = io::load_image(&bad).unwrap_err().to_string();
    assert!(e.contains("broken.jpg") && e.contains("JPEG"), "{e}");
}

#[test]
fn bad_items_fail_naming_themselves() {
    let t = tempfile::tempdir().unwrap();
    photos(t.path());
    std::fs::create_dir_all(t.path().join("empty")).unwrap();
    let base: serde_json::Value = serde_json::from_str(SPEC).unwrap();
    for (key, value, expect) in [
        ("backgrounds", r#"["grey"]"#, "backgrounds[0]: 'grey'"),
        (
            "backgrounds",
            r#"[{"folder": "photos", "blur": 2}]"#,
            "backgrounds[0]: \"blur\"",
        ),
        ("backgrounds", r#"[{"folder": "empty"}]"#, "backgrounds[0]:"),
        (
            "backgrounds",
            r#"[{"env": true, "blur": 90}]"#,
            "backgrounds[0]: blur",
        ),
        ("backgrounds", "[]", "backgrounds: the list is empty"),
        (
            "materials",
            r#"[{"preset": "gold", "perturb": {"colour": 3}}]"#,
            "materials[0]: perturb: colour",
        ),
        (
            "materials",
            r#"[{"preset": "gold", "perturb": {"shine": 1}}]"#,
            "materials[0]: perturb: unknown field",
        ),
        (
            "normals",
            r#"[{"shape": "torus", "views": "sideways"}]"#,
            "normals[0]: views",
        ),
        (
            "normals",
            r#"[{"sphere": 20, "views": "upright"}]"#,
            "normals[0]: \"views\"",
        ),
        (
            "envs",
            r#"[{"procedural": "studio", "exposure": [2, 1]}]"#,
            "envs[0]: exposure",
        ),
        (
            "envs",
            r#"[{"procedural": "studio", "white_balance": [100, 200]}]"#,
            "envs[0]: white_balance",
        ),
    ] {
        let mut v = base.clone();
        v[key] = serde_json::from_str(value).unwrap();
        let spec = t.path().join("bad.json");
        std::fs::write(&spec, v.to_string()).unwrap();
        let out = t.path().join("out");
        let o = synth_cmd(&spec, &out, &[]).output().unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{value}: {err}");
        assert!(err.contains(expect), "{value}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
        assert!(!out.exists());
    }
    // a photo that does not decode names the file
    std::fs::write(t.path().join("photos/d.jpg"), b"not a jpeg").unwrap();
    let spec = t.path().join("spec.json");
    std::fs::write(&spec, SPEC).unwrap();
    let o = synth_cmd(&spec, &t.path().join("out"), &[])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("backgrounds[1]") && err.contains("d.jpg"),
        "{err}"
    );
}
