//! The continuous light: the layer with each texel of an equirect map taken as an area
//! light of constant radiance over its patch of directions, instead of a point light at
//! its centre (docs/CONVENTIONS.md, "The continuous light"; docs/continuous_light.md).
//!
//! A texel split into s x s sub-texels of the same radiance, each a point light with its
//! own direction and solid angle, converges to the area light as s grows. Only a lobe
//! narrower than a texel tells the two apart, and only near its peak, so a level `q`
//! splits only the texels within a few lobe widths of each pixel's specular peak (the
//! mirror direction of w_p about n), each into as many sub-texels as put about `q` of
//! them across the lobe's narrowest width ([`lobe_width`]; a grazing view narrows it).
//! Each pixel then gets what the split adds: the area lights' sum less the point lights'
//! sum over those texels ([`Corrections`]). Pixels whose lobe is wider than a texel, and
//! every pixel of a diffuse material, keep the layer's value. dLoss/dL is the adjoint:
//! each sub-texel's gradient goes back to its texel.
//!
//! [`choose`] picks the level per scene from a measurement: on a sample of the pixels,
//! each level against the next finer one, the first whose difference (max over max, as
//! the levels of detail measure) is within half the tolerance.

mod groups;

pub use groups::{Corrections, MAX_RADIUS, MAX_SPLIT, check_detail, lobe_width, peak_texel};

use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::prepare::{PixelRec, Prepared};
use crate::renderer::{Accuracy, Renderer};
use crate::scene::{Batch, Gradients, Image, Scene, Wanted};
use crate::{Backend, lod};

/// The levels [`choose`] tries, coarse to fine: sub-texels across a lobe's width.
pub const LEVELS: [u32; 5] = [1, 2, 4, 8, 16];
/// Largest level accepted.
pub const MAX_LEVEL: u32 = 64;
/// Pixels the estimate spreads evenly over the image (at most) ...
const SAMPLED: usize = 2048;
/// ... and at most this many more whose peak is on one of the brightest texels ...
const HIGHLIGHT_PIXELS: usize = 512;
/// ... of this many.
const BRIGHT_TEXELS: usize = 16;
/// A level is taken when this many times its measured difference is within tolerance.
const SAFETY: f64 = 2.0;

/// How the light is integrated.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Integration {
    /// The layer: each texel a point light.
    #[default]
    Discrete,
    /// The texels near each pixel's peak split so that about this many sub-texels span the
    /// lobe's width (0: the layer).
    Level(u32),
    /// The coarsest level whose estimated relative error against the continuous light is
    /// within this.
    Tolerance(f64),
}

impl Integration {
    /// Checks the value and that the scene's map has solid angles to split.
    pub fn validate(&self, scene: &Scene) -> Result<()> {
        match *self {
            Integration::Discrete | Integration::Level(0) => return Ok(()),
            Integration::Level(q) if q > MAX_LEVEL => {
                return Err(Error::Invalid(format!(
                    "light: level {q} is above {MAX_LEVEL}"
                )));
            }
            Integration::Tolerance(t) if !(t.is_finite() && t > 0.0) => {
                return Err(Error::Invalid(format!(
                    "light: tolerance {t} is not a positive number"
                )));
            }
            _ => {}
        }
        if scene.env.convention != Convention::Equirect {
            return Err(Error::Invalid(
                "light: the continuous light needs the equirect convention (the paper's \
                 d_omega is not a solid angle to split)"
                    .into(),
            ));
        }
        Ok(())
    }
}

/// The level a scene got and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelChoice {
    /// The level (0: the layer).
    pub level: u32,
    /// The measured difference from the finest level, max over max, on the sample (0 for
    /// the finest itself).
    pub estimate: f64,
    /// Sampled pixels.
    pub sampled: usize,
    /// The tolerance.
    pub tolerance: f64,
}

impl std::fmt::Display for LevelChoice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let what = if self.level == 0 {
            "discrete (each texel a point light)".to_string()
        } else {
            format!("level {}", self.level)
        };
        write!(
            f,
            "{what} (estimated error {:.2e} against level {} on {} sampled pixels, tolerance {:e})",
            self.estimate,
            LEVELS[LEVELS.len() - 1],
            self.sampled,
            self.tolerance,
        )
    }
}

