//! `matedit synth`: the spec of docs/synth.md as written, the same chunk files (bit for
//! bit) from a whole run and from shards run in any order, a killed run resumed, every
//! sample's image against a render of its recorded inputs (through the library and
//! `matedit render`), and bad specs failing before anything is written.
//!
//! Datasets are tiny (16 x 16 images, 8 x 16 maps, 12 samples in chunks of 4, `--device
//! cpu`), except the spec of the documentation (64 x 64, 12 samples).

use std::path::{Path, PathBuf};

use crate::common;
use common::{npy_rgb, synth_cmd};

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::io::{self, npy};
use matedit::synth::{self, tar};
use matedit::{Batch, Convention, Device, EnvMap, NormalMap, Renderer, Scene};

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

#[test]
fn the_documented_spec_works_as_written() {
    let t = dir();
    write_sky(&t.path().join("sky.exr"), 64, 128);
    let spec = t.path().join("spec.json");
    std::fs::write(
        &spec,
        r#"{"count": 12, "seed": 7, "image_size": 64, "env_size": "32x64", "normals": [{"sphere": 64}, {"bumpy": 64}], "envs": ["sky.exr"], "materials": [{"preset": "gold"}, {"random": "merl"}]}"#,
    )
    .unwrap();
    let out = t.path().join("ds");
    let o = synth_cmd(&spec, &out, &[])
        .assert()
        .success()
        .get_output()
        .clone();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("12 samples in")
            && err.contains("samples/s")
            && err.contains("1 chunk written, 0 skipped"),
        "{err}"
    );
    let m = manifest(&out);
    assert_eq!(m["complete"], true);
    assert_eq!(m["count"], 12);
    assert_eq!(m["chunks"].as_array().unwrap().len(), 1);
    let bytes = std::fs::read(out.join("chunk-000000.tar")).unwrap();
    assert_eq!(
        m["chunks"][0]["sha256"].as_str().unwrap(),
        matedit::synth::spec::hex(&<sha2::Sha256 as sha2::Digest>::digest(&bytes))
    );
    let members = tar::decode(&bytes).unwrap();
    assert_eq!(members.len(), 12 * 6);
    assert_eq!(members[0].0, "00000000.env.npy");
    assert_eq!(members[2].0, "00000000.mask.npy");
    assert_eq!(members[71].0, "00000011.params.json");
    // both normal sources, both materials drawn; every sample's map turned by its own amount
    let params: Vec<serde_json::Value> = members
        .iter()
        .filter(|(n, _)| n.ends_with(".params.json"))
        .map(|(_, b)| serde_json::from_slice(b).unwrap())
        .collect();
    for key in ["normals_item", "material_item"] {
        let items: std::collections::BTreeSet<u64> =
            params.iter().map(|p| p[key].as_u64().unwrap()).collect();
        assert_eq!(items.len(), 2, "{key}: {items:?}");
    }
    let turns: Vec<f64> = params
        .iter()
        .map(|p| p["env"]["turn_degrees"].as_f64().unwrap())
        .collect();
    assert!(turns.iter().all(|t| (0.0..360.0).contains(t)), "{turns:?}");
    // any angle, not whole columns (5.625 degrees here)
    assert!(
        turns.iter().any(|t| (t / 5.625).fract().abs() > 1e-6),
        "{turns:?}"
    );
    assert_eq!(params[5]["index"], 5);
    assert_eq!(params[5]["seed"], 7);
    assert_eq!(params[5]["env"]["file"], "sky.exr");
}

