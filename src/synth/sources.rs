//! The spec's source lists (`normals`, `envs`, `materials`): each item parsed, checked,
//! loaded in full and hashed into the spec's digest, with the helpers they share (sizes,
//! weights, files and folders).

use std::path::Path;

use serde::Deserialize;
use serde_json::{Value, json};
use sha2::Sha256;

use super::augment::{EnvAugment, Views};
use super::files::{files_of, hash_file};
use super::perturb::Perturb;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::io::resample::{self, EnvSize};
use crate::io::source::MAX_IMAGE_SIDE;
use crate::material::Material;
use crate::scene::NormalMap;

/// Most presets a `{"random": "merl"}` draw mixes.
pub const MAX_MIX: usize = 16;

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
    weight: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEnv {
    procedural: Option<String>,
    file: Option<String>,
    folder: Option<String>,
    rotate: Option<bool>,
    exposure: Option<[f64; 2]>,
    white_balance: Option<[f64; 2]>,
    weight: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    preset: Option<String>,
    file: Option<String>,
    random: Option<String>,
    mix: Option<usize>,
    from: Option<Vec<String>>,
    except: Option<Vec<String>>,
    perturb: Option<Value>,
    weight: Option<f64>,
}

/// The fitted MERL presets a `{"random": "merl"}` source draws from: those named in
/// `from`, or all but those named in `except`, as indices into `presets::merl()`.
fn merl_subset(
    from: Option<&[String]>,
    except: Option<&[String]>,
) -> std::result::Result<Vec<usize>, String> {
    let merl = crate::presets::merl();
    let index = |name: &String| {
        merl.iter()
            .position(|p| p.name == name.as_str())
            .ok_or_else(|| {
                format!("'{name}' is not a fitted MERL preset (`matedit presets` lists them)")
            })
    };
    let mut picked = match (from, except) {
        (Some(_), Some(_)) => return Err("give \"from\" or \"except\", not both".into()),
        (Some(names), None) => names
            .iter()
            .map(index)
            .collect::<std::result::Result<Vec<_>, _>>()?,
        (None, Some(names)) => {
            let out = names
                .iter()
                .map(index)
                .collect::<std::result::Result<Vec<_>, _>>()?;
            (0..merl.len()).filter(|i| !out.contains(i)).collect()
        }
        (None, None) => (0..merl.len()).collect(),
    };
    picked.sort_unstable();
    picked.dedup();
    if picked.is_empty() {
        return Err("no preset left to draw from".into());
    }
    Ok(picked)
}

/// Where a sample's normals come from.
#[derive(Clone, Debug)]
pub enum NormalsSource {
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

/// Where a sample's lighting comes from.
#[derive(Clone, Debug)]
pub struct EnvSource {
    /// The maps at the spec's env size, each with its name as the spec gives it (none for
    /// a procedural light).
    pub maps: Vec<(String, EnvMap)>,
    /// A procedural light ([`crate::envgen`]) generated per sample at the env size, its
    /// parameters drawn per sample.
    pub procedural: Option<crate::envgen::Kind>,
    /// How each sample turns, exposes and white-balances its map.
    pub augment: EnvAugment,
}

/// A `materials` item: where a sample's material comes from, and how it is perturbed.
#[derive(Clone, Debug)]
pub struct MaterialItem {
    /// The material.
    pub source: MaterialSource,
    /// Perturbations drawn per sample, if any.
    pub perturb: Option<Perturb>,
}

/// Where a sample's material comes from.
#[derive(Clone, Debug)]
pub enum MaterialSource {
    /// A fixed material: a preset or a file, with what the sample records of it.
    Fixed(Box<Material>, Value),
    /// A random convex combination of `mix` distinct fitted MERL presets, weights uniform
    /// on the simplex.
    RandomMerl {
        /// How many presets each draw mixes.
        mix: usize,
        /// The presets drawn from: indices into `presets::merl()`, ascending.
        from: Vec<usize>,
    },
}

/// One item of a source list with its weight.
#[derive(Clone, Debug)]
pub struct Weighted<T> {
    /// Relative chance of the item being picked.
    pub weight: f64,
    /// The item.
    pub source: T,
}

fn parse_hxw(s: &str) -> Option<(usize, usize)> {
    let (h, w) = s.split_once(['x', 'X'])?;
    Some((h.trim().parse().ok()?, w.trim().parse().ok()?))
}

/// A size given as an integer (square) or "HxW": (width, height).
pub(super) fn image_dims(v: &Value) -> std::result::Result<(usize, usize), String> {
    let (w, h) = match v {
        Value::Number(n) => {
            let n = n
                .as_u64()
                .ok_or_else(|| format!("{n} is not a whole number"))? as usize;
            (n, n)
        }
        Value::String(s) => {
            let (h, w) = parse_hxw(s).ok_or_else(|| format!("'{s}' is not N or \"HxW\""))?;
            (w, h)
        }
        other => return Err(format!("{other} is not N or \"HxW\"")),
    };
    if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        return Err(format!(
            "{h}x{w}: each side must be between 1 and {MAX_IMAGE_SIDE}"
        ));
    }
    Ok((w, h))
}

