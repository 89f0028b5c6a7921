//! The normals' refinement (an experiment, off by default: docs/edit.md): the nets'
//! normals moved, material and light fixed, until the layer re-renders the photo better,
//! held smooth and near the nets' by two priors.

use super::{PhotoOptions, Stage};
use crate::edit::inputs::Inputs;
use crate::edit::loss::data_term;
use crate::error::Result;
use crate::{Batch, Camera, EnvMap, Material, NormalMap, Renderer, Scene};

/// The normals' refinement's first step moves the normal with the largest gradient by
/// this many radians (about 3 degrees).
const NORMAL_MOVE: f64 = 0.05;
/// Halvings of a step that raised the loss before the normals' refinement ends.
const NORMAL_HALVINGS: usize = 8;

/// The normals of `work` refined with the material and light fixed, on the fit's data term
/// plus `normal_smoothness` times the mean squared difference between neighbouring normals
/// on the object and `normal_anchor` times the mean squared difference from `work`'s:
/// projected gradient descent with a backtracking line search. Each step moves every
/// object pixel's normal against its gradient's part tangent to the sphere,
/// renormalises it (kept facing the camera), and is taken only if the loss falls; the step
/// length starts where the largest move is [`NORMAL_MOVE`] radians, halves on a rise (up to
/// [`NORMAL_HALVINGS`] times, then the refinement ends) and grows by half after a success.
/// The loss never rises: the normals returned are the last taken, with the loss of the
/// start and after each step taken.
pub(super) fn refine_normals(
    renderer: &Renderer,
    work: &Inputs,
    material: &Material,
    env: &EnvMap,
    options: &PhotoOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<(NormalMap, Vec<f64>)> {
    let (w, h) = (work.normals.width, work.normals.height);
    let on: Vec<usize> = (0..w * h).filter(|&i| work.mask[i]).collect();
    let n = (3 * on.len()) as f64;
    let c = on
        .iter()
        .map(|&i| {
            work.target.pixels[i]
                .iter()
                .map(|&v| f64::from(v).max(0.0))
                .sum::<f64>()
        })
        .sum::<f64>()
        / n;
    if c <= 0.0 || on.is_empty() {
        return Ok((work.normals.clone(), Vec::new()));
    }
    // neighbouring pairs on the object, right and down
    let mut pairs = Vec::new();
    for &i in &on {
        if i % w + 1 < w && work.mask[i + 1] {
            pairs.push((i, i + 1));
        }
        if i + w < w * h && work.mask[i + w] {
            pairs.push((i, i + w));
        }
    }
    let lambda = options.normal_smoothness / pairs.len().max(1) as f64;
    let mu = options.normal_anchor / on.len() as f64;
    let start = &work.normals;
    let sq = |a: [f32; 3], b: [f32; 3]| (0..3).map(|k| f64::from(a[k] - b[k]).powi(2)).sum::<f64>();
    let smoothness = |m: &NormalMap| -> f64 {
        lambda
            * pairs
                .iter()
                .map(|&(a, b)| sq(m.normals[a], m.normals[b]))
                .sum::<f64>()
            + mu * on
                .iter()
                .map(|&i| sq(m.normals[i], start.normals[i]))
                .sum::<f64>()
    };
    let scene = |m: &NormalMap| {
        Batch::single(Scene {
            normals: m.clone(),
            env: env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        })
    };
    let loss_of = |m: &NormalMap| -> Result<f64> {
        let img = renderer.render(&scene(m)?)?.remove(0);
        Ok(data_term(&img, work, c, n).0 + smoothness(m))
    };
    let wanted = crate::Wanted {
        env: false,
        normals: true,
        ctrl: false,
    };
    // dLoss/dn at the object's pixels, tangent to the sphere at each normal
    let gradient = |m: &NormalMap| -> Result<Vec<[f64; 3]>> {
        let batch = scene(m)?;
        let img = renderer.render(&batch)?.remove(0);
        let (_, up) = data_term(&img, work, c, n);
        let (mut grads, _) =
            renderer.backward_with(&batch, &[up], &crate::Accuracy::Exact, wanted)?;
        let d_n = grads.remove(0).d_normals;
        let mut g: Vec<[f64; 3]> = vec![[0.0; 3]; w * h];
        for &i in &on {
            g[i] = d_n[i].map(f64::from);
        }
        for &(a, b) in &pairs {
            for k in 0..3 {
                let d = 2.0 * lambda * f64::from(m.normals[a][k] - m.normals[b][k]);
                g[a][k] += d;
                g[b][k] -= d;
            }
        }
        for &i in &on {
            for k in 0..3 {
                g[i][k] += 2.0 * mu * f64::from(m.normals[i][k] - start.normals[i][k]);
            }
        }
        for &i in &on {
            let nv = m.normals[i].map(f64::from);
            let along = (0..3).map(|k| g[i][k] * nv[k]).sum::<f64>();
            for k in 0..3 {
                g[i][k] -= along * nv[k];
            }
        }
        Ok(g)
    };
    let moved = |m: &NormalMap, g: &[[f64; 3]], alpha: f64| -> NormalMap {
        let mut out = m.clone();
        for &i in &on {
            let mut v: [f64; 3] =
                std::array::from_fn(|k| f64::from(m.normals[i][k]) - alpha * g[i][k]);
            v[2] = v[2].max(0.02);
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            out.normals[i] = v.map(|x| (x / len) as f32);
        }
        out
    };
    let mut current = work.normals.clone();
    let mut loss = loss_of(&current)?;
    let mut losses = vec![loss];
    let mut g = gradient(&current)?;
    let largest = |g: &[[f64; 3]]| {
        on.iter()
            .map(|&i| (g[i][0] * g[i][0] + g[i][1] * g[i][1] + g[i][2] * g[i][2]).sqrt())
            .fold(0.0, f64::max)
    };
    let mut alpha = NORMAL_MOVE / largest(&g).max(1e-30);
    'steps: for step in 0..options.normal_steps {
        progress(Stage::Normals {
            step,
            steps: options.normal_steps,
        });
        for _ in 0..=NORMAL_HALVINGS {
            let trial = moved(&current, &g, alpha);
            let l = loss_of(&trial)?;
            if l.is_finite() && l < loss {
                (current, loss) = (trial, l);
                losses.push(loss);
                g = gradient(&current)?;
                if g.iter().flatten().any(|v| !v.is_finite()) {
                    break 'steps;
                }
                alpha *= 1.5;
                continue 'steps;
            }
            alpha /= 2.0;
        }
        break;
    }
    Ok((current, losses))
}
