//! Isotropic BRDFs that the fitter ([`crate::fit_brdf`]) and the measured-material renderer
//! ([`render`]) can evaluate: measured tables ([`merl`]), small networks fitted to them
//! ([`nbrdf`]) and the DSBRDF itself ([`Material`] implements [`Isotropic`]).
//!
//! Every BRDF is evaluated in Rusinkiewicz coordinates (theta_h, theta_d, phi_d): the
//! half vector h = normalize(w_i + w_o) at angle theta_h from the normal, and the
//! "difference" vector d = w_i seen from a frame whose z axis is h, at polar angle theta_d
//! and azimuth phi_d. Isotropy removes phi_h. [`to_rusinkiewicz`] and
//! [`from_rusinkiewicz`] convert from and to directions.

pub mod merl;
pub mod nbrdf;
pub mod render;

use crate::material::{Material, N_CHANNELS, N_COEFS, N_LOBES};
use crate::spline::N_CTRL_POINTS;

/// An isotropic, reciprocal BRDF with an RGB value in 1/sr.
pub trait Isotropic: Sync {
    /// The RGB value at (theta_h, theta_d, phi_d): theta_h, theta_d in [0, pi/2], phi_d
    /// in [0, 2 pi) (reciprocity makes phi_d and phi_d + pi the same).
    fn eval(&self, theta_h: f64, theta_d: f64, phi_d: f64) -> [f64; 3];

