//! The adjoints of every approximation: linear in the map with dLoss/dL as their adjoint,
//! and dLoss/dctrl and dLoss/dn against finite differences.

use super::{glossy, method, rel, smooth_env, sphere_scene, sun_env, upstream};
use crate::common::{Rng, random_material};
use matedit::lod::{self, Method};
use matedit::reference::Reference;
use matedit::{Convention, EnvMap, Material, Scene};

/// The approximations whose adjoints are checked.
const APPROX: [&str; 4] = ["env2", "env4+keep4", "table16", "table24+env2+keep4"];

/// sum of a . b over pixels and channels, in f64.
fn inner(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| f64::from(*x) * f64::from(*y))
        .sum()
}

/// The scene the adjoints are checked on: a 16-pixel sphere, a dim 16 x 32 map with four
/// suns, a random material with exponents up to 20.
fn adjoint_scene(seed: u64, convention: Convention) -> Scene {
    let mut rng = Rng::new(seed);
    sphere_scene(
        16,
        sun_env(16, 32, convention, seed, 4),
        random_material(&mut rng, (0.05, 1.5), (1.0, 20.0)),
    )
}

#[test]
fn approximations_are_linear_in_the_map_and_d_env_is_their_adjoint() {
    for (seed, conv) in [(7, Convention::Equirect), (8, Convention::Paper)] {
        let scene = adjoint_scene(seed, conv);
        let up = upstream(&scene, seed + 100);
        for m in APPROX.map(method) {
            let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
            let a = lod::render(&Reference, &scene, &m).unwrap();
            // a random non-negative step (the map stays valid) where dLoss/dL is
            // positive, so that <dL, d> is a sum of positive terms and does not cancel
            let mut rng = Rng::new(seed + 200);
            let d: Vec<[f32; 3]> = g
                .d_env
                .iter()
                .map(|dl| {
                    dl.map(|v| {
                        if v > 0.0 {
                            rng.uniform(0.0, 1.0) as f32
                        } else {
                            0.0
                        }
                    })
                })
                .collect();
            let mut moved = scene.clone();
            for (t, d) in moved.env.texels.iter_mut().zip(&d) {
                for k in 0..3 {
                    t[k] += d[k];
                }
            }
            let b = lod::render(&Reference, &moved, &m).unwrap();
            let lhs = inner(&up.pixels, &b.pixels) - inner(&up.pixels, &a.pixels);
            let rhs = inner(&g.d_env, &d);
            let e = (lhs - rhs).abs() / rhs.abs();
            eprintln!("{conv:?} {m}: <up, F(L + d) - F(L)> {lhs:.6e}, <dL, d> {rhs:.6e}: {e:.1e}");
            assert!(rhs > 0.0 && e <= 1e-5, "{conv:?} {m}: {lhs:e} vs {rhs:e}");
        }
    }
}

#[test]
fn d_ctrl_matches_finite_differences_of_every_approximation() {
    let scene = adjoint_scene(9, Convention::Equirect);
    let up = upstream(&scene, 10);
    let loss = |ctrl: &[f64], m: &Method| {
        let s = Scene {
            material: Material::new("fd", ctrl).unwrap(),
            ..scene.clone()
        };
        inner(&up.pixels, &lod::render(&Reference, &s, m).unwrap().pixels)
    };
    let eps = 1e-3;
    for m in APPROX.map(method) {
        let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
        let scale = g
            .d_ctrl
            .iter()
            .fold(0.0f64, |a, &v| a.max(f64::from(v).abs()));
        let mut worst = (0, 0.0f64);
        for i in 0..matedit::N_PARAMS {
            let mut c = scene.material.ctrl;
            c[i] += eps;
            let plus = loss(&c, &m);
            c[i] -= 2.0 * eps;
            let minus = loss(&c, &m);
            let fd = (plus - minus) / (2.0 * eps);
            let e = (fd - f64::from(g.d_ctrl[i])).abs() / scale;
            if e > worst.1 {
                worst = (i, e);
            }
        }
        eprintln!(
            "{m}: d_ctrl worst error {:.1e} of max {scale:.3e} at {}",
            worst.1, worst.0
        );
        assert!(
            worst.1 <= 1e-3,
            "{m}: d_ctrl[{}] off by {:e}",
            worst.0,
            worst.1
        );
    }
}