/// The largest difference between `a` and `b` over the largest value of `b`.
fn relative(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let max = b.iter().flatten().fold(0.0f64, |m, &v| m.max(f64::from(v)));
    let diff = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (&x, &y)| {
            m.max((f64::from(x) - f64::from(y)).abs())
        });
    if max > 0.0 { diff / max } else { diff }
}

/// The coarsest level of [`LEVELS`] (or the layer) whose difference from the finest level,
/// measured on a sample of the pixels (spread evenly, and those whose peak is on one of
/// the brightest texels), is within `tol / 2`; the finest level if none is.
///
/// `detail`: a finer map of the scene's light ([`Corrections::new`]).
pub fn choose(
    backend: &dyn Backend,
    scene: &Scene,
    detail: Option<&EnvMap>,
    tol: f64,
) -> Result<LevelChoice> {
    Integration::Tolerance(tol).validate(scene)?;
    if let Some(d) = detail {
        check_detail(&scene.env, d)?;
    }
    let prep = Prepared::new(scene);
    let pixels: Vec<PixelRec> = sample_positions(&prep, &scene.env)
        .into_iter()
        .enumerate()
        .map(|(k, i)| PixelRec {
            index: k,
            ..prep.pixels[i]
        })
        .collect();
    let sampled = pixels.len();
    let sample = prep.with_pixels(sampled, 1, pixels);
    let base = backend.render((&sample).into())?.remove(0);
    let at = |q: u32| -> Result<Image> {
        let mut image = base.clone();
        Corrections::new(&sample, &scene.env, detail, q).add_forward(backend, &mut image)?;
        Ok(image)
    };
    // the reference: the finest level, whose texels near a peak are split as finely as
    // the light is known (a detail map's texels) or into MAX_SPLIT x MAX_SPLIT. Against
    // the next level instead, a level that changes little (level 1 where few texels are
    // split) passed before one that changes much.
    let finest = LEVELS[LEVELS.len() - 1];
    let reference = at(finest)?;
    for q in std::iter::once(0).chain(LEVELS).take(LEVELS.len()) {
        let image = if q == 0 { base.clone() } else { at(q)? };
        let estimate = relative(&image.pixels, &reference.pixels);
        if SAFETY * estimate <= tol {
            return Ok(LevelChoice {
                level: q,
                estimate,
                sampled,
                tolerance: tol,
            });
        }
    }
    Ok(LevelChoice {
        level: finest,
        estimate: 0.0,
        sampled,
        tolerance: tol,
    })
}

/// The pixels the estimate runs on (positions in `prep.pixels`): [`SAMPLED`] spread evenly,
/// and up to [`HIGHLIGHT_PIXELS`] of those whose specular peak lies on or next to one of
/// the [`BRIGHT_TEXELS`] brightest texels: a small highlight, where the continuous light
/// differs most, can fall between evenly spread pixels.
fn sample_positions(prep: &Prepared, env: &EnvMap) -> Vec<usize> {
    let step = prep.pixels.len().div_ceil(SAMPLED).max(1);
    let mut positions: Vec<usize> = (0..prep.pixels.len()).step_by(step).collect();
    let mut energy: Vec<(f64, usize)> = env
        .texels
        .iter()
        .enumerate()
        .map(|(i, l)| {
            let (_, d_omega) =
                env.convention
                    .texel(i / env.width, i % env.width, env.height, env.width);
            (
                l.iter().map(|&v| f64::from(v).abs()).sum::<f64>() * d_omega,
                i,
            )
        })
        .collect();
    energy.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut near = vec![false; env.texels.len()];
    for &(e, i) in energy.iter().take(BRIGHT_TEXELS) {
        if e <= 0.0 {
            break;
        }
        let (r, c) = (i / env.width, i % env.width);
        for dr in [-1isize, 0, 1] {
            let rr = r as isize + dr;
            if rr < 0 || rr >= env.height as isize {
                continue;
            }
            for dc in [env.width - 1, 0, 1] {
                near[rr as usize * env.width + (c + dc) % env.width] = true;
            }
        }
    }
    let highlight: Vec<usize> = (0..prep.pixels.len())
        .filter(|&i| peak_texel(env, &prep.pixels[i]).is_some_and(|(r, c)| near[r * env.width + c]))
        .collect();
    let every = highlight.len().div_ceil(HIGHLIGHT_PIXELS).max(1);
    positions.extend(highlight.into_iter().step_by(every));
    positions.sort_unstable();
    positions.dedup();
    positions
}

