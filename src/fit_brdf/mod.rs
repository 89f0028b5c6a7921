//! Fitting the DSBRDF to an isotropic BRDF (a MERL table, an NBRDF network, an analytic
//! model): the 108 control points are fitted jointly against the BRDF over
//! (theta_h, theta_d), each channel's lobes by Levenberg-Marquardt ([`lm`]) on the
//! samples of [`samples`], the judge's pick then refined by [`joint`] least squares.

pub mod job;
pub mod joint;
pub mod judge;
pub mod lm;
pub mod samples;

use judge::Judge;
use lm::Problem;
use samples::{Grid, Tabulated};

use crate::brdf::Isotropic;
use crate::error::{Result, invalid};
use crate::material::{MAX_ABS_SCALE, MAX_EXPONENT, Material, N_CHANNELS, N_LOBES, N_PARAMS, idx};
use crate::spline::N_CTRL_POINTS;

/// How many lobes to fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Lobes {
    /// Exactly this many (1 to 3).
    Fixed(usize),
    /// 1, 2 and 3, keeping the fewest whose error (the judge's, else the BRDF error) is
    /// within [`BrdfFitOptions::tolerance`] of the best's.
    Auto,
}

/// The fitter's settings.
#[derive(Clone, Debug)]
pub struct BrdfFitOptions {
    /// Lobe count.
    pub lobes: Lobes,
    /// Relative slack over the best error allowed to a fit with fewer lobes (0: the best
    /// is kept; the presets were made with 0.05 and no joint refinement).
    pub tolerance: f64,
    /// The loss's scale c: residuals are taken on c ln(1 + f / c), linear below c and
    /// logarithmic above (infinite: linear).
    pub loss_scale: f64,
    /// Where the BRDF is sampled.
    pub grid: Grid,
    /// Judge candidates and lobe counts by images under built-in lights ([`judge`]);
    /// without, the BRDF error decides.
    pub judge: bool,
    /// Refine the judge's pick by [`joint`] least squares (free-sign scales, linear loss;
    /// the plane's weights, and every theta_d alike) and let the judge, with its broad
    /// lights too, keep the best of the three; without the judge, the first candidate
    /// refined with the plane's weights is kept.
    pub joint: bool,
}

impl Default for BrdfFitOptions {
    fn default() -> Self {
        BrdfFitOptions {
            lobes: Lobes::Auto,
            tolerance: 0.0,
            loss_scale: 1.0,
            grid: Grid::default(),
            judge: true,
            joint: true,
        }
    }
}

/// One fit.
#[derive(Clone, Debug)]
pub struct Fit {
    /// Lobes used (the others have m0 = 0).
    pub lobes: usize,
    /// The fitted material.
    pub material: Material,
    /// The BRDF's relative RMSE, cosine-weighted over the hemisphere ([`brdf_error`]).
    pub error: f64,
    /// The judge's image error (RMSE over peak, mean over its lights; [`judge`]), NaN
    /// when not judged.
    pub image_error: f64,
}

/// The fits tried for one BRDF.
#[derive(Clone, Debug)]
pub struct FittedBrdf {
    /// One fit per lobe count tried, ascending.
    pub fits: Vec<Fit>,
    /// Index into `fits` of the one kept.
    pub chosen: usize,
    /// The smallest BRDF error any DSBRDF could reach: the share of the BRDF that varies
    /// with phi_d, which the model cannot represent ([`samples::Tabulated::floor`]).
    pub floor: f64,
}

impl FittedBrdf {
    /// The fit kept.
    pub fn best(&self) -> &Fit {
        &self.fits[self.chosen]
    }
}

/// Exponents tried for a new lobe: broad to mirror-like.
const START_EXPONENTS: [f64; 5] = [1e-3, 3.0, 30.0, 300.0, 3000.0];
/// Loss scales a fit is refined with, as candidates for the judge.
const REFINE_SCALES: [f64; 2] = [10.0, f64::INFINITY];
/// LM steps for each start, and for the best start.
const START_STEPS: usize = 20;
const FINAL_STEPS: usize = 120;

