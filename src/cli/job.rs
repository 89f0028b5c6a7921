//! From options to a loaded batch: what the command line (and a manifest) say about the
//! scenes, the defaults that fill the gaps, and loading every input with checks.
//!
//! Defaults: a sphere of [`DEFAULT_SPHERE`] pixels, the procedural environment of
//! [`matedit::builtin_sky::procedural_env`], the preset [`matedit::presets::DEFAULT`], an
//! orthographic camera, env size 64x128 and the `equirect` convention.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use matedit::camera::Camera;
use matedit::envmap::{Convention, DEFAULT_ENV_SIZE, EnvMap};
use matedit::error::{Error, Result};
use matedit::io::manifest::Manifest;
use matedit::io::resample::{self, EnvSize};
use matedit::io::source::{MAX_IMAGE_SIDE, MaterialSource, NormalsSource};
use matedit::io::{load_env, load_material, load_normals, load_upstream};
use matedit::material::Material;
use matedit::scene::{Batch, Image, NormalMap, Scene};

/// Side of the default sphere image.
pub const DEFAULT_SPHERE: usize = 256;

/// Scene options as the command line gives them; `None` means "not given".
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneOptions {
    /// `--normals FILE` or `--sphere N`.
    pub normals: Option<NormalsSource>,
    /// `--env FILE`; the procedural environment if absent.
    pub env: Option<PathBuf>,
    /// `--env-size`.
    pub env_size: Option<EnvSize>,
    /// `--convention`.
    pub convention: Option<Convention>,
    /// `--material FILE` or `--preset NAME`.
    pub material: Option<MaterialSource>,
    /// `--fov DEG`: a perspective camera.
    pub fov: Option<f64>,
}

/// What every scene of a batch shares.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Size the environment maps are brought to.
    pub env_size: EnvSize,
    /// Texel convention.
    pub convention: Convention,
    /// Camera.
    pub camera: Camera,
}

/// One scene to load, with where its result goes.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneSpec {
    /// Normals.
    pub normals: NormalsSource,
    /// Environment map file, or `None` for the procedural one.
    pub env: Option<PathBuf>,
    /// Material.
    pub material: MaterialSource,
    /// Output file (`render`) or folder (`grad`).
    pub output: PathBuf,
    /// Upstream gradient file (`grad` only).
    pub upstream: Option<PathBuf>,
}

/// A whole run: shared settings and the scenes.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Shared settings.
    pub settings: Settings,
    /// The scenes, in batch order.
    pub scenes: Vec<SceneSpec>,
}

/// A loaded batch, with remarks for the user (e.g. how many negative texels were clamped).
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    /// The batch, ready to render.
    pub batch: Batch,
    /// One line each, for stderr.
    pub notes: Vec<String>,
}

fn settings(opts: &SceneOptions, manifest: Option<&Manifest>) -> Settings {
    let env_size = manifest
        .and_then(|m| m.env_size)
        .or(opts.env_size)
        .unwrap_or_default();
    let convention = manifest
        .and_then(|m| m.convention)
        .or(opts.convention)
        .unwrap_or_default();
    let camera = match manifest.and_then(|m| m.fov).or(opts.fov) {
        Some(fov_y_deg) => Camera::Perspective { fov_y_deg },
        None => Camera::Orthographic,
    };
    Settings {
        env_size,
        convention,
        camera,
    }
}

impl Plan {
    /// One scene from the command-line options.
    pub fn single(opts: &SceneOptions, output: PathBuf, upstream: Option<PathBuf>) -> Plan {
        Plan {
            settings: settings(opts, None),
            scenes: vec![SceneSpec {
                normals: opts
                    .normals
                    .clone()
                    .unwrap_or(NormalsSource::Sphere(DEFAULT_SPHERE)),
                env: opts.env.clone(),
                material: opts
                    .material
                    .clone()
                    .unwrap_or_else(|| MaterialSource::Preset(matedit::presets::DEFAULT.into())),
                output,
                upstream,
            }],
        }
    }

