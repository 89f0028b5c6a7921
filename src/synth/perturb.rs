//! Material perturbations that stay physical: brightness, colour and roughness drawn per
//! sample and applied to the 108 control points.
//!
//! Each lobe exp(m0 x^m1) - 1 is changed at each control point by what it reflects: its
//! energy E(m0, m1), the lobe integrated over the half vectors a viewer on the normal sees
//! (theta_h in [0, pi/4], weighted as the albedo at normal incidence weighs them, see
//! [`albedo`]). So, at every control point:
//! - roughness r divides the exponent, m1' = m1 / r (a rougher lobe is broader, a smoother
//!   one narrower), and m0' is solved for so that the lobe reflects what it did: a broader
//!   lobe is dimmer at its peak, a narrower one brighter;
//! - brightness b and colour gains g (luminance 1) scale that energy: E' = b g_k E;
//! - m0' solves E(m0', m1') = E' (E grows with m0: Newton's method, kept in a bracket). A
//!   negative lobe is scaled alike.
//!
//! So the albedo at normal incidence of every channel is scaled by b g_k (and kept by r)
//! up to how the spline's control points share theta_d. What stays physical: exponents
//! stay >= 0; a material that would reflect more than [`ALBEDO_CAP`] of the light at
//! normal incidence in some channel (or more than it did before, if that was higher) has
//! its brightness lowered until it does not.

use serde::Deserialize;
use serde_json::{Value, json};

use crate::brdf::Isotropic;
use crate::envgen::colour::luminance;
use crate::error::{Result, invalid};
use crate::material::{MAX_ABS_SCALE, MAX_EXPONENT, Material, N_CHANNELS, N_LOBES, N_PARAMS, idx};
use crate::spline::N_CTRL_POINTS;
use crate::splitmix::SplitMix;

/// The directional albedo at normal incidence a brightened material may reach.
pub const ALBEDO_CAP: f64 = 0.95;

/// The ranges perturbations are drawn from.
#[derive(Clone, Copy, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Perturb {
    /// Brightness factor, drawn log-uniformly in [lo, hi].
    #[serde(default = "default_brightness")]
    pub brightness: [f64; 2],
    /// Colour: per-channel gains exp(colour * N(0, 1)), scaled to luminance 1.
    #[serde(default = "default_colour")]
    pub colour: f64,
    /// Roughness factor (exponents divided by it), drawn log-uniformly in [lo, hi].
    #[serde(default = "default_roughness")]
    pub roughness: [f64; 2],
}

fn default_brightness() -> [f64; 2] {
    [0.7, 1.4]
}
fn default_colour() -> f64 {
    0.15
}
fn default_roughness() -> [f64; 2] {
    [0.6, 1.6]
}

impl Default for Perturb {
    fn default() -> Self {
        Perturb {
            brightness: default_brightness(),
            colour: default_colour(),
            roughness: default_roughness(),
        }
    }
}

/// One draw of [`Perturb`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drawn {
    /// Brightness factor.
    pub brightness: f64,
    /// Per-channel gains, luminance 1.
    pub gains: [f64; 3],
    /// Roughness factor.
    pub roughness: f64,
}

impl Perturb {
    /// Checks the ranges: factors finite and positive with lo <= hi, at most a factor of
    /// 10 either way; colour in [0, 1].
    pub fn validate(&self) -> std::result::Result<(), String> {
        for (name, [lo, hi]) in [
            ("brightness", self.brightness),
            ("roughness", self.roughness),
        ] {
            if !(lo.is_finite() && hi.is_finite() && lo >= 0.1 && lo <= hi && hi <= 10.0) {
                return Err(format!(
                    "{name}: [{lo}, {hi}] must be a range within [0.1, 10] with lo <= hi"
                ));
            }
        }
        if !(self.colour.is_finite() && (0.0..=1.0).contains(&self.colour)) {
            return Err(format!("colour: {} must be in [0, 1]", self.colour));
        }
        Ok(())
    }

    /// A draw: arithmetic and `ln`/`exp` on the generator's uniforms only.
    pub fn draw(&self, rng: &mut SplitMix) -> Drawn {
        let log_uniform = |rng: &mut SplitMix, [lo, hi]: [f64; 2]| {
            (lo.ln() + rng.uniform() * (hi.ln() - lo.ln())).exp()
        };
        let brightness = log_uniform(rng, self.brightness);
        let roughness = log_uniform(rng, self.roughness);
        let raw = [0, 1, 2].map(|_| (self.colour * normal(rng)).exp());
        let l = luminance(raw);
        Drawn {
            brightness,
            gains: raw.map(|g| g / l),
            roughness,
        }
    }
}

