//! The fit itself: Adam on the parameters of `params.rs` through the layer's
//! backward pass, the step halved when the loss stalls.

use std::time::Instant;

use super::adam;
use super::inputs::Inputs;
use super::loss::{data_term, priors};
use super::options::{Light, Options};
use super::params::{decode_env, decode_material, encode_material};
use crate::envmap::EnvMap;
use crate::error::{Error, Result, invalid};
use crate::material::{Material, N_COEFS};
use crate::spline::N_CTRL_POINTS;
use crate::{Accuracy, Batch, Camera, Image, Renderer, Scene, Wanted};

/// A fit's result.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// The fitted material.
    pub material: Material,
    /// The light: the given map, or the fitted one.
    pub env: EnvMap,
    /// The loss after each step (data term and priors).
    pub losses: Vec<f64>,
    /// Steps taken.
    pub steps: usize,
    /// Wall-clock seconds of the fit.
    pub seconds: f64,
    /// The size the fit ran at (width, height).
    pub work_size: (usize, usize),
}

/// Halve the step when the loss has not improved by this much (relatively) for
/// [`PATIENCE`] steps; stop when the step is [`MIN_STEP_RATIO`] of the first.
const MIN_GAIN: f64 = 1e-3;
const PATIENCE: usize = 20;
const MIN_STEP_RATIO: f64 = 1.0 / 64.0;