    /// The scenes of a manifest; what it leaves out comes from `opts` (and `upstream`, the
    /// command line's `--upstream`), then the defaults.
    pub fn from_manifest(
        opts: &SceneOptions,
        manifest: &Manifest,
        upstream: Option<&Path>,
    ) -> Plan {
        let base = Plan::single(opts, PathBuf::new(), upstream.map(Path::to_path_buf));
        let default = &base.scenes[0];
        Plan {
            settings: settings(opts, Some(manifest)),
            scenes: manifest
                .scenes
                .iter()
                .map(|s| SceneSpec {
                    normals: s.normals.clone().unwrap_or_else(|| default.normals.clone()),
                    env: s.env.clone().or_else(|| default.env.clone()),
                    material: s
                        .material
                        .clone()
                        .unwrap_or_else(|| default.material.clone()),
                    output: s.output.clone(),
                    upstream: s.upstream.clone().or_else(|| default.upstream.clone()),
                })
                .collect(),
        }
    }

    /// Every scene's output file (`render`) or folder (`grad`), in batch order.
    pub fn outputs(&self) -> Vec<PathBuf> {
        self.scenes.iter().map(|s| s.output.clone()).collect()
    }

    /// Loads and checks every input and builds the batch. Files shared by several scenes
    /// are read once.
    pub fn load(&self) -> Result<Loaded> {
        let s = self.settings;
        s.camera.validate()?;
        let mut notes = Vec::new();
        let mut envs: HashMap<Option<PathBuf>, EnvMap> = HashMap::new();
        let mut normals: HashMap<PathBuf, NormalMap> = HashMap::new();
        let mut materials: HashMap<PathBuf, Material> = HashMap::new();
        let mut scenes = Vec::with_capacity(self.scenes.len());
        for spec in &self.scenes {
            let env = match envs.get(&spec.env) {
                Some(e) => e.clone(),
                None => {
                    let e = load_env_sized(spec.env.as_deref(), s, &mut notes)?;
                    envs.insert(spec.env.clone(), e.clone());
                    e
                }
            };
            let n = match &spec.normals {
                NormalsSource::Sphere(n) => {
                    if *n == 0 || *n > MAX_IMAGE_SIDE {
                        return Err(Error::Invalid(format!(
                            "sphere size {n} must be between 1 and {MAX_IMAGE_SIDE}"
                        )));
                    }
                    NormalMap::sphere(*n)
                }
                NormalsSource::File(p) => match normals.get(p) {
                    Some(n) => n.clone(),
                    None => {
                        let n = load_normals(p)?;
                        normals.insert(p.clone(), n.clone());
                        n
                    }
                },
            };
            let material = match &spec.material {
                MaterialSource::Preset(name) => {
                    matedit::presets::lookup(name).ok_or_else(|| {
                        Error::Invalid(format!(
                            "unknown preset '{name}'; the presets are {}",
                            matedit::presets::names().join(", ")
                        ))
                    })?
                }
                MaterialSource::File(p) => match materials.get(p) {
                    Some(m) => m.clone(),
                    None => {
                        let m = load_material(p)?;
                        materials.insert(p.clone(), m.clone());
                        m
                    }
                },
            };
            scenes.push(Scene {
                normals: n,
                env,
                material,
                camera: s.camera,
            });
        }
        Ok(Loaded {
            batch: Batch::new(scenes)?,
            notes,
        })
    }

