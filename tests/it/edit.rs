//! Material editing against synthetic ground truth: targets rendered from known presets
//! under the built-in sky, fitted from a different preset, judged by renders (the fitted
//! render against the target, and the fitted material under another light against the
//! true material under it); then `matedit fit`, `transfer` and `grid` end to end and their
//! bad inputs.
//!
//! Scenes are small (a 32 x 32 sphere, 8 x 16 maps, the fast CPU path).

use crate::common;

use std::path::Path;

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::edit::{self, Inputs, Light, Options};
use matedit::{
    Batch, Camera, Convention, Device, EnvMap, Image, Material, NormalMap, Renderer, Scene,
};

fn sky(height: usize, width: usize) -> EnvMap {
    matedit::builtin_sky::procedural_env(height, width, Convention::Equirect)
}

/// The map turned about the vertical by `columns`.
fn turned(env: &EnvMap, columns: usize) -> EnvMap {
    let (h, w) = (env.height, env.width);
    let texels = (0..h * w)
        .map(|i| env.texels[(i / w) * w + (i % w + columns) % w])
        .collect();
    EnvMap {
        texels,
        ..env.clone()
    }
}

fn render(r: &Renderer, normals: &NormalMap, env: &EnvMap, m: &Material) -> Image {
    let batch = Batch::single(Scene {
        normals: normals.clone(),
        env: env.clone(),
        material: m.clone(),
        camera: Camera::Orthographic,
    })
    .expect("valid scene");
    r.render(&batch).expect("renders").remove(0)
}

fn preset(name: &str) -> Material {
    matedit::presets::lookup(name).expect("a preset")
}

fn all_of(normals: &NormalMap) -> Vec<bool> {
    (0..normals.normals.len())
        .map(|i| !normals.is_background(i))
        .collect()
}

#[test]
fn known_light_recovers_the_material() {
    let r = Renderer::new(Device::Cpu).expect("cpu");
    let normals = NormalMap::sphere(32);
    let env = sky(8, 16);
    // (truth, init, least PSNR of the fitted render, least under the sky turned by a
    // quarter). From a glossy start a fabric keeps some of the start's specular lobe at
    // the theta_d that this one light does not show: the image is matched, the other
    // light shows it.
    for (truth, init, min_fit, min_turned) in [
        ("gold-metallic-paint", "clay", 35.0, 30.0),
        ("pink-fabric", "clay", 35.0, 30.0),
        ("pink-fabric", "red-specular-plastic", 30.0, 20.0),
    ] {
        let target = render(&r, &normals, &env, &preset(truth));
        let inputs = Inputs::new(normals.clone(), target.clone(), None).expect("inputs");
        let options = Options {
            steps: 400,
            ..Options::new(preset(init), Light::Fixed(env.clone()))
        };
        let fitted = edit::fit(&r, &inputs, &options, &mut |_, _| {}).expect("fits");
        let mask = all_of(&normals);
        let fit_psnr = edit::psnr(
            &render(&r, &normals, &env, &fitted.material),
            &target,
            &mask,
        );
        // the material under lights it was not fitted under: the sky turned by a
        // quarter (the sun to the side) and by half a turn (the sun behind the object,
        // lighting the rim at theta_d the image saw only under the sky's dim light)
        let under = |columns| {
            let other = turned(&env, columns);
            edit::psnr(
                &render(&r, &normals, &other, &fitted.material),
                &render(&r, &normals, &other, &preset(truth)),
                &mask,
            )
        };
        let (transfer_psnr, behind) = (under(4), under(8));
        eprintln!(
            "{truth} from {init}: {} steps, fitted render {fit_psnr:.1} dB, under the sky turned by a quarter {transfer_psnr:.1} dB, by a half {behind:.1} dB",
            fitted.steps
        );
        assert!(
            fit_psnr >= min_fit,
            "{truth}: fitted render {fit_psnr:.1} dB"
        );
        assert!(
            transfer_psnr >= min_turned,
            "{truth}: under another light {transfer_psnr:.1} dB"
        );
        // the loss went down and the best parameters are returned
        assert!(fitted.losses.last() < fitted.losses.first());
    }
}

