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
use serde_json::{Value, json};
use sha2::{Digest, Sha256};

use crate::camera::Camera;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::io::resample::{self, EnvSize};
use crate::io::source::MAX_IMAGE_SIDE;
use crate::material::{Material, N_PARAMS};
use crate::scene::{NormalMap, Scene};
pub use crate::splitmix::SplitMix;

/// Samples per chunk when the spec does not say (or `count`, if smaller).
pub const DEFAULT_CHUNK_SIZE: usize = 64;

/// Most presets a `{"random": "merl"}` draw mixes.
pub const MAX_MIX: usize = 16;

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
    fov: Option<f64>,
    convention: Option<String>,
    normals: Vec<Value>,
    envs: Vec<Value>,
    materials: Vec<Value>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawNormals {
    sphere: Option<Value>,
    bumpy: Option<Value>,
    file: Option<String>,
    folder: Option<String>,
    weight: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEnv {
    file: Option<String>,
    folder: Option<String>,
    rotate: Option<bool>,
    weight: Option<f64>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMaterial {
    preset: Option<String>,
    file: Option<String>,
    random: Option<String>,
    mix: Option<usize>,
    weight: Option<f64>,
}

/// Where a sample's normals come from.
#[derive(Clone, Debug)]
pub enum NormalsSource {
    /// The unit sphere at the image size.
    Sphere(NormalMap),
    /// [`NormalMap::bumpy`] at the image size, its seed drawn per sample.
    Bumpy,
    /// Normal-map files (one, or a folder's), each with its name as the spec gives it.
    Files(Vec<(String, NormalMap)>),
}

/// Where a sample's lighting comes from.
#[derive(Clone, Debug)]
pub struct EnvSource {
    /// The maps at the spec's env size, each with its name as the spec gives it.
    pub maps: Vec<(String, EnvMap)>,
    /// Whether each sample turns its map about the vertical axis by a random whole number
    /// of columns.
    pub rotate: bool,
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
    pub normals: Vec<Weighted<NormalsSource>>,
    /// Lighting sources.
    pub envs: Vec<Weighted<EnvSource>>,
    /// Material sources.
    pub materials: Vec<Weighted<MaterialSource>>,
    /// SHA-256 of the spec's content and of every input file, hex.
    pub digest: String,
}

/// A sample's inputs and the parameters that made it.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Its index in the dataset.
    pub index: u64,
    /// What is rendered.
    pub scene: Scene,
    /// The draws: sources, rotation, mixing weights, seed and index (JSON).
    pub params: Value,
}

impl SplitMix {
    /// The generator of sample `k` under `seed`: independent of every other sample's.
    pub fn for_sample(seed: u64, k: u64) -> Self {
        let a = SplitMix(seed).next_u64();
        let b = SplitMix(k ^ 0x5851_f42d_4c95_7f2d).next_u64();
        SplitMix(a ^ b.rotate_left(17))
    }
}

fn parse_hxw(s: &str) -> Option<(usize, usize)> {
    let (h, w) = s.split_once(['x', 'X'])?;
    Some((h.trim().parse().ok()?, w.trim().parse().ok()?))
}

/// A size given as an integer (square) or "HxW": (width, height).
fn image_dims(v: &Value) -> std::result::Result<(usize, usize), String> {
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

fn weight(w: Option<f64>) -> std::result::Result<f64, String> {
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
fn serde_message(e: &serde_json::Error) -> String {
    let m = e.to_string();
    match m.rfind(" at line ") {
        Some(i) => m[..i].to_string(),
        None => m,
    }
}

/// The files of `folder` with one of `exts` (lower case), sorted by name.
fn list_folder(folder: &Path, exts: &[&str]) -> std::result::Result<Vec<String>, String> {
    let entries = std::fs::read_dir(folder).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => format!("{}: no such folder", folder.display()),
        _ => format!("{}: cannot list the folder: {e}", folder.display()),
    })?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| format!("{}: cannot list: {e}", folder.display()))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let ext = Path::new(name)
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if name.starts_with('.') || !ext.is_some_and(|e| exts.contains(&e.as_str())) {
            continue;
        }
        if entry.path().is_file() {
            names.push(name.to_string());
        }
    }
    names.sort();
    if names.is_empty() {
        return Err(format!(
            "{}: the folder has no .{} files",
            folder.display(),
            exts.join(" or .")
        ));
    }
    Ok(names)
}

