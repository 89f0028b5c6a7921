//! The draws that several of a sample's parts share: an item of a source list by weight,
//! a material from a `materials` list (a preset, a file or a random MERL mix, perturbed if
//! the item says so), and merging records.

use serde_json::{Value, json};

use super::sources::{MaterialItem, SampleMaterial, Weighted};
use crate::error::{Error, Result};
use crate::material::{Material, N_PARAMS};
use crate::spline::N_CTRL_POINTS;
use crate::splitmix::SplitMix;

/// A material drawn from `items`: the item's index, the material (perturbed if the item
/// says so) and what the sample records of it.
pub(super) fn draw_material(
    rng: &mut SplitMix,
    items: &[Weighted<MaterialItem>],
) -> Result<(usize, Material, Value)> {
    let mi = pick(rng, items);
    let item = &items[mi].source;
    let (material, mut mparams) = match &item.source {
        SampleMaterial::Fixed(m, p) => (Material::clone(m), p.clone()),
        SampleMaterial::RandomMerl { mix, from } => random_merl(rng, *mix, from)?,
    };
    let material = match &item.perturb {
        None => material,
        Some(p) => {
            let (m, record) = super::perturb::apply(&material, &p.draw(rng))?;
            merge(&mut mparams, json!({ "perturb": record }));
            m
        }
    };
    Ok((mi, material, mparams))
}

/// Adds `extra`'s keys to the object `into`.
pub(super) fn merge(into: &mut Value, extra: Value) {
    if let (Some(o), Value::Object(e)) = (into.as_object_mut(), extra) {
        o.extend(e);
    }
}

/// An item by weight.
pub(super) fn pick<T>(rng: &mut SplitMix, items: &[Weighted<T>]) -> usize {
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

/// `mix` distinct fitted MERL presets of `from` (indices into `presets::merl()`) with
/// weights uniform on the simplex (the gaps between sorted uniforms: arithmetic only, the
/// same bits on every machine), mixed control point by control point.
fn random_merl(rng: &mut SplitMix, mix: usize, from: &[usize]) -> Result<(Material, Value)> {
    let merl = crate::presets::merl();
    let mut order: Vec<usize> = from.to_vec();
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
    // a convex combination stays within the presets' ranges, up to rounding (an exponent
    // of 1e4 mixed came to 10000.000000000002): clamp to the valid ranges
    for (i, c) in ctrl.iter_mut().enumerate() {
        *c = if (i / N_CTRL_POINTS) % 2 == 1 {
            c.clamp(0.0, crate::material::MAX_EXPONENT)
        } else {
            c.clamp(
                -crate::material::MAX_ABS_SCALE,
                crate::material::MAX_ABS_SCALE,
            )
        };
    }
    let material = Material::new("merl-mix", &ctrl)
        .map_err(|e| Error::Invalid(format!("random merl material: {e}")))?;
    Ok((material, json!({ "random": "merl", "mix": parts })))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn merl_mixes_are_valid() {
        // many draws: mixing presets whose exponents reach 1e4 once rounded past it
        let mut rng = SplitMix(3);
        let all: Vec<usize> = (0..crate::presets::merl().len()).collect();
        for draw in 0..3000 {
            let mix = [1, 2, 3, 8, 16][draw % 5];
            let (m, p) = random_merl(&mut rng, mix, &all).unwrap();
            m.validate().unwrap();
            let parts = p["mix"].as_array().unwrap();
            assert_eq!(parts.len(), mix);
            let sum: f64 = parts.iter().map(|x| x["weight"].as_f64().unwrap()).sum();
            assert!((sum - 1.0).abs() < 1e-12);
        }
        // two generator states whose mixes of three rounded an exponent of 1e4 past 1e4
        for (seed, k) in [(1, 151), (3, 38)] {
            let mut rng = SplitMix::for_sample(seed, k);
            let _ = (rng.uniform(), rng.next_u64(), rng.next_u64());
            let _ = (rng.uniform(), rng.next_u64());
            random_merl(&mut rng, 3, &all)
                .unwrap()
                .0
                .validate()
                .unwrap();
        }
    }

    #[test]
    fn merl_mixes_draw_from_their_subset() {
        let merl = crate::presets::merl();
        let from = [4, 17, 60];
        let mut rng = SplitMix(9);
        for _ in 0..200 {
            let (_, p) = random_merl(&mut rng, 2, &from).unwrap();
            for part in p["mix"].as_array().unwrap() {
                let name = part["preset"].as_str().unwrap();
                assert!(from.iter().any(|&i| merl[i].name == name), "{name}");
            }
        }
    }
}