#[test]
fn fitted_light_and_material_reproduce_the_image() {
    let r = Renderer::new(Device::Cpu).expect("cpu");
    let normals = NormalMap::sphere(32);
    let truth = preset("blue-metallic-paint");
    let target = render(&r, &normals, &sky(8, 16), &truth);
    let inputs = Inputs::new(normals.clone(), target.clone(), None).expect("inputs");
    let options = Options {
        steps: 500,
        ..Options::new(
            preset("clay"),
            Light::Fit {
                height: 8,
                width: 16,
            },
        )
    };
    let fitted = edit::fit(&r, &inputs, &options, &mut |_, _| {}).expect("fits");
    let psnr = edit::psnr(
        &render(&r, &normals, &fitted.env, &fitted.material),
        &target,
        &all_of(&normals),
    );
    eprintln!(
        "fitted light and material: {} steps, {psnr:.1} dB",
        fitted.steps
    );
    assert!(psnr >= 35.0, "fitted render {psnr:.1} dB");
    assert!(
        fitted
            .env
            .texels
            .iter()
            .flatten()
            .all(|&v| v > 0.0 && v.is_finite())
    );
    assert!(fitted.material.validate().is_ok());
}

#[test]
fn fits_are_deterministic_and_masks_count() {
    let r = Renderer::new(Device::Cpu).expect("cpu");
    let normals = NormalMap::sphere(16);
    let env = sky(4, 8);
    let mut target = render(&r, &normals, &env, &preset("clay"));
    // garbage in the left half, masked out
    let mask: Vec<bool> = (0..256).map(|i| i % 16 >= 8).collect();
    for (i, p) in target.pixels.iter_mut().enumerate() {
        if i % 16 < 8 {
            *p = [50.0, 0.0, 50.0];
        }
    }
    let inputs = Inputs::new(normals.clone(), target.clone(), Some(mask.clone())).expect("inputs");
    let options = Options {
        steps: 150,
        ..Options::new(preset("plastic-red"), Light::Fixed(env.clone()))
    };
    let a = edit::fit(&r, &inputs, &options, &mut |_, _| {}).expect("fits");
    let b = edit::fit(&r, &inputs, &options, &mut |_, _| {}).expect("fits");
    assert_eq!(a.material.ctrl, b.material.ctrl);
    assert_eq!(a.losses, b.losses);
    let masked: Vec<bool> = mask
        .iter()
        .enumerate()
        .map(|(i, &m)| m && !normals.is_background(i))
        .collect();
    let psnr = edit::psnr(&render(&r, &normals, &env, &a.material), &target, &masked);
    assert!(
        psnr > 25.0,
        "masked fit {psnr:.1} dB: the garbage half leaked in"
    );
}

#[test]
fn bad_inputs_are_errors() {
    let normals = NormalMap::sphere(8);
    let image = Image::zeros(8, 8);
    assert!(Inputs::new(normals.clone(), Image::zeros(8, 4), None).is_err());
    assert!(Inputs::new(normals.clone(), image.clone(), Some(vec![true; 3])).is_err());
    assert!(Inputs::new(normals.clone(), image.clone(), Some(vec![false; 64])).is_err());
    let mut nan = image.clone();
    nan.pixels[27] = [f32::NAN, 0.0, 0.0];
    let e = Inputs::new(normals.clone(), nan, None)
        .unwrap_err()
        .to_string();
    assert!(e.contains("column 3, row 3"), "{e}");
    // a black image cannot be fitted
    let r = Renderer::new(Device::Cpu).expect("cpu");
    let inputs = Inputs::new(normals, image, None).expect("inputs");
    let options = Options::new(
        preset("clay"),
        Light::Fit {
            height: 4,
            width: 8,
        },
    );
    let e = edit::fit(&r, &inputs, &options, &mut |_, _| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("black"), "{e}");
}

