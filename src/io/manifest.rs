//! Batch manifests: a JSON file that lists several scenes to render (or differentiate) in
//! one [`Batch`](crate::Batch) call.
//!
//! ```json
//! {
//!   "env_size": "64x128",
//!   "convention": "equirect",
//!   "fov": 40,
//!   "scenes": [
//!     { "output": "red.png",  "sphere": 128, "preset": "plastic-red" },
//!     { "output": "gold.exr", "normals": "face.npy", "env": "sky.exr", "material": "gold.json" }
//!   ]
//! }
//! ```
//!
//! Batch-wide keys (optional): `env_size` (`"HxW"` or `"full"`), `convention`
//! (`"equirect"` or `"paper"`), `fov` (degrees; perspective camera). Per-scene keys:
//! `output` (required), at most one of `normals` / `sphere`, `env`, at most one of
//! `material` / `preset`, and `upstream` (for `matedit grad`). What a scene or the
//! manifest leaves out comes from the command line's options, then the built-in defaults.
//! Relative paths are relative to the manifest's folder, outputs to the `-o` folder if
//! one is given. Unknown keys are errors, to catch typos.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use serde::Deserialize;

use super::resample::EnvSize;
use super::source::{MAX_IMAGE_SIDE, MaterialSource, NormalsSource};
use crate::camera::Camera;
use crate::envmap::Convention;
use crate::error::{Error, Result};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ManifestFile {
    env_size: Option<String>,
    convention: Option<String>,
    fov: Option<f64>,
    scenes: Vec<SceneEntry>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneEntry {
    output: PathBuf,
    normals: Option<PathBuf>,
    sphere: Option<usize>,
    env: Option<PathBuf>,
    material: Option<PathBuf>,
    preset: Option<String>,
    upstream: Option<PathBuf>,
}

/// A validated manifest, paths resolved.
#[derive(Clone, Debug, PartialEq)]
pub struct Manifest {
    /// Batch-wide env size, if given.
    pub env_size: Option<EnvSize>,
    /// Batch-wide convention, if given.
    pub convention: Option<Convention>,
    /// Batch-wide perspective field of view in degrees, if given.
    pub fov: Option<f64>,
    /// The scenes, in order.
    pub scenes: Vec<ManifestScene>,
}

/// One scene of a manifest; `None` fields fall back to the command line's options.
#[derive(Clone, Debug, PartialEq)]
pub struct ManifestScene {
    /// Where the image (or, for `grad`, the gradient folder) goes.
    pub output: PathBuf,
    /// The normals, if given.
    pub normals: Option<NormalsSource>,
    /// The environment map file, if given.
    pub env: Option<PathBuf>,
    /// The material, if given.
    pub material: Option<MaterialSource>,
    /// The upstream gradient file, if given.
    pub upstream: Option<PathBuf>,
}

fn resolve(base: &Path, p: PathBuf) -> PathBuf {
    if p.is_absolute() { p } else { base.join(p) }
}

/// Reads and validates a manifest. Relative inputs resolve against the manifest's folder;
/// relative outputs against `output_dir` if given, else the manifest's folder.
pub fn read(path: &Path, output_dir: Option<&Path>) -> Result<Manifest> {
    parse(path, &super::read_bytes(path)?, output_dir)
}

/// [`read`] on a file's bytes; `path` names the file in errors and is where relative paths
/// resolve from.
pub fn parse(path: &Path, bytes: &[u8], output_dir: Option<&Path>) -> Result<Manifest> {
    let file: ManifestFile = super::json::from_slice(bytes)
        .map_err(|e| Error::file(path, format!("not a valid manifest: {e}")))?;
    let err = |m: String| Error::file(path, m);
    // An empty parent (a manifest in the current folder) leaves relative paths as they are.
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let out_base = output_dir
        .map(Path::to_path_buf)
        .unwrap_or_else(|| base.clone());

    let env_size = file
        .env_size
        .map(|s| s.parse::<EnvSize>())
        .transpose()
        .map_err(|m| err(format!("env_size: {m}")))?;
    let convention = file
        .convention
        .map(|s| s.parse::<Convention>())
        .transpose()
        .map_err(|m| err(format!("convention: {m}")))?;
    if let Some(fov) = file.fov {
        Camera::Perspective { fov_y_deg: fov }
            .validate()
            .map_err(|e| err(format!("fov: {e}")))?;
    }
    if file.scenes.is_empty() {
        return Err(err("'scenes' is empty; list at least one scene".into()));
    }
    let mut seen = HashSet::new();
    let mut scenes = Vec::with_capacity(file.scenes.len());
    for (i, s) in file.scenes.into_iter().enumerate() {
        let at = |m: String| err(format!("scenes[{i}]: {m}"));
        let normals = match (s.normals, s.sphere) {
            (Some(_), Some(_)) => {
                return Err(at("give 'normals' or 'sphere', not both".into()));
            }
            (Some(p), None) => Some(NormalsSource::File(resolve(&base, p))),
            (None, Some(n)) if n == 0 || n > MAX_IMAGE_SIDE => {
                return Err(at(format!(
                    "'sphere' is {n}; it must be between 1 and {MAX_IMAGE_SIDE}"
                )));
            }
            (None, Some(n)) => Some(NormalsSource::Sphere(n)),
            (None, None) => None,
        };
        let material = match (s.material, s.preset) {
            (Some(_), Some(_)) => {
                return Err(at("give 'material' or 'preset', not both".into()));
            }
            (Some(p), None) => Some(MaterialSource::File(resolve(&base, p))),
            (None, Some(name)) => {
                if crate::presets::lookup(&name).is_none() {
                    return Err(at(format!(
                        "unknown preset '{name}'; the presets are {}",
                        crate::presets::names().join(", ")
                    )));
                }
                Some(MaterialSource::Preset(name))
            }
            (None, None) => None,
        };
        if s.output.as_os_str().is_empty() {
            return Err(at("'output' is empty".into()));
        }
        let output = resolve(&out_base, s.output);
        if !seen.insert(output.clone()) {
            return Err(at(format!(
                "output {} is also the output of an earlier scene",
                output.display()
            )));
        }
        scenes.push(ManifestScene {
            output,
            normals,
            env: s.env.map(|p| resolve(&base, p)),
            material,
            upstream: s.upstream.map(|p| resolve(&base, p)),
        });
    }
    Ok(Manifest {
        env_size,
        convention,
        fov: file.fov,
        scenes,
    })
}
