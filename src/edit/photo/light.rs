//! The light's level and colour from the whole photo. A photo alone cannot tell a bright
//! material under a dim light from a dark one under a bright light: the layer renders the
//! product of the two, and the nets settle on one split of it. A new material needs the
//! true light to look as bright as a photo of it would. The photo's background is lit by
//! that light, and, where it shows the surroundings, is that light: so the predicted
//! light's mean luminance is set to the background's (times [`BACKGROUND_GAIN`]) before the
//! refinement, whose level prior then holds the light near that level while the material
//! takes what the object's shading asks for.
//!
//! Its mean colour is set to grey, the nets' variation of colour across it kept: a camera
//! balances its colours so that the light comes out grey, and what colour a background
//! has is mostly that of what it shows (a wooden table, foliage), not of the light. Until
//! 2026-12-06 the light took the background's colour, and white paint on a flower before
//! foliage came out mint green (docs/edit.md, "The light's colour").
//!
//! A background much darker than the object (an object photographed on black, a swatch)
//! says nothing of the light. The nets' split is then a guess that goes wrong both ways
//! (shiny metals read under a light ten times too bright come out nearly black, black
//! rubber under one too dim comes out grey), so the photo is taken to be exposed as a
//! camera exposes for a grey card: the light's mean luminance is set to [`EXPOSED_LEVEL`],
//! grey. Photos of the same exposure then give materials on one scale.
//!
//! The background leaves out the object's edge ([`EDGE`]). After the refinement, which
//! leaves the light brighter than it is, [`relabel`] moves [`REFINED_BIAS`] of it into the
//! material: the same renders, each nearer its true level.
//!
//! What a photo of a dull object tells of its light is the light's broad shape (where it
//! comes from, brighter above than below); the finer structure of a 16 x 32 map is the
//! nets' guess and the refinement's fit to the photo's noise, and a shiny new material
//! mirrors it as blotches. Edits render under the refined light blurred on the sphere by
//! [`EDIT_LIGHT_BLUR`] ([`blur`]).

use rayon::prelude::*;

use crate::envgen::colour::luminance;
use crate::{EnvMap, Image, Material, raster};

/// The light's mean radiance over the background's mean radiance. The frame shows little
/// of the light's bright parts (sky, lamps, windows) and much of what it lights (a floor,
/// a table: albedos about one half), so the light is brighter than the background: on the
/// tune split of the photo-like set the true ratio (the map's mean luminance times the
/// exposure, over the background's mean) was 1.3 to 4.4, median 2.45 (docs/edit.md).
pub const BACKGROUND_GAIN: f64 = 2.45;
/// The background informs the light only when its mean luminance is at least this
/// fraction of the object's.
const MIN_BACKGROUND: f64 = 0.05;
/// The light's mean luminance (over the sphere) where the background says nothing: a
/// white diffuse surface under a uniform light of this level shows this linear value. The
/// swatches of the photo-like set's tune split, exposed as for a grey card, had 0.30 to
/// 0.62, median 0.41 (docs/edit.md).
pub const EXPOSED_LEVEL: f64 = 0.41;
/// The background leaves out the pixels within this fraction of the photo's longer side
/// of the object (at least [`MIN_EDGE`] pixels): an object's edge spreads over a pixel or
/// two beyond any mask, and a mask drawn by hand or cut by the nets is a few pixels off.
/// On a swatch on black those pixels alone made the background 5 % of the object's mean,
/// a lit background, and a light forty times too dim (docs/edit.md).
pub const EDGE: f64 = 0.01;
/// The least width of the edge left out, in pixels.
pub const MIN_EDGE: usize = 2;
/// How many times too bright the refinement leaves the light. Light and material both
/// start from a guess (the background's level, the nets' material) and the refinement's
/// Adam steps move the log of each at one rate, so the gap between the nets' render and
/// the photo is shared between them: a gold swatch's light went from the grey card's 0.41
/// to 0.85 in 20 steps, and its gold came out khaki. On the tune split of the photo-like
/// set (48 scenes: 24, balanced as a camera balances them and not) the refined light's mean
/// luminance was a median 1.31 times the true light's (1.24 on the first 8 scenes; the
/// start's median 1.0; docs/edit.md); after the refinement the light is divided by it and
/// the material takes it up ([`relabel`]).
pub const REFINED_BIAS: f64 = 1.31;
/// The width (degrees) of the spherical Gaussian edits blur the refined light with. On the
/// tune split of the photo-like set (24 scenes balanced as a camera balances them) the
/// median gain of edits `--like` a swatch rose from +6.09 dB unblurred to +6.72 (30
/// degrees), +7.18 (45), +7.28 (60) and +7.34 (90), on the same scenes unbalanced from
/// +5.05 to +6.29 (45), +6.36 (60), +6.40 (90); a uniform light of the same colour gave
/// +6.30: the light's broad shape helps, its detail does not. On the paper's test split,
/// rendered by the layer itself, the render alone loses 0.6 dB at 45 and 0.8 at 60 (the
/// fine structure is real there), so 45 (docs/edit.md, "The light edits render under").
pub const EDIT_LIGHT_BLUR: f64 = 45.0;
/// The factor applied to a channel is kept within [1 / MAX_FACTOR, MAX_FACTOR].
const MAX_FACTOR: f64 = 64.0;

