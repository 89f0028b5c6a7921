//! The joint least-squares fit of a material's control points: every lobe's scales and
//! exponents of each channel at once, on linear residuals sqrt(w_i) (f_i - t_i) over the
//! plane's samples, whose weights w_i are the cosines and measure that make an image's
//! pixels ([`super::samples`]). Channels do not share control points, so the joint problem
//! over all of them is three independent problems, solved one after the other.
//!
//! Scales are free control points (either sign at each point, [`Problem::with_free_scales`]),
//! exponents exp(p). [`refine`] starts from a fitted material (the fitter's last step);
//! [`plain`] from a fixed generic start (the baseline the fitter is measured against).

use super::lm::{self, Problem};
use super::samples::{Grid, Plane, Tabulated};
use super::{Lobe, lobe_of, write_channel};
use crate::brdf::Isotropic;
use crate::error::{Result, invalid};
use crate::material::{MAX_ABS_SCALE, Material, N_CHANNELS, N_LOBES, N_PARAMS, idx};
use crate::spline::N_CTRL_POINTS;

/// LM steps of a refinement.
pub const REFINE_STEPS: usize = 50;
/// LM steps of the plain fit from its generic start.
pub const PLAIN_STEPS: usize = 300;

/// `material`'s first `lobes` lobes refined jointly (each channel's scales and exponents
/// together) on linear residuals for at most `steps` LM steps; lobes past `lobes` stay
/// zero. The result's cost is never above the start's (LM only takes steps that lower it),
/// up to the start's control points being moved inside the bounds.
pub fn refine(plane: &Plane, material: &Material, lobes: usize, steps: usize) -> Result<Material> {
    if !(1..=N_LOBES).contains(&lobes) {
        return Err(invalid!(
            "joint fit: {lobes} lobes asked for; the DSBRDF has 1 to {N_LOBES}"
        ));
    }
    let mut ctrl = [0.0; N_PARAMS];
    for k in 0..N_CHANNELS {
        let target: Vec<f64> = plane.target.iter().map(|t| t[k]).collect();
        let problem = Problem::new(plane, &target, f64::INFINITY).with_free_scales();
        let mut p = Vec::with_capacity(lobes * lm::PER_LOBE);
        for s in 0..lobes {
            p.extend((0..N_CTRL_POINTS).map(|j| material.ctrl[idx(k, s, 0, j)]));
            p.extend((0..N_CTRL_POINTS).map(|j| {
                material.ctrl[idx(k, s, 1, j)]
                    .max(lm::EXPONENT_BOUNDS.0.exp())
                    .ln()
            }));
        }
        problem.solve(&mut p, steps);
        write_channel(&mut ctrl, k, free_lobes(&p));
    }
    Material::new(material.name.clone(), &ctrl)
}

/// The lobes of one channel's free-scale parameters.
fn free_lobes(p: &[f64]) -> Vec<Lobe> {
    p.chunks_exact(lm::PER_LOBE)
        .map(|lobe| lobe_of(lobe, |v| v.clamp(-MAX_ABS_SCALE, MAX_ABS_SCALE)))
        .collect()
}

/// Exponents of the plain fit's generic start: a constant lobe, a glossy and a sharp one.
const PLAIN_EXPONENTS: [f64; N_LOBES] = [1e-3, 30.0, 1000.0];

/// The plain joint least-squares fit of all 108 control points to `brdf` on `grid`, with
/// no search over starts, loss or lobe count: 3 lobes started at exponents
/// [`PLAIN_EXPONENTS`], the constant lobe's scale at ln(1 + the channel's weighted mean)
/// and the others' at 0.1, then [`refine`]d for [`PLAIN_STEPS`] steps.
pub fn plain(brdf: &dyn Isotropic, name: &str, grid: Grid) -> Result<Material> {
    let plane = Tabulated::new(brdf, grid).plane();
    if plane.x.is_empty() {
        return Err(invalid!(
            "joint fit: material '{name}' has no known values where surfaces are seen"
        ));
    }
    if plane
        .target
        .iter()
        .any(|t| !t.iter().all(|v| v.is_finite()))
    {
        return Err(invalid!("joint fit: material '{name}' is not finite"));
    }
    let total: f64 = plane.weight.iter().sum::<f64>().max(1e-300);
    let mut ctrl = [0.0; N_PARAMS];
    for k in 0..N_CHANNELS {
        let mean = plane
            .weight
            .iter()
            .zip(&plane.target)
            .map(|(w, t)| w * t[k])
            .sum::<f64>()
            / total;
        for (s, &e) in PLAIN_EXPONENTS.iter().enumerate() {
            for j in 0..N_CTRL_POINTS {
                ctrl[idx(k, s, 0, j)] = if s == 0 { mean.max(0.0).ln_1p() } else { 0.1 };
                ctrl[idx(k, s, 1, j)] = e;
            }
        }
    }
    let start = Material::new(name, &ctrl)?;
    refine(&plane, &start, N_LOBES, PLAIN_STEPS)
}
