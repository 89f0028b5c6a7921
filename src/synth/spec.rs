//! The synthesis spec: what a dataset is drawn from, parsed, checked and loaded in full
//! before anything is written, and the pure function from (spec, sample index) to a scene.
//!
//! ```json
//! {"count": 12, "seed": 7, "image_size": 64, "env_size": "32x64",
//!  "normals": [{"sphere": 64}, {"bumpy": 64}], "envs": ["sky.exr"],
//!  "materials": [{"preset": "gold"}, {"random": "merl"}]}
//! ```
//!
//! docs/synth.md describes every key. Errors name the spec file and the item
//! (`spec.json: normals[1]: unknown field "bumpi"`); relative paths resolve against the
//! spec's folder, and what a sample records of them is the path as the spec gives it, so
//! the bytes do not depend on where the spec lives.

use std::path::{Path, PathBuf};

use serde::Deserialize;
use serde_json::Value;
use sha2::{Digest, Sha256};

use super::background::{self, Background};
use super::camera_effects::CameraEffects;
use super::clutter::{self, Clutter};
use super::sources::{
    self, EnvSource, MaterialItem, SampleNormals, Weighted, image_dims, serde_message,
};
use super::world::{RawWorld, World};
use crate::camera::Camera;
use crate::envmap::Convention;
use crate::error::{Error, Result};
use crate::io::resample::EnvSize;

/// Samples per chunk when the spec does not say (or `count`, if smaller).
pub const DEFAULT_CHUNK_SIZE: usize = 64;

/// The spec as written.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpec {
    count: u64,
    #[serde(default)]
    seed: u64,
    image_size: Value,
    env_size: Option<String>,
    chunk_size: Option<u64>,
    fov: Option<Value>,
    elevation: Option<Value>,
    floor: Option<Vec<Value>>,
    shadows: Option<bool>,
    clutter: Option<Value>,
    convention: Option<String>,
    normals: Vec<Value>,
    envs: Vec<Value>,
    materials: Vec<Value>,
    backgrounds: Option<Vec<Value>>,
    camera_effects: Option<Value>,
    edit: Option<Value>,
}

/// A checked and loaded spec.
#[derive(Clone, Debug)]
pub struct Spec {
    /// The spec file.
    pub path: PathBuf,
    /// Samples in the dataset.
    pub count: u64,
    /// The seed every sample's draws derive from.
    pub seed: u64,
    /// Image (width, height).
    pub image_size: (usize, usize),
    /// Environment maps' (height, width).
    pub env_size: (usize, usize),
    /// Samples per chunk (every chunk holds exactly this many).
    pub chunk_size: u64,
    /// The camera.
    pub camera: Camera,
    /// The texel convention.
    pub convention: Convention,
    /// Normal sources.
    pub normals: Vec<Weighted<SampleNormals>>,
    /// Lighting sources.
    pub envs: Vec<Weighted<EnvSource>>,
    /// Material sources.
    pub materials: Vec<Weighted<MaterialItem>>,
    /// Background sources (black when the spec gives none).
    pub backgrounds: Vec<Weighted<Background>>,
    /// Camera effects each sample draws (none when the spec gives none).
    pub camera_effects: Option<CameraEffects>,
    /// Material sources of the true edit (none: no edit).
    pub edit: Option<Vec<Weighted<MaterialItem>>>,
    /// The photo-like options: fov and elevation ranges, floor, shadows.
    pub world: World,
    /// Other objects on the floor (none: no clutter).
    pub clutter: Option<Clutter>,
    /// SHA-256 of the spec's content and of every input file, hex.
    pub digest: String,
}

/// Lower-case hex of bytes.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