/// A path as the spec gives it (labels) and as it resolves.
struct Named {
    label: String,
    path: PathBuf,
}

/// The files an item names: `file` alone, or every matching file of `folder`.
fn files_of(
    base: &Path,
    file: Option<String>,
    folder: Option<String>,
    exts: &[&str],
) -> std::result::Result<Vec<Named>, String> {
    let resolve = |p: &str| {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    };
    match (file, folder) {
        (Some(f), None) => {
            let path = resolve(&f);
            if path.is_dir() {
                let names = list_folder(&path, exts)?;
                let label = f.trim_end_matches('/').to_string();
                return Ok(names
                    .into_iter()
                    .map(|n| Named {
                        label: format!("{label}/{n}"),
                        path: path.join(&n),
                    })
                    .collect());
            }
            if !path.exists() {
                return Err(format!("{}: no such file", path.display()));
            }
            Ok(vec![Named { label: f, path }])
        }
        (None, Some(d)) => {
            let path = resolve(&d);
            if path.exists() && !path.is_dir() {
                return Err(format!("{}: is a file, not a folder", path.display()));
            }
            let label = d.trim_end_matches('/').to_string();
            Ok(list_folder(&path, exts)?
                .into_iter()
                .map(|n| Named {
                    label: format!("{label}/{n}"),
                    path: path.join(&n),
                })
                .collect())
        }
        _ => Err("give \"file\" or \"folder\"".into()),
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
            *n = crate::scene::loader_stable_unit(v);
        }
    }
    m
}