/// Where the light's level came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelFrom {
    /// The nets' own level (the background's light turned off).
    Nets,
    /// The photo's background: [`BACKGROUND_GAIN`] times its mean.
    Background,
    /// A background too dark to say (a swatch on black): the photo taken as exposed for a
    /// grey card, [`EXPOSED_LEVEL`].
    GreyCard,
    /// Known: given with the photo ([`PhotoOptions::env`](super::PhotoOptions::env)).
    Given,
}

impl LevelFrom {
    /// The name reports use.
    pub fn as_str(self) -> &'static str {
        match self {
            LevelFrom::Nets => "nets",
            LevelFrom::Background => "background",
            LevelFrom::GreyCard => "grey card",
            LevelFrom::Given => "given",
        }
    }
}

/// The factors the light was scaled by, per channel, and where its level came from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Factors {
    pub gains: [f64; 3],
    /// Where the level came from.
    pub from: LevelFrom,
}

impl Factors {
    /// The light as the nets predicted it.
    pub const ONE: Factors = Factors {
        gains: [1.0; 3],
        from: LevelFrom::Nets,
    };
    /// A light given with the photo, as it was given.
    pub const GIVEN: Factors = Factors {
        gains: [1.0; 3],
        from: LevelFrom::Given,
    };
}

/// Scales `env` per channel so that its mean radiance (over the sphere, by solid angle) is
/// grey at [`BACKGROUND_GAIN`] times the mean luminance of the photo's pixels off `mask`
/// and its [`EDGE`]; where the background is too dark to say anything (or there is none),
/// grey at [`EXPOSED_LEVEL`]. Returns the factors applied.
pub fn match_background(env: &mut EnvMap, photo: &Image, mask: &[bool]) -> Factors {
    let (w, h) = (photo.width, photo.height);
    let edge = ((EDGE * w.max(h) as f64).round() as usize).max(MIN_EDGE);
    let near = raster::dilate(mask, w, h, edge);
    // sums per row in parallel, added in row order: the same for any thread count
    let rows: Vec<Sums> = photo
        .pixels
        .par_chunks(w.max(1))
        .zip(mask.par_chunks(w.max(1)))
        .zip(near.par_chunks(w.max(1)))
        .map(|((p, m), n)| Sums::of(p, m, n))
        .collect();
    let Sums {
        bg,
        obj,
        n_bg,
        n_obj,
    } = rows.iter().fold(Sums::default(), |a, r| a.add(r));
    let mean = mean_radiance(env);
    if n_obj == 0 || mean.iter().any(|&m| m <= 0.0) {
        return Factors::ONE;
    }
    let bg = luminance(bg.map(|v| v / n_bg.max(1) as f64));
    let obj = luminance(obj.map(|v| v / n_obj as f64));
    let (level, from) = if n_bg == 0 || bg < MIN_BACKGROUND * obj {
        (EXPOSED_LEVEL, LevelFrom::GreyCard)
    } else {
        (BACKGROUND_GAIN * bg.max(1e-6), LevelFrom::Background)
    };
    let factors = Factors {
        gains: mean.map(|m| (level / m).clamp(1.0 / MAX_FACTOR, MAX_FACTOR)),
        from,
    };
    scale(env, factors.gains);
    factors
}

