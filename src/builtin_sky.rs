//! Built-in default scene parts: a procedural HDR environment (sky, sun, ground).
//!
//! The environment is a clear day: a blue sky that brightens towards the horizon
//! (radiance about 0.5 to 1.3) with a faint warm glow around the sun, a warm white sun disc
//! 2.5 degrees in radius and 600 times brighter than the sky (so that it gives about as
//! much light as the whole sky, and casts a visible highlight and terminator), and a
//! brown ground (radiance about 0.1 to 0.3). The sun stands 40 degrees above the horizon,
//! in front of the camera and to its right, so that an orthographic sphere shows its lit
//! side.
//!
//! The map is generated at the requested size: each texel is the solid-angle-weighted
//! mean over a grid of sub-texel samples, and the sun's power (radiance times its solid
//! angle) is spread over the texels it covers in proportion to their coverage, so it is the
//! same at every resolution, even where the sun is far smaller than a texel.

use crate::envmap::{Convention, EnvMap};

/// `matedit render`'s level of the continuous light for the built-in sky (see
/// [`crate::continuous_light`]): without it a glossy sphere shows the sky's texels as rings
/// near its rim. Level 1 (sub-texels as wide as the lobe) removes them at about twice the
/// layer's time on the default sphere (docs/continuous_light.md).
pub const LIGHT_LEVEL: u32 = 1;

/// The continuous light takes each texel's radiance distribution from the same light at
/// this many times the rows and columns (16 times the texels): the procedural sky
/// generated finer, or the map's file where it is that large.
pub const LIGHT_DETAIL: usize = 4;

/// Direction towards the sun (unit; y up, z towards the viewer): 40 degrees above the
/// horizon, at phi = 60 degrees, which both conventions cover.
pub const SUN_DIR: [f64; 3] = [
    0.383_022_221_559_489, // cos(60) sin(50)
    0.642_787_609_686_539, // cos(50)
    0.663_413_948_168_938, // sin(60) sin(50)
];

/// Angular radius of the sun disc, radians (2.5 degrees).
pub const SUN_RADIUS: f64 = 0.043_633_231_299_858_24;

/// Radiance of the sun disc (warm white).
pub const SUN_RADIANCE: [f64; 3] = [600.0, 560.0, 490.0];

const ZENITH: [f64; 3] = [0.35, 0.55, 1.05];
const HORIZON: [f64; 3] = [1.0, 1.1, 1.25];
const GLOW: [f64; 3] = [0.45, 0.35, 0.2];
const GROUND_NEAR: [f64; 3] = [0.30, 0.22, 0.14];
const GROUND_FAR: [f64; 3] = [0.13, 0.095, 0.065];

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn mix(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
    [0, 1, 2].map(|k| a[k] + (b[k] - a[k]) * t)
}

/// Radiance of the sky and ground (no sun disc) in direction `w`.
pub fn sky_radiance(w: [f64; 3]) -> [f64; 3] {
    let y = w[1];
    if y >= 0.0 {
        let sky = mix(HORIZON, ZENITH, y.sqrt());
        // A glow that falls off over about 10 degrees around the sun.
        let glow = ((dot(w, SUN_DIR) - 1.0) / 0.015).exp();
        [0, 1, 2].map(|k| sky[k] + GLOW[k] * glow)
    } else {
        mix(GROUND_NEAR, GROUND_FAR, (-y).sqrt())
    }
}

/// Direction and true solid angle of the sub-texel sample (r, c) of an `h` x `w` grid
/// under `convention`. The paper convention's own d_omega is not a solid angle, so the
/// physical one (sin theta dtheta dphi, phi spanning pi) is used to place the sun's power.
fn sample(convention: Convention, r: usize, c: usize, h: usize, w: usize) -> ([f64; 3], f64) {
    let (dir, d_omega) = convention.texel(r, c, h, w);
    let true_d_omega = match convention {
        Convention::Equirect => d_omega,
        Convention::Paper => {
            d_omega * (std::f64::consts::PI / h as f64) * (std::f64::consts::PI / w as f64)
        }
    };
    (dir, true_d_omega)
}

/// The default environment: a procedural clear-day sky with a sun and a ground, `height`
/// rows x `width` columns, generated directly at that size under `convention`.
pub fn procedural_env(height: usize, width: usize, convention: Convention) -> EnvMap {
    generate(height, width, convention, true)
}

