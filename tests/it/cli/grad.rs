//! `matedit grad`: the gradients against the library's, only those asked for, batches, and a
//! batch that fails half way leaving nothing behind.

use std::path::Path;

use matedit::io;
use matedit::{Batch, Image};

use super::{
    SMALL, assert_close, cpu, dir, listing, matedit, path_str, small_scene, write_exr,
    write_manifest, write_npy,
};

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