#[test]
fn shards_in_any_order_write_the_whole_runs_bytes() {
    let t = dir();
    let spec = small_spec(t.path());
    let whole = t.path().join("whole");
    synth_cmd(&spec, &whole, &[]).assert().success();
    let split = t.path().join("split");
    for i in [2, 0, 1] {
        synth_cmd(
            &spec,
            &split,
            &["--shard", &format!("{i}/3"), "--threads", "1"],
        )
        .assert()
        .success();
    }
    let (a, b) = (data(&whole), data(&split));
    assert_eq!(
        names(&a),
        [
            "chunk-000000.json",
            "chunk-000000.tar",
            "chunk-000001.json",
            "chunk-000001.tar",
            "chunk-000002.json",
            "chunk-000002.tar"
        ]
    );
    assert!(a == b, "the shards wrote other bytes than the whole run");
    // the last shard to finish saw every chunk; --verify says so too
    assert_eq!(manifest(&split)["complete"], true);
    synth_cmd(&spec, &split, &["--verify"]).assert().success();
    // the library gives the same sample twice
    let sp = synth::Spec::load(&spec).unwrap();
    let (x, y) = (sp.sample(5).unwrap(), sp.sample(5).unwrap());
    assert_eq!(x.scene, y.scene);
    assert_eq!(x.params, y.params);
}

#[test]
fn a_killed_run_resumes_and_ends_identical() {
    let t = dir();
    let spec = small_spec(t.path());
    let whole = t.path().join("whole");
    synth_cmd(&spec, &whole, &[]).assert().success();
    let reference = data(&whole);

    // killed while writing chunk 1: its temporary file is there, the chunk is not; chunk 2
    // was damaged afterwards
    std::fs::remove_file(whole.join("chunk-000001.tar")).unwrap();
    std::fs::remove_file(whole.join("chunk-000001.json")).unwrap();
    std::fs::write(whole.join(".chunk-000001.tar.a1b2c3.tmp"), b"partial").unwrap();
    let c2 = whole.join("chunk-000002.tar");
    let mut bytes = std::fs::read(&c2).unwrap();
    bytes[700] ^= 1;
    std::fs::write(&c2, bytes).unwrap();
    let o = synth_cmd(&spec, &whole, &["--verify"])
        .assert()
        .code(1)
        .get_output()
        .clone();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(
            "2 chunks missing or not matching their record: chunk-000001.tar, chunk-000002.tar"
        ),
        "{err}"
    );

    let o = synth_cmd(&spec, &whole, &[])
        .assert()
        .success()
        .get_output()
        .clone();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("2 chunks written, 1 skipped"), "{err}");
    assert!(
        data(&whole) == reference,
        "the resumed run wrote other bytes"
    );
    assert!(!whole.join(".chunk-000001.tar.a1b2c3.tmp").exists());
    assert_eq!(manifest(&whole)["complete"], true);

    // a complete dataset: nothing to do
    let o = synth_cmd(&spec, &whole, &[])
        .assert()
        .success()
        .get_output()
        .clone();
    assert!(String::from_utf8_lossy(&o.stderr).contains("0 samples in"));
    assert!(data(&whole) == reference);
}

/// The f32 array of an .npy member as RGB triples, with its (height, width).