/// Moves a factor `c` of the light into the material: `env` divided by `c`, the material
/// returned `c` times as bright ([`Material::scaled`]). The layer renders nearly the same
/// (exactly at each lobe's peak and where lobes are small); what changes is how much of
/// it is called light and how much material.
pub fn relabel(material: &Material, env: &mut EnvMap, c: f64) -> Material {
    scale(env, [1.0 / c; 3]);
    material.scaled([c; 3])
}

/// `env` blurred on the sphere: each texel the mean of all, weighted by their solid angles
/// and a spherical Gaussian exp((cos(angle) - 1) / w^2) of the angle between them, w =
/// `degrees` (the von Mises-Fisher kernel: about a Gaussian of that width for small
/// widths), then scaled per channel to keep the map's mean radiance. The map's grid and
/// convention are kept; `degrees` <= 0 returns it as it is.
pub fn blur(env: &EnvMap, degrees: f64) -> EnvMap {
    if degrees <= 0.0 {
        return env.clone();
    }
    let (w, h) = (env.width, env.height);
    let kappa = 1.0 / degrees.to_radians().powi(2);
    let texels: Vec<([f64; 3], f64)> = (0..w * h)
        .map(|i| env.convention.texel(i / w, i % w, h, w))
        .collect();
    let mut out = env.clone();
    out.texels
        .par_iter_mut()
        .zip(&texels)
        .for_each(|(t, &(d, _))| {
            let (mut sum, mut weight) = ([0.0f64; 3], 0.0f64);
            for (&(e, d_omega), s) in texels.iter().zip(&env.texels) {
                let cos = d[0] * e[0] + d[1] * e[1] + d[2] * e[2];
                let k = d_omega * (kappa * (cos - 1.0)).exp();
                for c in 0..3 {
                    sum[c] += k * f64::from(s[c]);
                }
                weight += k;
            }
            *t = sum.map(|v| (v / weight) as f32);
        });
    let (before, after) = (mean_radiance(env), mean_radiance(&out));
    scale(
        &mut out,
        std::array::from_fn(|c| {
            if after[c] > 0.0 {
                before[c] / after[c]
            } else {
                1.0
            }
        }),
    );
    out
}

/// Multiplies each texel of `env` by `gains`, channel by channel.
fn scale(env: &mut EnvMap, gains: [f64; 3]) {
    for t in env.texels.iter_mut() {
        for k in 0..3 {
            t[k] = (f64::from(t[k]) * gains[k]) as f32;
        }
    }
}

/// Sums of the pixels off and on the object, and their counts.
#[derive(Clone, Copy, Default)]
struct Sums {
    bg: [f64; 3],
    obj: [f64; 3],
    n_bg: usize,
    n_obj: usize,
}

impl Sums {
    /// The pixels on `mask`, and those off `near` (the mask and its edge).
    fn of(pixels: &[[f32; 3]], mask: &[bool], near: &[bool]) -> Sums {
        let mut s = Sums::default();
        for ((p, &m), &near) in pixels.iter().zip(mask).zip(near) {
            let (sum, n) = if m {
                (&mut s.obj, &mut s.n_obj)
            } else if !near {
                (&mut s.bg, &mut s.n_bg)
            } else {
                continue;
            };
            for k in 0..3 {
                sum[k] += f64::from(p[k]);
            }
            *n += 1;
        }
        s
    }

    fn add(self, o: &Sums) -> Sums {
        Sums {
            bg: std::array::from_fn(|k| self.bg[k] + o.bg[k]),
            obj: std::array::from_fn(|k| self.obj[k] + o.obj[k]),
            n_bg: self.n_bg + o.n_bg,
            n_obj: self.n_obj + o.n_obj,
        }
    }
}