/// Unit directions of the `factor` x `factor` blocks of a map: their solid-angle-weighted
/// mean texel direction.
fn block_dirs(env: &EnvMap, factor: usize) -> Vec<[f64; 3]> {
    let (h, w) = (env.height, env.width);
    let cols = w.div_ceil(factor);
    let mut acc = vec![[0.0f64; 3]; h.div_ceil(factor) * cols];
    for r in 0..h {
        for c in 0..w {
            let (d, dw) = env.convention.texel(r, c, h, w);
            let a = &mut acc[(r / factor) * cols + c / factor];
            for k in 0..3 {
                a[k] += d[k] * dw;
            }
        }
    }
    acc.into_iter()
        .filter_map(|a| {
            let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            (l > 0.0).then(|| a.map(|v| v / l))
        })
        .collect()
}

#[test]
fn d_normals_match_finite_differences_of_env_levels() {
    let scene = adjoint_scene(11, Convention::Equirect);
    let up = upstream(&scene, 12);
    let eps = 2f32.powi(-11);
    for m in ["env2", "env4+keep4"].map(method) {
        let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
        // light directions: the blocks' and every texel's (the kept ones)
        let mut dirs = block_dirs(&scene.env, m.env_factor);
        dirs.extend(block_dirs(&scene.env, 1));
        // pixels at least 4 steps away from every kink (n.w = 0, n.h = 0)
        let margin = |n: [f32; 3]| {
            let n = n.map(f64::from);
            dirs.iter()
                .map(|w| {
                    let h = [w[0], w[1], w[2] + 1.0];
                    let hl = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                    let c = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
                    let x = (n[0] * h[0] + n[1] * h[1] + n[2] * h[2]) / hl;
                    c.abs().min(x.abs())
                })
                .fold(f64::INFINITY, f64::min)
        };
        let pixels: Vec<usize> = (0..scene.normals.normals.len())
            .filter(|&p| !scene.normals.is_background(p))
            .filter(|&p| margin(scene.normals.normals[p]) > 4.0 * f64::from(eps))
            .step_by(7)
            .take(5)
            .collect();
        assert!(
            pixels.len() >= 3,
            "{m}: only {} pixels away from kinks",
            pixels.len()
        );
        for &p in &pixels {
            let want = g.d_normals[p].map(f64::from);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (c, &want) in want.iter().enumerate() {
                let at = |delta: f32| {
                    let mut s = scene.clone();
                    s.normals.normals[p][c] += delta;
                    let img = lod::render(&Reference, &s, &m).unwrap();
                    (
                        inner(&[up.pixels[p]], &[img.pixels[p]]),
                        s.normals.normals[p][c],
                    )
                };
                let ((lp, np), (lm, nm)) = (at(eps), at(-eps));
                let fd = (lp - lm) / f64::from(np - nm);
                let e = (fd - want).abs() / scale;
                assert!(
                    e <= 2e-3,
                    "{m} pixel {p} dn[{c}]: fd {fd:e} vs {want:e} ({e:.1e})"
                );
            }
        }
    }
}

#[test]
fn table_d_normals_approach_the_exact_ones() {
    // dLoss/dn of a table interpolates the nodes' exact Jacobians (not the derivative of
    // the interpolated image): it must converge to the layer's as the table grows
    let scene = sphere_scene(32, smooth_env(16, 32, Convention::Equirect, 13), glossy());
    let up = upstream(&scene, 14);
    let exact = lod::backward(&Reference, &scene, &up, &Method::EXACT).unwrap();
    let err = |r: usize| {
        let m = Method {
            table: Some(r),
            ..Method::EXACT
        };
        let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
        rel(&g.d_normals, &exact.d_normals)
    };
    let (e16, e64) = (err(16), err(64));
    eprintln!("d_normals error: table16 {e16:.2e}, table64 {e64:.2e}");
    assert!(e64 < e16 / 4.0, "table64 {e64:e} vs table16 {e16:e}");
    assert!(e64 <= 1e-2, "table64: {e64:e}");
}