/// Fits the DSBRDF to `brdf`; `name` names the material.
///
/// The lobes' shapes are found on the channels' mean, nested: the best 1-lobe fit over
/// [`START_EXPONENTS`], then each next lobe added to the previous best with each start
/// exponent. Each channel is then refined from the mean's fit; candidates refined with
/// other losses, and (with [`BrdfFitOptions::joint`]) the judge's pick refined by [`joint`] least
/// squares, are judged by their images ([`judge`]). Deterministic: fixed order, and the
/// judge's renders are bitwise equal for any thread count (the fast CPU path's SIMD
/// instruction set, chosen at run time, may round differently on another machine).
pub fn fit(brdf: &dyn Isotropic, name: &str, options: &BrdfFitOptions) -> Result<FittedBrdf> {
    let counts: Vec<usize> = match options.lobes {
        Lobes::Fixed(n) if (1..=N_LOBES).contains(&n) => vec![n],
        Lobes::Fixed(n) => {
            return Err(invalid!(
                "fit: {n} lobes asked for; the DSBRDF has 1 to {N_LOBES}"
            ));
        }
        Lobes::Auto => (1..=N_LOBES).collect(),
    };
    if !(options.tolerance >= 0.0 && options.tolerance.is_finite()) {
        return Err(invalid!(
            "fit: tolerance {} is not a number >= 0",
            options.tolerance
        ));
    }
    let table = Tabulated::new(brdf, options.grid);
    let plane = table.plane();
    if plane.x.is_empty() {
        return Err(invalid!(
            "fit: material '{name}' has no known values where surfaces are seen"
        ));
    }
    if let Some(i) = plane
        .target
        .iter()
        .position(|t| !t.iter().all(|v| v.is_finite()))
    {
        let (x, _) = (plane.x[i], i);
        return Err(invalid!(
            "fit: material '{name}' is not finite at theta_h = {:.4} rad",
            x.acos()
        ));
    }
    let gray: Vec<f64> = plane
        .target
        .iter()
        .map(|t| (t[0] + t[1] + t[2]) / 3.0)
        .collect();
    let gray_problem = Problem::new(&plane, &gray, options.loss_scale);
    let mean = weighted_mean(&plane.weight, &gray);
    let first_scale = mean.ln_1p().clamp(1e-3, 5.0).ln();

    let max_count = *counts.last().expect("at least one count");
    // Each lobe count's shapes: log-parameters and the sign of each lobe's scales. A new
    // lobe is tried with either sign; the signs of a fit are those of the fit with one
    // lobe fewer, plus the new lobe's.
    let mut shapes: Vec<(Vec<f64>, Vec<f64>)> = Vec::with_capacity(max_count);
    for lobes in 1..=max_count {
        let (prev, prev_signs) = shapes.last().cloned().unwrap_or_default();
        let mut best: Option<(f64, Vec<f64>, Vec<f64>)> = None;
        let new_signs: &[f64] = if lobes == 1 { &[1.0] } else { &[1.0, -1.0] };
        for &sign in new_signs {
            let mut signs = prev_signs.clone();
            signs.push(sign);
            let problem = gray_problem.clone().with_signs(&signs);
            for &e in &START_EXPONENTS {
                let mut p = prev.clone();
                let scale = if lobes == 1 { first_scale } else { 0.1f64.ln() };
                p.extend([scale; N_CTRL_POINTS]);
                p.extend([e.ln(); N_CTRL_POINTS]);
                let cost = problem.solve(&mut p, START_STEPS);
                if best.as_ref().is_none_or(|(c, _, _)| cost < *c) {
                    best = Some((cost, p, signs.clone()));
                }
            }
        }
        let (_, mut p, signs) = best.expect("starts tried");
        gray_problem
            .clone()
            .with_signs(&signs)
            .solve(&mut p, FINAL_STEPS);
        shapes.push((p, signs));
    }

    // Each channel from the mean's shapes, nested like them: a fit with more lobes also
    // starts from the channel's own fit with one lobe fewer plus a negligible lobe, so
    // that adding a lobe never makes the fit worse.
    let mut channels: Vec<Vec<Vec<f64>>> = vec![Vec::new(); N_CHANNELS];
    for (k, fits) in channels.iter_mut().enumerate() {
        let target: Vec<f64> = plane.target.iter().map(|t| t[k]).collect();
        for lobes in 1..=max_count {
            let (shape, signs) = &shapes[lobes - 1];
            let problem = Problem::new(&plane, &target, options.loss_scale).with_signs(signs);
            let mut p = shape.clone();
            let cost = problem.solve(&mut p, FINAL_STEPS);
            if let Some(prev) = fits.last() {
                let mut q: Vec<f64> = prev.clone();
                q.extend([lm::SCALE_BOUNDS.0 + 4.0; N_CTRL_POINTS]);
                q.extend(shape[(lobes - 1) * lm::PER_LOBE + N_CTRL_POINTS..].iter());
                let c = problem.solve(&mut q, FINAL_STEPS);
                if c < cost {
                    p = q;
                }
            }
            fits.push(p);
        }
    }
    // Candidates per lobe count: the fit above, and the same refined with a loss that
    // weighs large values more (c = 10, and linear); the judge keeps the one whose
    // images are closest to the measured BRDF's.
    let judge = if options.judge {
        Some(if options.joint {
            Judge::broad(brdf)?
        } else {
            Judge::new(brdf)?
        })
    } else {
        None
    };
    let targets: Vec<Vec<f64>> = (0..N_CHANNELS)
        .map(|k| plane.target.iter().map(|t| t[k]).collect())
        .collect();
    let joint_planes = if options.joint {
        vec![plane.clone(), plane.rows_alike()]
    } else {
        Vec::new()
    };
    let mut fits = Vec::with_capacity(counts.len());
    for &lobes in &counts {
        let signs = &shapes[lobes - 1].1;
        let base: Vec<&Vec<f64>> = channels.iter().map(|c| &c[lobes - 1]).collect();
        let mut candidates = vec![material_of(name, &base, signs)?];
        if judge.is_some() {
            for &c in &REFINE_SCALES {
                let refined: Vec<Vec<f64>> = base
                    .iter()
                    .zip(&targets)
                    .map(|(p, t)| {
                        let mut p = (*p).clone();
                        Problem::new(&plane, t, c)
                            .with_signs(signs)
                            .solve(&mut p, FINAL_STEPS);
                        p
                    })
                    .collect();
                candidates.push(material_of(
                    name,
                    &refined.iter().collect::<Vec<_>>(),
                    signs,
                )?);
            }
        }
        let pick = |candidates: Vec<Material>| match &judge {
            Some(j) => candidates
                .into_iter()
                .map(|m| {
                    let e = j.error(&m);
                    (m, e)
                })
                .min_by(|a, b| a.1.total_cmp(&b.1))
                .expect("one candidate at least"),
            None => (
                candidates.into_iter().next().expect("one candidate"),
                f64::NAN,
            ),
        };
        let (mut material, mut image_error) = pick(candidates);
        if options.joint {
            // The kept candidate refined jointly, weighted as the BRDF is seen and with
            // every theta_d alike; the judge keeps the refinement only if it is better.
            let mut refined = Vec::with_capacity(joint_planes.len() + 1);
            for p in &joint_planes {
                refined.push(joint::refine(p, &material, lobes, joint::REFINE_STEPS)?);
            }
            if judge.is_some() {
                refined.push(material);
            }
            (material, image_error) = pick(refined);
        }
        let error = table.error(&material);
        fits.push(Fit {
            lobes,
            material,
            error,
            image_error,
        });
    }
    let score = |f: &Fit| {
        if judge.is_some() {
            f.image_error
        } else {
            f.error
        }
    };
    let best = fits.iter().map(score).fold(f64::INFINITY, f64::min);
    let chosen = fits
        .iter()
        .position(|f| score(f) <= best * (1.0 + options.tolerance))
        .expect("the best fit qualifies");
    Ok(FittedBrdf {
        fits,
        chosen,
        floor: table.floor(),
    })
}

