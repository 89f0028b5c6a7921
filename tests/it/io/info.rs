//! `matedit info FILE`: the report on each kind of file.

use std::path::Path;

use exr::prelude::Compression;
use matedit::io;

use super::{dir, image, patch_compression, write_exr};

/// `matedit info FILE`'s report on stdout (the report is the command line's).
fn info(path: &Path) -> String {
    let out = assert_cmd::cargo::cargo_bin_cmd!("matedit")
        .arg("info")
        .arg(path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

#[test]
fn info_reports() {
    let d = dir();
    let p = d.path().join("env.npy");
    let mut data = vec![[0.5f32, 0.25, 2.0]; 4 * 8];
    data[3] = [-1.0, f32::NAN, 0.0];
    std::fs::write(&p, io::npy::encode_rgb(8, 4, &data)).unwrap();
    let r = info(&p);
    assert!(r.contains("8 wide x 4 high"), "{r}");
    assert!(
        r.contains("NaN values: 1") && r.contains("negative values: 1"),
        "{r}"
    );
    assert!(
        r.contains("env       no: pixel (3, 0) is not finite"),
        "{r}"
    );

    let m = d.path().join("m.json");
    std::fs::write(
        &m,
        io::json::encode_material(&matedit::presets::lookup("clay").unwrap(), None),
    )
    .unwrap();
    let r = info(&m);
    assert!(r.contains("material  yes"), "{r}");

    let x = d.path().join("x.exr");
    write_exr(&x, &image(4, 2), Compression::ZIP16);
    patch_compression(&x, 10);
    let r = info(&x);
    assert!(
        r.contains("cannot be used") && r.contains("HTJ2K256"),
        "{r}"
    );
}
