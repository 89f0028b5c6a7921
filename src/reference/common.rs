//! The lobe math of shaders/common.wgsl in f64, with the same helper names.

use crate::prepare::{N_COEF_VALUES, PixelRec, TexelRec, coefficients, dot, half_vector};

/// log(x) is taken of max(x, TINY), as in the shaders.
pub const TINY: f64 = 1e-30;
/// Clamp of m1 x^(m1 - 1) in the dn term, as in the shaders.
pub const DPOW_MAX: f64 = 1e10;

/// exp(y) - 1 without cancellation.
pub fn stable_expm1(y: f64) -> f64 {
    y.exp_m1()
}

/// log(x) for the lobe powers; finite for every x.
pub fn lobe_log(x: f64) -> f64 {
    x.max(TINY).ln()
}

/// The lobe argument x = max(0, h . n) and ln x for the unit half vector `h` (0 where it
/// is undefined: then x = 0) and the normal `n` with `nn_m1` = |n|^2 - 1, as in the shaders:
/// h . n = 1 - d with d = (|h - n|^2 - nn_m1) / 2, and ln x = log1p(-d) (the shaders' way
/// gives the same value to rounding).
pub fn lobe_x(h: [f64; 3], n: [f64; 3], nn_m1: f64) -> (f64, f64) {
    if h == [0.0; 3] {
        return (0.0, lobe_log(0.0));
    }
    let v = [h[0] - n[0], h[1] - n[1], h[2] - n[2]];
    let d = 0.5 * (dot(v, v) - nn_m1);
    let x = (1.0 - d).max(0.0);
    let lnx = if x > 0.0 {
        (-d).ln_1p().max(TINY.ln())
    } else {
        lobe_log(0.0)
    };
    (x, lnx)
}

/// x^e, with x^e = 0 at x = 0 for e > 0 and x^0 = 1.
pub fn lobe_pow(x: f64, lnx: f64, e: f64) -> f64 {
    if e == 0.0 {
        1.0
    } else if x <= 0.0 {
        0.0
    } else {
        (e * lnx).exp()
    }
}

/// x^e ln x given p = x^e; 0 at x = 0.
pub fn lobe_pow_log(x: f64, lnx: f64, p: f64) -> f64 {
    if x <= 0.0 { 0.0 } else { p * lnx }
}

/// e x^(e - 1); 0 at x = 0 and for e = 0; clamped to DPOW_MAX.
pub fn lobe_dpow(x: f64, lnx: f64, e: f64) -> f64 {
    if x <= 0.0 || e == 0.0 {
        0.0
    } else {
        (e * ((e - 1.0) * lnx).exp()).min(DPOW_MAX)
    }
}

/// The half vector and the 18 coefficients for a pixel-texel pair: from the texel table
/// for orthographic cameras, else from the pair's theta_d. Also theta_d.
pub fn pair_terms(
    ctrl: &[f64; crate::N_PARAMS],
    perspective: bool,
    t: &TexelRec,
    p: &PixelRec,
) -> ([f64; 3], [f64; N_COEF_VALUES], f64) {
    if !perspective {
        (t.h, t.coef, t.theta_d)
    } else {
        let (h, theta_d) = half_vector(t.w, p.wp);
        (h, coefficients(ctrl, theta_d), theta_d)
    }
}

/// One channel's BRDF and its derivatives with respect to the lobes' coefficients.
pub struct LobeGrads {
    /// sum_s exp(m0_s x^m1_s) - 1.
    pub f: f64,
    /// d f / d m0_s = E_s x^m1_s.
    pub d0: [f64; 3],
    /// d f / d m1_s = E_s m0_s x^m1_s ln x.
    pub d1: [f64; 3],
}

/// See [`LobeGrads`].
pub fn lobe_grads(x: f64, lnx: f64, m0: [f64; 3], m1: [f64; 3]) -> LobeGrads {
    let mut g = LobeGrads {
        f: 0.0,
        d0: [0.0; 3],
        d1: [0.0; 3],
    };
    for s in 0..3 {
        let pw = lobe_pow(x, lnx, m1[s]);
        let e = stable_expm1(m0[s] * pw);
        g.f += e;
        g.d0[s] = (e + 1.0) * pw;
        g.d1[s] = (e + 1.0) * m0[s] * lobe_pow_log(x, lnx, pw);
    }
    g
}

/// Channel k's coefficient vectors over lobes (m0, m1) from the 18 coefficients.
pub fn channel_coef(m: &[f64; N_COEF_VALUES], k: usize) -> ([f64; 3], [f64; 3]) {
    (
        [0, 1, 2].map(|s| m[(k * 3 + s) * 2]),
        [0, 1, 2].map(|s| m[(k * 3 + s) * 2 + 1]),
    )
}