/// An item's weight: 1 unless given; a positive number.
pub(super) fn weight_of(w: Option<f64>) -> std::result::Result<f64, String> {
    match w {
        None => Ok(1.0),
        Some(w) if w.is_finite() && w > 0.0 => Ok(w),
        Some(w) => Err(format!("weight {w} must be a positive number")),
    }
}

/// Exactly one of `keys` is given: its index.
fn one_of(given: &[bool], keys: &[&str]) -> std::result::Result<usize, String> {
    let n = given.iter().filter(|&&g| g).count();
    match given.iter().position(|&g| g) {
        Some(i) if n == 1 => Ok(i),
        _ => Err(format!(
            "give exactly one of {}",
            keys.iter()
                .map(|k| format!("\"{k}\""))
                .collect::<Vec<_>>()
                .join(", ")
        )),
    }
}

/// A serde error without its position suffix, with `unknown field` made plain.
pub(super) fn serde_message(e: &serde_json::Error) -> String {
    let m = e.to_string();
    match m.rfind(" at line ") {
        Some(i) => m[..i].to_string(),
        None => m,
    }
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
pub(super) fn normals(
    items: &[Value],
    (w, h): (usize, usize),
    base: &Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<NormalsSource>>> {
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
                NormalsSource::Sphere(loader_stable(NormalMap::sphere(w)))
            }
            1 => {
                size_of("bumpy", r.bumpy.as_ref().unwrap_or(&Value::Null))?;
                NormalsSource::Bumpy
            }
            4 => {
                let spec = r.shape.as_deref().unwrap_or_default();
                let shape = spec.parse().map_err(|e| at(format!("shape: {e}")))?;
                NormalsSource::Shape(shape, views)
            }
            5 => {
                let exts = ["obj", "ply", "stl", "off", "gltf", "glb"];
                let files =
                    files_of(base, r.mesh, None, &exts).map_err(|m| at(format!("mesh: {m}")))?;
                let mut meshes = Vec::with_capacity(files.len());
                for f in files {
                    let m = crate::shapes::load_mesh(&f.path).map_err(|e| at(e.to_string()))?;
                    hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                    meshes.push((f.label, m));
                }
                NormalsSource::Meshes(meshes, views)
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
                NormalsSource::Files(maps)
            }
        };
        normals.push(Weighted { weight, source });
    }
    Ok(normals)
}

/// A `{"procedural": KIND}` item: an `envgen` kind, under the equirect convention.
fn procedural(
    name: Option<&str>,
    convention: Convention,
) -> std::result::Result<EnvSource, String> {
    let kind = name
        .unwrap_or_default()
        .parse()
        .map_err(|e| format!("procedural: {e}"))?;
    if convention != Convention::Equirect {
        return Err("procedural: lights are generated under the equirect convention".into());
    }
    Ok(EnvSource {
        maps: Vec::new(),
        procedural: Some(kind),
        augment: EnvAugment::default(),
    })
}

/// The spec's `envs` list, loaded (every map brought to `env_size`) and hashed; errors
/// name the item.
pub(super) fn envs(
    items: &[Value],
    env_size: (usize, usize),
    convention: Convention,
    base: &Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<EnvSource>>> {
    let mut envs = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let at = |m: String| err(format!("envs[{i}]: {m}"));
        let r = match item {
            Value::String(s) => RawEnv {
                procedural: None,
                file: Some(s.clone()),
                folder: None,
                rotate: None,
                exposure: None,
                white_balance: None,
                weight: None,
            },
            _ => serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?,
        };
        let kind = one_of(
            &[r.file.is_some(), r.folder.is_some(), r.procedural.is_some()],
            &["file", "folder", "procedural"],
        )
        .map_err(at)?;
        let weight = weight_of(r.weight).map_err(at)?;
        let augment = EnvAugment {
            // files turn unless told not to; procedural lights draw their own azimuths
            turn: r.rotate.unwrap_or(kind != 2),
            exposure: r.exposure,
            white_balance: r.white_balance,
        };
        augment.validate().map_err(at)?;
        if augment != EnvAugment::default() && convention != Convention::Equirect {
            return Err(at(
                "rotate, exposure and white_balance need the equirect convention (the 'paper' convention's columns span 180 degrees)".into(),
            ));
        }
        if kind == 2 {
            let mut source = procedural(r.procedural.as_deref(), convention).map_err(at)?;
            source.augment = augment;
            envs.push(Weighted { weight, source });
            continue;
        }
        let files = files_of(base, r.file, r.folder, &["exr", "npy"]).map_err(at)?;
        let mut maps = Vec::with_capacity(files.len());
        for f in files {
            let loaded = crate::io::load_env(&f.path, convention).map_err(|e| at(e.to_string()))?;
            let env = resample::fit(
                loaded.env,
                EnvSize::Size {
                    height: env_size.0,
                    width: env_size.1,
                },
                &f.path,
            )
            .map_err(|e| at(format!("env_size {}x{}: {e}", env_size.0, env_size.1)))?;
            hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
            maps.push((f.label, env));
        }
        envs.push(Weighted {
            weight,
            source: EnvSource {
                maps,
                procedural: None,
                augment,
            },
        });
    }
    Ok(envs)
}

