//! The spec's source lists (`normals`, `envs`, `materials`): each item parsed, checked,
//! loaded in full and hashed into the spec's digest; one file per list, and here the
//! helpers they share (sizes, weights, one key of several, serde messages).

mod envs;
mod materials;
mod normals;

use serde_json::Value;

use crate::io::source::MAX_IMAGE_SIDE;

pub use envs::EnvSource;
pub(super) use envs::envs;
pub(super) use materials::materials;
pub use materials::{MAX_MIX, MaterialItem, SampleMaterial};
pub use normals::SampleNormals;
pub(super) use normals::normals;

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
pub(in crate::synth) fn image_dims(v: &Value) -> std::result::Result<(usize, usize), String> {
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
pub(in crate::synth) fn weight_of(w: Option<f64>) -> std::result::Result<f64, String> {
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
pub(in crate::synth) fn serde_message(e: &serde_json::Error) -> String {
    let m = e.to_string();
    match m.rfind(" at line ") {
        Some(i) => m[..i].to_string(),
        None => m,
    }
}