/// The material of each channel's log-parameters, lobe s's scales of sign `signs[s]`.
fn material_of(name: &str, channels: &[&Vec<f64>], signs: &[f64]) -> Result<Material> {
    let mut ctrl = [0.0; N_PARAMS];
    for (k, p) in channels.iter().enumerate() {
        write_channel(&mut ctrl, k, log_lobes(p, signs));
    }
    Material::new(name, &ctrl)
}

/// One lobe's control points: scales m0 and exponents m1.
#[derive(Clone, Copy, Debug)]
struct Lobe {
    m0: [f64; N_CTRL_POINTS],
    m1: [f64; N_CTRL_POINTS],
}

/// The lobes of one channel's log-parameters, lobe s's scales of sign `signs[s]`.
fn log_lobes(p: &[f64], signs: &[f64]) -> Vec<Lobe> {
    p.chunks_exact(lm::PER_LOBE)
        .zip(signs.iter().copied())
        .map(|(lobe, sign)| lobe_of(lobe, |v| sign * v.exp().min(MAX_ABS_SCALE)))
        .collect()
}

/// One lobe of a channel's parameters (scales then log-exponents), each scale parameter
/// made a control point by `scale`; a lobe whose exponents all sit at the lower bound
/// becomes constant (m1 = 0), which the renderers treat as such.
fn lobe_of(params: &[f64], scale: impl Fn(f64) -> f64) -> Lobe {
    let (scales, exponents) = params.split_at(N_CTRL_POINTS);
    let flat = exponents.iter().all(|&q| q <= lm::EXPONENT_BOUNDS.0 + 1e-9);
    Lobe {
        m0: std::array::from_fn(|j| scale(scales[j])),
        m1: std::array::from_fn(|j| {
            if flat {
                0.0
            } else {
                exponents[j].exp().min(MAX_EXPONENT)
            }
        }),
    }
}