fn hash_file(hasher: &mut Sha256, label: &str, path: &Path) -> Result<()> {
    let bytes = crate::io::read_bytes(path)?;
    hasher.update(label.as_bytes());
    hasher.update([0]);
    hasher.update(Sha256::digest(&bytes));
    Ok(())
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
        let camera = match raw.fov {
            None => Camera::Orthographic,
            Some(fov_y_deg) => {
                let c = Camera::Perspective { fov_y_deg };
                c.validate().map_err(|e| err(format!("fov: {e}")))?;
                c
            }
        };
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

        let (w, h) = image_size;
        let mut normals = Vec::new();
        for (i, item) in raw.normals.iter().enumerate() {
            let at = |m: String| err(format!("normals[{i}]: {m}"));
            let r = match item {
                Value::String(s) => RawNormals {
                    sphere: None,
                    bumpy: None,
                    file: Some(s.clone()),
                    folder: None,
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
                ],
                &["sphere", "bumpy", "file", "folder"],
            )
            .map_err(at)?;
            let weight = weight(r.weight).map_err(at)?;
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
                _ => {
                    let files =
                        files_of(&base, r.file, r.folder, &["exr", "npy", "png"]).map_err(at)?;
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
                        hash_file(&mut hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                        maps.push((f.label, loader_stable(m)));
                    }
                    NormalsSource::Files(maps)
                }
            };
            normals.push(Weighted { weight, source });
        }

        let mut envs = Vec::new();
        for (i, item) in raw.envs.iter().enumerate() {
            let at = |m: String| err(format!("envs[{i}]: {m}"));
            let r = match item {
                Value::String(s) => RawEnv {
                    file: Some(s.clone()),
                    folder: None,
                    rotate: None,
                    weight: None,
                },
                _ => serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?,
            };
            one_of(&[r.file.is_some(), r.folder.is_some()], &["file", "folder"]).map_err(at)?;
            let weight = weight(r.weight).map_err(at)?;
            let files = files_of(&base, r.file, r.folder, &["exr", "npy"]).map_err(at)?;
            let mut maps = Vec::with_capacity(files.len());
            for f in files {
                let loaded =
                    crate::io::load_env(&f.path, convention).map_err(|e| at(e.to_string()))?;
                let env = resample::fit(
                    loaded.env,
                    EnvSize::Size {
                        height: env_size.0,
                        width: env_size.1,
                    },
                    &f.path,
                )
                .map_err(|e| at(format!("env_size {}x{}: {e}", env_size.0, env_size.1)))?;
                hash_file(&mut hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                maps.push((f.label, env));
            }
            envs.push(Weighted {
                weight,
                source: EnvSource {
                    maps,
                    rotate: r.rotate.unwrap_or(true),
                },
            });
        }

        let mut materials = Vec::new();
        for (i, item) in raw.materials.iter().enumerate() {
            let at = |m: String| err(format!("materials[{i}]: {m}"));
            let r: RawMaterial =
                serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?;
            let kind = one_of(
                &[r.preset.is_some(), r.file.is_some(), r.random.is_some()],
                &["preset", "file", "random"],
            )
            .map_err(at)?;
            if r.mix.is_some() && kind != 2 {
                return Err(at("\"mix\" goes with \"random\" only".into()));
            }
            let weight = weight(r.weight).map_err(at)?;
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
                    let files =
                        files_of(&base, Some(label.clone()), None, &["json"]).map_err(at)?;
                    let [f] = &files[..] else {
                        return Err(at(format!("{label}: is a folder; give a material file")));
                    };
                    let m = crate::io::load_material(&f.path).map_err(|e| at(e.to_string()))?;
                    hash_file(&mut hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                    MaterialSource::Fixed(Box::new(m), json!({ "file": label }))
                }
                _ => {
                    let what = r.random.unwrap_or_default();
                    if what != "merl" {
                        return Err(at(format!(
                            "random: unknown source '{what}'; the one known is \"merl\" (the fitted MERL presets)"
                        )));
                    }
                    let n = crate::presets::merl().len();
                    let mix = r.mix.unwrap_or(3);
                    if mix == 0 || mix > MAX_MIX.min(n) {
                        return Err(at(format!(
                            "mix: {mix} must be between 1 and {}",
                            MAX_MIX.min(n)
                        )));
                    }
                    MaterialSource::RandomMerl { mix }
                }
            };
            materials.push(Weighted { weight, source });
        }

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
            digest: hex(&hasher.finalize()),
        })
    }

    /// Chunks in the dataset.
    pub fn chunks(&self) -> u64 {
        self.count / self.chunk_size
    }

    /// Sample `k`'s scene and the parameters that made it: a pure function of the spec,
    /// its seed and `k`.
    pub fn sample(&self, k: u64) -> Result<Sample> {
        if k >= self.count {
            return Err(Error::Invalid(format!(
                "sample {k}: the spec has {} samples",
                self.count
            )));
        }
        let mut rng = SplitMix::for_sample(self.seed, k);
        let (w, h) = self.image_size;

        let ni = pick(&mut rng, &self.normals);
        let (normals, nparams) = match &self.normals[ni].source {
            NormalsSource::Sphere(m) => (m.clone(), json!({ "sphere": w })),
            NormalsSource::Bumpy => {
                let seed = rng.next_u64();
                (
                    NormalMap::bumpy(w, h, seed),
                    json!({ "bumpy": [h, w], "bumpy_seed": seed }),
                )
            }
            NormalsSource::Files(maps) => {
                let (label, m) = &maps[rng.below(maps.len())];
                (m.clone(), json!({ "file": label }))
            }
        };

        let ei = pick(&mut rng, &self.envs);
        let src = &self.envs[ei].source;
        let (label, map) = &src.maps[rng.below(src.maps.len())];
        let shift = if src.rotate { rng.below(map.width) } else { 0 };
        let env = rotate(map, shift);
        let eparams = json!({
            "file": label,
            "rotate_columns": shift,
            "rotate_degrees": shift as f64 * 360.0 / map.width as f64,
        });

        let mi = pick(&mut rng, &self.materials);
        let (material, mparams) = match &self.materials[mi].source {
            MaterialSource::Fixed(m, p) => (Material::clone(m), p.clone()),
            MaterialSource::RandomMerl { mix } => random_merl(&mut rng, *mix)?,
        };

        let params = json!({
            "index": k,
            "seed": self.seed,
            "normals": nparams,
            "normals_item": ni,
            "env": eparams,
            "env_item": ei,
            "material": mparams,
            "material_item": mi,
            "image_size": [h, w],
            "env_size": [self.env_size.0, self.env_size.1],
            "convention": self.convention.name(),
            "fov": match self.camera {
                Camera::Perspective { fov_y_deg } => json!(fov_y_deg),
                Camera::Orthographic => Value::Null,
            },
        });
        Ok(Sample {
            index: k,
            scene: Scene {
                normals,
                env,
                material,
                camera: self.camera,
            },
            params,
        })
    }
}

