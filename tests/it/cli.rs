//! End-to-end runs of the `matedit` binary: every subcommand's happy path, every output
//! format read back with `matedit::io` and compared with a render done through the library
//! on the same (fast CPU) path, the devices and thread counts against each other, and every
//! kind of bad input (exit code 2, a one-line error naming the file, no output left behind,
//! no panic).
//!
//! Scenes are tiny (16 x 16 sphere, 8 x 16 environment, `--device cpu`).

use std::path::{Path, PathBuf};

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::io::{self, Preview, Tonemap};
use matedit::{
    Batch, Camera, Convention, Device, EnvMap, Image, Material, NormalMap, Renderer, Scene,
};

/// The small scene options every test uses.
const SMALL: [&str; 6] = ["--sphere", "16", "--env-size", "8x16", "--device", "cpu"];

fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

/// `matedit render -o OUT` of an 8-pixel sphere against a 4x8 map: the smallest real render.
fn tiny_render(out: &Path) -> assert_cmd::Command {
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

fn dir() -> tempfile::TempDir {
    tempfile::tempdir().expect("temp dir")
}

fn cpu() -> Renderer {
    Renderer::new(Device::Cpu).expect("CPU renderer")
}

fn default_material() -> Material {
    matedit::presets::lookup(matedit::presets::DEFAULT).expect("default preset")
}

fn procedural(h: usize, w: usize) -> EnvMap {
    matedit::builtin_sky::procedural_env(h, w, Convention::Equirect)
}

/// The scene that `SMALL` with no other option describes.
fn small_scene() -> Scene {
    Scene {
        normals: NormalMap::sphere(16),
        env: procedural(8, 16),
        material: default_material(),
        camera: Camera::Orthographic,
    }
}

fn render_lib(scenes: Vec<Scene>) -> Vec<Image> {
    cpu().render(&Batch::new(scenes).unwrap()).unwrap()
}

/// Same CPU code on both sides, so only float formatting could differ: demand 1e-6.
fn assert_close(actual: &[[f32; 3]], expected: &[[f32; 3]]) {
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
fn listing(d: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

/// Runs a command that must fail on bad input: exit code 2, one line on stderr that starts
/// with "error: " and contains every string of `want`, no panic, and `d` unchanged.
fn fails_with(cmd: &mut assert_cmd::Command, d: &Path, want: &[&str]) -> String {
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

fn write_npy(path: &Path, w: usize, h: usize, data: &[[f32; 3]]) {
    std::fs::write(path, io::npy::encode_rgb(w, h, data)).unwrap();
}

fn write_exr(path: &Path, w: usize, h: usize, data: &[[f32; 3]]) {
    std::fs::write(path, io::exr::encode_rgb(w, h, data).unwrap()).unwrap();
}

/// A 16 x 32 environment with structure, a bright spot and some negative texels.
fn env_texels() -> Vec<[f32; 3]> {
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

fn path_str(p: &Path) -> &str {
    p.to_str().unwrap()
}

// ---------------------------------------------------------------- happy paths

#[test]
fn help_has_examples_for_every_subcommand() {
    for sub in ["render", "grad", "info", "presets"] {
        let out = matedit().args([sub, "--help"]).output().unwrap();
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        assert!(
            text.contains("Examples:") && text.contains(&format!("matedit {sub}")),
            "{text}"
        );
    }
    let out = matedit().args(["render", "--help"]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("reinhard") && text.contains("sRGB"),
        "tonemap documented"
    );
}

#[test]
fn presets_list_and_export() {
    let out = matedit().arg("presets").output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for p in matedit::presets::all() {
        assert!(text.contains(p.name) && text.contains(&p.description));
    }
    let d = dir();
    let out = matedit().args(["presets", "gold"]).output().unwrap();
    assert!(out.status.success());
    let p = d.path().join("gold.json");
    std::fs::write(&p, &out.stdout).unwrap();
    assert_eq!(
        io::load_material(&p).unwrap(),
        matedit::presets::lookup("gold").unwrap()
    );
}

#[test]
fn render_each_format_matches_the_library() {
    let d = dir();
    let expected = render_lib(vec![small_scene()]).remove(0);
    assert!(expected.max_value() > 0.1, "the default scene is lit");
    for ext in ["exr", "npy", "png"] {
        let out = d.path().join(format!("out.{ext}"));
        let res = matedit()
            .args(["render", "-o", path_str(&out), "--light-tolerance", "off"])
            .args(SMALL)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert!(res.status.success(), "{stderr}");
        assert!(stderr.contains("device: "), "names the backend: {stderr}");
        match ext {
            "png" => {
                let dec = io::png::decode(&out).unwrap();
                assert_eq!(
                    (dec.width, dec.height, dec.channels, dec.bit_depth),
                    (16, 16, 3, 8)
                );
                let want: Vec<u16> = expected
                    .pixels
                    .iter()
                    .flatten()
                    .map(|&v| io::png::display_value(v, &Preview::default()) as u16)
                    .collect();
                assert_eq!(dec.samples, want);
            }
            _ => {
                let got = io::load_upstream(&out).unwrap();
                assert_eq!((got.width, got.height), (16, 16));
                assert_close(&got.pixels, &expected.pixels);
            }
        }
    }
    assert_eq!(listing(d.path()), ["out.exr", "out.npy", "out.png"]);
}

#[test]
fn the_built_in_sky_renders_the_continuous_light() {
    let d = dir();
    let out = d.path().join("c.npy");
    let run = |extra: &[&str]| {
        let res = matedit()
            .args(["render", "-o", path_str(&out), "--preset", "chrome-ish"])
            .args(["--sphere", "24", "--env-size", "16x32"])
            .args(extra)
            .output()
            .unwrap();
        assert!(res.status.success());
        String::from_utf8_lossy(&res.stderr).into_owned()
    };
    // by default a level is chosen and reported; 'off' is the layer, as is any --env
    assert!(run(&[]).contains("matedit: continuous light: level"));
    assert!(!run(&["--light-tolerance", "off"]).contains("continuous light"));
    // the paper convention has no solid angles to split: one line, exit 2
    fails_with(
        tiny_render(&out).args(["--supersample", "2", "--convention", "paper"]),
        d.path(),
        &["light:", "equirect"],
    );
}

#[test]
fn png_exposure_and_tonemap() {
    let d = dir();
    let out = d.path().join("p.png");
    matedit()
        .args([
            "render",
            "-o",
            path_str(&out),
            "--light-tolerance",
            "off",
            "--exposure",
            "-1.5",
            "--tonemap",
            "reinhard",
        ])
        .args(SMALL)
        .assert()
        .success();
    let expected = render_lib(vec![small_scene()]).remove(0);
    let preview = Preview {
        exposure: -1.5,
        tonemap: Tonemap::Reinhard,
    };
    let want: Vec<u16> = expected
        .pixels
        .iter()
        .flatten()
        .map(|&v| io::png::display_value(v, &preview) as u16)
        .collect();
    assert_eq!(io::png::decode(&out).unwrap().samples, want);
}

#[test]
fn render_from_files_matches_the_library() {
    let d = dir();
    // normals: a sphere with a tilt, stored unnormalised (scaled by 2)
    let sphere = NormalMap::sphere(12);
    let raw: Vec<[f32; 3]> = sphere
        .normals
        .iter()
        .map(|n| [2.0 * n[0] + 0.2 * n[2], 2.0 * n[1], 2.0 * n[2]])
        .collect();
    let normals = d.path().join("normals.npy");
    write_npy(&normals, 12, 12, &raw);
    let env = d.path().join("env.exr");
    write_exr(&env, 32, 16, &env_texels());
    let material = d.path().join("mat.json");
    std::fs::write(
        &material,
        io::json::encode_material(&matedit::presets::lookup("clay").unwrap(), None),
    )
    .unwrap();

    let out = d.path().join("out.npy");
    let res = matedit()
        .args([
            "render",
            "-o",
            path_str(&out),
            "--device",
            "cpu",
            "--env-size",
            "8x16",
        ])
        .args(["--normals", path_str(&normals), "--env", path_str(&env)])
        .args([
            "--material",
            path_str(&material),
            "--fov",
            "40",
            "--convention",
            "paper",
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{stderr}");
    assert!(
        stderr.contains("clamped 14 negative values to 0"),
        "{stderr}"
    );

    let loaded = io::load_env(&env, Convention::Paper).unwrap();
    assert_eq!(loaded.clamped, 14);
    let scene = Scene {
        normals: io::load_normals(&normals).unwrap(),
        env: io::resample::fit(loaded.env, "8x16".parse().unwrap(), &env).unwrap(),
        material: io::load_material(&material).unwrap(),
        camera: Camera::Perspective { fov_y_deg: 40.0 },
    };
    let expected = render_lib(vec![scene]).remove(0);
    assert!(expected.max_value() > 0.0);
    assert_close(&io::load_upstream(&out).unwrap().pixels, &expected.pixels);
}

#[test]
fn render_png_and_exr_normals_and_full_env() {
    let d = dir();
    // 8-bit PNG normals: a 4 x 2 image, one transparent background pixel
    let mut rgba = Vec::new();
    for i in 0..8u8 {
        rgba.extend_from_slice(&[100 + 10 * i, 150, 220, if i == 5 { 0 } else { 255 }]);
    }
    let png_path = d.path().join("n.png");
    let mut bytes = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut bytes, 4, 2);
        enc.set_color(png::ColorType::Rgba);
        enc.set_depth(png::BitDepth::Eight);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&rgba).unwrap();
    }
    std::fs::write(&png_path, bytes).unwrap();
    // EXR normals holding the same values
    let png_normals = io::load_normals(&png_path).unwrap();
    let exr_path = d.path().join("n.exr");
    write_exr(&exr_path, 4, 2, &png_normals.normals);
    // an 8 x 16 env rendered at its full size
    let env = d.path().join("env.npy");
    let texels: Vec<[f32; 3]> = (0..128)
        .map(|i| [1.0 + (i % 16) as f32 * 0.1, 1.0, 0.5])
        .collect();
    write_npy(&env, 16, 8, &texels);

    let scene = Scene {
        normals: png_normals,
        env: EnvMap::new(8, 16, Convention::Equirect, texels).unwrap(),
        material: default_material(),
        camera: Camera::Orthographic,
    };
    let expected = render_lib(vec![scene]).remove(0);
    assert_eq!(expected.pixels[5], [0.0; 3], "background");
    for normals in [&png_path, &exr_path] {
        let out = d.path().join("out.exr");
        matedit()
            .args([
                "render",
                "-o",
                path_str(&out),
                "--device",
                "cpu",
                "--env-size",
                "full",
            ])
            .args(["--normals", path_str(normals), "--env", path_str(&env)])
            .assert()
            .success();
        assert_close(&io::load_upstream(&out).unwrap().pixels, &expected.pixels);
    }
}

fn write_manifest(path: &Path, text: &str) {
    std::fs::write(path, text).unwrap();
}

#[test]
fn batch_render_matches_the_library() {
    let d = dir();
    let env = d.path().join("env.exr");
    write_exr(&env, 32, 16, &env_texels());
    let outdir = d.path().join("renders");
    std::fs::create_dir(&outdir).unwrap();
    let manifest = d.path().join("batch.json");
    write_manifest(
        &manifest,
        r#"{
            "env_size": "8x16",
            "scenes": [
                {"output": "a.exr"},
                {"output": "b.npy", "preset": "gold", "env": "env.exr"},
                {"output": "c.png", "preset": "blue-rubber"}
            ]
        }"#,
    );
    let res = matedit()
        .args([
            "render",
            "--batch",
            path_str(&manifest),
            "-o",
            path_str(&outdir),
        ])
        .args(["--sphere", "16", "--device", "cpu", "--preset", "clay"])
        .output()
        .unwrap();
    assert!(
        res.status.success(),
        "{}",
        String::from_utf8_lossy(&res.stderr)
    );
    assert_eq!(listing(&outdir), ["a.exr", "b.npy", "c.png"]);

    let mut file_env = io::load_env(&env, Convention::Equirect).unwrap().env;
    file_env = io::resample::fit(file_env, "8x16".parse().unwrap(), &env).unwrap();
    let scene = |material: &str, env: EnvMap| Scene {
        normals: NormalMap::sphere(16),
        env,
        material: matedit::presets::lookup(material).unwrap(),
        camera: Camera::Orthographic,
    };
    let expected = render_lib(vec![
        scene("clay", procedural(8, 16)),
        scene("gold", file_env),
        scene("blue-rubber", procedural(8, 16)),
    ]);
    assert_close(
        &io::load_upstream(&outdir.join("a.exr")).unwrap().pixels,
        &expected[0].pixels,
    );
    assert_close(
        &io::load_upstream(&outdir.join("b.npy")).unwrap().pixels,
        &expected[1].pixels,
    );
    let want: Vec<u16> = expected[2]
        .pixels
        .iter()
        .flatten()
        .map(|&v| io::png::display_value(v, &Preview::default()) as u16)
        .collect();
    assert_eq!(
        io::png::decode(&outdir.join("c.png")).unwrap().samples,
        want
    );
}

fn read_ctrl(path: &Path) -> Vec<f64> {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    v["ctrl"]
        .as_array()
        .expect("ctrl array")
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

#[test]
fn grad_matches_the_library() {
    let d = dir();
    let upstream: Vec<[f32; 3]> = (0..256)
        .map(|i| [1.0, (i % 7) as f32 * 0.1 - 0.3, 0.5])
        .collect();
    let up_npy = d.path().join("up.npy");
    write_npy(&up_npy, 16, 16, &upstream);
    let up_exr = d.path().join("up.exr");
    write_exr(&up_exr, 16, 16, &upstream);

    let batch = Batch::single(small_scene()).unwrap();
    let up_img = Image {
        width: 16,
        height: 16,
        pixels: upstream.clone(),
    };
    let expected = cpu().backward(&batch, &[up_img]).unwrap().remove(0);

    for up in [&up_npy, &up_exr] {
        let out = d.path().join("grads");
        let res = matedit()
            .args(["grad", "-o", path_str(&out), "--upstream", path_str(up)])
            .args(SMALL)
            .output()
            .unwrap();
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
        assert_eq!(
            listing(&out),
            ["d_env.npy", "d_material.json", "d_normals.npy"]
        );
        let d_env = io::npy::read(&out.join("d_env.npy")).unwrap();
        assert_eq!(d_env.shape, [8, 16, 3]);
        let d_normals = io::npy::read(&out.join("d_normals.npy")).unwrap();
        assert_eq!(d_normals.shape, [16, 16, 3]);
        assert_close(
            &io::load_upstream(&out.join("d_env.npy")).unwrap().pixels,
            &expected.d_env,
        );
        assert_close(
            &io::load_upstream(&out.join("d_normals.npy"))
                .unwrap()
                .pixels,
            &expected.d_normals,
        );
        let ctrl = read_ctrl(&out.join("d_material.json"));
        assert_eq!(ctrl.len(), 108);
        for (a, e) in ctrl.iter().zip(&expected.d_ctrl) {
            assert!(
                (a - *e as f64).abs() <= 1e-6 * (*e as f64).abs().max(1.0),
                "{a} vs {e}"
            );
        }
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn grad_only_writes_the_gradients_asked_for() {
    let d = dir();
    let upstream: Vec<[f32; 3]> = (0..256)
        .map(|i| [1.0, (i % 5) as f32 * 0.2 - 0.4, 0.5])
        .collect();
    let up = d.path().join("up.npy");
    write_npy(&up, 16, 16, &upstream);
    let run = |out: &Path, only: Option<&str>| {
        let mut cmd = matedit();
        cmd.args(["grad", "-o", path_str(out), "--upstream", path_str(&up)])
            .args(SMALL);
        if let Some(only) = only {
            cmd.args(["--only", only]);
        }
        let res = cmd.output().unwrap();
        assert!(
            res.status.success(),
            "{}",
            String::from_utf8_lossy(&res.stderr)
        );
    };
    let all = d.path().join("all");
    run(&all, None);
    let some = d.path().join("some");
    run(&some, Some("ctrl,normals"));
    assert_eq!(listing(&some), ["d_material.json", "d_normals.npy"]);
    let a = read_ctrl(&all.join("d_material.json"));
    let b = read_ctrl(&some.join("d_material.json"));
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() <= 1e-5 * x.abs().max(1e-3), "{x} vs {y}");
    }
    let ctrl = d.path().join("ctrl");
    run(&ctrl, Some("ctrl"));
    assert_eq!(listing(&ctrl), ["d_material.json"]);
    // an unknown name: an error naming the value, nothing written
    let bad = d.path().join("bad");
    let res = matedit()
        .args([
            "grad",
            "-o",
            path_str(&bad),
            "--upstream",
            path_str(&up),
            "--only",
            "light",
        ])
        .args(SMALL)
        .output()
        .unwrap();
    assert!(!res.status.success());
    assert!(String::from_utf8_lossy(&res.stderr).contains("invalid value 'light' for '--only"));
    assert!(!bad.exists());
}

#[test]
fn grad_batch() {
    let d = dir();
    let ones = vec![[1.0f32; 3]; 64];
    write_npy(&d.path().join("up.npy"), 8, 8, &ones);
    let manifest = d.path().join("g.json");
    write_manifest(
        &manifest,
        r#"{"env_size": "4x8", "scenes": [
            {"output": "g0", "sphere": 8, "upstream": "up.npy"},
            {"output": "g1", "sphere": 8, "preset": "gold", "upstream": "up.npy"}
        ]}"#,
    );
    matedit()
        .args(["grad", "--batch", path_str(&manifest), "--device", "cpu"])
        .assert()
        .success();
    for g in ["g0", "g1"] {
        assert_eq!(
            listing(&d.path().join(g)),
            ["d_env.npy", "d_material.json", "d_normals.npy"]
        );
        assert_eq!(
            io::npy::read(&d.path().join(g).join("d_env.npy"))
                .unwrap()
                .shape,
            [4, 8, 3]
        );
    }
}

/// A batch whose last write fails leaves nothing: not the first scene's files, nor the
/// folder the run created for them (here `g1/d_env.npy` is a folder, so putting that file
/// in place fails after `g0`'s files are in place).
#[test]
fn grad_batch_failing_half_way_leaves_nothing() {
    let d = dir();
    write_npy(&d.path().join("up.npy"), 8, 8, &vec![[1.0f32; 3]; 64]);
    std::fs::create_dir_all(d.path().join("g1").join("d_env.npy")).unwrap();
    let manifest = d.path().join("g.json");
    write_manifest(
        &manifest,
        r#"{"env_size": "4x8", "scenes": [
            {"output": "g0", "sphere": 8, "upstream": "up.npy"},
            {"output": "g1", "sphere": 8, "upstream": "up.npy"}
        ]}"#,
    );
    let out = matedit()
        .args(["grad", "--batch", path_str(&manifest), "--device", "cpu"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(
        err.lines().filter(|l| l.starts_with("error")).count(),
        1,
        "{err}"
    );
    assert!(err.contains("d_env.npy"), "{err}");
    assert!(
        !d.path().join("g0").exists(),
        "the run's folder was left behind"
    );
    assert_eq!(listing(&d.path().join("g1")), ["d_env.npy"]);
}

#[test]
fn info_describes_inputs() {
    let d = dir();
    let env = d.path().join("env.exr");
    write_exr(&env, 32, 16, &env_texels());
    let out = matedit().args(["info", path_str(&env)]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("32 wide x 16 high") && text.contains("negative values: 14"),
        "{text}"
    );
    assert!(
        text.contains("env       yes: 14 negative values will be clamped"),
        "{text}"
    );

    let m = d.path().join("m.json");
    std::fs::write(&m, r#"{"ctrl": [1, 2]}"#).unwrap();
    let out = matedit().args(["info", path_str(&m)]).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    assert!(
        text.contains("material  no: 'ctrl' has 2 numbers"),
        "{text}"
    );
}

#[test]
fn device_gpu_fails_with_the_hint_or_works() {
    let d = dir();
    let out = d.path().join("g.npy");
    let res = tiny_render(&out)
        .args(["--device", "gpu"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr);
    if res.status.success() {
        assert!(out.exists());
    } else {
        assert_eq!(res.status.code(), Some(1), "{stderr}");
        assert!(
            stderr.contains("no GPU adapter") && stderr.contains("--device cpu"),
            "{stderr}"
        );
        assert!(!out.exists());
    }
    // auto never fails for lack of a GPU
    tiny_render(&out).assert().success();
}

#[test]
fn no_adapter_for_device_gpu_is_a_runtime_error_with_the_hint() {
    // No adapter has this name, so `--device gpu` must fail (exit 1, the install hint) and
    // `--device auto` must fall back to the CPU.
    let d = dir();
    let out = d.path().join("g.npy");
    let res = tiny_render(&out)
        .env("WGPU_ADAPTER_NAME", "matedit-test-no-such-adapter")
        .args(["--device", "gpu"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("error: no GPU adapter") && stderr.contains("apt-get install"),
        "{stderr}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(listing(d.path()).is_empty());
    tiny_render(&out)
        .env("WGPU_ADAPTER_NAME", "matedit-test-no-such-adapter")
        .assert()
        .success();
    assert!(out.exists());
}

#[test]
fn devices_and_thread_counts_agree() {
    let d = dir();
    let run = |name: &str, args: &[&str]| {
        let out = d.path().join(name);
        let res = matedit()
            .args([
                "render",
                "-o",
                path_str(&out),
                "--sphere",
                "24",
                "--env-size",
                "8x16",
            ])
            .args(args)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&res.stderr).into_owned();
        assert!(res.status.success(), "{stderr}");
        (
            std::fs::read(&out).unwrap(),
            io::npy::read(&out).unwrap().data,
            stderr,
        )
    };
    let (one, img1, err1) = run("t1.npy", &["--device", "cpu", "--threads", "1"]);
    let (two, _, err2) = run("t2.npy", &["--device", "cpu", "--threads", "2"]);
    assert!(
        err1.contains("device: cpu: f32") && err1.contains("1 thread\n"),
        "{err1}"
    );
    assert!(err2.contains("2 threads"), "{err2}");
    assert_eq!(one, two, "1 and 2 threads must give the same bytes");
    let (_, reference, err) = run("r.npy", &["--device", "reference"]);
    assert!(err.contains("f64 reference"), "{err}");
    let max = reference.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    for (a, b) in img1.iter().zip(&reference) {
        assert!((a - b).abs() <= 1e-5 * max, "{a} vs {b}");
    }
}

#[test]
fn auto_without_a_hardware_gpu_runs_the_fast_cpu_path() {
    let d = dir();
    let out = d.path().join("a.npy");
    let res = tiny_render(&out)
        .env("WGPU_ADAPTER_NAME", "matedit-test-no-such-adapter")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert!(res.status.success(), "{stderr}");
    assert!(stderr.contains("device: cpu: f32"), "{stderr}");
}

// ---------------------------------------------------------------- bad input

#[test]
fn unknown_simd_level_and_device() {
    let d = dir();
    let out = d.path().join("x.npy");
    fails_with(
        tiny_render(&out)
            .env("MATEDIT_SIMD", "avx9")
            .args(["--device", "cpu"]),
        d.path(),
        &["MATEDIT_SIMD", "avx9", "avx512, avx2, neon or scalar"],
    );
    let res = tiny_render(&out)
        .args(["--device", "tpu"])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&res.stderr);
    assert_eq!(res.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains("expected auto, gpu, cpu or reference"),
        "{stderr}"
    );
}

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

/// Max |a - b| over max |b|.
fn rel_err(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let diff = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).abs())
        .fold(0.0, f64::max);
    let scale = b
        .iter()
        .flatten()
        .map(|y| f64::from(y.abs()))
        .fold(0.0, f64::max);
    diff / scale
}

#[test]
fn levels_of_detail_by_name_and_by_tolerance() {
    let d = dir();
    // A glossy material that a 32-node table can follow (the default's sharper lobe
    // needs a finer one; the chooser below would pick it).
    let scene_args = [
        "--sphere",
        "96",
        "--env-size",
        "32x64",
        "--device",
        "cpu",
        "--preset",
        "plastic-red",
    ];
    let exact = render_lib(vec![Scene {
        normals: NormalMap::sphere(96),
        env: procedural(32, 64),
        material: matedit::presets::lookup("plastic-red").unwrap(),
        ..small_scene()
    }])
    .remove(0);
    let run = |extra: &[&str], name: &str| {
        let out = d.path().join(name);
        let res = matedit()
            .args(["render", "-o", path_str(&out)])
            .args(scene_args)
            .args(extra)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&res.stderr).into_owned();
        assert!(res.status.success(), "{stderr}");
        (io::load_upstream(&out).unwrap().pixels, stderr)
    };
    // by name: the method is named on stderr, and the image is the library's
    let (img, stderr) = run(&["--method", "table32+keep8"], "named.npy");
    assert!(
        stderr.contains("level of detail: method table32+keep8"),
        "{stderr}"
    );
    let err = rel_err(&img, &exact.pixels);
    assert!(err > 0.0 && err < 2e-2, "table32+keep8 error {err}");
    // by tolerance: the choice and its estimate on stderr, the error within it
    for tol in ["1e-2", "1e-3"] {
        let (img, stderr) = run(&["--tolerance", tol], "chosen.npy");
        assert!(stderr.contains("level of detail: method "), "{stderr}");
        assert!(stderr.contains(&format!("tolerance {tol}")), "{stderr}");
        let err = rel_err(&img, &exact.pixels);
        assert!(
            err <= tol.parse::<f64>().unwrap(),
            "tolerance {tol}: error {err}: {stderr}"
        );
    }
    // grad takes them too
    let up = d.path().join("up.npy");
    write_npy(&up, 96, 96, &vec![[1.0, -0.5, 0.25]; 96 * 96]);
    for extra in [["--tolerance", "1e-2"], ["--method", "env2+keep4"]] {
        let out = d.path().join("grads");
        let res = matedit()
            .args(["grad", "-o", path_str(&out), "--upstream", path_str(&up)])
            .args(scene_args)
            .args(extra)
            .output()
            .unwrap();
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert!(res.status.success(), "{stderr}");
        assert!(stderr.contains("level of detail: method"), "{stderr}");
        assert_eq!(
            listing(&out),
            ["d_env.npy", "d_material.json", "d_normals.npy"]
        );
        std::fs::remove_dir_all(&out).unwrap();
    }
}

#[test]
fn bad_levels_of_detail() {
    let d = dir();
    let out = d.path().join("x.npy");
    // a table needs an orthographic camera
    fails_with(
        tiny_render(&out).args(["--method", "table16", "--fov", "40"]),
        d.path(),
        &["table16", "orthographic"],
    );
    // usage errors from the parser: exit 2, the value named
    for (args, want) in [
        (
            vec!["--method", "table16+tbl"],
            "unknown method 'table16+tbl'",
        ),
        (vec!["--method", "env0"], "block side"),
        (vec!["--tolerance", "0"], "not a positive number"),
        (vec!["--tolerance", "nan"], "not a positive number"),
        (vec!["--light-tolerance", "0"], "not a positive number"),
        (vec!["--supersample", "65"], "--supersample"),
        (
            vec!["--light-tolerance", "1e-3", "--supersample", "2"],
            "cannot be used with",
        ),
        (
            vec!["--tolerance", "1e-3", "--method", "env2"],
            "cannot be used with",
        ),
    ] {
        let res = tiny_render(&out).args(&args).output().unwrap();
        let stderr = String::from_utf8_lossy(&res.stderr);
        assert_eq!(res.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(want), "{args:?}: {stderr}");
        assert!(!out.exists());
    }
}

#[test]
fn timings_on_the_host_and_per_gpu_pass() {
    let d = dir();
    let out = d.path().join("t.npy");
    let run = |device: &str| {
        let mut cmd = matedit();
        cmd.args(["render", "-o", path_str(&out), "--sphere", "16"])
            .args(["--env-size", "8x16", "--device", device, "--timings"]);
        cmd.output().expect("runs")
    };
    // off the GPU: the call's host time, and a word on where per-pass times come from
    let o = run("cpu");
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(
        err.contains("matedit: timings: ") && err.contains("s on the host"),
        "{err}"
    );
    // on the GPU (lavapipe in CI): one line per pass, the forward with its pairs per second
    if std::env::var("MATEDIT_REQUIRE_GPU").as_deref() == Ok("1") {
        let o = run("gpu");
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(o.status.success(), "{err}");
        let forward = err.lines().find(|l| {
            l.trim_start_matches("matedit:")
                .trim()
                .starts_with("forward")
        });
        assert!(
            forward.is_some_and(|l| l.contains("M pairs/s")),
            "no forward timing: {err}"
        );
    }
}