/// The map's mean radiance per channel, weighted by the texels' solid angles.
pub fn mean_radiance(env: &EnvMap) -> [f64; 3] {
    let (mut sum, mut weight) = ([0.0f64; 3], 0.0f64);
    for r in 0..env.height {
        for c in 0..env.width {
            let (_, d_omega) = env.convention.texel(r, c, env.height, env.width);
            let t = env.texels[r * env.width + c];
            for k in 0..3 {
                sum[k] += d_omega * f64::from(t[k]);
            }
            weight += d_omega;
        }
    }
    sum.map(|s| s / weight.max(1e-300))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::Convention;

    #[test]
    fn the_light_takes_the_backgrounds_level_in_grey() {
        // a green floor under an orange light whose texels differ in colour
        let (h, w) = (8, 16);
        let mut env = EnvMap::constant(h, w, Convention::Equirect, [2.0, 1.0, 0.5]).unwrap();
        env.texels[3] = [4.0, 1.0, 0.25];
        let before = env.clone();
        let mut photo = Image::zeros(4, 4);
        let mask: Vec<bool> = (0..16).map(|i| i < 4).collect();
        let bg = [0.1, 0.25, 0.1];
        for (p, &m) in photo.pixels.iter_mut().zip(&mask) {
            *p = if m { [0.5; 3] } else { bg.map(|v| v as f32) };
        }
        let f = match_background(&mut env, &photo, &mask);
        assert_eq!(f.from, LevelFrom::Background);
        let mean = mean_radiance(&env);
        for k in 0..3 {
            assert!(
                (mean[k] - BACKGROUND_GAIN * luminance(bg)).abs() < 1e-6,
                "{mean:?}"
            );
        }
        // one factor a channel: the texels keep their colours against one another
        for (a, b) in env.texels.iter().zip(&before.texels) {
            for k in 0..3 {
                assert!((f64::from(a[k]) - f.gains[k] * f64::from(b[k])).abs() < 1e-6);
            }
        }
        let red_over_blue = |t: [f32; 3]| t[0] / t[2];
        let relative = red_over_blue(env.texels[3]) / red_over_blue(env.texels[0]);
        assert!((relative - 4.0).abs() < 1e-4, "{relative}");
    }

    #[test]
    fn the_objects_edge_is_not_background() {
        // a disc on black whose antialiased edge spills one pixel beyond the mask: the
        // spill alone is over 5 % of the object's mean, and must not make it a lit scene
        let (w, h) = (32, 32);
        let r2 = |i: usize| {
            let (x, y) = ((i % w) as f64 - 15.5, (i / w) as f64 - 15.5);
            x * x + y * y
        };
        let mask: Vec<bool> = (0..w * h).map(|i| r2(i) < 100.0).collect();
        let mut photo = Image::zeros(w, h);
        for (i, p) in photo.pixels.iter_mut().enumerate() {
            if r2(i) < 100.0 {
                *p = [0.5; 3];
            } else if r2(i) < 121.0 {
                *p = [0.6; 3];
            }
        }
        let spill = photo.pixels.iter().zip(&mask).filter(|(_, m)| !**m);
        let (sum, n) = spill.fold((0.0, 0), |(s, n), (p, _)| (s + f64::from(p[0]), n + 1));
        assert!(
            sum / f64::from(n) > MIN_BACKGROUND * 0.5,
            "the spill is too faint to test"
        );
        let mut env = EnvMap::constant(8, 16, Convention::Equirect, [2.0, 1.0, 0.5]).unwrap();
        let f = match_background(&mut env, &photo, &mask);
        assert_eq!(f.from, LevelFrom::GreyCard);
        assert!((luminance(mean_radiance(&env)) - EXPOSED_LEVEL).abs() < 1e-6);
    }

    #[test]
    fn relabelling_moves_light_into_the_material_and_renders_the_same() {
        let renderer = crate::Renderer::new(crate::Device::Cpu).unwrap();
        let normals = crate::NormalMap::sphere(48);
        let env = crate::envgen::generate(crate::envgen::LightKind::Studio, 3, 16, 32).unwrap();
        for preset in [
            "gold",
            "chrome-steel",
            "red-plastic",
            "white-paint",
            "black-phenolic",
        ] {
            let material = crate::presets::lookup(preset).unwrap();
            let mut moved = env.clone();
            let relabelled = relabel(&material, &mut moved, REFINED_BIAS);
            let level = |e: &EnvMap| luminance(mean_radiance(e));
            assert!((level(&env) / level(&moved) - REFINED_BIAS).abs() < 1e-5);
            let render = |m: &Material, e: &EnvMap| {
                let scene = crate::Scene {
                    normals: normals.clone(),
                    env: e.clone(),
                    material: m.clone(),
                    camera: crate::Camera::Orthographic,
                };
                let batch = crate::Batch::single(scene).unwrap();
                renderer.render(&batch).unwrap().remove(0)
            };
            let (a, b) = (render(&material, &env), render(&relabelled, &moved));
            let (mut d, mut s) = (0.0f64, 0.0f64);
            for (p, q) in a.pixels.iter().zip(&b.pixels) {
                for k in 0..3 {
                    d += f64::from(p[k] - q[k]).abs();
                    s += f64::from(p[k]).abs();
                }
            }
            assert!(
                d / s < 0.03,
                "{preset}: the render moved by {:.3} of itself",
                d / s
            );
        }
    }

    #[test]
    fn blurring_spreads_a_light_keeps_its_mean_and_leaves_a_uniform_one() {
        let (h, w) = (16, 32);
        let uniform = EnvMap::constant(h, w, Convention::Equirect, [0.5, 1.0, 2.0]).unwrap();
        for (a, b) in blur(&uniform, 60.0).texels.iter().zip(&uniform.texels) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() < 1e-5 * b[k], "{a:?} {b:?}");
            }
        }
        // a lamp above the horizon, on the map's seam (column 0): it spreads to both sides
        let mut lamp = EnvMap::constant(h, w, Convention::Equirect, [0.0; 3]).unwrap();
        lamp.texels[4 * w] = [10.0, 10.0, 10.0];
        let soft = blur(&lamp, 30.0);
        let (m0, m1) = (mean_radiance(&lamp), mean_radiance(&soft));
        assert!((m0[0] - m1[0]).abs() < 1e-6 * m0[0], "{m0:?} {m1:?}");
        let at = |r: usize, c: usize| soft.texels[r * w + c][0];
        assert!(
            at(4, 0) < 10.0 && at(4, 0) > at(4, 2),
            "the lamp is not spread"
        );
        // symmetric across the seam, and little at the opposite side of the sphere
        assert!((at(4, 1) - at(4, w - 1)).abs() < 1e-3 * at(4, 1));
        assert!(at(h - 1 - 4, w / 2) < 0.01 * at(4, 0));
        // wider blurs spread further
        let wide = blur(&lamp, 60.0);
        assert!(wide.texels[4 * w + w / 4][0] > soft.texels[4 * w + w / 4][0]);
        assert_eq!(blur(&lamp, 0.0).texels, lamp.texels);
    }

    #[test]
    fn on_black_the_light_takes_the_exposed_level_in_grey() {
        let colour = [2.0, 1.0, 0.5];
        let mut env = EnvMap::constant(8, 16, Convention::Equirect, colour).unwrap();
        let mut photo = Image::zeros(4, 4);
        let mask: Vec<bool> = (0..16).map(|i| i < 4).collect();
        for (p, &m) in photo.pixels.iter_mut().zip(&mask) {
            *p = if m { [0.5; 3] } else { [0.001; 3] };
        }
        let f = match_background(&mut env, &photo, &mask);
        assert_eq!(f.from, LevelFrom::GreyCard);
        let mean = mean_radiance(&env);
        for k in 0..3 {
            assert!((mean[k] - EXPOSED_LEVEL).abs() < 1e-6, "{mean:?}");
        }
        // no background at all: the same
        let mut env = EnvMap::constant(8, 16, Convention::Equirect, colour).unwrap();
        assert_eq!(match_background(&mut env, &photo, &[true; 16]), f);
    }
}