/// Every backend runs the same fit: a few steps on the GPU (lavapipe in CI) track the
/// fast CPU path's losses.
#[test]
fn gpu_fit_tracks_the_cpu_fit() {
    let Some(gpu) = common::gpu("gpu_fit_tracks_the_cpu_fit") else {
        return;
    };
    let gpu = Renderer::with_backend(Box::new(gpu));
    let cpu = Renderer::new(Device::Cpu).expect("cpu");
    let normals = NormalMap::sphere(16);
    let target = render(&cpu, &normals, &sky(4, 8), &preset("clay"));
    let inputs = Inputs::new(normals, target, None).expect("inputs");
    let options = Options {
        steps: 8,
        ..Options::new(
            preset("plastic-red"),
            Light::Fit {
                height: 4,
                width: 8,
            },
        )
    };
    let a = edit::fit(&cpu, &inputs, &options, &mut |_, _| {}).expect("cpu fit");
    let b = edit::fit(&gpu, &inputs, &options, &mut |_, _| {}).expect("gpu fit");
    for (x, y) in a.losses.iter().zip(&b.losses) {
        assert!((x - y).abs() <= 1e-3 * x.abs(), "cpu {x} gpu {y}");
    }
}

fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

/// Runs `cmd`, failing with its stderr unless it succeeds.
fn run_ok(cmd: &mut assert_cmd::Command) {
    let out = cmd.output().expect("runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn write_exr(path: &Path, image: &Image) {
    let bytes =
        matedit::io::exr::encode_rgb(image.width, image.height, &image.pixels).expect("encodes");
    std::fs::write(path, bytes).expect("writes");
}

#[test]
fn fit_transfer_and_grid_from_the_command_line() {
    let tmp = tempfile::tempdir().expect("tmp");
    let r = Renderer::new(Device::Cpu).expect("cpu");
    let normals = NormalMap::sphere(24);
    let env = sky(64, 128);
    let mut dirs = Vec::new();
    for name in ["gold-metallic-paint", "clay"] {
        let image = tmp.path().join(format!("{name}.exr"));
        write_exr(&image, &render(&r, &normals, &env, &preset(name)));
        let dir = tmp.path().join("fits").join(name);
        run_ok(
            matedit()
                .args(["fit", "--image"])
                .arg(&image)
                .args([
                    "--sphere",
                    "--fit-env",
                    "4x8",
                    "--steps",
                    "40",
                    "--device",
                    "cpu",
                    "-o",
                ])
                .arg(&dir),
        );
        for f in [
            "material.json",
            "env.exr",
            "normals.npy",
            "target.exr",
            "render.exr",
            "render.png",
            "compare.png",
            "loss.png",
            "report.json",
        ] {
            assert!(dir.join(f).is_file(), "{f} missing");
        }
        let report: serde_json::Value =
            serde_json::from_slice(&std::fs::read(dir.join("report.json")).expect("reads"))
                .expect("json");
        assert!(report["psnr"].as_f64().expect("psnr") > 15.0, "{report}");
        assert!(report["steps"].as_u64().expect("steps") >= 1);
        assert!(report["seconds"].as_f64().expect("seconds") > 0.0);
        #[cfg(unix)]
        {
            // what a file created here gets under the test's umask
            use std::os::unix::fs::PermissionsExt;
            let probe = tmp.path().join("probe");
            std::fs::write(&probe, b"").expect("writes");
            let normal = std::fs::metadata(&probe)
                .expect("stat")
                .permissions()
                .mode();
            let mode = std::fs::metadata(dir.join("render.png"))
                .expect("stat")
                .permissions()
                .mode();
            assert_eq!(
                mode & 0o777,
                normal & 0o777,
                "outputs get a normal file's mode"
            );
        }
        // the material file is a material matedit reads
        matedit::io::load_material(&dir.join("material.json")).expect("a material");
        dirs.push(dir);
    }
    let out_png = tmp.path().join("transfer.png");
    run_ok(
        matedit()
            .args(["transfer", "--device", "cpu", "--shape-light"])
            .arg(&dirs[0])
            .arg("--material")
            .arg(&dirs[1])
            .arg("-o")
            .arg(&out_png),
    );
    assert_eq!(matedit::io::png::decode(&out_png).expect("png").width, 24);
    // transfer of A's own material is A's render
    let exr = tmp.path().join("self.exr");
    run_ok(
        matedit()
            .args(["transfer", "--device", "cpu", "--shape-light"])
            .arg(&dirs[0])
            .arg("--material")
            .arg(dirs[0].join("material.json"))
            .arg("-o")
            .arg(&exr),
    );
    let a = matedit::io::read_raster(&exr, "x").expect("reads");
    let b = matedit::io::read_raster(&dirs[0].join("render.exr"), "x").expect("reads");
    // (normals.npy went through the loader's normalisation: the last bit may move)
    let peak = b.pixels.iter().flatten().fold(0.0f64, |m, &v| m.max(v));
    for (x, y) in a.pixels.iter().flatten().zip(b.pixels.iter().flatten()) {
        assert!((x - y).abs() <= 1e-5 * peak, "{x} vs {y}");
    }

    let grid = tmp.path().join("grid.png");
    run_ok(
        matedit()
            .args(["grid", "--device", "cpu", "--cell", "16"])
            .args(&dirs)
            .arg("-o")
            .arg(&grid),
    );
    let d = matedit::io::png::decode(&grid).expect("png");
    assert_eq!((d.width, d.height), (2 * 16 + 3 * 4, 2 * 16 + 3 * 4));
}

#[test]
fn fit_bad_inputs_fail_with_one_line_and_no_output() {
    let tmp = tempfile::tempdir().expect("tmp");
    let image = tmp.path().join("img.exr");
    write_exr(&image, &Image::zeros(16, 8));
    let square = tmp.path().join("square.exr");
    let mut img = Image::zeros(16, 16);
    img.pixels.iter_mut().for_each(|p| *p = [0.5; 3]);
    write_exr(&square, &img);
    let mask = tmp.path().join("mask.npy");
    std::fs::write(&mask, matedit::io::npy::encode_f32(&[4, 4], &[1.0; 16])).expect("writes");
    let out_dir = tmp.path().join("out");
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec!["--image".into(), "missing.exr".into(), "--sphere".into()],
            "missing.exr",
        ),
        (
            vec![
                "--image".into(),
                image.display().to_string(),
                "--sphere".into(),
            ],
            "sphere",
        ),
        (
            vec![
                "--image".into(),
                square.display().to_string(),
                "--sphere".into(),
                "8".into(),
            ],
            "8x8",
        ),
        (
            vec![
                "--image".into(),
                square.display().to_string(),
                "--sphere".into(),
                "--mask".into(),
                mask.display().to_string(),
            ],
            "mask.npy",
        ),
        (
            vec![
                "--image".into(),
                square.display().to_string(),
                "--sphere".into(),
                "--env".into(),
                "nowhere.exr".into(),
            ],
            "nowhere.exr",
        ),
    ];
    for (args, needle) in cases {
        let out = matedit()
            .arg("fit")
            .args(&args)
            .args(["--device", "cpu", "--steps", "2", "-o"])
            .arg(&out_dir)
            .output()
            .expect("runs");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert_eq!(err.trim().lines().count(), 1, "{args:?}: {err}");
        assert!(err.contains(needle), "{args:?}: {err}");
        assert!(!out_dir.exists(), "{args:?} left output behind");
    }
    // transfer from a folder that is no fit
    let out = matedit()
        .args(["transfer", "--shape-light"])
        .arg(tmp.path())
        .args(["--material", "nope", "-o"])
        .arg(tmp.path().join("t.png"))
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("report.json"));
}
