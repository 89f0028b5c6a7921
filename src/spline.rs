//! The quadratic clamped uniform B-spline on [0, pi/2] that carries the material's
//! coefficients over theta_d. Kept in sync with `spline_basis` in shaders/common.wgsl.

use std::f64::consts::FRAC_PI_2;

/// Number of control points (and basis functions).
pub const N_CTRL_POINTS: usize = 6;

/// The 9 knots 0, 0, 0, pi/8, pi/4, 3pi/8, pi/2, pi/2, pi/2.
pub const KNOTS: [f64; 9] = [
    0.0,
    0.0,
    0.0,
    FRAC_PI_2 / 4.0,
    FRAC_PI_2 / 2.0,
    FRAC_PI_2 * 3.0 / 4.0,
    FRAC_PI_2,
    FRAC_PI_2,
    FRAC_PI_2,
];

/// The 6 basis functions B_0..B_5 at `t` (clamped to [0, pi/2]), by Cox-de Boor.
/// Spans are half-open except the last, so that B_5(pi/2) = 1.
pub fn spline_basis(t: f64) -> [f64; N_CTRL_POINTS] {
    let t = t.clamp(0.0, FRAC_PI_2);
    // degree 0: the span that holds t (the last non-empty span is closed)
    let mut b = [0.0f64; 8];
    let span = if t >= KNOTS[5] {
        5
    } else if t >= KNOTS[4] {
        4
    } else if t >= KNOTS[3] {
        3
    } else {
        2
    };
    b[span] = 1.0;
    for d in 1..=2 {
        for j in 0..(8 - d) {
            let mut v = 0.0;
            let den = KNOTS[j + d] - KNOTS[j];
            if den > 0.0 {
                v += (t - KNOTS[j]) / den * b[j];
            }
            let den = KNOTS[j + d + 1] - KNOTS[j + 1];
            if den > 0.0 {
                v += (KNOTS[j + d + 1] - t) / den * b[j + 1];
            }
            b[j] = v;
        }
    }
    [b[0], b[1], b[2], b[3], b[4], b[5]]
}

/// The same basis in closed form per span, as shaders/common.wgsl evaluates it.
pub fn spline_basis_closed(t: f64) -> [f64; N_CTRL_POINTS] {
    let tau = t.clamp(0.0, FRAC_PI_2) * (4.0 / FRAC_PI_2);
    let s = tau.floor().min(3.0);
    let r = tau - s;
    let (a, c) = ((1.0 - r) * (1.0 - r), r * r);
    let (first, last) = (s == 0.0, s == 3.0);
    let v0 = if first { a } else { 0.5 * a };
    let v1 = if first {
        0.5 * r * (4.0 - 3.0 * r)
    } else if last {
        0.5 * (1.0 - r) * (3.0 * r + 1.0)
    } else {
        0.5 + r - c
    };
    let v2 = if last { c } else { 0.5 * c };
    let mut b = [0.0; N_CTRL_POINTS];
    let s = s as usize;
    b[s] = v0;
    b[s + 1] = v1;
    b[s + 2] = v2;
    b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_matches_cox_de_boor() {
        for i in 0..=4000 {
            let t = i as f64 / 4000.0 * FRAC_PI_2;
            let (a, b) = (spline_basis(t), spline_basis_closed(t));
            for j in 0..N_CTRL_POINTS {
                assert!(
                    (a[j] - b[j]).abs() < 1e-12,
                    "B_{j}({t}): {} vs {}",
                    a[j],
                    b[j]
                );
            }
        }
    }

    #[test]
    fn partition_of_unity_and_non_negative() {
        for i in 0..=1000 {
            let t = i as f64 / 1000.0 * FRAC_PI_2;
            let b = spline_basis(t);
            let s: f64 = b.iter().sum();
            assert!((s - 1.0).abs() < 1e-14, "sum {s} at t = {t}");
            assert!(
                b.iter().all(|&v| v >= 0.0),
                "negative basis at t = {t}: {b:?}"
            );
        }
        assert_eq!(spline_basis(FRAC_PI_2)[5], 1.0);
        assert_eq!(spline_basis(0.0)[0], 1.0);
    }

    #[test]
    fn matches_closed_form_in_first_span() {
        // On [0, pi/8) with knot step u = pi/8: B_0 = (1 - t/u)^2.
        let u = FRAC_PI_2 / 4.0;
        for &t in &[0.0, 0.1, 0.3] {
            let b = spline_basis(t);
            assert!((b[0] - (1.0 - t / u).powi(2)).abs() < 1e-14);
        }
    }
}