/// An item by weight.
fn pick<T>(rng: &mut SplitMix, items: &[Weighted<T>]) -> usize {
    if items.len() == 1 {
        return 0;
    }
    let total: f64 = items.iter().map(|i| i.weight).sum();
    let mut u = rng.uniform() * total;
    for (i, item) in items.iter().enumerate() {
        if u < item.weight {
            return i;
        }
        u -= item.weight;
    }
    items.len() - 1
}

/// The map turned about the vertical axis: column c is the source's column (c + shift)
/// mod width, exactly.
pub fn rotate(env: &EnvMap, shift: usize) -> EnvMap {
    let (h, w) = (env.height, env.width);
    let mut texels = Vec::with_capacity(h * w);
    for r in 0..h {
        let row = &env.texels[r * w..(r + 1) * w];
        texels.extend_from_slice(&row[shift % w..]);
        texels.extend_from_slice(&row[..shift % w]);
    }
    EnvMap {
        height: h,
        width: w,
        convention: env.convention,
        texels,
    }
}

/// `mix` distinct fitted MERL presets with weights uniform on the simplex (the gaps
/// between sorted uniforms: arithmetic only, the same bits on every machine), mixed
/// control point by control point.
fn random_merl(rng: &mut SplitMix, mix: usize) -> Result<(Material, Value)> {
    let merl = crate::presets::merl();
    let mut order: Vec<usize> = (0..merl.len()).collect();
    for i in 0..mix {
        let j = i + rng.below(order.len() - i);
        order.swap(i, j);
    }
    let mut cuts: Vec<f64> = (0..mix - 1).map(|_| rng.uniform()).collect();
    cuts.sort_by(f64::total_cmp);
    let mut weights = Vec::with_capacity(mix);
    let mut prev = 0.0;
    for &c in &cuts {
        weights.push(c - prev);
        prev = c;
    }
    weights.push(1.0 - prev);
    let mut ctrl = [0.0f64; N_PARAMS];
    let mut parts = Vec::with_capacity(mix);
    for (&i, &wt) in order[..mix].iter().zip(&weights) {
        let m = merl[i].material();
        for (c, v) in ctrl.iter_mut().zip(m.ctrl) {
            *c += wt * v;
        }
        parts.push(json!({ "preset": merl[i].name, "weight": wt }));
    }
    let material = Material::new("merl-mix", &ctrl)
        .map_err(|e| Error::Invalid(format!("random merl material: {e}")))?;
    Ok((material, json!({ "random": "merl", "mix": parts })))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rotation_is_a_column_shift() {
        let texels: Vec<[f32; 3]> = (0..2 * 4).map(|i| [i as f32; 3]).collect();
        let env = EnvMap::new(2, 4, Convention::Equirect, texels).unwrap();
        let r = rotate(&env, 1);
        let col0: Vec<f32> = r.texels.iter().map(|t| t[0]).collect();
        assert_eq!(col0, [1.0, 2.0, 3.0, 0.0, 5.0, 6.0, 7.0, 4.0]);
        assert_eq!(rotate(&env, 0), env);
    }

    #[test]
    fn draws_are_per_sample() {
        let a: Vec<u64> = (0..4)
            .map(|k| SplitMix::for_sample(7, k).next_u64())
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|k| SplitMix::for_sample(7, k).next_u64())
            .collect();
        assert_eq!(a, b);
        assert_ne!(a[0], a[1]);
        assert_ne!(
            SplitMix::for_sample(7, 0).next_u64(),
            SplitMix::for_sample(8, 0).next_u64()
        );
        let mut r = SplitMix(1);
        assert!((0..1000).all(|_| r.below(5) < 5));
    }

    #[test]
    fn merl_mixes_are_valid() {
        let mut rng = SplitMix(3);
        for mix in [1, 2, 3, 8] {
            let (m, p) = random_merl(&mut rng, mix).unwrap();
            m.validate().unwrap();
            let parts = p["mix"].as_array().unwrap();
            assert_eq!(parts.len(), mix);
            let sum: f64 = parts.iter().map(|x| x["weight"].as_f64().unwrap()).sum();
            assert!((sum - 1.0).abs() < 1e-12);
        }
    }
}
