//! End-to-end runs of `matedit env`: every kind written and read back equal to the
//! library's map, loaded by `matedit render --env`, the augmentations of a file, and bad
//! options (exit code 2, a one-line error, no output left behind).

use std::path::Path;

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::envgen::{self, LightKind, Params, WhiteBalance};
use matedit::{Convention, EnvMap, io};

fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("UTF-8 temp path")
}

fn load(p: &Path) -> EnvMap {
    io::load_env(p, Convention::Equirect)
        .expect("reads the map")
        .env
}

#[test]
fn every_kind_written_and_rendered() {
    let dir = tempfile::tempdir().unwrap();
    for kind in LightKind::ALL {
        let out = dir.path().join(format!("{kind}.exr"));
        let o = matedit()
            .args([
                "env",
                "--kind",
                kind.name(),
                "--seed",
                "4",
                "--size",
                "16x32",
            ])
            .args(["-o", path_str(&out)])
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(
            stderr.contains("wrote") && stderr.contains("seed 4"),
            "{stderr}"
        );
        assert_eq!(
            load(&out),
            envgen::generate(kind, 4, 16, 32).unwrap(),
            "{kind}"
        );
        let png = dir.path().join(format!("{kind}.png"));
        matedit()
            .args([
                "render",
                "--env",
                path_str(&out),
                "--sphere",
                "8",
                "--device",
                "cpu",
            ])
            .args(["--env-size", "full", "-o", path_str(&png)])
            .assert()
            .success();
        assert!(png.is_file());
    }
}

#[test]
fn npy_and_png_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let npy = dir.path().join("s.npy");
    matedit()
        .args(["env", "--kind", "studio", "--seed", "9", "--size", "8x16"])
        .args(["--turn", "30", "--exposure", "-1", "-o", path_str(&npy)])
        .assert()
        .success();
    let want = envgen::generate(LightKind::Studio, 9, 8, 16).unwrap();
    let want = envgen::exposure(&envgen::turn(&want, 30.0).unwrap(), -1.0).unwrap();
    assert_eq!(load(&npy), want);
    let png = dir.path().join("s.png");
    matedit()
        .args([
            "env",
            "--kind",
            "indoor",
            "--size",
            "8x16",
            "-o",
            path_str(&png),
        ])
        .assert()
        .success();
    let d = io::png::decode(&png).unwrap();
    assert_eq!((d.width, d.height), (16, 8));
}

#[test]
fn sun_options_override_the_draw() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("dusk.exr");
    matedit()
        .args([
            "env",
            "--kind",
            "sun-sky",
            "--size",
            "16x32",
            "--sun-elevation",
            "4",
        ])
        .args([
            "--sun-azimuth",
            "-30",
            "--turbidity",
            "5",
            "-o",
            path_str(&out),
        ])
        .assert()
        .success();
    let Params::SunSky(mut p) = Params::draw(LightKind::SunSky, 0) else {
        unreachable!()
    };
    (p.elevation, p.azimuth, p.turbidity) = (4.0, -30.0, 5.0);
    assert_eq!(load(&out), p.env(16, 32).unwrap());
}

#[test]
fn input_file_is_augmented() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("src.exr");
    let base = envgen::generate(LightKind::SunSky, 1, 16, 32).unwrap();
    io::write_env(&src, &base, &Default::default()).unwrap();
    let out = dir.path().join("out.exr");
    matedit()
        .args([
            "env",
            "--input",
            path_str(&src),
            "--size",
            "8x16",
            "--turn",
            "12.5",
        ])
        .args(["--white-balance", "3200K", "-o", path_str(&out)])
        .assert()
        .success();
    let small = io::resample::downsample(&base, 8, 16).unwrap();
    let want = envgen::white_balance(
        &envgen::turn(&small, 12.5).unwrap(),
        WhiteBalance::Temperature(3200.0),
    )
    .unwrap();
    assert_eq!(load(&out), want);
}

/// Runs `matedit env ARGS -o DIR/out.exr`, expects exit 2 with one line on stderr
/// containing every one of `needles`, and no output.
fn fails(args: &[&str], needles: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.exr");
    let o = matedit()
        .arg("env")
        .args(args)
        .args(["-o", path_str(&out)])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    for n in needles {
        assert!(stderr.contains(n), "{args:?}: '{n}' not in: {stderr}");
    }
    assert!(!out.exists(), "{args:?} left an output");
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        0,
        "{args:?} left a file"
    );
}

#[test]
fn bad_options_fail_cleanly() {
    fails(&["--kind", "sunny"], &["unknown light kind 'sunny'"]);
    fails(&["--kind", "studio", "--size", "0x4"], &["between 1 and"]);
    fails(
        &["--kind", "studio", "--size", "full"],
        &["--size full needs --input"],
    );
    fails(&["--kind", "studio", "--turn", "nan"], &["turn", "NaN"]);
    fails(
        &["--kind", "studio", "--white-balance", "1,2"],
        &["three gains"],
    );
    fails(
        &["--kind", "studio", "--white-balance", "100K"],
        &["100 K is outside"],
    );
    fails(
        &["--kind", "studio", "--exposure", "100"],
        &["exposure", "[-60, 60]"],
    );
    fails(
        &["--kind", "sun-sky", "--sun-elevation", "95"],
        &["sun elevation is 95"],
    );
    fails(
        &["--kind", "sun-sky", "--turbidity", "1"],
        &["turbidity is 1"],
    );
    fails(
        &["--kind", "studio", "--turbidity", "3"],
        &["for --kind sun-sky, not studio"],
    );
    fails(
        &["--input", "/no/such/map.exr"],
        &["/no/such/map.exr", "no such file"],
    );
    fails(
        &["--kind", "studio", "--input", "x.exr"],
        &["cannot be used with"],
    );
    fails(&[], &["--kind"]);
    let o = matedit()
        .args(["env", "--kind", "studio", "-o", "/tmp/out.txt"])
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains(".exr, .npy or .png"));
}
