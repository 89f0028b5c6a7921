//! Bad input: missing, NaN and wrong-size files, bad materials, environment sizes, EXR
//! compressions, outputs and manifests, and usage errors; each exits with code 2 and one line
//! naming the problem, and leaves no file behind.

use std::path::{Path, PathBuf};

use super::{
    SMALL, dir, env_texels, fails_with, listing, matedit, path_str, write_exr, write_manifest,
    write_npy,
};

#[test]
fn missing_normals_file() {
    let d = dir();
    let out = d.path().join("out.exr");
    let missing = d.path().join("nope.npy");
    fails_with(
        matedit()
            .args([
                "render",
                "-o",
                path_str(&out),
                "--normals",
                path_str(&missing),
            ])
            .args(["--env-size", "8x16", "--device", "cpu"]),
        d.path(),
        &["nope.npy: no such file"],
    );
}

#[test]
fn nan_in_normals() {
    let d = dir();
    let normals = d.path().join("normals.npy");
    let mut data = vec![[0.0f32, 0.0, 1.0]; 10 * 10];
    data[7 * 10 + 3][0] = f32::NAN;
    write_npy(&normals, 10, 10, &data);
    let out = d.path().join("out.png");
    fails_with(
        matedit()
            .args([
                "render",
                "-o",
                path_str(&out),
                "--normals",
                path_str(&normals),
            ])
            .args(["--env-size", "8x16", "--device", "cpu"]),
        d.path(),
        &["normals.npy: pixel (3, 7) is NaN"],
    );
}

#[test]
fn wrong_size_upstream() {
    let d = dir();
    let up = d.path().join("up.npy");
    write_npy(&up, 8, 8, &[[1.0; 3]; 64]);
    let out = d.path().join("grads");
    fails_with(
        matedit()
            .args(["grad", "-o", path_str(&out), "--upstream", path_str(&up)])
            .args(SMALL),
        d.path(),
        &["up.npy: is 8x8", "16x16"],
    );
}

#[test]
fn nan_in_upstream() {
    let d = dir();
    let up = d.path().join("up.npy");
    let mut data = vec![[1.0f32; 3]; 256];
    data[17][2] = f32::NAN;
    write_npy(&up, 16, 16, &data);
    fails_with(
        matedit()
            .args([
                "grad",
                "-o",
                path_str(&d.path().join("g")),
                "--upstream",
                path_str(&up),
            ])
            .args(SMALL),
        d.path(),
        &["up.npy: pixel (1, 1) channel B is NaN"],
    );
}

#[test]
fn bad_materials() {
    let d = dir();
    let gold = matedit::presets::lookup("gold").unwrap();
    let json = |ctrl: &[f64]| {
        format!(
            "{{\"name\": \"x\", \"ctrl\": [{}]}}",
            ctrl.iter()
                .map(|v| v.to_string())
                .collect::<Vec<_>>()
                .join(", ")
        )
    };
    let mut neg = gold.ctrl.to_vec();
    neg[idx_exponent()] = -2.0;
    let cases: [(&str, String, &[&str]); 3] = [
        (
            "neg.json",
            json(&neg),
            &[
                "neg.json: ctrl[6] (channel R, lobe 0, exponent m1, point 0) is -2",
                ">= 0",
            ],
        ),
        (
            "short.json",
            json(&gold.ctrl[..107]),
            &["short.json: 'ctrl' has 107 numbers", "108"],
        ),
        (
            "broken.json",
            "{\"ctrl\": [1, 2,".into(),
            &["broken.json: not a material file"],
        ),
    ];
    let out = d.path().join("out.exr");
    for (name, text, want) in cases {
        let p = d.path().join(name);
        std::fs::write(&p, text).unwrap();
        fails_with(
            matedit()
                .args(["render", "-o", path_str(&out), "--material", path_str(&p)])
                .args(SMALL),
            d.path(),
            want,
        );
    }
}

/// Flat index of channel R, lobe 0, exponent, control point 0.
fn idx_exponent() -> usize {
    matedit::material::idx(0, 0, 1, 0)
}

#[test]
fn non_dividing_env_size() {
    let d = dir();
    let env = d.path().join("sky.npy");
    write_npy(&env, 32, 16, &vec![[1.0; 3]; 512]);
    let out = d.path().join("out.exr");
    fails_with(
        matedit()
            .args(["render", "-o", path_str(&out), "--env", path_str(&env)])
            .args(["--env-size", "5x10", "--sphere", "8", "--device", "cpu"]),
        d.path(),
        &["sky.npy", "5x10", "1, 2, 4, 8, 16", "8x16"],
    );
}