#[test]
fn every_image_is_a_render_of_its_recorded_inputs() {
    let t = dir();
    let spec = small_spec(t.path());
    let out = t.path().join("ds");
    synth_cmd(&spec, &out, &[]).assert().success();
    let cpu = Renderer::new(Device::Cpu).unwrap();
    let mut checked = 0;
    let mut kinds = std::collections::BTreeSet::new();
    for tar_path in synth::data_files(&out).unwrap() {
        if tar_path.extension().is_some_and(|e| e != "tar") {
            continue;
        }
        let members = tar::decode(&std::fs::read(&tar_path).unwrap()).unwrap();
        for sample in members.chunks(6) {
            let get = |suffix: &str| {
                let (n, b) = sample.iter().find(|(n, _)| n.ends_with(suffix)).unwrap();
                (n.clone(), b.clone())
            };
            let key = get("params.json").0.split('.').next().unwrap().to_string();
            let params: serde_json::Value = serde_json::from_slice(&get("params.json").1).unwrap();
            kinds.insert(params["normals_item"].to_string() + &params["material_item"].to_string());
            let (h, w, normals) = npy_rgb(&get("normals.npy").1);
            let (eh, ew, texels) = npy_rgb(&get("env.npy").1);
            let (_, _, image) = npy_rgb(&get("image.npy").1);
            // the mask marks the object: the pixels whose normal is not zero
            let mask = npy::parse(&get("mask.npy").1).unwrap();
            assert_eq!(mask.shape, [h, w]);
            for (m, n) in mask.data.iter().zip(&normals) {
                assert_eq!(*m == 1.0, *n != [0.0; 3]);
            }
            let sample_dir = t.path().join(&key);
            std::fs::create_dir_all(&sample_dir).unwrap();
            let mat_path = sample_dir.join("material.json");
            std::fs::write(&mat_path, get("material.json").1).unwrap();
            let scene = Scene {
                normals: NormalMap::new(w, h, normals).unwrap(),
                env: EnvMap::new(eh, ew, Convention::Equirect, texels).unwrap(),
                material: io::load_material(&mat_path).unwrap(),
                camera: matedit::Camera::Orthographic,
            };
            let again = cpu
                .render(&Batch::single(scene).unwrap())
                .unwrap()
                .remove(0);
            assert!(
                again.pixels == image,
                "sample {key}: the library renders other bits"
            );

            // and `matedit render` of the recorded files
            for m in ["normals.npy", "env.npy"] {
                std::fs::write(sample_dir.join(m), get(m).1).unwrap();
            }
            let render_out = sample_dir.join("render.npy");
            matedit()
                .args(["render", "--device", "cpu", "--env-size", "full", "-o"])
                .arg(&render_out)
                .arg("--normals")
                .arg(sample_dir.join("normals.npy"))
                .arg("--env")
                .arg(sample_dir.join("env.npy"))
                .arg("--material")
                .arg(&mat_path)
                .assert()
                .success();
            let (_, _, rendered) = npy_rgb(&std::fs::read(&render_out).unwrap());
            assert!(
                rendered == image,
                "sample {key}: `matedit render` gives other bits"
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 12);
    assert!(kinds.len() > 4, "too few kinds of sample drawn: {kinds:?}");
}

#[test]
fn bad_specs_fail_before_anything_is_written() {
    // (key and value replacing or joining the spec's, arguments, what the error says)
    let cases: &[(&str, &str, &[&str], &[&str])] = &[
        (
            "envs",
            r#"["missing.exr"]"#,
            &[],
            &["spec.json: envs[0]:", "missing.exr: no such file"],
        ),
        (
            "normals",
            r#"[{"sphere": 16}, {"bumpi": 16}]"#,
            &[],
            &["spec.json: normals[1]:", "unknown field `bumpi`"],
        ),
        (
            "colour",
            "1",
            &[],
            &["spec.json: colour: unknown field `colour`"],
        ),
        (
            "chunk_size",
            "5",
            &[],
            &["spec.json: count: 12 is not a multiple of chunk_size 5"],
        ),
        (
            "seed",
            "-1",
            &[],
            &["spec.json: seed: invalid value: integer `-1`"],
        ),
        (
            "materials",
            r#"[{"preset": "golden"}]"#,
            &[],
            &["spec.json: materials[0]: unknown preset 'golden'"],
        ),
        (
            "env_size",
            r#""5x16""#,
            &[],
            &["spec.json: envs[0]:", "a.exr", "cannot make a 5x16 map"],
        ),
        (
            "normals",
            r#"[{"sphere": 32}]"#,
            &[],
            &["spec.json: normals[0]: sphere: size 32x32 differs from image_size 16x16"],
        ),
        (
            "materials",
            r#"[{"random": "merl", "mix": 0}]"#,
            &[],
            &["spec.json: materials[0]: mix: 0"],
        ),
        (
            "",
            "",
            &["--shard", "3/3"],
            &["shard 3/3: I must be below N"],
        ),
        ("", "", &["--shard", "1-3"], &["is not I/N"]),
    ];
    for (key, value, args, expect) in cases {
        let t = dir();
        std::fs::create_dir_all(t.path().join("envs")).unwrap();
        write_sky(&t.path().join("envs/a.exr"), 16, 32);
        let mut spec_value: serde_json::Value = serde_json::from_str(
            r#"{"count": 12, "image_size": 16, "env_size": "8x16", "chunk_size": 4,
               "normals": [{"sphere": 16}], "envs": ["envs/a.exr"],
               "materials": [{"preset": "gold"}]}"#,
        )
        .unwrap();
        if !key.is_empty() {
            spec_value[*key] = serde_json::from_str(value).unwrap();
        }
        let body = spec_value.to_string();
        let spec = t.path().join("spec.json");
        std::fs::write(&spec, &body).unwrap();
        let out = t.path().join("ds");
        let o = synth_cmd(&spec, &out, args)
            .assert()
            .code(2)
            .get_output()
            .clone();
        let err = String::from_utf8_lossy(&o.stderr);
        for e in *expect {
            assert!(err.contains(e), "{body} {args:?}: expected '{e}' in: {err}");
        }
        // one line (clap's usage errors add a hint below theirs)
        assert_eq!(
            err.lines()
                .filter(|l| !l.trim().is_empty() && !l.starts_with("For more"))
                .count(),
            1,
            "{err}"
        );
        assert!(!err.contains("panicked"), "{err}");
        assert!(!out.exists(), "{body}: the output folder was created");
    }
}

#[test]
fn a_folder_of_another_spec_is_refused() {
    let t = dir();
    let spec = small_spec(t.path());
    let out = t.path().join("ds");
    synth_cmd(&spec, &out, &[]).assert().success();
    let before = data(&out);
    let text = std::fs::read_to_string(&spec)
        .unwrap()
        .replace("\"seed\": 3", "\"seed\": 4");
    std::fs::write(&spec, text).unwrap();
    let o = synth_cmd(&spec, &out, &[])
        .assert()
        .code(2)
        .get_output()
        .clone();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains("manifest.json: the folder holds a dataset of another spec"),
        "{err}"
    );
    assert!(data(&out) == before);
}