/// A standard normal draw (Box-Muller on two uniforms).
fn normal(rng: &mut SplitMix) -> f64 {
    let u1 = 1.0 - rng.uniform(); // in (0, 1]
    let u2 = rng.uniform();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

/// Nodes of the lobe-energy integral: (ln x, weight) with x = cos theta_h, theta_h =
/// (pi/4) t^2 on a midpoint rule in t (dense near the peak, where sharp lobes live), the
/// weight that of the albedo at normal incidence (theta_i = 2 theta_h).
fn energy_nodes() -> &'static [(f64, f64)] {
    static NODES: std::sync::OnceLock<Vec<(f64, f64)>> = std::sync::OnceLock::new();
    NODES.get_or_init(|| {
        const N: usize = 512;
        let q = std::f64::consts::FRAC_PI_4;
        (0..N)
            .map(|i| {
                let t = (i as f64 + 0.5) / N as f64;
                let th = q * t * t;
                let d_th = 2.0 * q * t / N as f64;
                let ti = 2.0 * th;
                let w = std::f64::consts::TAU * ti.cos() * ti.sin() * 2.0 * d_th;
                (th.cos().ln(), w)
            })
            .collect()
    })
}

/// The lobe's energy E(m0, m1) and dE/dm0 on the nodes' powers p = x^m1.
fn energy(m0: f64, powers: &[(f64, f64)]) -> (f64, f64) {
    powers.iter().fold((0.0, 0.0), |(e, d), &(p, w)| {
        let u = m0 * p;
        (e + u.exp_m1() * w, d + p * u.exp() * w)
    })
}

/// m0' with E(m0', m1') = `target`, starting from `start`.
fn solve_scale(target: f64, m1: f64, start: f64) -> f64 {
    let powers: Vec<(f64, f64)> = energy_nodes()
        .iter()
        .map(|&(ln_x, w)| (if m1 == 0.0 { 1.0 } else { (m1 * ln_x).exp() }, w))
        .collect();
    let (mut lo, mut hi) = (-MAX_ABS_SCALE, MAX_ABS_SCALE);
    if energy(hi, &powers).0 <= target {
        return hi;
    }
    if energy(lo, &powers).0 >= target {
        return lo;
    }
    let mut m = start.clamp(lo, hi);
    for _ in 0..100 {
        let (e, de) = energy(m, &powers);
        if e > target {
            hi = m;
        } else {
            lo = m;
        }
        if (e - target).abs() <= 1e-12 * target.abs().max(1e-300) || hi - lo < 1e-12 {
            break;
        }
        let next = m - (e - target) / de;
        m = if next > lo && next < hi && de > 0.0 {
            next
        } else {
            0.5 * (lo + hi)
        };
    }
    m
}

/// `material` with the brightness scaled by `t` on top of `d`.
fn apply_scaled(material: &Material, d: &Drawn, t: f64) -> Result<Material> {
    let mut ctrl = [0.0; N_PARAMS];
    ctrl.copy_from_slice(&material.ctrl);
    for k in 0..N_CHANNELS {
        let g = d.brightness * t * d.gains[k];
        for s in 0..N_LOBES {
            for j in 0..N_CTRL_POINTS {
                let (i0, i1) = (idx(k, s, 0, j), idx(k, s, 1, j));
                let (m0, m1) = (ctrl[i0], ctrl[i1]);
                let m1_new = (m1 / d.roughness).min(MAX_EXPONENT);
                if m1 == 0.0 {
                    // a constant lobe: its energy is its value
                    ctrl[i0] = (m0.exp_m1() * g).max(-1.0 + 1e-9).ln_1p();
                    continue;
                }
                let powers: Vec<(f64, f64)> = energy_nodes()
                    .iter()
                    .map(|&(ln_x, w)| ((m1 * ln_x).exp(), w))
                    .collect();
                let target = energy(m0, &powers).0 * g;
                ctrl[i0] = solve_scale(target, m1_new, m0);
                ctrl[i1] = m1_new;
            }
        }
    }
    Material::new(material.name.clone(), &ctrl)
}

/// The directional albedo at normal incidence, per channel: the share of light from the
/// whole hemisphere reflected towards a viewer along the normal. With the viewer on the
/// normal, theta_h = theta_d = theta_i / 2, so it is the one integral
/// 2 pi int_0^{pi/2} f(theta_i / 2, theta_i / 2) cos theta_i sin theta_i d theta_i
/// (midpoint rule, 2048 steps: a lobe of exponent 1e4 spans about 18 of them).
pub fn albedo(material: &Material) -> [f64; 3] {
    const STEPS: usize = 2048;
    let dt = std::f64::consts::FRAC_PI_2 / STEPS as f64;
    let mut a = [0.0; 3];
    for i in 0..STEPS {
        let t = (i as f64 + 0.5) * dt;
        let f = material.eval(t / 2.0, t / 2.0, 0.0);
        let w = std::f64::consts::TAU * t.cos() * t.sin() * dt;
        for (a, f) in a.iter_mut().zip(f) {
            *a += f * w;
        }
    }
    a
}