/// Writes one channel's lobes as control points, sorted by their mean log-exponent
/// (broadest first).
fn write_channel(ctrl: &mut [f64; N_PARAMS], k: usize, mut lobes: Vec<Lobe>) {
    let mean_exponent = |l: &Lobe| {
        l.m1.iter()
            .map(|&e| e.max(lm::EXPONENT_BOUNDS.0.exp()).ln())
            .sum::<f64>()
    };
    lobes.sort_by(|a, b| mean_exponent(a).total_cmp(&mean_exponent(b)));
    for (s, lobe) in lobes.iter().enumerate() {
        for j in 0..N_CTRL_POINTS {
            ctrl[idx(k, s, 0, j)] = lobe.m0[j];
            ctrl[idx(k, s, 1, j)] = lobe.m1[j];
        }
    }
}

fn weighted_mean(w: &[f64], v: &[f64]) -> f64 {
    let total: f64 = w.iter().sum();
    w.iter().zip(v).map(|(w, v)| w * v).sum::<f64>() / total.max(1e-300)
}

/// The relative RMSE of `model` against `measured`, weighted by cos theta_i cos theta_o
/// and the measure of direction pairs over the upper hemisphere, on the fitter's default
/// grid (see [`samples`]).
pub fn brdf_error(model: &dyn Isotropic, measured: &dyn Isotropic) -> f64 {
    Tabulated::new(measured, Grid::default()).error(model)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_dsbrdf() {
        // A diffuse lobe and a glossy one whose scale rises towards grazing theta_d.
        let mut ctrl = [0.0; N_PARAMS];
        for k in 0..N_CHANNELS {
            for j in 0..N_CTRL_POINTS {
                ctrl[idx(k, 0, 0, j)] = [0.12, 0.08, 0.05][k];
                ctrl[idx(k, 1, 0, j)] = 1.5 + 0.3 * j as f64;
                ctrl[idx(k, 1, 1, j)] = 60.0;
            }
        }
        let truth = Material::new("truth", &ctrl).unwrap();
        let options = BrdfFitOptions {
            lobes: Lobes::Fixed(2),
            ..BrdfFitOptions::default()
        };
        let f = fit(&truth, "fitted", &options).unwrap();
        assert_eq!(f.fits.len(), 1);
        assert!(f.best().error < 0.01, "error {}", f.best().error);
        assert_eq!(f.best().material.name, "fitted");
        // The unused lobe costs nothing.
        assert!((0..N_CHANNELS).all(|k| (0..N_CTRL_POINTS).all(|j| f.best().material.ctrl[idx(k, 2, 0, j)] == 0.0)));
    }

    #[test]
    fn rejects_bad_options() {
        let m = Material::constant("m", [(0.1, 0.0), (0.0, 0.0), (0.0, 0.0)]).unwrap();
        let e = fit(
            &m,
            "m",
            &BrdfFitOptions {
                lobes: Lobes::Fixed(4),
                ..BrdfFitOptions::default()
            },
        );
        assert!(e.unwrap_err().to_string().contains("4 lobes"));
    }
}
