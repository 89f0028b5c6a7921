//! The spec's `materials` list: presets, material files and random mixes of the fitted
//! MERL presets, each with the perturbations a sample draws.

use std::path::Path;

use serde::Deserialize;
use serde_json::{Value, json};
use sha2::Sha256;

use super::{Weighted, one_of, serde_message, weight_of};
use crate::error::{Error, Result};
use crate::material::Material;
use crate::synth::files::{files_of, hash_file};
use crate::synth::perturb::Perturb;

/// Most presets a `{"random": "merl"}` draw mixes.
pub const MAX_MIX: usize = 16;

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

/// A `materials` item: where a sample's material comes from, and how it is perturbed.
#[derive(Clone, Debug)]
pub struct MaterialItem {
    /// The material.
    pub source: SampleMaterial,
    /// Perturbations drawn per sample, if any.
    pub perturb: Option<Perturb>,
}

/// Where a sample's material comes from, loaded (a scene's, as the command line and a
/// manifest name it, is an [`crate::io::source::MaterialSource`]).
#[derive(Clone, Debug)]
pub enum SampleMaterial {
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

/// The spec's `materials` list, loaded and hashed; errors name the item.
pub(in crate::synth) fn materials(
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
                SampleMaterial::Fixed(Box::new(m), json!({ "preset": name }))
            }
            1 => {
                let label = r.file.unwrap_or_default();
                let files = files_of(base, Some(label.clone()), None, &["json"]).map_err(at)?;
                let [f] = &files[..] else {
                    return Err(at(format!("{label}: is a folder; give a material file")));
                };
                let m = crate::io::load_material(&f.path).map_err(|e| at(e.to_string()))?;
                hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                SampleMaterial::Fixed(Box::new(m), json!({ "file": label }))
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
                SampleMaterial::RandomMerl { mix, from }
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
