//! What depends on a texel alone or a pixel alone, computed once per scene on the host in
//! f64: texel directions, solid angles, radiance x solid angle, and for orthographic cameras
//! the half vector, theta_d and the 18 spline coefficients; the foreground pixel list.
//! Both backends start from a [`Prepared`] scene, so the per-pair loops are all they differ in.

use rayon::prelude::*;

use crate::camera::Camera;
use crate::envmap::Convention;
use crate::material::N_PARAMS;
use crate::scene::{BACKGROUND_EPS, Image, Scene};
use crate::spline::{N_CTRL_POINTS, spline_basis};

/// Coefficients m_{s,t}^k per direction: index (k * 3 + s) * 2 + t.
pub const N_COEF_VALUES: usize = N_PARAMS / N_CTRL_POINTS;

/// Below this |w_i + w_p| the half vector is undefined (w_i = -w_p); it is then taken as
/// 0, which makes x = 0 and theta_d = pi/2.
pub const HALF_VECTOR_EPS: f64 = 1e-6;

/// One environment texel that can receive or give light (d_omega > 0).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelRec {
    /// Texel index r * W_L + c in the map.
    pub index: usize,
    /// Direction towards the light.
    pub w: [f64; 3],
    /// Solid angle.
    pub d_omega: f64,
    /// L^k(i) * d_omega_i.
    pub ld: [f64; 3],
    /// Orthographic cameras: the half vector with w_p = (0, 0, 1).
    pub h: [f64; 3],
    /// Orthographic cameras: theta_d.
    pub theta_d: f64,
    /// Orthographic cameras: the 18 coefficients at theta_d.
    pub coef: [f64; N_COEF_VALUES],
    /// Orthographic cameras: per channel, the sum over the material's constant lobes
    /// (exponent 0 everywhere, so x^0 = 1) of exp(m0) - 1: their share of f, the same
    /// for every pixel.
    pub fconst: [f64; 3],
}

/// One light direction given to [`Prepared::from_lights`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PointLight {
    /// Where its dLoss/dL goes: r * W_L + c in the grid the gradients are laid out in.
    pub index: usize,
    /// Unit direction towards the light.
    pub w: [f64; 3],
    /// Solid angle.
    pub d_omega: f64,
    /// Radiance per channel.
    pub l: [f64; 3],
}

/// One foreground pixel.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelRec {
    /// Pixel index y * W + x in the image.
    pub index: usize,
    /// The normal, as given.
    pub n: [f64; 3],
    /// The view direction.
    pub wp: [f64; 3],
    /// |n|^2 - 1, so that the lobe argument can be taken as x = 1 - (|h - n|^2 - nn_m1) / 2
    /// (for unit h), which keeps 1 - x to full relative precision where x is near 1.
    pub nn_m1: f64,
}

/// A scene reduced to the lists the per-pair loops run over.
#[derive(Clone, Debug, PartialEq)]
pub struct Prepared {
    /// Image columns.
    pub width: usize,
    /// Image rows.
    pub height: usize,
    /// Env rows.
    pub env_height: usize,
    /// Env columns.
    pub env_width: usize,
    /// Camera.
    pub camera: Camera,
    /// Material control points.
    pub ctrl: [f64; N_PARAMS],
    /// Foreground pixels (|n| >= 1e-6), in image order.
    pub pixels: Vec<PixelRec>,
    /// Texels with d_omega > 0, in map order: the ones dLoss/dL can be non-zero for.
    pub texels: Vec<TexelRec>,
    /// Positions in `texels` of the lit ones (some L^k > 0): the only ones that add to the
    /// image, dLoss/dn or dLoss/dctrl.
    pub lit: Vec<usize>,
    /// The lobes whose share of f depends on x (some scale and some exponent control point
    /// non-zero), in order: the only ones the image and dLoss/dn evaluate per pair. Lobes
    /// with every scale 0 add nothing; lobes with every exponent 0 are in `fconst`.
    pub active_lobes: Vec<usize>,
    /// The lobes whose exponents are all 0 (and some scale is not): f gets exp(m0) - 1
    /// from each, whatever x is.
    pub const_lobes: Vec<usize>,
}

/// The material's lobes that depend on x (see [`Prepared::active_lobes`]) and the constant
/// ones (every exponent control point 0, some scale non-zero).
pub fn classify_lobes(ctrl: &[f64; N_PARAMS]) -> (Vec<usize>, Vec<usize>) {
    let all_zero = |s: usize, t: usize| {
        (0..3).all(|k| (0..N_CTRL_POINTS).all(|j| ctrl[crate::material::idx(k, s, t, j)] == 0.0))
    };
    let mut active = Vec::new();
    let mut constant = Vec::new();
    for s in 0..3 {
        if all_zero(s, 0) {
            continue;
        }
        if all_zero(s, 1) {
            constant.push(s);
        } else {
            active.push(s);
        }
    }
    (active, constant)
}

