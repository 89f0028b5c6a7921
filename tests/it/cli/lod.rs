//! Levels of detail on the command line (`--method`, `--tolerance`): chosen by name and by
//! tolerance for `render` and `grad`, and the bad ones refused.

use matedit::io;
use matedit::{NormalMap, Scene};

use super::{
    dir, fails_with, listing, matedit, path_str, procedural, render_lib, small_scene, tiny_render,
    write_npy,
};

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