fn largest(a: [f64; 3]) -> f64 {
    a.into_iter().fold(f64::NEG_INFINITY, f64::max)
}

/// `material` perturbed by `d`, and what the sample records of it (the draw and the
/// brightness kept after the albedo cap).
pub fn apply(material: &Material, d: &Drawn) -> Result<(Material, Value)> {
    let cap = ALBEDO_CAP.max(largest(albedo(material)));
    let mut t = 1.0;
    let mut out = apply_scaled(material, d, t)?;
    // the albedo scales close to linearly with the brightness: a few corrections
    for _ in 0..4 {
        let a = largest(albedo(&out));
        if a <= cap {
            break;
        }
        t *= cap / a * (1.0 - 1e-3);
        out = apply_scaled(material, d, t)?;
    }
    if !out.ctrl.iter().all(|v| v.is_finite()) {
        return Err(invalid!(
            "perturbed material '{}' is not finite",
            material.name
        ));
    }
    let record = json!({
        "brightness": d.brightness * t,
        "brightness_drawn": d.brightness,
        "gains": d.gains,
        "roughness": d.roughness,
    });
    Ok((out, record))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn presets() -> Vec<Material> {
        crate::presets::merl()
            .iter()
            .step_by(9)
            .map(|p| p.material())
            .collect()
    }

    #[test]
    fn identity_draw_changes_nothing() {
        let d = Drawn {
            brightness: 1.0,
            gains: [1.0; 3],
            roughness: 1.0,
        };
        for m in presets() {
            let (p, _) = apply(&m, &d).unwrap();
            for (a, b) in p.ctrl.iter().zip(&m.ctrl) {
                assert!((a - b).abs() <= 1e-12 * (1.0 + b.abs()), "{a} vs {b}");
            }
        }
    }

    #[test]
    fn brightness_scales_albedo_and_is_capped() {
        for m in presets() {
            let a = albedo(&m);
            let half = Drawn {
                brightness: 0.5,
                gains: [1.0; 3],
                roughness: 1.0,
            };
            let b = albedo(&apply(&m, &half).unwrap().0);
            for k in 0..3 {
                // all 90 presets: within 0.7% (the spline's control points share theta_d)
                assert!(
                    (b[k] / a[k] / 0.5 - 1.0).abs() < 0.02,
                    "{}: {:?} vs {:?}",
                    m.name,
                    b,
                    a
                );
            }
            let bright = Drawn {
                brightness: 10.0,
                gains: [1.0; 3],
                roughness: 1.0,
            };
            let c = albedo(&apply(&m, &bright).unwrap().0);
            assert!(
                largest(c) <= ALBEDO_CAP.max(largest(a)) + 1e-9,
                "{}: {c:?}",
                m.name
            );
        }
    }

    #[test]
    fn roughness_keeps_energy_and_widens() {
        let m = crate::presets::lookup("gold").unwrap();
        let a = albedo(&m);
        for r in [0.6, 1.6] {
            let d = Drawn {
                brightness: 1.0,
                gains: [1.0; 3],
                roughness: r,
            };
            let (p, _) = apply(&m, &d).unwrap();
            let b = albedo(&p);
            for k in 0..3 {
                // all 90 presets: within 4.3%
                assert!((b[k] / a[k] - 1.0).abs() < 0.06, "r {r}: {b:?} vs {a:?}");
            }
            // exponents divided by r
            let (i, j) = (idx(0, 1, 1, 2), idx(0, 1, 1, 2));
            assert!((p.ctrl[i] - m.ctrl[j] / r).abs() < 1e-9 * m.ctrl[j].max(1.0));
        }
    }

    #[test]
    fn draws_are_seeded_and_in_range() {
        let p = Perturb::default();
        p.validate().unwrap();
        let mut a = SplitMix(5);
        let mut b = SplitMix(5);
        for _ in 0..100 {
            let (x, y) = (p.draw(&mut a), p.draw(&mut b));
            assert_eq!(x, y);
            assert!((0.7..=1.4).contains(&x.brightness));
            assert!((0.6..=1.6).contains(&x.roughness));
            let l = luminance(x.gains);
            assert!((l - 1.0).abs() < 1e-12);
        }
        assert!(Perturb { colour: 2.0, ..p }.validate().is_err());
        assert!(
            Perturb {
                brightness: [2.0, 1.0],
                ..p
            }
            .validate()
            .is_err()
        );
    }
}