#[test]
fn gpu_shards_write_the_whole_runs_bytes() {
    // the GPU path (lavapipe in CI): skipped without an adapter unless MATEDIT_REQUIRE_GPU=1
    if let Err(e) = matedit::gpu::GpuRenderer::new() {
        assert_ne!(
            std::env::var("MATEDIT_REQUIRE_GPU").as_deref(),
            Ok("1"),
            "MATEDIT_REQUIRE_GPU=1 but no GPU: {e}"
        );
        eprintln!("SKIPPED gpu_shards_write_the_whole_runs_bytes: {e}");
        return;
    }
    let t = dir();
    let spec = small_spec(t.path());
    let run = |out: &Path, extra: &[&str]| {
        matedit()
            .args(["synth", s(&spec), "-o", s(out), "--device", "gpu"])
            .args(extra)
            .assert()
            .success();
    };
    let whole = t.path().join("whole");
    run(&whole, &[]);
    let split = t.path().join("split");
    for i in [1, 2, 0] {
        run(&split, &["--shard", &format!("{i}/3")]);
    }
    let (a, b) = (data(&whole), data(&split));
    assert_eq!(a.len(), 6);
    assert!(
        a == b,
        "the GPU shards wrote other bytes than the whole run"
    );
    // the GPU's images are the GPU's, within f32 rounding of the fast CPU path's
    let cpu = t.path().join("cpu");
    synth_cmd(&spec, &cpu, &[]).assert().success();
    let tars = |d: &Path| -> Vec<(String, Vec<u8>)> {
        (0..3)
            .flat_map(|c| {
                let bytes = std::fs::read(d.join(format!("chunk-{c:06}.tar"))).unwrap();
                tar::decode(&bytes).unwrap()
            })
            .collect()
    };
    let (g, c) = (tars(&whole), tars(&cpu));
    assert_eq!(g.len(), c.len());
    let mut images = 0;
    for ((ng, dg), (nc, dc)) in g.iter().zip(&c) {
        assert_eq!(ng, nc);
        if ng.ends_with(".image.npy") {
            images += 1;
            let (_, _, pg) = npy_rgb(dg);
            let (_, _, pc) = npy_rgb(dc);
            let peak = pc.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
            assert!(peak > 0.0, "{ng}: a black image");
            for (x, y) in pg.iter().flatten().zip(pc.iter().flatten()) {
                assert!((x - y).abs() <= 1e-4 * peak, "{ng}: {x} vs {y}");
            }
        }
    }
    assert_eq!(images, 12);
}

