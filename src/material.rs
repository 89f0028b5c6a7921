//! The material: a Directional Statistics BRDF whose 3 channels x 3 lobes x 2 coefficients
//! vary with theta_d through 6 spline control points, 108 numbers in all.

use crate::error::{Result, invalid};
use crate::spline::{N_CTRL_POINTS, spline_basis};

/// Colour channels (R, G, B).
pub const N_CHANNELS: usize = 3;
/// Lobes per channel.
pub const N_LOBES: usize = 3;
/// Coefficients per lobe: t = 0 the scale m0 (kappa), t = 1 the exponent m1 (gamma).
pub const N_COEFS: usize = 2;
/// Control points in a material: 3 x 3 x 2 x 6 = 108.
pub const N_PARAMS: usize = N_CHANNELS * N_LOBES * N_COEFS * N_CTRL_POINTS;

/// Largest |m0| control point accepted: keeps exp(m0 x^m1) far from f32 overflow.
pub const MAX_ABS_SCALE: f64 = 40.0;
/// Largest exponent control point accepted.
pub const MAX_EXPONENT: f64 = 1.0e4;

/// Flat index of control point j of coefficient t of lobe s of channel k:
/// ((k * 3 + s) * 2 + t) * 6 + j.
pub const fn idx(k: usize, s: usize, t: usize, j: usize) -> usize {
    ((k * N_LOBES + s) * N_COEFS + t) * N_CTRL_POINTS + j
}

/// A material: 108 control points in the flat order of [`idx`].
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// A name for reports and files.
    pub name: String,
    /// The control points, flat order of [`idx`].
    pub ctrl: [f64; N_PARAMS],
}

impl Material {
    /// A validated material from a slice of exactly 108 numbers.
    pub fn new(name: impl Into<String>, ctrl: &[f64]) -> Result<Self> {
        let ctrl: [f64; N_PARAMS] = ctrl.try_into().map_err(|_| {
            invalid!(
                "material: {} control points given; a material has exactly {N_PARAMS}",
                ctrl.len()
            )
        })?;
        let m = Material {
            name: name.into(),
            ctrl,
        };
        m.validate()?;
        Ok(m)
    }

    /// The same lobe in every channel, constant over theta_d: scale m0 and exponent m1 for
    /// each of the three lobes.
    pub fn constant(name: impl Into<String>, lobes: [(f64, f64); N_LOBES]) -> Result<Self> {
        let mut ctrl = [0.0; N_PARAMS];
        for k in 0..N_CHANNELS {
            for (s, &(m0, m1)) in lobes.iter().enumerate() {
                for j in 0..N_CTRL_POINTS {
                    ctrl[idx(k, s, 0, j)] = m0;
                    ctrl[idx(k, s, 1, j)] = m1;
                }
            }
        }
        Material::new(name, &ctrl)
    }

    /// A seeded random material with nothing to share: every lobe of every channel has its
    /// own scale curve (around a level drawn from [0.02, 1.2]) and its own exponent curve
    /// (around a level drawn log-uniformly from [0.3, 80]), each control point within 30%
    /// of its curve's level and inside those ranges. What a network or a fit produces, and
    /// what the benchmarks call `random-SEED`.
    pub fn random(seed: u64) -> Self {
        let mut rng = crate::splitmix::SplitMix(seed);
        let mut u = |lo: f64, hi: f64| lo + (hi - lo) * rng.uniform();
        let mut ctrl = [0.0; N_PARAMS];
        for k in 0..N_CHANNELS {
            for s in 0..N_LOBES {
                let scale = u(0.02, 1.2);
                let exponent = (u(0.3f64.ln(), 80f64.ln())).exp();
                for j in 0..N_CTRL_POINTS {
                    ctrl[idx(k, s, 0, j)] = (scale * u(0.7, 1.3)).clamp(0.02, 1.2);
                    ctrl[idx(k, s, 1, j)] = (exponent * u(0.7, 1.3)).clamp(0.3, 80.0);
                }
            }
        }
        Material::new(format!("random-{seed}"), &ctrl).expect("within the valid ranges")
    }

    /// The material `factors[k]` times as bright in channel k. Each lobe
    /// exp(m0 x^m1) - 1, as a function of y = x^m1, is matched at its peak y = 1 (exactly:
    /// m0' = ln(1 + r (e^m0 - 1))) and in its log slope there (m1' = p m1 with p the slope
    /// of ln(1 + r (e^(m0 y) - 1)) at y = 1 over m0'): a small lobe (diffuse, broad) scales as
    /// a whole (p = 1), a sharp one keeps its width where it is bright. Scales stay within
    /// +-[`MAX_ABS_SCALE`], exponents within [`MAX_EXPONENT`]; a lobe whose peak a factor
    /// would turn below -1 (a negative lobe made darker than black) is left as it was.
    pub fn scaled(&self, factors: [f64; N_CHANNELS]) -> Material {
        let mut m = self.clone();
        for (k, &r) in factors.iter().enumerate() {
            for s in 0..N_LOBES {
                for j in 0..N_CTRL_POINTS {
                    let (a, b) = (idx(k, s, 0, j), idx(k, s, 1, j));
                    let m0 = m.ctrl[a];
                    let v = 1.0 + r * m0.exp_m1();
                    if v <= 0.0 || m0 == 0.0 {
                        continue;
                    }
                    let m0_new = v.ln().clamp(-MAX_ABS_SCALE, MAX_ABS_SCALE);
                    // d/dy ln(1 + r (e^(m0 y) - 1)) at y = 1, over m0'
                    let p = r * m0 * m0.exp() / v / m0_new;
                    m.ctrl[a] = m0_new;
                    if p.is_finite() && p > 0.0 {
                        m.ctrl[b] = (m.ctrl[b] * p).min(MAX_EXPONENT);
                    }
                }
            }
        }
        m
    }