/// Dot product.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Half vector of w_i and w_p, guarded where w_i = -w_p, and theta_d = acos(clamp(w_i . h,
/// 0, 1)), computed as atan2(|w_i - w_p|, |w_i + w_p|): the same angle for unit vectors
/// (h bisects them), without acos's loss of digits near 1. Mirrors `half_vector` in
/// shaders/common.wgsl.
pub fn half_vector(w: [f64; 3], wp: [f64; 3]) -> ([f64; 3], f64) {
    let s = [w[0] + wp[0], w[1] + wp[1], w[2] + wp[2]];
    let d = [w[0] - wp[0], w[1] - wp[1], w[2] - wp[2]];
    let len = dot(s, s).sqrt();
    let h = if len < HALF_VECTOR_EPS {
        [0.0; 3]
    } else {
        [s[0] / len, s[1] / len, s[2] / len]
    };
    (h, dot(d, d).sqrt().atan2(len))
}

/// The 18 coefficients at theta_d: m[(k * 3 + s) * 2 + t] = sum_j B_j ctrl[idx(k, s, t, j)].
/// The spline is quadratic: at most three consecutive basis functions are non-zero at any
/// theta_d, and the sum skips the others' exact zeros (the same value, bit for bit, as the
/// sum over all six in order: adding 0 changes nothing). This runs once per pixel-texel
/// pair in perspective, where the six-term sum was a quarter of the reference's time.
pub fn coefficients(ctrl: &[f64; N_PARAMS], theta_d: f64) -> [f64; N_COEF_VALUES] {
    let b = spline_basis(theta_d);
    let first = b
        .iter()
        .position(|&v| v != 0.0)
        .unwrap_or(0)
        .min(N_CTRL_POINTS - 3);
    let (b0, b1, b2) = (b[first], b[first + 1], b[first + 2]);
    let mut m = [0.0; N_COEF_VALUES];
    for (mc, c) in m.iter_mut().zip(ctrl.chunks_exact(N_CTRL_POINTS)) {
        *mc = b0 * c[first] + b1 * c[first + 1] + b2 * c[first + 2];
    }
    m
}

/// `[f64; 3]` of an f32 vector.
fn to64(v: &[f32; 3]) -> [f64; 3] {
    [v[0] as f64, v[1] as f64, v[2] as f64]
}

/// Whether normal `n` is a foreground pixel's: |n| >= [`BACKGROUND_EPS`].
pub fn is_foreground(n: [f64; 3]) -> bool {
    dot(n, n) >= BACKGROUND_EPS * BACKGROUND_EPS
}

/// The lights of an `env_height` x `env_width` lat-long map of radiances `env` under
/// `convention`, in map order.
fn map_lights(
    env_height: usize,
    env_width: usize,
    convention: Convention,
    env: &[[f64; 3]],
) -> Vec<PointLight> {
    let mut lights = Vec::with_capacity(env_height * env_width);
    for r in 0..env_height {
        for c in 0..env_width {
            let (w, d_omega) = convention.texel(r, c, env_height, env_width);
            let index = r * env_width + c;
            lights.push(PointLight {
                index,
                w,
                d_omega,
                l: env[index],
            });
        }
    }
    lights
}

impl PixelRec {
    /// Pixel `index` with normal `n` seen from `wp`.
    pub fn new(index: usize, n: [f64; 3], wp: [f64; 3]) -> Self {
        let nn_m1 = (n[0] * n[0] - 1.0) + n[1] * n[1] + n[2] * n[2];
        PixelRec {
            index,
            n,
            wp,
            nn_m1,
        }
    }
}

impl Prepared {
    /// Prepares a validated scene.
    pub fn new(scene: &Scene) -> Self {
        let (width, height) = (scene.normals.width, scene.normals.height);
        let pixels = scene
            .normals
            .normals
            .par_iter()
            .enumerate()
            .filter_map(|(index, n)| {
                let n = to64(n);
                is_foreground(n).then(|| {
                    let wp = scene
                        .camera
                        .view_dir(index % width, index / width, width, height);
                    PixelRec::new(index, n, wp)
                })
            })
            .collect();
        Prepared {
            pixels,
            ..Prepared::without_pixels(scene)
        }
    }

    /// A validated scene's lights, material and camera with no pixels listed (its image
    /// size kept): for a backend that takes the foreground pixels from the normal map
    /// itself ([`is_foreground`], [`PixelRec::new`]).
    pub fn without_pixels(scene: &Scene) -> Self {
        let env: Vec<[f64; 3]> = scene.env.texels.iter().map(to64).collect();
        let lights = map_lights(
            scene.env.height,
            scene.env.width,
            scene.env.convention,
            &env,
        );
        Prepared::from_lights(
            scene.normals.width,
            scene.normals.height,
            Vec::new(),
            scene.env.height,
            scene.env.width,
            &lights,
            &scene.material.ctrl,
            scene.camera,
        )
    }

