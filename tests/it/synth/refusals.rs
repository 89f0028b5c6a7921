//! Bad specs, and a folder of another spec, refused before anything is written.

use super::{data, dir, small_spec, synth_cmd, write_sky};

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