/// Fits the material (and, with [`Light::Fit`], the light) so that the layer renders
/// `inputs.target`, calling `progress(step, loss)` after each step. Returns the best
/// parameters seen.
pub fn fit(
    renderer: &Renderer,
    inputs: &Inputs,
    options: &Options,
    progress: &mut dyn FnMut(usize, f64),
) -> Result<Fitted> {
    let start = Instant::now();
    options.init.validate()?;
    options.camera.validate()?;
    let work = inputs.at_work_size(options.work_size);
    let n = (3 * work.mask.iter().filter(|&&m| m).count()) as f64;
    if n == 0.0 {
        return Err(invalid!(
            "mask: no pixel of the object is left at the working size {}x{}; use a larger work size",
            work.target.width,
            work.target.height
        ));
    }
    let c = work
        .mask
        .iter()
        .zip(&work.target.pixels)
        .filter(|(m, _)| **m)
        .map(|(_, p)| p.iter().map(|&v| f64::from(v).max(0.0)).sum::<f64>())
        .sum::<f64>()
        / n;
    if c <= 0.0 {
        return Err(invalid!("image: the masked pixels are all black"));
    }

    let (mut u, signs) = encode_material(&options.init);
    let n_mat = u.len();
    // the light: fixed, or log radiance at the level where the initial material renders
    // the target's mean brightness under a uniform map
    let (fixed_env, env_size) = match &options.light {
        Light::Fixed(env) => (Some(env.clone()), (env.height, env.width)),
        Light::Fit { height, width } => (None, (*height, *width)),
        Light::FitFrom(env) => (None, (env.height, env.width)),
    };
    let convention = match &options.light {
        Light::FitFrom(env) => env.convention,
        _ => options.convention,
    };
    // a starting map's log radiance (a texel is at least 1e-6 of the map's mean)
    let start_logs: Option<Vec<f64>> = match &options.light {
        Light::FitFrom(env) => {
            let mean = env
                .texels
                .iter()
                .flatten()
                .map(|&v| f64::from(v).max(0.0))
                .sum::<f64>()
                / (3 * env.texels.len()).max(1) as f64;
            if !(mean > 0.0 && mean.is_finite()) {
                return Err(invalid!("light: the starting map is black or not finite"));
            }
            Some(
                env.texels
                    .iter()
                    .flatten()
                    .map(|&v| f64::from(v).max(1e-6 * mean).ln())
                    .collect(),
            )
        }
        _ => None,
    };
    let level = match (&fixed_env, &start_logs) {
        (Some(_), _) => 0.0,
        (None, Some(logs)) => logs.iter().sum::<f64>() / logs.len() as f64,
        (None, None) => {
            let uniform = EnvMap::constant(env_size.0, env_size.1, convention, [1.0; 3])?;
            let image = render_one(renderer, &work, &options.init, &uniform, options.camera)?;
            let mean = work
                .mask
                .iter()
                .zip(&image.pixels)
                .filter(|(m, _)| **m)
                .map(|(_, p)| p.iter().map(|&v| f64::from(v)).sum::<f64>())
                .sum::<f64>()
                / n;
            if mean.is_nan() || mean <= 0.0 {
                return Err(invalid!(
                    "init: material '{}' renders black under a uniform light; start from another",
                    options.init.name
                ));
            }
            (c / mean).ln()
        }
    };
    match (&fixed_env, &start_logs) {
        (Some(_), _) => {}
        (None, Some(logs)) => u.extend(logs),
        (None, None) => u.extend(std::iter::repeat_n(level, 3 * env_size.0 * env_size.1)),
    }
    let mut lr = vec![options.learning_rate; u.len()];
    let mut adam = adam::Adam::new(u.len());
    let mut lr_scale = 1.0;
    let (mut best, mut best_u) = (f64::INFINITY, u.clone());
    let mut last_gain_at = (f64::INFINITY, 0usize);
    let mut losses = Vec::new();
    let mut steps = 0;
    while steps < options.steps {
        let (ctrl, dctrl) = decode_material(&u[..n_mat], &signs);
        let material = Material {
            name: options.init.name.clone(),
            ctrl,
        };
        let env = match &fixed_env {
            Some(e) => e.clone(),
            None => EnvMap {
                height: env_size.0,
                width: env_size.1,
                convention,
                texels: decode_env(&u[n_mat..]),
            },
        };
        let scene = Scene {
            normals: work.normals.clone(),
            env,
            material,
            camera: options.camera,
        };
        let batch = Batch::single(scene)?;
        let image = renderer.render(&batch)?.remove(0);
        let (mut loss, up) = data_term(&image, &work, c, n);
        // dLoss/dn is never used, dLoss/dL only when the light is fitted
        let wanted = Wanted {
            env: fixed_env.is_none(),
            normals: false,
            ctrl: true,
        };
        let (mut grads, _) = renderer.backward_with(&batch, &[up], &Accuracy::Exact, wanted)?;
        let grads = grads.remove(0);
        let mut g = vec![0.0; u.len()];
        for i in 0..n_mat {
            g[i] = f64::from(grads.d_ctrl[i]) * dctrl[i];
            if (i / N_CTRL_POINTS).is_multiple_of(N_COEFS) {
                // d|ctrl|/du = |ctrl| (0 where clamped)
                loss += options.sparsity * ctrl[i].abs();
                g[i] += options.sparsity * dctrl[i].abs();
            }
        }
        for coef in 0..n_mat / N_CTRL_POINTS {
            for j in 0..N_CTRL_POINTS - 1 {
                let (a, b) = (coef * N_CTRL_POINTS + j, coef * N_CTRL_POINTS + j + 1);
                let d = u[a] - u[b];
                loss += options.theta_d_smoothness * d * d;
                g[a] += 2.0 * options.theta_d_smoothness * d;
                g[b] -= 2.0 * options.theta_d_smoothness * d;
            }
        }
        if fixed_env.is_none() {
            let texels = &batch.scenes()[0].env.texels;
            for (t, (dl, l)) in grads.d_env.iter().zip(texels).enumerate() {
                for k in 0..3 {
                    g[n_mat + 3 * t + k] = f64::from(dl[k]) * f64::from(l[k]);
                }
            }
            loss += priors(
                &u[n_mat..],
                env_size.0,
                env_size.1,
                options,
                level,
                &mut g[n_mat..],
            );
        }
        if !loss.is_finite() || g.iter().any(|v| !v.is_finite()) {
            return Err(Error::Invalid(format!(
                "fit: the loss or its gradient is not finite at step {steps}"
            )));
        }
        losses.push(loss);
        progress(steps, loss);
        if loss < best {
            best = loss;
            best_u.clone_from(&u);
        }
        if loss < last_gain_at.0 * (1.0 - MIN_GAIN) {
            last_gain_at = (loss, steps);
        } else if steps - last_gain_at.1 >= PATIENCE {
            lr_scale *= 0.5;
            last_gain_at = (best, steps);
            if lr_scale < MIN_STEP_RATIO {
                steps += 1;
                break;
            }
        }
        lr.fill(options.learning_rate * lr_scale);
        adam.step(&mut u, &g, &lr);
        steps += 1;
    }
    let (ctrl, _) = decode_material(&best_u[..n_mat], &signs);
    let material = Material::new(options.init.name.clone(), &ctrl)?;
    let env = match fixed_env {
        Some(e) => e,
        None => EnvMap::new(
            env_size.0,
            env_size.1,
            convention,
            decode_env(&best_u[n_mat..]),
        )?,
    };
    Ok(Fitted {
        material,
        env,
        losses,
        steps,
        seconds: start.elapsed().as_secs_f64(),
        work_size: (work.target.width, work.target.height),
    })
}

/// Renders `inputs`' normals with a material and a map.
pub(super) fn render_one(
    renderer: &Renderer,
    inputs: &Inputs,
    material: &Material,
    env: &EnvMap,
    camera: Camera,
) -> Result<Image> {
    let batch = Batch::single(Scene {
        normals: inputs.normals.clone(),
        env: env.clone(),
        material: material.clone(),
        camera,
    })?;
    Ok(renderer.render(&batch)?.remove(0))
}
