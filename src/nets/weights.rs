//! Weight files written by `matedit.nets.save` (python/matedit/nets/model.py): safetensors
//! with the config as JSON in the metadata (`format` = "matedit-nets 1").

use std::collections::{BTreeSet, HashMap};
use std::path::{Path, PathBuf};

use safetensors::SafeTensors;
use serde::Deserialize;

use crate::error::{Error, Result};

/// The metadata's `format`, as `matedit.nets.save` writes it.
pub const FORMAT: &str = "matedit-nets 1";

/// The networks' sizes (model.py's `NetsConfig`), read from a weights file's metadata.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(default)]
pub struct NetsConfig {
    /// Channels of the first level; doubled per level.
    pub width: usize,
    /// U-Net / encoder levels; images must be multiples of 2^(levels - 1).
    pub levels: usize,
    /// Rows of the light net's map.
    pub env_height: usize,
    /// Columns of the light net's map.
    pub env_width: usize,
    /// How many fitted MERL presets the material net mixes (the metadata names them in
    /// `basis`; none named: all 90).
    #[serde(rename = "basis", deserialize_with = "basis_size")]
    pub basis: usize,
    /// The image side the nets were trained at: photos are analysed at it.
    pub image_size: usize,
    /// How the nets saw whole photos in training (absent: [`Frame::Square`]).
    pub frame: Frame,
}

/// How the nets saw whole photos in training, and so how an edit without a mask or a
/// pointing shows them a photo to find the object in (docs/edit.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Frame {
    /// Objects alone, centred in square frames on black or an environment: a photo is
    /// padded to a square with black.
    #[default]
    Square,
    /// Photo-like frames (a floor, the environment behind, clutter): a photo is shown at its
    /// own shape.
    Photo,
}

/// The number of presets a metadata `basis` names, 90 (all) for none.
fn basis_size<'de, D: serde::Deserializer<'de>>(d: D) -> std::result::Result<usize, D::Error> {
    let names: Vec<String> = Deserialize::deserialize(d)?;
    Ok(if names.is_empty() {
        super::N_MERL
    } else {
        names.len()
    })
}

impl Default for NetsConfig {
    fn default() -> Self {
        NetsConfig {
            width: 16,
            levels: 3,
            env_height: 16,
            env_width: 32,
            basis: super::N_MERL,
            image_size: 64,
            frame: Frame::Square,
        }
    }
}

/// The tensors of one weights file, taken one by one by name with their expected shape;
/// [`Weights::finish`] refuses tensors nobody took.
pub(super) struct Weights {
    path: PathBuf,
    tensors: HashMap<String, (Vec<usize>, Vec<f32>)>,
    taken: BTreeSet<String>,
}

impl Weights {
    /// Reads `path`: its config and every tensor (float32 or float64, kept on the CPU as
    /// float32).
    pub(super) fn read(path: &Path) -> Result<(NetsConfig, Weights)> {
        let bytes = std::fs::read(path).map_err(|e| Error::file(path, e.to_string()))?;
        Self::parse(path, &bytes)
    }

    /// [`Weights::read`] on a file's bytes; `path` names it in errors.
    pub(super) fn parse(path: &Path, bytes: &[u8]) -> Result<(NetsConfig, Weights)> {
        let bad = |m: String| Error::file(path, m);
        let (_, meta) = SafeTensors::read_metadata(bytes)
            .map_err(|e| bad(format!("not a safetensors file ({e})")))?;
        let meta = meta.metadata().clone().unwrap_or_default();
        match meta.get("format") {
            Some(f) if f == FORMAT => {}
            f => {
                return Err(bad(format!(
                    "not matedit nets weights (metadata format {f:?}, expected {FORMAT:?})"
                )));
            }
        }
        let config = meta
            .get("config")
            .ok_or_else(|| bad("metadata has no config".into()))?;
        let cfg: NetsConfig =
            serde_json::from_str(config).map_err(|e| bad(format!("metadata config: {e}")))?;
        if cfg.width == 0 || cfg.levels == 0 || cfg.env_height == 0 || cfg.env_width == 0 {
            return Err(bad(format!("metadata config: {config} has a zero size")));
        }
        if cfg.levels <= 16
            && (cfg.image_size == 0
                || cfg.image_size > 1024
                || !cfg.image_size.is_multiple_of(1 << (cfg.levels - 1)))
        {
            return Err(bad(format!(
                "metadata config: image_size {} is not a multiple of 2^(levels - 1) in 1..=1024",
                cfg.image_size
            )));
        }
        let too_large = cfg.levels > 16
            || cfg.width.checked_mul(1 << (cfg.levels + 2)).is_none()
            || cfg
                .env_height
                .checked_mul(cfg.env_width)
                .and_then(|n| n.checked_mul(3))
                .is_none();
        if too_large {
            return Err(bad(format!("metadata config: {config} is too large")));
        }
        let st = SafeTensors::deserialize(bytes)
            .map_err(|e| bad(format!("not a safetensors file ({e})")))?;
        let mut tensors = HashMap::new();
        for (name, view) in st.tensors() {
            // little-endian values, as safetensors stores them
            let d = view.data();
            let t: Vec<f32> = match view.dtype() {
                safetensors::Dtype::F32 => d
                    .chunks_exact(4)
                    .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
                    .collect(),
                safetensors::Dtype::F64 => d
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().expect("8 bytes")) as f32)
                    .collect(),
                d => return Err(bad(format!("tensor {name}: dtype {d:?}, expected F32"))),
            };
            let shape = view.shape().to_vec();
            if t.len() != shape.iter().product::<usize>() {
                return Err(bad(format!(
                    "tensor {name}: {} values for shape {shape:?}",
                    t.len()
                )));
            }
            tensors.insert(name, (shape, t));
        }
        let w = Weights {
            path: path.to_owned(),
            tensors,
            taken: BTreeSet::new(),
        };
        Ok((cfg, w))
    }

    /// The values of tensor `name` (row-major), which must have `shape`.
    pub(super) fn take(&mut self, name: &str, shape: &[usize]) -> Result<Vec<f32>> {
        let Some((have, t)) = self.tensors.get(name) else {
            return Err(self.error(format!("tensor {name} is missing (shape {shape:?})")));
        };
        if have != shape {
            return Err(self.error(format!(
                "tensor {name}: shape {have:?}, expected {shape:?} for the config"
            )));
        }
        let t = t.clone();
        self.taken.insert(name.to_owned());
        Ok(t)
    }

    /// An error unless every tensor was taken.
    pub(super) fn finish(self) -> Result<()> {
        let mut left: Vec<_> = self
            .tensors
            .keys()
            .filter(|k| !self.taken.contains(*k))
            .collect();
        left.sort();
        match left.first() {
            None => Ok(()),
            Some(k) => Err(self.error(format!(
                "tensor {k} is not part of the nets ({} unexpected tensors)",
                left.len()
            ))),
        }
    }

    /// An [`Error::File`] about this file.
    pub(super) fn error(&self, message: String) -> Error {
        Error::file(&self.path, message)
    }
}