/// The spec's `materials` list, loaded and hashed; errors name the item.
pub(super) fn materials(
    items: &[Value],
    base: &Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<MaterialItem>>> {
    let mut materials = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let at = |m: String| err(format!("materials[{i}]: {m}"));
        let r: RawMaterial =
            serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?;
        let kind = one_of(
            &[r.preset.is_some(), r.file.is_some(), r.random.is_some()],
            &["preset", "file", "random"],
        )
        .map_err(at)?;
        if (r.mix.is_some() || r.from.is_some() || r.except.is_some()) && kind != 2 {
            return Err(at(
                "\"mix\", \"from\" and \"except\" go with \"random\" only".into(),
            ));
        }
        let perturb = match &r.perturb {
            None | Some(Value::Bool(false)) => None,
            Some(Value::Bool(true)) => Some(Perturb::default()),
            Some(v) => {
                let p: Perturb = serde_json::from_value(v.clone())
                    .map_err(|e| at(format!("perturb: {}", serde_message(&e))))?;
                Some(p)
            }
        };
        if let Some(p) = &perturb {
            p.validate().map_err(|m| at(format!("perturb: {m}")))?;
        }
        let weight = weight_of(r.weight).map_err(at)?;
        let source = match kind {
            0 => {
                let name = r.preset.unwrap_or_default();
                let m = crate::presets::lookup(&name).ok_or_else(|| {
                    at(format!(
                        "unknown preset '{name}'; `matedit presets` lists them"
                    ))
                })?;
                MaterialSource::Fixed(Box::new(m), json!({ "preset": name }))
            }
            1 => {
                let label = r.file.unwrap_or_default();
                let files = files_of(base, Some(label.clone()), None, &["json"]).map_err(at)?;
                let [f] = &files[..] else {
                    return Err(at(format!("{label}: is a folder; give a material file")));
                };
                let m = crate::io::load_material(&f.path).map_err(|e| at(e.to_string()))?;
                hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                MaterialSource::Fixed(Box::new(m), json!({ "file": label }))
            }
            _ => {
                let what = r.random.unwrap_or_default();
                if what != "merl" {
                    return Err(at(format!(
                        "random: unknown source '{what}'; the one known is \"merl\" (the fitted MERL presets)"
                    )));
                }
                let from = merl_subset(r.from.as_deref(), r.except.as_deref()).map_err(at)?;
                let n = from.len();
                let mix = r.mix.unwrap_or(3.min(n));
                if mix == 0 || mix > MAX_MIX.min(n) {
                    return Err(at(format!(
                        "mix: {mix} must be between 1 and {}",
                        MAX_MIX.min(n)
                    )));
                }
                MaterialSource::RandomMerl { mix, from }
            }
        };
        materials.push(Weighted {
            weight,
            source: MaterialItem { source, perturb },
        });
    }
    Ok(materials)
}

#[cfg(test)]
mod tests {
    use super::merl_subset;

    #[test]
    fn merl_subsets() {
        let n = crate::presets::merl().len();
        let names = |ix: &[usize]| -> Vec<String> {
            ix.iter()
                .map(|&i| crate::presets::merl()[i].name.to_string())
                .collect()
        };
        assert_eq!(merl_subset(None, None).unwrap(), (0..n).collect::<Vec<_>>());
        assert_eq!(
            merl_subset(Some(&names(&[7, 2, 7])), None).unwrap(),
            vec![2, 7]
        );
        let rest = merl_subset(None, Some(&names(&[0, 5]))).unwrap();
        assert_eq!(rest.len(), n - 2);
        assert!(!rest.contains(&0) && !rest.contains(&5));
        let e = merl_subset(Some(&["gold-ish".to_string()]), None).unwrap_err();
        assert!(e.contains("'gold-ish' is not a fitted MERL preset"), "{e}");
        assert!(
            merl_subset(Some(&[]), None)
                .unwrap_err()
                .contains("no preset left")
        );
        assert!(
            merl_subset(Some(&[]), Some(&[]))
                .unwrap_err()
                .contains("not both")
        );
    }
}