    /// Whether a value is known there: measured tables mark missing cells; a fitter gives
    /// them no weight. True by default.
    fn known(&self, _theta_h: f64, _theta_d: f64, _phi_d: f64) -> bool {
        true
    }
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

fn normalize(a: [f64; 3]) -> Option<[f64; 3]> {
    let len = dot(a, a).sqrt();
    (len > 1e-12).then(|| [a[0] / len, a[1] / len, a[2] / len])
}

/// (theta_h, theta_d, phi_d) of the unit directions `w_i` (to the light) and `w_o` (to
/// the viewer) about the unit normal `n`; `None` where w_i = -w_o (no half vector).
/// phi_d is in [0, 2 pi). Angles come from atan2, which keeps their digits near 0.
pub fn to_rusinkiewicz(n: [f64; 3], w_i: [f64; 3], w_o: [f64; 3]) -> Option<[f64; 3]> {
    let h = normalize([w_i[0] + w_o[0], w_i[1] + w_o[1], w_i[2] + w_o[2]])?;
    let cos_h = dot(h, n);
    // The component of h across the normal: its direction is phi_h's tangent.
    let across = [
        h[0] - cos_h * n[0],
        h[1] - cos_h * n[1],
        h[2] - cos_h * n[2],
    ];
    let sin_h = dot(across, across).sqrt();
    let theta_h = sin_h.atan2(cos_h);
    // The frame of d: z = h, y = the binormal n x t (t = h's tangent direction), x = y x h.
    // At theta_h = 0 any tangent gives the same BRDF value of an isotropic material up to
    // phi_d's origin; pick one perpendicular to n.
    let t = match normalize(across) {
        Some(t) if sin_h > 1e-9 => t,
        _ => any_perpendicular(n),
    };
    let y = cross(n, t);
    let x = cross(y, h);
    let d = [dot(w_i, x), dot(w_i, y), dot(w_i, h)];
    let theta_d = (d[0] * d[0] + d[1] * d[1]).sqrt().atan2(d[2]);
    let mut phi_d = d[1].atan2(d[0]);
    if phi_d < 0.0 {
        phi_d += std::f64::consts::TAU;
    }
    Some([theta_h, theta_d, phi_d])
}

/// A unit vector perpendicular to the unit vector `n`.
fn any_perpendicular(n: [f64; 3]) -> [f64; 3] {
    let a = if n[0].abs() < 0.9 {
        [1.0, 0.0, 0.0]
    } else {
        [0.0, 1.0, 0.0]
    };
    normalize(cross(a, n)).expect("a is not parallel to n")
}

/// The directions (w_i, w_o) in the frame whose normal is +z and where phi_h = 0, for
/// (theta_h, theta_d, phi_d): h = (sin theta_h, 0, cos theta_h), w_i is d rotated about
/// y by theta_h, and w_o is w_i mirrored about h.
pub fn from_rusinkiewicz(theta_h: f64, theta_d: f64, phi_d: f64) -> ([f64; 3], [f64; 3]) {
    let (sh, ch) = theta_h.sin_cos();
    let (sd, cd) = theta_d.sin_cos();
    let (sp, cp) = phi_d.sin_cos();
    let d = [sd * cp, sd * sp, cd];
    let rot = |v: [f64; 3]| [ch * v[0] + sh * v[2], v[1], -sh * v[0] + ch * v[2]];
    let w_i = rot(d);
    let w_o = rot([-d[0], -d[1], d[2]]);
    (w_i, w_o)
}

/// The DSBRDF as an isotropic BRDF: x = cos theta_h, the coefficients at theta_d, and
/// f = sum_s (exp(m0 x^m1) - 1) per channel (no phi_d dependence).
impl Isotropic for Material {
    fn eval(&self, theta_h: f64, theta_d: f64, _phi_d: f64) -> [f64; 3] {
        let c = self.coefficients(theta_d);
        let x = theta_h.cos().max(0.0);
        let mut f = [0.0; 3];
        for (k, fk) in f.iter_mut().enumerate() {
            for s in 0..N_LOBES {
                let m0 = c[(k * N_LOBES + s) * N_COEFS];
                let m1 = c[(k * N_LOBES + s) * N_COEFS + 1];
                *fk += lobe(m0, m1, x);
            }
        }
        f
    }
}

/// exp(m0 x^m1) - 1 with x^0 = 1 and x^e = 0 at x = 0 for e > 0 (CONVENTIONS).
pub fn lobe(m0: f64, m1: f64, x: f64) -> f64 {
    let p = if m1 == 0.0 {
        1.0
    } else if x <= 0.0 {
        0.0
    } else {
        x.powf(m1)
    };
    (m0 * p).exp_m1()
}

const _: () = assert!(N_CHANNELS == 3 && N_CTRL_POINTS == 6);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rusinkiewicz_round_trip() {
        let n = [0.0, 0.0, 1.0];
        for &(th, td, pd) in &[
            (0.3, 0.7, 1.1),
            (1.2, 0.1, 5.5),
            (0.01, 1.4, 3.0),
            (0.8, 0.9, 0.2),
        ] {
            let (wi, wo) = from_rusinkiewicz(th, td, pd);
            let [a, b, c] = to_rusinkiewicz(n, wi, wo).unwrap();
            assert!((a - th).abs() < 1e-12, "{a} {th}");
            assert!((b - td).abs() < 1e-12, "{b} {td}");
            assert!((c - pd).abs() < 1e-12, "{c} {pd}");
        }
    }

    #[test]
    fn rusinkiewicz_is_rotation_invariant() {
        // The same configuration about a tilted normal: rotate everything about x.
        let (wi, wo) = from_rusinkiewicz(0.4, 0.6, 2.0);
        let (s, c) = 0.7f64.sin_cos();
        let r = |v: [f64; 3]| [v[0], c * v[1] - s * v[2], s * v[1] + c * v[2]];
        let a = to_rusinkiewicz([0.0, 0.0, 1.0], wi, wo).unwrap();
        let b = to_rusinkiewicz(r([0.0, 0.0, 1.0]), r(wi), r(wo)).unwrap();
        for i in 0..3 {
            assert!((a[i] - b[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn material_matches_lobe_sum() {
        let m = Material::constant("t", [(0.5, 0.0), (2.0, 40.0), (0.0, 0.0)]).unwrap();
        let f = m.eval(0.2, 0.5, 0.0);
        let x = 0.2f64.cos();
        let want = 0.5f64.exp_m1() + (2.0 * x.powf(40.0)).exp_m1();
        assert!((f[1] - want).abs() < 1e-12);
    }
}