fn generate(height: usize, width: usize, convention: Convention, with_sun: bool) -> EnvMap {
    // Enough sub-samples that small maps still see a smooth horizon and find the sun.
    let s = (256 / height.max(1)).clamp(1, 8);
    let (hs, ws) = (height * s, width * s);
    let cos_sun = SUN_RADIUS.cos();
    let sun_omega = 2.0 * std::f64::consts::PI * (1.0 - cos_sun);

    let mut sky = Vec::with_capacity(height * width);
    let mut sun_weight = Vec::with_capacity(height * width);
    let mut omega = Vec::with_capacity(height * width);
    for r in 0..height {
        for c in 0..width {
            let mut sum = [0.0f64; 3];
            let mut om = 0.0;
            let mut plain = [0.0f64; 3];
            let mut in_sun = 0.0;
            for i in 0..s {
                for j in 0..s {
                    let (dir, d) = sample(convention, r * s + i, c * s + j, hs, ws);
                    let l = sky_radiance(dir);
                    for k in 0..3 {
                        sum[k] += l[k] * d;
                        plain[k] += l[k];
                    }
                    om += d;
                    if dot(dir, SUN_DIR) >= cos_sun {
                        in_sun += d;
                    }
                }
            }
            sky.push(if om > 0.0 {
                sum.map(|v| v / om)
            } else {
                plain.map(|v| v / (s * s) as f64)
            });
            // The renderer weighs the texel by its own d_omega: convert the sun's power
            // to radiance with that, and leave texels that weigh nothing out.
            let texel_omega = sample(convention, r, c, height, width).1;
            sun_weight.push(if texel_omega > 0.0 { in_sun } else { 0.0 });
            omega.push(texel_omega);
        }
    }

    // Spread the sun's power over the texels its disc covers; if no sample fell in the
    // disc (a tiny map), give it all to the texel nearest the sun.
    let total: f64 = sun_weight.iter().sum();
    if total <= 0.0 {
        let nearest = (0..height * width)
            .filter(|&i| omega[i] > 0.0)
            .max_by(|&a, &b| {
                let da = dot(
                    convention.texel(a / width, a % width, height, width).0,
                    SUN_DIR,
                );
                let db = dot(
                    convention.texel(b / width, b % width, height, width).0,
                    SUN_DIR,
                );
                da.total_cmp(&db)
            });
        if let Some(i) = nearest {
            sun_weight[i] = 1.0;
        }
    }
    let total: f64 = sun_weight.iter().sum();
    let texels = (0..height * width)
        .map(|i| {
            let share = if with_sun && total > 0.0 && omega[i] > 0.0 {
                sun_weight[i] / total * sun_omega / omega[i]
            } else {
                0.0
            };
            [0, 1, 2].map(|k| (sky[i][k] + SUN_RADIANCE[k] * share) as f32)
        })
        .collect();
    EnvMap {
        height,
        width,
        convention,
        texels,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn power(e: &EnvMap) -> f64 {
        e.texels
            .iter()
            .enumerate()
            .map(|(i, t)| {
                t[0] as f64 * sample(e.convention, i / e.width, i % e.width, e.height, e.width).1
            })
            .sum()
    }

    #[test]
    fn plausible_values() {
        let e = procedural_env(64, 128, Convention::Equirect);
        e.validate().unwrap();
        let max = e.texels.iter().map(|t| t[0]).fold(0.0f32, f32::max);
        assert!(max > 100.0, "sun peak {max}");
        // the zenith row is bluish sky, the bottom row brownish ground
        let top = e.texels[0];
        assert!(top[2] > top[0] && (0.3..1.5).contains(&top[2]), "{top:?}");
        let bottom = e.texels[63 * 128];
        assert!(
            bottom[0] > bottom[2] && (0.05..0.35).contains(&bottom[0]),
            "{bottom:?}"
        );
    }

    #[test]
    fn sun_power_is_resolution_independent() {
        let sun = SUN_RADIANCE[0] * 2.0 * std::f64::consts::PI * (1.0 - SUN_RADIUS.cos());
        for conv in [Convention::Equirect, Convention::Paper] {
            for (h, w) in [(2, 4), (4, 8), (8, 16), (64, 128), (256, 512)] {
                let p = power(&generate(h, w, conv, true)) - power(&generate(h, w, conv, false));
                // f32 texels: relative error around 1e-6 of the sky's power
                assert!(
                    (p - sun).abs() < 1e-4 * sun,
                    "{conv:?} {h}x{w}: {p} vs {sun}"
                );
            }
        }
    }
}