#[test]
fn a_shard_with_no_chunk_succeeds_and_says_so() {
    // an array job of 4 tasks over a spec of 3 chunks: task 3 has nothing to write
    let t = dir();
    std::fs::create_dir_all(t.path().join("envs")).unwrap();
    write_sky(&t.path().join("envs/a.exr"), 16, 32);
    let spec = t.path().join("spec.json");
    std::fs::write(
        &spec,
        r#"{"count": 12, "image_size": 16, "env_size": "8x16", "chunk_size": 4,
           "normals": [{"sphere": 16}], "envs": ["envs/a.exr"],
           "materials": [{"preset": "gold"}]}"#,
    )
    .unwrap();
    let out = t.path().join("ds");
    let o = synth_cmd(&spec, &out, &["--shard", "3/4"])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("shard 3/4: no chunk to write (the spec makes 3 chunks"),
        "{err}"
    );
    assert!(!out.join("chunk-000000.tar").exists());
    // the other tasks still write every chunk
    for i in 0..3 {
        let o = synth_cmd(&spec, &out, &["--shard", &format!("{i}/4")])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    for c in 0..3 {
        assert!(out.join(format!("chunk-{c:06}.tar")).exists());
    }
}

#[test]
fn shapes_and_procedural_lights_are_sources_and_shards_agree() {
    // procedural shapes (parameters and rotation drawn per sample) and procedural lights
    // (parameters drawn per sample), perspective: the shards write the whole run's bytes
    let t = dir();
    let spec = t.path().join("spec.json");
    std::fs::write(
        &spec,
        r#"{"count": 6, "seed": 3, "image_size": 24, "env_size": "16x32", "chunk_size": 2,
           "fov": 40,
           "normals": [{"shape": "blobby"}, {"shape": "union"}],
           "envs": [{"procedural": "sun-sky"}, {"procedural": "studio"}],
           "materials": [{"preset": "gold"}]}"#,
    )
    .unwrap();
    let whole = t.path().join("whole");
    synth_cmd(&spec, &whole, &[]).assert().success();
    let split = t.path().join("split");
    for i in [1, 0, 2] {
        synth_cmd(&spec, &split, &["--shard", &format!("{i}/3")])
            .assert()
            .success();
    }
    assert!(data(&whole) == data(&split), "the shards wrote other bytes");
    let sp = synth::Spec::load(&spec).unwrap();
    let (mut shapes, mut lights) = (Vec::new(), Vec::new());
    for k in 0..6 {
        let x = sp.sample(k).unwrap();
        assert!(x.params["normals"]["shape_seed"].is_u64(), "{}", x.params);
        assert!(x.params["normals"]["rotation"].is_array());
        assert!(x.params["env"]["procedural"].is_string());
        // some pixels are the object and some background
        let fg = foreground(&x.scene.normals);
        assert!(
            fg > 24 && fg < 24 * 24,
            "sample {k}: {fg} foreground pixels"
        );
        assert!(
            x.scene
                .env
                .texels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0)
        );
        shapes.push(x.scene.normals.normals.clone());
        lights.push(x.scene.env.texels.clone());
    }
    // each sample its own draw
    assert!(shapes.windows(2).all(|w| w[0] != w[1]));
    assert!(lights.windows(2).all(|w| w[0] != w[1]));
    // bad kinds: one line naming the item
    for (key, value, expect) in [
        ("normals", r#"[{"shape": "blobb"}]"#, "normals[0]: shape:"),
        (
            "envs",
            r#"[{"procedural": "sunny"}]"#,
            "envs[0]: procedural:",
        ),
    ] {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&spec).unwrap()).unwrap();
        v[key] = serde_json::from_str(value).unwrap();
        let bad = t.path().join("bad.json");
        std::fs::write(&bad, v.to_string()).unwrap();
        let o = synth_cmd(&bad, &t.path().join("bad"), &[])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(expect), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}

