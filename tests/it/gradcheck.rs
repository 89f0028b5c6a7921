//! The CPU backward pass against central finite differences of the CPU forward pass, in
//! f64, on small random scenes kept away from the kinks of max(0, .); and the one-sided
//! value the layer returns at a kink.

use crate::common;

use common::{Rng, assert_close, random_material};
use matedit::prepare::{Prepared, dot, half_vector};
use matedit::reference;
use matedit::{Camera, Convention, N_PARAMS};

/// A scene as raw f64 arrays, so that it can be perturbed below f32 resolution.
#[derive(Clone)]
struct Raw {
    w: usize,
    h: usize,
    normals: Vec<[f64; 3]>,
    hl: usize,
    wl: usize,
    convention: Convention,
    env: Vec<[f64; 3]>,
    ctrl: [f64; N_PARAMS],
    camera: Camera,
}

impl Raw {
    fn prepare(&self) -> Prepared {
        Prepared::from_parts(
            self.w,
            self.h,
            &self.normals,
            self.hl,
            self.wl,
            self.convention,
            &self.env,
            &self.ctrl,
            self.camera,
        )
    }

    fn loss(&self, g: &[[f64; 3]]) -> f64 {
        let img = reference::forward(&self.prepare());
        img.iter().zip(g).map(|(i, g)| dot(*i, *g)).sum()
    }
}

/// Smallest distance of any pair of the scene from a kink: c = n.w = 0 or x = n.h = 0.
fn kink_margin(raw: &Raw, n: [f64; 3], px: usize) -> f64 {
    let prep = raw.prepare();
    let wp = raw.camera.view_dir(px % raw.w, px / raw.w, raw.w, raw.h);
    prep.texels
        .iter()
        .map(|t| {
            let (h, _) = half_vector(t.w, wp);
            dot(n, t.w).abs().min(dot(n, h).abs())
        })
        .fold(f64::INFINITY, f64::min)
}

fn random_raw(seed: u64, convention: Convention, camera: Camera) -> Raw {
    let mut rng = Rng::new(seed);
    let (w, h, hl, wl) = (4, 3, 4, 8);
    let env = (0..hl * wl)
        .map(|_| [0; 3].map(|_: i32| rng.uniform(-1.0, 1.0).exp()))
        .collect();
    let ctrl = random_material(&mut rng, (-0.5, 2.0), (0.5, 20.0)).ctrl;
    let mut raw = Raw {
        w,
        h,
        normals: vec![[0.0; 3]; w * h],
        hl,
        wl,
        convention,
        env,
        ctrl,
        camera,
    };
    for p in 0..w * h {
        if p == 5 {
            continue; // one background pixel
        }
        loop {
            let n = rng.unit_facing(-0.3);
            // not unit length: the layer uses n as given (kept <= 1 so x <= 1)
            let s = rng.uniform(0.8, 1.0);
            let n = n.map(|v| v * s);
            if kink_margin(&raw, n, p) > 1e-3 {
                raw.normals[p] = n;
                break;
            }
        }
    }
    raw
}

fn upstream(seed: u64, n: usize) -> Vec<[f64; 3]> {
    let mut rng = Rng::new(seed ^ 0xABCD);
    (0..n)
        .map(|_| [0; 3].map(|_: i32| rng.uniform(-1.0, 1.0)))
        .collect()
}

/// Central difference of the loss along one scalar of the scene.
fn central(raw: &Raw, g: &[[f64; 3]], step: f64, set: impl Fn(&mut Raw, f64)) -> f64 {
    let mut plus = raw.clone();
    set(&mut plus, step);
    let mut minus = raw.clone();
    set(&mut minus, -step);
    (plus.loss(g) - minus.loss(g)) / (2.0 * step)
}

fn check(convention: Convention, camera: Camera, seed: u64) {
    let raw = random_raw(seed, convention, camera);
    check_raw(raw, seed, &format!("{convention:?} {camera:?} seed {seed}"));
}

