//! JSON files: materials (`{"name": ..., "ctrl": [108 numbers]}`) and material gradients
//! (`{"ctrl": [108 numbers]}`).
//!
//! `ctrl` is in the flat order idx(k, s, t, j) = ((k * 3 + s) * 2 + t) * 6 + j: k the
//! channel (R, G, B), s the lobe, t the coefficient (0 the scale m0, 1 the exponent m1),
//! j the spline control point over theta_d in [0, pi/2].

use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::material::{Material, N_PARAMS};

/// A material file as written on disk.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialFile {
    /// A name for reports; the file name's stem if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// A free-text description, ignored by matedit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// The 108 control points in flat order.
    pub ctrl: Vec<f64>,
}

/// A material gradient file: dLoss/dctrl in the flat order.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct GradientFile {
    /// The 108 partial derivatives.
    pub ctrl: Vec<f32>,
}

/// Where the control points are checked; here for the material files' readers.
pub use crate::material::{describe_index, material_from_ctrl};

/// Parses JSON text into `T`; the error names where in the document it is (`scenes[2].
/// material: invalid type: ...`) as well as serde_json's line and column.
pub fn from_slice<T: serde::de::DeserializeOwned>(bytes: &[u8]) -> std::result::Result<T, String> {
    let mut de = serde_json::Deserializer::from_slice(bytes);
    let value = serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let at = e.path().to_string();
        if at == "." {
            e.inner().to_string()
        } else {
            format!("{at}: {}", e.inner())
        }
    })?;
    de.end().map_err(|e| e.to_string())?;
    Ok(value)
}

/// Reads a material JSON file.
pub fn read_material(path: &Path) -> Result<Material> {
    parse_material(path, &super::read_bytes(path)?)
}

/// [`read_material`] on a file's bytes; `path` names the file in errors and, where the
/// file has no name, the material.
pub fn parse_material(path: &Path, bytes: &[u8]) -> Result<Material> {
    let file: MaterialFile =
        from_slice(bytes).map_err(|e| Error::file(path, format!("not a material file: {e}")))?;
    let name = file.name.unwrap_or_else(|| {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    });
    material_from_ctrl(name, &file.ctrl).map_err(|m| Error::file(path, m))
}

/// Encodes a material as pretty JSON, one control point a line in the flat order.
pub fn encode_material(material: &Material, description: Option<&str>) -> Vec<u8> {
    let file = MaterialFile {
        name: Some(material.name.clone()),
        description: description.map(str::to_string),
        ctrl: material.ctrl.to_vec(),
    };
    let mut out = serde_json::to_vec_pretty(&file).unwrap_or_default();
    out.push(b'\n');
    out
}

/// Encodes dLoss/dctrl as `{"ctrl": [108 numbers]}`.
pub fn encode_gradient(d_ctrl: &[f32; N_PARAMS]) -> Vec<u8> {
    let file = GradientFile {
        ctrl: d_ctrl.to_vec(),
    };
    let mut out = serde_json::to_vec_pretty(&file).unwrap_or_default();
    out.push(b'\n');
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn index_description() {
        assert_eq!(
            describe_index(7),
            "ctrl[7] (channel R, lobe 0, exponent m1, point 1)"
        );
        assert_eq!(
            describe_index(107),
            "ctrl[107] (channel B, lobe 2, exponent m1, point 5)"
        );
    }

    #[test]
    fn validation_messages() {
        let mut c = vec![0.5; 108];
        assert!(material_from_ctrl("a".into(), &c).is_ok());
        c[6] = -1.0;
        let e = material_from_ctrl("a".into(), &c).unwrap_err();
        assert!(e.contains("ctrl[6]") && e.contains(">= 0"), "{e}");
        let e = material_from_ctrl("a".into(), &c[..107]).unwrap_err();
        assert!(e.contains("107") && e.contains("108"), "{e}");
    }
}