#[test]
fn meshes_are_a_source_turned_per_sample() {
    // a folder of two small meshes (a tetrahedron as OBJ, the same as OFF): each sample
    // picks one and turns it; shards agree with the whole run; a bad mesh names the item
    let t = dir();
    let meshes = t.path().join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::write(
        meshes.join("tet.obj"),
        "v 1 1 1\nv -1 -1 1\nv -1 1 -1\nv 1 -1 -1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n",
    )
    .unwrap();
    std::fs::write(
        meshes.join("tet.off"),
        "OFF\n4 4 0\n1 1 1\n-1 -1 1\n-1 1 -1\n1 -1 -1\n3 0 1 2\n3 0 3 1\n3 0 2 3\n3 1 3 2\n",
    )
    .unwrap();
    let spec = t.path().join("spec.json");
    let body = |normals: &str| {
        format!(
            r#"{{"count": 4, "seed": 5, "image_size": 20, "env_size": "8x16", "chunk_size": 2,
               "normals": [{normals}], "envs": [{{"procedural": "overcast"}}],
               "materials": [{{"preset": "gold"}}]}}"#
        )
    };
    std::fs::write(&spec, body(r#"{"mesh": "meshes"}"#)).unwrap();
    let whole = t.path().join("whole");
    synth_cmd(&spec, &whole, &[]).assert().success();
    let split = t.path().join("split");
    for i in [1, 0] {
        synth_cmd(&spec, &split, &["--shard", &format!("{i}/2")])
            .assert()
            .success();
    }
    assert!(data(&whole) == data(&split), "the shards wrote other bytes");
    let sp = synth::Spec::load(&spec).unwrap();
    for k in 0..4 {
        let x = sp.sample(k).unwrap();
        let label = x.params["normals"]["mesh"].as_str().unwrap().to_string();
        assert!(label.starts_with("meshes/tet."), "{label}");
        let fg = foreground(&x.scene.normals);
        assert!(fg > 20, "sample {k}: {fg} foreground pixels");
    }
    std::fs::write(meshes.join("bad.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let o = synth_cmd(&spec, &t.path().join("bad"), &[])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("normals[0]") && err.contains("bad.obj"),
        "{err}"
    );
}

/// Pixels of a normal map that face the viewer (the object, not the background).
fn foreground(n: &matedit::NormalMap) -> usize {
    n.normals.iter().filter(|v| v[2] > 0.0).count()
}

#[test]
fn the_contact_sheets_spec_loads_and_draws() {
    // docs/synth/sheet.json, as examples/synth_sheet reads it: needs no file
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/synth/sheet.json");
    let spec = synth::Spec::load(&path).unwrap();
    assert_eq!(spec.count, 24);
    let x = spec.sample(3).unwrap();
    assert!(x.params["env"]["procedural"].is_string(), "{}", x.params);
    assert!(foreground(&x.scene.normals) > 0);
}