/// Each scene's level under `light`, and the choice where a tolerance made it.
fn levels(
    backend: &dyn Backend,
    batch: &Batch,
    light: Integration,
    details: &[Option<EnvMap>],
) -> Result<Vec<(u32, Option<LevelChoice>)>> {
    batch
        .scenes()
        .iter()
        .enumerate()
        .map(|(b, s)| {
            light.validate(s)?;
            let detail = detail_of(details, b);
            if let Some(d) = detail {
                check_detail(&s.env, d)?;
            }
            Ok(match light {
                Integration::Discrete => (0, None),
                Integration::Level(q) => (q, None),
                Integration::Tolerance(t) => {
                    let c = choose(backend, s, detail, t)?;
                    (c.level, Some(c))
                }
            })
        })
        .collect()
}

/// Scene `b`'s detail map, if any.
fn detail_of(details: &[Option<EnvMap>], b: usize) -> Option<&EnvMap> {
    details.get(b).and_then(Option::as_ref)
}

/// What [`render`] and [`backward`] chose per scene: the level of detail and the light.
pub type Choices = (Vec<Option<lod::Choice>>, Vec<Option<LevelChoice>>);

/// One image per scene under `accuracy` (the levels of detail) and `light`: the layer's
/// image plus each scene's corrections. `details`: per scene, a finer map of its light
/// (2, 4 or 8 times the rows and columns), or none (an empty slice: none for any).
pub fn render(
    renderer: &Renderer,
    batch: &Batch,
    accuracy: &Accuracy,
    light: Integration,
    details: &[Option<EnvMap>],
) -> Result<(Vec<Image>, Choices)> {
    let levels = levels(renderer.backend(), batch, light, details)?;
    let (mut images, lod_choices) = renderer.render_with(batch, accuracy)?;
    for (b, ((scene, image), &(q, _))) in batch
        .scenes()
        .iter()
        .zip(&mut images)
        .zip(&levels)
        .enumerate()
    {
        Corrections::new(&Prepared::new(scene), &scene.env, detail_of(details, b), q)
            .add_forward(renderer.backend(), image)?;
    }
    check(images.iter().map(|i| &i.pixels), "image")?;
    let light_choices = levels.into_iter().map(|(_, c)| c).collect();
    Ok((images, (lod_choices, light_choices)))
}

/// Gradients per scene under `accuracy` and `light`, only those `wanted` (the others
/// zeros): the layer's plus each scene's corrections' (which compute all three).
pub fn backward(
    renderer: &Renderer,
    batch: &Batch,
    upstream: &[Image],
    accuracy: &Accuracy,
    light: Integration,
    wanted: Wanted,
    details: &[Option<EnvMap>],
) -> Result<(Vec<Gradients>, Choices)> {
    let levels = levels(renderer.backend(), batch, light, details)?;
    let (mut grads, lod_choices) = renderer.backward_with(batch, upstream, accuracy, wanted)?;
    if wanted.any() {
        for (b, (((scene, g), u), &(q, _))) in batch
            .scenes()
            .iter()
            .zip(&mut grads)
            .zip(upstream)
            .zip(&levels)
            .enumerate()
        {
            Corrections::new(&Prepared::new(scene), &scene.env, detail_of(details, b), q)
                .add_backward(renderer.backend(), u, g)?;
            g.keep(wanted);
        }
    }
    check(grads.iter().map(|g| &g.d_env), "d_env")?;
    check(grads.iter().map(|g| &g.d_normals), "d_normals")?;
    if grads
        .iter()
        .any(|g| g.d_ctrl.iter().any(|v| !v.is_finite()))
    {
        return Err(Error::Invalid(
            "d_ctrl: overflowed f32; scale the upstream gradient down".into(),
        ));
    }
    let light_choices = levels.into_iter().map(|(_, c)| c).collect();
    Ok((grads, (lod_choices, light_choices)))
}

/// An error naming the first scene whose output `what` is not finite.
fn check<'a>(outputs: impl Iterator<Item = &'a Vec<[f32; 3]>>, what: &str) -> Result<()> {
    for (b, v) in outputs.enumerate() {
        if v.iter().flatten().any(|x| !x.is_finite()) {
            return Err(Error::Invalid(format!(
                "{what}: scene {b} overflowed f32 with the continuous light; scale the radiance \
                 or the upstream gradient down"
            )));
        }
    }
    Ok(())
}
