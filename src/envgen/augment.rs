//! Augmentations of any `equirect` map, real or procedural: a turn about the vertical axis
//! by any angle, an exposure change and a white balance.

use crate::envmap::{Convention, EnvMap, MAX_RADIANCE};
use crate::error::{Result, invalid};

use super::colour::{TEMPERATURE_RANGE, luminance, temperature_rgb};

/// The map turned about the vertical (y) axis by `degrees`: what was at azimuth phi is
/// at phi + degrees (phi as in the equirect convention, from +x towards +z). Each row is
/// resampled along phi with linear interpolation, periodically, so every column of the
/// source gives away exactly its radiance: the power (sum of L d_omega) is kept, and a
/// turn by a whole number k of columns (k 360 / W degrees) is a roll of the columns by k.
pub fn turn(env: &EnvMap, degrees: f64) -> Result<EnvMap> {
    if env.convention != Convention::Equirect {
        return Err(invalid!(
            "env: a turn needs an 'equirect' map (the 'paper' convention's columns span 180 degrees)"
        ));
    }
    if !degrees.is_finite() {
        return Err(invalid!("turn: {degrees} degrees is not a finite angle"));
    }
    let w = env.width;
    // the shift in columns, split into a whole part and a fraction in [0, 1)
    let shift = (degrees / 360.0).rem_euclid(1.0) * w as f64;
    let whole = shift.floor();
    let frac = shift - whole;
    let k = whole as usize % w;
    // output column c takes (1 - frac) of source column c - k and frac of c - k - 1
    let (a, b) = ((1.0 - frac) as f32, frac as f32);
    let mut texels = Vec::with_capacity(env.texels.len());
    for row in env.texels.chunks_exact(w) {
        for c in 0..w {
            let i0 = (c + w - k) % w;
            let i1 = (i0 + w - 1) % w;
            let (p, q) = (row[i0], row[i1]);
            texels.push([0, 1, 2].map(|ch| {
                if b == 0.0 {
                    p[ch]
                } else {
                    a * p[ch] + b * q[ch]
                }
            }));
        }
    }
    EnvMap::new(env.height, w, env.convention, texels)
}

/// The map times 2^`stops`.
pub fn exposure(env: &EnvMap, stops: f64) -> Result<EnvMap> {
    if !stops.is_finite() || stops.abs() > 60.0 {
        return Err(invalid!("exposure: {stops} stops is outside [-60, 60]"));
    }
    gains(env, [stops.exp2(); 3], "exposure")
}

/// How to change a map's white balance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum WhiteBalance {
    /// The light made to look as if its source were a black body at this many kelvin
    /// rather than at 6500 K: per-channel gains of that black body's colour over 6500 K's,
    /// scaled to keep luminance (below 6500 K warmer, above cooler).
    Temperature(f64),
    /// Per-channel gains (R, G, B), each finite and >= 0.
    Gains([f64; 3]),
}

impl WhiteBalance {
    /// The per-channel gains.
    pub fn gains(&self) -> Result<[f64; 3]> {
        match *self {
            WhiteBalance::Temperature(k) => {
                let (lo, hi) = TEMPERATURE_RANGE;
                if !(lo..=hi).contains(&k) {
                    return Err(invalid!("white balance: {k} K is outside [{lo}, {hi}] K"));
                }
                let (t, d) = (temperature_rgb(k), temperature_rgb(6500.0));
                let g = [0, 1, 2].map(|i| t[i] / d[i]);
                let l = luminance(g);
                Ok(g.map(|v| v / l))
            }
            WhiteBalance::Gains(g) => {
                if let Some(v) = g.iter().find(|v| !(v.is_finite() && **v >= 0.0)) {
                    return Err(invalid!("white balance: gain {v} must be finite and >= 0"));
                }
                Ok(g)
            }
        }
    }
}

impl std::str::FromStr for WhiteBalance {
    type Err = String;
    /// `KELVIN` (e.g. `3200` or `3200K`) or three gains `R,G,B` (e.g. `1.1,1,0.9`).
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        let number = |t: &str| -> std::result::Result<f64, String> {
            t.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("'{t}' is not a number"))
        };
        if s.contains(',') {
            let parts = s
                .split(',')
                .map(number)
                .collect::<std::result::Result<Vec<_>, _>>()?;
            let [r, g, b] = parts[..] else {
                return Err(format!("white balance '{s}': give three gains R,G,B"));
            };
            let wb = WhiteBalance::Gains([r, g, b]);
            wb.gains().map_err(|e| e.to_string())?;
            return Ok(wb);
        }
        let k = s.strip_suffix(['K', 'k']).unwrap_or(s);
        let wb = WhiteBalance::Temperature(number(k).map_err(|_| {
            format!("white balance '{s}' is neither a temperature (e.g. 3200K) nor gains R,G,B")
        })?);
        wb.gains().map_err(|e| e.to_string())?;
        Ok(wb)
    }
}

/// The map with its white balance changed.
pub fn white_balance(env: &EnvMap, wb: WhiteBalance) -> Result<EnvMap> {
    gains(env, wb.gains()?, "white balance")
}

/// Every texel times `g`, channel by channel; an error if a texel would exceed the
/// largest radiance accepted.
fn gains(env: &EnvMap, g: [f64; 3], what: &str) -> Result<EnvMap> {
    let mut texels = Vec::with_capacity(env.texels.len());
    for t in &env.texels {
        let v = [0, 1, 2].map(|k| (t[k] as f64 * g[k]) as f32);
        if v.iter().any(|x| !(x.is_finite() && *x <= MAX_RADIANCE)) {
            return Err(invalid!(
                "{what}: a texel would reach {:e}, above the largest radiance accepted ({MAX_RADIANCE:e})",
                v.iter().fold(0.0f32, |a, b| a.max(*b))
            ));
        }
        texels.push(v);
    }
    EnvMap::new(env.height, env.width, env.convention, texels)
}
