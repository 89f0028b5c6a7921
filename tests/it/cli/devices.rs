//! Where a run computes: `--device`, `--threads` and `MATEDIT_SIMD`, the devices and thread
//! counts against each other, a missing GPU, and the timings `--timings` reports.

use matedit::io;

use super::{dir, fails_with, listing, matedit, path_str, tiny_render};

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