    /// Prepares a scene given as raw f64 arrays (used by gradient checks, which perturb
    /// inputs below f32 resolution). Inputs are assumed valid.
    #[expect(clippy::too_many_arguments, reason = "the parts of a scene")]
    pub fn from_parts(
        width: usize,
        height: usize,
        normals: &[[f64; 3]],
        env_height: usize,
        env_width: usize,
        convention: Convention,
        env: &[[f64; 3]],
        ctrl: &[f64; N_PARAMS],
        camera: Camera,
    ) -> Self {
        let lights = map_lights(env_height, env_width, convention, env);
        let pixels = normals
            .iter()
            .enumerate()
            .filter(|(_, n)| is_foreground(**n))
            .map(|(index, &n)| {
                PixelRec::new(
                    index,
                    n,
                    camera.view_dir(index % width, index / width, width, height),
                )
            })
            .collect();
        Prepared::from_lights(
            width, height, pixels, env_height, env_width, &lights, ctrl, camera,
        )
    }

    /// Prepares a scene from its foreground pixels and a list of light directions, each
    /// with its solid angle and radiance: a lat-long map's texels, or any other set (a
    /// downsampled map, a map's brightest texels alone). `index` places each light's
    /// dLoss/dL in an `env_height` x `env_width` grid; lights with `d_omega <= 0` are
    /// dropped.
    #[expect(clippy::too_many_arguments, reason = "the parts of a scene")]
    pub fn from_lights(
        width: usize,
        height: usize,
        pixels: Vec<PixelRec>,
        env_height: usize,
        env_width: usize,
        lights: &[PointLight],
        ctrl: &[f64; N_PARAMS],
        camera: Camera,
    ) -> Self {
        let ortho_wp = [0.0, 0.0, 1.0];
        let (active_lobes, const_lobes) = classify_lobes(ctrl);
        let mut texels = Vec::with_capacity(lights.len());
        let mut lit = Vec::new();
        for &PointLight {
            index,
            w,
            d_omega,
            l,
        } in lights
        {
            if d_omega <= 0.0 {
                continue;
            }
            let ld = [l[0] * d_omega, l[1] * d_omega, l[2] * d_omega];
            let (h, theta_d) = half_vector(w, ortho_wp);
            let coef = if camera.is_orthographic() {
                coefficients(ctrl, theta_d)
            } else {
                [0.0; N_COEF_VALUES]
            };
            let mut fconst = [0.0; 3];
            if camera.is_orthographic() {
                for (k, f) in fconst.iter_mut().enumerate() {
                    for &s in &const_lobes {
                        *f += coef[(k * 3 + s) * 2].exp_m1();
                    }
                }
            }
            if ld.iter().any(|&v| v != 0.0) {
                lit.push(texels.len());
            }
            texels.push(TexelRec {
                index,
                w,
                d_omega,
                ld,
                h,
                theta_d,
                coef,
                fconst,
            });
        }
        Prepared {
            width,
            height,
            env_height,
            env_width,
            camera,
            ctrl: *ctrl,
            pixels,
            texels,
            lit,
            active_lobes,
            const_lobes,
        }
    }

    /// An image of this scene's size.
    pub fn image(&self, pixels: Vec<[f32; 3]>) -> Image {
        Image {
            width: self.width,
            height: self.height,
            pixels,
        }
    }

    /// This scene's lights, material and camera on other pixels (and image size).
    pub fn with_pixels(&self, width: usize, height: usize, pixels: Vec<PixelRec>) -> Prepared {
        Prepared {
            width,
            height,
            env_height: self.env_height,
            env_width: self.env_width,
            camera: self.camera,
            ctrl: self.ctrl,
            pixels,
            texels: self.texels.clone(),
            lit: self.lit.clone(),
            active_lobes: self.active_lobes.clone(),
            const_lobes: self.const_lobes.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The three-term sum is the six-term sum bit for bit, at every span, at the knots
    /// and past both ends.
    #[test]
    fn coefficients_skip_only_exact_zeros() {
        let ctrl: [f64; N_PARAMS] =
            std::array::from_fn(|i| ((i * 37 % 101) as f64 - 50.0) / 7.0 + 1e-3 * i as f64);
        let mut thetas: Vec<f64> = (0..=2000).map(|i| i as f64 * 1.6 / 2000.0 - 0.01).collect();
        thetas.extend(crate::spline::KNOTS);
        for t in thetas {
            let b = spline_basis(t);
            assert!(b.iter().filter(|&&v| v != 0.0).count() <= 3, "{t}: {b:?}");
            let mut want = [0.0; N_COEF_VALUES];
            for (c, w) in want.iter_mut().enumerate() {
                for (j, bj) in b.iter().enumerate() {
                    *w += bj * ctrl[c * N_CTRL_POINTS + j];
                }
            }
            let got = coefficients(&ctrl, t);
            for c in 0..N_COEF_VALUES {
                assert_eq!(
                    got[c].to_bits(),
                    want[c].to_bits(),
                    "theta_d {t}, value {c}"
                );
            }
        }
    }
}
