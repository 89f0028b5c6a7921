//! The specs of the documentation, loaded and run as written.

use std::path::Path;

use matedit::synth::{self, tar};

use super::{dir, foreground, manifest, synth_cmd, write_sky};

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
fn the_contact_sheets_spec_loads_and_draws() {
    // docs/synth/sheet.json, as examples/synth_sheet reads it: needs no file
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/synth/sheet.json");
    let spec = synth::Spec::load(&path).unwrap();
    assert_eq!(spec.count, 24);
    let x = spec.sample(3).unwrap();
    assert!(x.params["env"]["procedural"].is_string(), "{}", x.params);
    assert!(foreground(&x.scene.normals) > 0);
}
