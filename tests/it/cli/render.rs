//! `matedit render`, one scene and a batch: every output format, the built-in sky, the PNG's
//! exposure and tone map, inputs from files, each read back and compared with the library's
//! render of the same scene.

use matedit::io::{self, Preview, Tonemap};
use matedit::{Camera, Convention, EnvMap, NormalMap, Scene};

use super::{
    SMALL, assert_close, default_material, dir, env_texels, fails_with, listing, matedit, path_str,
    procedural, render_lib, small_scene, tiny_render, write_exr, write_manifest, write_npy,
};

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