/// An EXR whose header names an HTJ2K compression, which the decoder lacks.
fn unsupported_exr(path: &Path) {
    write_exr(path, 32, 16, &env_texels());
    let mut bytes = std::fs::read(path).unwrap();
    let key = b"compression\0compression\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap();
    bytes[at + key.len() + 4] = 10; // HTJ2K256
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn unsupported_exr_compression() {
    let d = dir();
    let env = d.path().join("sky.exr");
    unsupported_exr(&env);
    let out = d.path().join("out.exr");
    fails_with(
        matedit()
            .args(["render", "-o", path_str(&out), "--env", path_str(&env)])
            .args(SMALL),
        d.path(),
        &[
            "sky.exr: EXR compression HTJ2K256 is not supported",
            "oiiotool sky.exr --compression zip",
        ],
    );
    // info still answers, and says why the file cannot be used
    let res = matedit().args(["info", path_str(&env)]).output().unwrap();
    assert!(res.status.success());
    assert!(String::from_utf8_lossy(&res.stdout).contains("HTJ2K256"));
}

#[test]
fn mislabelled_dwaa_is_an_error() {
    // ZIP data under a DWAA label: a decoding error, not garbage and not a panic.
    let d = dir();
    let env = d.path().join("liar.exr");
    write_exr(&env, 32, 16, &env_texels());
    let mut bytes = std::fs::read(&env).unwrap();
    let key = b"compression\0compression\0";
    let at = bytes.windows(key.len()).position(|w| w == key).unwrap();
    bytes[at + key.len() + 4] = 8;
    std::fs::write(&env, bytes).unwrap();
    fails_with(
        matedit()
            .args([
                "render",
                "-o",
                path_str(&d.path().join("o.exr")),
                "--env",
                path_str(&env),
            ])
            .args(SMALL),
        d.path(),
        &["liar.exr"],
    );
}

#[test]
fn bad_outputs() {
    let d = dir();
    fails_with(
        matedit()
            .args(["render", "-o", path_str(&d.path().join("out.jpg"))])
            .args(SMALL),
        d.path(),
        &["out.jpg", ".exr, .npy or .png"],
    );
    fails_with(
        matedit()
            .args(["render", "-o", path_str(&d.path().join("no/such/out.exr"))])
            .args(SMALL),
        d.path(),
        &["does not exist"],
    );
}

#[test]
fn bad_manifests() {
    let d = dir();
    let m = d.path().join("batch.json");
    let cases = [
        (
            r#"{"scenes": [{"output": "a.exr", "sphere": 8, "normals": "n.npy"}]}"#,
            "scenes[0]: give 'normals' or 'sphere'",
        ),
        (
            r#"{"scenes": [{"output": "a.exr", "colour": "red"}]}"#,
            "unknown field `colour`",
        ),
        (
            r#"{"scenes": [{"output": "a.exr", "normals": "missing.npy"}]}"#,
            "missing.npy: no such file",
        ),
        (r#"{"scenes": [{"output": "a.gif"}]}"#, "a.gif"),
        (
            r#"{"scenes": [{"output": "a.exr", "sphere": 8}, {"output": "b.exr", "sphere": 4}]}"#,
            "batch: scene 1 differs",
        ),
    ];
    for (text, want) in cases {
        write_manifest(&m, text);
        fails_with(
            matedit()
                .args(["render", "--batch", path_str(&m)])
                .args(SMALL),
            d.path(),
            &[want],
        );
    }
}

#[test]
fn usage_errors_exit_2() {
    let d = dir();
    let out = d.path().join("o.exr");
    let o = path_str(&out);
    for args in [
        vec!["render", "-o", o, "--sphere", "8", "--normals", "n.npy"],
        vec!["render", "-o", o, "--fov", "200"],
        vec!["render", "-o", o, "--preset", "nope"],
        vec!["render", "-o", o, "--env-size", "64"],
        vec!["render", "-o", o, "--device", "tpu"],
        vec!["render", "-o", o, "--threads", "0"],
        vec!["render"],
        vec!["grad", "-o", o],
    ] {
        let res = matedit().args(&args).output().unwrap();
        assert_eq!(res.status.code(), Some(2), "{args:?}");
        assert!(!String::from_utf8_lossy(&res.stderr).contains("panicked"));
    }
    assert!(listing(d.path()).is_empty());
    // our own checks: unknown preset name, missing info file
    let res = matedit().args(["presets", "nope"]).output().unwrap();
    assert_eq!(res.status.code(), Some(2));
    let missing: PathBuf = d.path().join("x.exr");
    fails_with(
        matedit().args(["info", path_str(&missing)]),
        d.path(),
        &["x.exr: no such file"],
    );
}

/// An option that needs another (`requires`) is refused beside the one that other excludes:
/// clap waives the requirement there, so each such option excludes it too. `fit
/// --env-size` with `--fit-env` (the size of a known light, with none known), `fit-brdf
/// --name` with `--merl` (a material of an NBRDF file, with no such file).
#[test]
fn an_option_for_an_absent_input_is_refused() {
    let d = dir();
    let out = d.path().join("o");
    let o = path_str(&out);
    for (args, pair) in [
        (
            vec![
                "fit",
                "--image",
                "i.exr",
                "--sphere",
                "--fit-env",
                "4x8",
                "--env-size",
                "8x16",
                "-o",
                o,
            ],
            ("--fit-env", "--env-size"),
        ),
        (
            vec!["fit-brdf", "--merl", "m.binary", "--name", "gold", "-o", o],
            ("--merl", "--name"),
        ),
    ] {
        let res = matedit().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.contains("cannot be used with") && err.contains(pair.0) && err.contains(pair.1),
            "{err}"
        );
    }
    assert!(listing(d.path()).is_empty());
}