fn check_raw(raw: Raw, seed: u64, what: &str) {
    let g = upstream(seed, raw.w * raw.h);
    let an = reference::backward(&raw.prepare(), &g);

    // Step sizes: the loss is linear in L (any step is exact up to rounding); for n and
    // ctrl, 1e-5 keeps truncation (~step^2) and rounding (~1e-16 / step) below 1e-9.
    let mut fd_env = Vec::new();
    for i in 0..raw.hl * raw.wl {
        for k in 0..3 {
            fd_env.push(central(&raw, &g, 1e-3, |r, d| r.env[i][k] += d));
        }
    }
    let mut fd_n = Vec::new();
    for p in 0..raw.w * raw.h {
        for a in 0..3 {
            fd_n.push(if p == 5 {
                0.0
            } else {
                central(&raw, &g, 1e-5, |r, d| r.normals[p][a] += d)
            });
        }
    }
    let fd_ctrl: Vec<f64> = (0..N_PARAMS)
        .map(|c| central(&raw, &g, 1e-5, |r, d| r.ctrl[c] += d))
        .collect();

    let scale = |v: &[f64]| v.iter().fold(0.0f64, |a, b| a.max(b.abs()));
    // 1e-6 relative, with an absolute floor of 1e-9 of the largest entry for entries that
    // are (near) zero
    let d_env: Vec<f64> = an.d_env.iter().flatten().copied().collect();
    assert_close(
        &format!("dL {what}"),
        &d_env,
        &fd_env,
        1e-9 * scale(&fd_env),
        1e-6,
    );
    let d_n: Vec<f64> = an.d_normals.iter().flatten().copied().collect();
    assert_close(
        &format!("dn {what}"),
        &d_n,
        &fd_n,
        1e-9 * scale(&fd_n),
        1e-6,
    );
    assert_close(
        &format!("dctrl {what}"),
        &an.d_ctrl,
        &fd_ctrl,
        1e-9 * scale(&fd_ctrl),
        1e-6,
    );
    // the test must be able to fail: gradients are not all zero
    assert!(scale(&d_env) > 0.0 && scale(&d_n) > 0.0 && scale(&an.d_ctrl) > 0.0);
    // the background pixel gets nothing
    assert_eq!(an.d_normals[5], [0.0; 3]);
}

#[test]
fn gradcheck_equirect_orthographic() {
    for seed in [1, 2] {
        check(Convention::Equirect, Camera::Orthographic, seed);
    }
}

/// A material with a constant lobe (every exponent 0) and a lobe of scale 0, which the
/// image and dn leave out of the per-pair loop: finite differences cross from "left out"
/// to "evaluated", so they check that leaving them out changes nothing.
#[test]
fn gradcheck_constant_and_zero_lobes() {
    let mut raw = random_raw(8, Convention::Equirect, Camera::Orthographic);
    for k in 0..3 {
        for j in 0..6 {
            raw.ctrl[matedit::material::idx(k, 1, 1, j)] = 0.0; // lobe 1: constant
            raw.ctrl[matedit::material::idx(k, 2, 0, j)] = 0.0; // lobe 2: scale 0
        }
    }
    let prep = raw.prepare();
    assert_eq!(prep.active_lobes, vec![0]);
    assert_eq!(prep.const_lobes, vec![1]);
    check_raw(raw.clone(), 8, "constant and zero lobes");
    raw.camera = Camera::Perspective { fov_y_deg: 60.0 };
    check_raw(raw, 8, "constant and zero lobes, perspective");
}

#[test]
fn gradcheck_paper_orthographic() {
    check(Convention::Paper, Camera::Orthographic, 3);
}

#[test]
fn gradcheck_equirect_perspective() {
    check(
        Convention::Equirect,
        Camera::Perspective { fov_y_deg: 50.0 },
        4,
    );
}

#[test]
fn gradcheck_paper_perspective() {
    check(
        Convention::Paper,
        Camera::Perspective { fov_y_deg: 70.0 },
        5,
    );
}

/// At a pixel whose normal is exactly perpendicular to one texel's direction (c = n.w = 0,
/// the kink of max(0, n.w)), dLoss/dn is the one-sided derivative from the side where that
/// texel is below the horizon (its term is zero), not the average of the two sides.
#[test]
fn gradient_at_horizon_kink_is_one_sided_from_zero_side() {
    let mut raw = random_raw(7, Convention::Equirect, Camera::Orthographic);
    let g = upstream(7, raw.w * raw.h);
    let prep = raw.prepare();
    // a texel with w.x < 0, and n = (w.z, 0, -w.x): exactly perpendicular to w in floating
    // point, facing the camera, with n.h > 0 so that the texel's term is not flat there
    let t = prep
        .texels
        .iter()
        .find(|t| t.w[0] < -0.3 && t.w[2].abs() > 0.2)
        .expect("such a texel");
    let w = t.w;
    let n = [w[2], 0.0, -w[0]];
    assert_eq!(dot(n, w), 0.0, "exactly on the kink");
    assert!(dot(n, t.h) > 0.1);
    let p = 0;
    raw.normals[p] = n;
    let an = reference::backward(&raw.prepare(), &g);
    let along_w = dot(an.d_normals[p], w);
    let step = 1e-6;
    let loss0 = raw.loss(&g);
    let mut below = raw.clone();
    below.normals[p] = [n[0] - step * w[0], n[1] - step * w[1], n[2] - step * w[2]];
    let mut above = raw.clone();
    above.normals[p] = [n[0] + step * w[0], n[1] + step * w[1], n[2] + step * w[2]];
    let from_below = (loss0 - below.loss(&g)) / step;
    let from_above = (above.loss(&g) - loss0) / step;
    assert!(
        (from_above - from_below).abs() > 1e-3 * from_below.abs().max(1e-12),
        "the two sides must differ for this test to mean anything: {from_above} vs {from_below}"
    );
    assert_close("dn.w at the kink", &[along_w], &[from_below], 0.0, 1e-4);
}
