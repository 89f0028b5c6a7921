//! Property tests (proptest) of every loader and validator:
//! - arbitrary bytes, and valid files with truncations, byte flips and header fields set to
//!   odd values, never panic: each loader gives Ok or one line naming the file;
//! - what the writers write (NPY, EXR, PNG, material JSON) reads back exactly;
//! - the validators accept a material, normals, env map or camera exactly when the limits
//!   of docs/CONVENTIONS.md hold, the loaders accept exactly the values they document, and
//!   what is accepted renders finite (fast CPU path and reference, tiny scenes);
//! - no loader allocates what a header claims before checking it against the file
//!   (a counting allocator watches the largest request).
//!
//! Failures proptest finds are kept in tests/proptest-regressions/MODULE.txt (where
//! proptest looks for a test in tests/inputs_prop/MODULE.rs, this folder holding a main.rs)
//! and, as plain tests, in found.rs, with the inputs the fuzz targets (fuzz/) found, as
//! bytes. fuzz_seeds.rs (ignored) writes the fuzz targets' seeds.

mod binary_files;
mod found;
mod fuzz_seeds;
mod header_claims;
mod json_files;
mod mutations;
mod no_panic;
mod round_trips;
mod validators;

use std::path::Path;

use matedit::brdf::{merl, nbrdf};
use matedit::fit_brdf::job::Bundle;
use matedit::io::{self, EnvSize};
use matedit::{Convention, Error};
use proptest::prelude::*;
use proptest::test_runner::TestCaseError;

// ---------------------------------------------------------------------------------------
// The loaders and what a clean result is

type Load = fn(&Path, &[u8]) -> matedit::Result<()>;

fn raster(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::raster_from_bytes(p, b, "a raster").map(drop)
}
fn normals(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::normals_from_bytes(p, b).map(drop)
}
/// As the command line loads a map: both conventions, brought to 1 x 1 (always a divisor)
/// and to the default size.
fn env(p: &Path, b: &[u8]) -> matedit::Result<()> {
    for c in [Convention::Paper, Convention::Equirect] {
        let e = io::env_from_bytes(p, b, c)?.env;
        io::resample::fit(
            e.clone(),
            EnvSize::Size {
                height: 1,
                width: 1,
            },
            p,
        )?;
        if c == Convention::Equirect {
            io::resample::fit(e, EnvSize::default(), p)?;
        }
    }
    Ok(())
}
fn png_image(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::png::decode_bytes(p, b).map(drop)
}
fn material(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::json::parse_material(p, b).map(drop)
}
fn manifest(p: &Path, b: &[u8]) -> matedit::Result<()> {
    io::manifest::parse(p, b, None).map(drop)
}
/// As `nbrdf::read` does after reading the file.
fn nbrdf_nets(p: &Path, b: &[u8]) -> matedit::Result<()> {
    let text = std::str::from_utf8(b).map_err(|e| Error::file(p, format!("cannot read: {e}")))?;
    nbrdf::parse(text).map(drop).map_err(|m| Error::file(p, m))
}
fn bundle(p: &Path, b: &[u8]) -> matedit::Result<()> {
    let text = std::str::from_utf8(b).map_err(|e| Error::file(p, format!("cannot read: {e}")))?;
    Bundle::parse(text).map(drop).map_err(|m| Error::file(p, m))
}
/// As `merl::read` does after reading the file.
fn merl_table(p: &Path, b: &[u8]) -> matedit::Result<()> {
    merl::parse(b, "t").map(drop).map_err(|m| Error::file(p, m))
}

/// Every loader on bytes, by the name of the file it is given (the extension picks the
/// format, as on the command line).
const LOADERS: &[(&str, Load)] = &[
    ("in/a.npy", raster),
    ("in/a.exr", raster),
    ("in/a.npy", normals),
    ("in/a.exr", normals),
    ("in/a.png", normals),
    ("in/a.npy", env),
    ("in/a.exr", env),
    ("in/a.png", png_image),
    ("in/a.json", material),
    ("in/a.json", manifest),
    ("in/a.json", nbrdf_nets),
    ("in/a.json", bundle),
    ("in/a.binary", merl_table),
];

/// Ok, or an [`Error::File`] naming `path` whose message is one line.
fn clean<T>(path: &Path, r: matedit::Result<T>) -> Result<Option<T>, TestCaseError> {
    match r {
        Ok(v) => Ok(Some(v)),
        Err(e) => {
            let m = e.to_string();
            prop_assert!(
                matches!(&e, Error::File { path: p, .. } if p == path),
                "not an error naming {}: {m}",
                path.display()
            );
            prop_assert!(!m.contains(['\n', '\r']), "more than one line: {m:?}");
            prop_assert!(m.len() > path.as_os_str().len() + 2, "no message: {m:?}");
            Ok(None)
        }
    }
}

/// Runs every loader for files ending in `ext` on `bytes`.
fn load_all(ext: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    for (name, load) in LOADERS.iter().filter(|(n, _)| n.ends_with(ext)) {
        let path = Path::new(name);
        clean(path, load(path, bytes))?;
    }
    Ok(())
}

/// Every path-based loader on a real file `name` holding `bytes`: the command line's way in.
fn load_file(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
    let dir = tempfile::tempdir().expect("temp dir");
    let p = dir.path().join(name);
    std::fs::write(&p, bytes).expect("write");
    clean(&p, io::read_raster(&p, "a raster"))?;
    clean(&p, io::load_normals(&p))?;
    clean(&p, io::load_env(&p, Convention::Equirect))?;
    clean(&p, io::load_image(&p))?;
    clean(&p, io::load_mask(&p))?;
    clean(&p, io::load_upstream(&p))?;
    clean(&p, io::load_material(&p))?;
    clean(&p, io::manifest::read(&p, None))?;
    clean(&p, merl::read(&p))?;
    clean(&p, nbrdf::read(&p))?;
    info_is_clean(&p)?;
    Ok(())
}

/// `matedit info` on `path` (the report is the command line's): a report, or as [`clean`]
/// asks of an error, through the command's exit code 2 (bad input) and its one-line stderr
/// `error: PATH: MESSAGE`.
fn info_is_clean(path: &Path) -> Result<(), TestCaseError> {
    let out = assert_cmd::cargo::cargo_bin_cmd!("matedit")
        .arg("info")
        .arg(path)
        .output()
        .expect("runs matedit");
    if out.status.success() {
        return Ok(());
    }
    let m = String::from_utf8_lossy(&out.stderr);
    let m = m.strip_suffix('\n').unwrap_or(&m);
    let named = format!("error: {}: ", path.display());
    prop_assert_eq!(out.status.code(), Some(2), "not an input error: {}", m);
    prop_assert!(
        m.starts_with(&named),
        "not an error naming {}: {m}",
        path.display()
    );
    prop_assert!(!m.contains(['\n', '\r']), "more than one line: {m:?}");
    prop_assert!(m.len() > named.len(), "no message: {m:?}");
    Ok(())
}