    /// Loads the upstream gradient of every scene and checks it against the batch's image
    /// size (for `grad`).
    pub fn load_upstream(&self, batch: &Batch) -> Result<Vec<Image>> {
        let (w, h) = batch.image_size();
        self.scenes
            .iter()
            .enumerate()
            .map(|(b, spec)| {
                let Some(path) = &spec.upstream else {
                    return Err(Error::Invalid(if self.scenes.len() > 1 {
                        format!("scene {b} has no upstream gradient: give 'upstream' in the manifest or --upstream")
                    } else {
                        "no upstream gradient: give --upstream FILE".into()
                    }));
                };
                let g = load_upstream(path)?;
                if (g.width, g.height) != (w, h) {
                    return Err(Error::file(
                        path,
                        format!(
                            "is {}x{} (width x height) but the render is {w}x{h}; the upstream \
                             gradient must match the normal map's size",
                            g.width, g.height
                        ),
                    ));
                }
                Ok(g)
            })
            .collect()
    }
}

impl Plan {
    /// Per scene of [`Plan::load`]'s batch (whose maps it is given), a finer map of the
    /// same light for the continuous light (`matedit::continuous_light`): the procedural
    /// environment generated at `factor` times the rows and columns; a file brought to the
    /// largest power-of-two multiple of its scene's map, up to `factor`, that its own size
    /// allows (none when it is no larger). Files shared by several scenes are read once.
    pub fn details(&self, batch: &Batch, factor: usize) -> Result<Vec<Option<EnvMap>>> {
        let s = self.settings;
        let mut done: HashMap<Option<PathBuf>, Option<EnvMap>> = HashMap::new();
        let mut out = Vec::with_capacity(self.scenes.len());
        for (spec, scene) in self.scenes.iter().zip(batch.scenes()) {
            if let Some(d) = done.get(&spec.env) {
                out.push(d.clone());
                continue;
            }
            let (h, w) = (scene.env.height, scene.env.width);
            let detail = match &spec.env {
                None => Some(matedit::builtin_sky::procedural_env(
                    h * factor,
                    w * factor,
                    s.convention,
                )),
                Some(p) => {
                    let full = load_env(p, s.convention)?.env;
                    let mut f = factor;
                    while f >= 2 && !(full.height % (h * f) == 0 && full.width % (w * f) == 0) {
                        f /= 2;
                    }
                    (f >= 2)
                        .then(|| resample::downsample(&full, h * f, w * f))
                        .transpose()
                        .map_err(|m| Error::file(p, m))?
                }
            };
            done.insert(spec.env.clone(), detail.clone());
            out.push(detail);
        }
        Ok(out)
    }
}

/// Loads (or generates) an environment map at the plan's size and convention.
fn load_env_sized(path: Option<&Path>, s: Settings, notes: &mut Vec<String>) -> Result<EnvMap> {
    match path {
        None => {
            let (height, width) = match s.env_size {
                EnvSize::Full => DEFAULT_ENV_SIZE,
                EnvSize::Size { height, width } => (height, width),
            };
            Ok(matedit::builtin_sky::procedural_env(
                height,
                width,
                s.convention,
            ))
        }
        Some(p) => {
            let loaded = load_env(p, s.convention)?;
            if loaded.clamped > 0 {
                notes.push(format!(
                    "{}: clamped {} negative values to 0",
                    p.display(),
                    loaded.clamped
                ));
            }
            resample::fit(loaded.env, s.env_size, p)
        }
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use matedit::io::manifest;

    use super::{Plan, SceneOptions};

    /// A manifest's scenes become the plan's, one for one: a scene that gives everything
    /// and one that gives little.
    #[test]
    fn a_plan_has_the_manifests_scenes() {
        let path = Path::new("in/batch.json");
        let bytes = br#"{"convention": "paper", "env_size": "8x16", "fov": 40, "scenes": [
            {"output": "a.png", "preset": "red-specular-plastic", "sphere": 16},
            {"env": "sky.exr", "material": "m.json", "normals": "n.npy", "output": "b.exr",
             "upstream": "up.npy"}]}"#;
        let m = manifest::parse(path, bytes, None).unwrap();
        let plan = Plan::from_manifest(&SceneOptions::default(), &m, None);
        assert_eq!(plan.scenes.len(), m.scenes.len());
    }
}