    /// Checks that every control point is finite, scales are within +-[`MAX_ABS_SCALE`]
    /// and exponents within [0, [`MAX_EXPONENT`]].
    pub fn validate(&self) -> Result<()> {
        for (i, &v) in self.ctrl.iter().enumerate() {
            let is_exponent = (i / N_CTRL_POINTS) % N_COEFS == 1;
            let what = if is_exponent { "exponent" } else { "scale" };
            if !v.is_finite() {
                return Err(invalid!("material: {what} control point idx {i} is {v}"));
            }
            if is_exponent && v < 0.0 {
                return Err(invalid!(
                    "material: exponent control point idx {i} is {v}; exponents must be >= 0"
                ));
            }
            if is_exponent && v > MAX_EXPONENT {
                return Err(invalid!(
                    "material: exponent control point idx {i} is {v}; exponents must be <= {MAX_EXPONENT}"
                ));
            }
            if !is_exponent && v.abs() > MAX_ABS_SCALE {
                return Err(invalid!(
                    "material: scale control point idx {i} is {v}; scales must be within +-{MAX_ABS_SCALE}"
                ));
            }
        }
        Ok(())
    }

    /// The 18 coefficients m_{s,t}^k(theta_d), indexed (k * 3 + s) * 2 + t.
    pub fn coefficients(&self, theta_d: f64) -> [f64; N_PARAMS / N_CTRL_POINTS] {
        let b = spline_basis(theta_d);
        let mut out = [0.0; N_PARAMS / N_CTRL_POINTS];
        for (c, o) in out.iter_mut().enumerate() {
            *o = (0..N_CTRL_POINTS)
                .map(|j| b[j] * self.ctrl[c * N_CTRL_POINTS + j])
                .sum();
        }
        out
    }
}

/// Describes flat index `i`: `ctrl[7] (channel R, lobe 0, exponent m1, point 1)`.
pub fn describe_index(i: usize) -> String {
    let j = i % N_CTRL_POINTS;
    let t = (i / N_CTRL_POINTS) % 2;
    let s = (i / (N_CTRL_POINTS * 2)) % 3;
    let k = i / (N_CTRL_POINTS * 6);
    let channel = ["R", "G", "B"].get(k).copied().unwrap_or("?");
    let coef = if t == 0 { "scale m0" } else { "exponent m1" };
    format!("ctrl[{i}] (channel {channel}, lobe {s}, {coef}, point {j})")
}

/// Checks 108 control points and builds the material; the error message names the item
/// (without the file name).
pub fn material_from_ctrl(name: String, ctrl: &[f64]) -> std::result::Result<Material, String> {
    if ctrl.len() != N_PARAMS {
        return Err(format!(
            "'ctrl' has {} numbers; a material has exactly {N_PARAMS} (3 channels x 3 lobes x \
             2 coefficients x 6 control points, index ((k*3 + s)*2 + t)*6 + j)",
            ctrl.len()
        ));
    }
    for (i, &v) in ctrl.iter().enumerate() {
        let is_exponent = (i / N_CTRL_POINTS) % 2 == 1;
        let why = if !v.is_finite() {
            Some("is not a finite number".to_string())
        } else if is_exponent && v < 0.0 {
            Some(format!("is {v}; exponents must be >= 0"))
        } else if is_exponent && v > MAX_EXPONENT {
            Some(format!("is {v}; exponents must be <= {MAX_EXPONENT}"))
        } else if !is_exponent && v.abs() > MAX_ABS_SCALE {
            Some(format!("is {v}; scales must be within +-{MAX_ABS_SCALE}"))
        } else {
            None
        };
        if let Some(why) = why {
            return Err(format!("{} {why}", describe_index(i)));
        }
    }
    Material::new(name, ctrl).map_err(|e| {
        let m = e.to_string();
        m.strip_prefix("material: ")
            .map(str::to_string)
            .unwrap_or(m)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_scaled_lobe_keeps_its_peak_times_the_factor() {
        let m = Material::random(7);
        let r = [1.5, 0.5, 2.0];
        let s = m.scaled(r);
        s.validate().unwrap();
        for k in 0..N_CHANNELS {
            for l in 0..N_LOBES {
                for j in 0..N_CTRL_POINTS {
                    let (a, b) = (m.ctrl[idx(k, l, 0, j)], s.ctrl[idx(k, l, 0, j)]);
                    let want = r[k] * a.exp_m1();
                    assert!(
                        (b.exp_m1() - want).abs() < 1e-9 * (1.0 + want.abs()),
                        "{k} {l} {j}"
                    );
                }
            }
        }
        // a small lobe scales as a whole: the same exponent, twice the scale
        let small = Material::constant("small", [(1e-4, 3.0), (0.0, 0.0), (0.0, 0.0)]).unwrap();
        let twice = small.scaled([2.0; 3]);
        assert!((twice.ctrl[idx(0, 0, 1, 0)] - 3.0).abs() < 1e-3);
        assert!((twice.ctrl[idx(0, 0, 0, 0)] - 2e-4).abs() < 1e-7);
        // a sharp bright lobe keeps its width where it is bright: the exponent barely moves
        let sharp = Material::constant("sharp", [(8.0, 200.0), (0.0, 0.0), (0.0, 0.0)]).unwrap();
        let p = sharp.scaled([2.0; 3]).ctrl[idx(0, 0, 1, 0)] / 200.0;
        assert!(p > 0.9 && p < 1.0, "{p}");
    }
}
