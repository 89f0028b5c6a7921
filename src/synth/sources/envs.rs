//! The spec's `envs` list: environment-map files brought to the spec's env size, and
//! procedural lights, each with how a sample turns, exposes and white-balances it.

use std::path::Path;

use serde::Deserialize;
use serde_json::Value;
use sha2::Sha256;

use super::{Weighted, one_of, serde_message, weight_of};
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::io::resample::{self, EnvSize};
use crate::synth::augment::EnvAugment;
use crate::synth::files::{files_of, hash_file};

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

/// Where a sample's lighting comes from.
#[derive(Clone, Debug)]
pub struct EnvSource {
    /// The maps at the spec's env size, each with its name as the spec gives it (none for
    /// a procedural light).
    pub maps: Vec<(String, EnvMap)>,
    /// A procedural light ([`crate::envgen`]) generated per sample at the env size, its
    /// parameters drawn per sample.
    pub procedural: Option<crate::envgen::LightKind>,
    /// How each sample turns, exposes and white-balances its map.
    pub augment: EnvAugment,
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
pub(in crate::synth) fn envs(
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