impl Spec {
    /// Reads, checks and loads a spec and every input it names; nothing is written.
    pub fn load(path: &Path) -> Result<Spec> {
        let bytes = crate::io::read_bytes(path)?;
        let err = |m: String| Error::file(path, m);
        let value: Value =
            serde_json::from_slice(&bytes).map_err(|e| err(format!("not valid JSON: {e}")))?;
        if !value.is_object() {
            return Err(err("a spec is a JSON object".into()));
        }
        let raw: RawSpec = serde_path_to_error::deserialize(value.clone()).map_err(|e| {
            let at = e.path().to_string();
            let message = serde_message(e.inner());
            if at == "." {
                err(format!("not a valid spec: {message}"))
            } else {
                err(format!("{at}: {message}"))
            }
        })?;
        let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut hasher = Sha256::new();
        hasher.update(b"matedit synth spec 1\n");
        // serde_json's maps are ordered by key: this is a canonical form of the content
        hasher.update(value.to_string().as_bytes());
        hasher.update(b"\n");

        if raw.count == 0 {
            return Err(err("count: must be at least 1".into()));
        }
        let image_size =
            image_dims(&raw.image_size).map_err(|m| err(format!("image_size: {m}")))?;
        let env_size = match &raw.env_size {
            None => crate::envmap::DEFAULT_ENV_SIZE,
            Some(s) => match s.parse::<EnvSize>() {
                Ok(EnvSize::Size { height, width }) => (height, width),
                Ok(EnvSize::Full) => {
                    return Err(err(
                        "env_size: 'full' is not allowed: every sample's map must have one size; give \"HxW\"".into(),
                    ));
                }
                Err(m) => return Err(err(format!("env_size: {m}"))),
            },
        };
        let chunk_size = match raw.chunk_size {
            Some(0) => return Err(err("chunk_size: must be at least 1".into())),
            Some(c) => c,
            None => raw.count.min(DEFAULT_CHUNK_SIZE as u64),
        };
        if !raw.count.is_multiple_of(chunk_size) {
            let fit = (1..=chunk_size)
                .rev()
                .find(|d| raw.count.is_multiple_of(*d))
                .unwrap_or(1);
            return Err(err(format!(
                "count: {} is not a multiple of chunk_size {chunk_size}{}; every chunk holds \
                 chunk_size samples: give a count that is, or a chunk_size that divides it \
                 (e.g. {fit})",
                raw.count,
                if raw.chunk_size.is_none() {
                    " (the default)"
                } else {
                    ""
                }
            )));
        }
        let convention = match &raw.convention {
            None => Convention::default(),
            Some(s) => s
                .parse()
                .map_err(|m: String| err(format!("convention: {m}")))?,
        };
        for (key, list) in [
            ("normals", &raw.normals),
            ("envs", &raw.envs),
            ("materials", &raw.materials),
        ] {
            if list.is_empty() {
                return Err(err(format!("{key}: the list is empty; give at least one")));
            }
        }

        let normals = sources::normals(&raw.normals, image_size, &base, &mut hasher, &err)?;
        let (camera, world) = World::parse(
            RawWorld {
                fov: raw.fov.as_ref(),
                elevation: raw.elevation.as_ref(),
                floor: raw.floor.as_deref(),
                shadows: raw.shadows,
            },
            &normals,
            convention,
            &base,
            &mut hasher,
            &err,
        )?;
        camera.validate().map_err(|e| err(format!("fov: {e}")))?;
        let envs = sources::envs(&raw.envs, env_size, convention, &base, &mut hasher, &err)?;
        let materials = sources::materials(&raw.materials, &base, &mut hasher, &err)?;
        let backgrounds = background::backgrounds(
            raw.backgrounds.as_deref(),
            image_size,
            camera,
            convention,
            &base,
            &mut hasher,
            &err,
        )?;
        let camera_effects = (raw.camera_effects.as_ref())
            .map(CameraEffects::parse)
            .transpose()
            .map_err(err)?;
        let edit = (raw.edit.as_ref())
            .map(|v| edit_materials(v, &base, &mut hasher, &err))
            .transpose()?;
        let defaults = || clutter::Defaults {
            normals: &normals,
            materials: &materials,
            image_size,
            has_floor: world.floors.is_some(),
        };
        let clutter = (raw.clutter.as_ref())
            .map(|v| Clutter::parse(v, defaults(), &base, &mut hasher, &err))
            .transpose()?;

        Ok(Spec {
            path: path.to_path_buf(),
            count: raw.count,
            seed: raw.seed,
            image_size,
            env_size,
            chunk_size,
            camera,
            convention,
            normals,
            envs,
            materials,
            backgrounds,
            camera_effects,
            edit,
            world,
            clutter,
            digest: hex(&hasher.finalize()),
        })
    }

    /// Chunks in the dataset.
    pub fn chunks(&self) -> u64 {
        self.count / self.chunk_size
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEdit {
    materials: Vec<Value>,
}

/// The spec's `edit` object: its material sources, loaded and hashed into the digest;
/// errors name `edit.materials[i]`.
fn edit_materials(
    v: &Value,
    base: &std::path::Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<MaterialItem>>> {
    let raw: RawEdit = serde_path_to_error::deserialize(v.clone()).map_err(|e| {
        let at = e.path().to_string();
        let m = serde_message(e.inner());
        err(if at == "." {
            format!("edit: {m}")
        } else {
            format!("edit.{at}: {m}")
        })
    })?;
    if raw.materials.is_empty() {
        return Err(err(
            "edit.materials: the list is empty; give at least one".into()
        ));
    }
    super::sources::materials(&raw.materials, base, hasher, &|m| err(format!("edit.{m}")))
}
