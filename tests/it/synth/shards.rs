//! The same chunk files (bit for bit) from a whole run, from shards run in any order
//! (CPU and GPU), from a killed run resumed, and from a shard with no chunk.

use std::path::Path;

use matedit::synth::{self, tar};

use super::{data, dir, manifest, matedit, names, npy_rgb, s, small_spec, synth_cmd, write_sky};

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
