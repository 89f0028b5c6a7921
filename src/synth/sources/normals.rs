//! The spec's `normals` list: spheres, bumpy maps, procedural shapes, meshes and
//! normal-map files, each item checked against the image size, loaded and hashed.

use std::path::Path;

use serde::Deserialize;
use serde_json::Value;
use sha2::Sha256;

use super::{Weighted, image_dims, one_of, serde_message, weight_of};
use crate::error::{Error, Result};
use crate::scene::NormalMap;
use crate::synth::augment::Views;
use crate::synth::files::{files_of, hash_file};

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNormals {
    sphere: Option<Value>,
    bumpy: Option<Value>,
    shape: Option<String>,
    mesh: Option<String>,
    file: Option<String>,
    folder: Option<String>,
    views: Option<Value>,
    crease: Option<f64>,
    weight: Option<f64>,
}

/// Where a sample's normals come from, loaded (a scene's, as the command line and a
/// manifest name them, is an [`crate::io::source::NormalsSource`]).
#[derive(Clone, Debug)]
pub enum SampleNormals {
    /// The unit sphere at the image size.
    Sphere(NormalMap),
    /// [`NormalMap::bumpy`] at the image size, its seed drawn per sample.
    Bumpy,
    /// A procedural shape ([`crate::shapes::Shape`]), its parameters and a rotation
    /// ([`Views`]) drawn per sample, drawn with the spec's camera at the image size.
    Shape(crate::shapes::Shape, Views),
    /// Mesh files (one, or a folder's), each with its name as the spec gives it: one
    /// picked and turned by a rotation ([`Views`]) per sample, drawn as a shape is.
    Meshes(Vec<(String, crate::shapes::Mesh)>, Views),
    /// Normal-map files (one, or a folder's), each with its name as the spec gives it.
    Files(Vec<(String, NormalMap)>),
}

/// Normals as the file loaders give them back after a round trip through a float32 file:
/// a sample's recorded normals, read by `matedit render`, render the same bits.
fn loader_stable(mut m: NormalMap) -> NormalMap {
    for n in &mut m.normals {
        let v = n.map(f64::from);
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        if len < crate::scene::BACKGROUND_EPS {
            *n = [0.0; 3];
        } else if v.map(|c| (c / len) as f32) != *n {
            *n = crate::normals::loader_stable_unit(v);
        }
    }
    m
}

/// The spec's `normals` list, loaded (every map at the image size `(w, h)`) and hashed;
/// errors name the item.
pub(in crate::synth) fn normals(
    items: &[Value],
    (w, h): (usize, usize),
    base: &Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<SampleNormals>>> {
    let mut normals = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let at = |m: String| err(format!("normals[{i}]: {m}"));
        let r = match item {
            Value::String(s) => RawNormals {
                sphere: None,
                bumpy: None,
                shape: None,
                mesh: None,
                file: Some(s.clone()),
                folder: None,
                views: None,
                crease: None,
                weight: None,
            },
            _ => serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?,
        };
        let kind = one_of(
            &[
                r.sphere.is_some(),
                r.bumpy.is_some(),
                r.file.is_some(),
                r.folder.is_some(),
                r.shape.is_some(),
                r.mesh.is_some(),
            ],
            &["sphere", "bumpy", "file", "folder", "shape", "mesh"],
        )
        .map_err(at)?;
        if r.views.is_some() && kind < 4 {
            return Err(at("\"views\" goes with \"shape\" or \"mesh\" only".into()));
        }
        if r.crease.is_some() && kind != 5 {
            return Err(at("\"crease\" goes with \"mesh\" only".into()));
        }
        if let Some(c) = r.crease {
            crate::shapes::check_crease(c).map_err(|m| at(format!("crease: {m}")))?;
        }
        let views = Views::parse(r.views.as_ref()).map_err(at)?;
        let weight = weight_of(r.weight).map_err(at)?;
        let size_of = |key: &str, v: &Value| -> Result<()> {
            let (sw, sh) = image_dims(v).map_err(|m| at(format!("{key}: {m}")))?;
            if (sw, sh) != (w, h) {
                return Err(at(format!(
                    "{key}: size {sh}x{sw} differs from image_size {h}x{w}; generated \
                     normals are made at the image size"
                )));
            }
            Ok(())
        };
        let source = match kind {
            0 => {
                let v = r.sphere.as_ref().unwrap_or(&Value::Null);
                size_of("sphere", v)?;
                if w != h {
                    return Err(at(format!(
                        "sphere: a sphere is square but image_size is {h}x{w}; use \"bumpy\" or a file"
                    )));
                }
                SampleNormals::Sphere(loader_stable(NormalMap::sphere(w)))
            }
            1 => {
                size_of("bumpy", r.bumpy.as_ref().unwrap_or(&Value::Null))?;
                SampleNormals::Bumpy
            }
            4 => {
                let spec = r.shape.as_deref().unwrap_or_default();
                let shape = spec.parse().map_err(|e| at(format!("shape: {e}")))?;
                SampleNormals::Shape(shape, views)
            }
            5 => {
                let exts = ["obj", "ply", "stl", "off", "gltf", "glb"];
                let files =
                    files_of(base, r.mesh, None, &exts).map_err(|m| at(format!("mesh: {m}")))?;
                let mut meshes = Vec::with_capacity(files.len());
                for f in files {
                    let mut m = crate::shapes::load_mesh(&f.path).map_err(|e| at(e.to_string()))?;
                    if let Some(degrees) = r.crease {
                        m = m.creased(degrees);
                    }
                    hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                    meshes.push((f.label, m));
                }
                SampleNormals::Meshes(meshes, views)
            }
            _ => {
                let files = files_of(base, r.file, r.folder, &["exr", "npy", "png"]).map_err(at)?;
                let mut maps = Vec::with_capacity(files.len());
                for f in files {
                    let m = crate::io::load_normals(&f.path).map_err(|e| at(e.to_string()))?;
                    if (m.width, m.height) != (w, h) {
                        return Err(at(format!(
                            "{}: is {}x{} (height x width) but image_size is {h}x{w}",
                            f.path.display(),
                            m.height,
                            m.width
                        )));
                    }
                    hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                    maps.push((f.label, loader_stable(m)));
                }
                SampleNormals::Files(maps)
            }
        };
        normals.push(Weighted { weight, source });
    }
    Ok(normals)
}
