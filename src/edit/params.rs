//! The fit's free parameters: every scale control point `sign * exp(u)`, every exponent
//! `exp(u)`, every env texel channel `exp(w)` (see [`crate::edit`]).

use crate::envmap::MAX_RADIANCE;
use crate::material::{MAX_ABS_SCALE, MAX_EXPONENT, Material, N_COEFS, N_LOBES, N_PARAMS, idx};
use crate::spline::N_CTRL_POINTS;

const SCALE_FLOOR: f64 = 1e-4;
const EXPONENT_FLOOR: f64 = 1e-2;

/// The material as free parameters: (u, signs) with ctrl = sign exp(u) for scales and
/// exp(u) for exponents. A lobe whose scales are all 0 starts as a faint lobe (m0 1e-4,
/// exponent 1) that the fit may grow.
pub(super) fn encode_material(m: &Material) -> (Vec<f64>, [f64; N_PARAMS]) {
    let mut u = vec![0.0; N_PARAMS];
    let mut signs = [1.0; N_PARAMS];
    for k in 0..3 {
        for s in 0..N_LOBES {
            let unused = (0..N_CTRL_POINTS).all(|j| m.ctrl[idx(k, s, 0, j)] == 0.0);
            for j in 0..N_CTRL_POINTS {
                let (a, b) = (idx(k, s, 0, j), idx(k, s, 1, j));
                let scale = m.ctrl[a];
                signs[a] = if scale < 0.0 { -1.0 } else { 1.0 };
                u[a] = scale.abs().max(SCALE_FLOOR).ln();
                u[b] = if unused {
                    0.0
                } else {
                    m.ctrl[b].max(EXPONENT_FLOOR).ln()
                };
            }
        }
    }
    (u, signs)
}

/// Control points from parameters, and d ctrl / d u (0 where a bound clamps).
pub(super) fn decode_material(
    u: &[f64],
    signs: &[f64; N_PARAMS],
) -> ([f64; N_PARAMS], [f64; N_PARAMS]) {
    let mut ctrl = [0.0; N_PARAMS];
    let mut d = [0.0; N_PARAMS];
    for i in 0..N_PARAMS {
        let is_exponent = (i / N_CTRL_POINTS) % N_COEFS == 1;
        let bound = if is_exponent {
            MAX_EXPONENT
        } else {
            MAX_ABS_SCALE
        };
        let v = u[i].exp();
        if v >= bound {
            ctrl[i] = signs[i] * bound;
        } else {
            ctrl[i] = signs[i] * v;
            d[i] = ctrl[i];
        }
    }
    (ctrl, d)
}

/// Largest log radiance of a fitted map: keeps every texel far inside the accepted range.
fn max_log_radiance() -> f64 {
    (f64::from(MAX_RADIANCE) * 1e-3).ln()
}

pub(super) fn decode_env(w: &[f64]) -> Vec<[f32; 3]> {
    let top = max_log_radiance();
    w.chunks_exact(3)
        .map(|c| std::array::from_fn(|k| c[k].min(top).exp() as f32))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parameters_round_trip_and_keep_signs() {
        let mut m = crate::presets::lookup("plastic-red").unwrap_or_else(|| {
            Material::constant("m", [(0.5, 1.0), (2.0, 50.0), (0.0, 0.0)]).unwrap()
        });
        m.ctrl[idx(1, 1, 0, 2)] = -0.25;
        let (u, signs) = encode_material(&m);
        let (ctrl, d) = decode_material(&u, &signs);
        for i in 0..N_PARAMS {
            let want = m.ctrl[i];
            let is_exponent = (i / N_CTRL_POINTS) % N_COEFS == 1;
            if want != 0.0 && (!is_exponent || want >= EXPONENT_FLOOR) {
                assert!((ctrl[i] - want).abs() <= 1e-12 * want.abs(), "{i}");
                assert_eq!(d[i], ctrl[i]);
            }
            if !is_exponent {
                assert!(ctrl[i] * want >= 0.0, "{i}: sign lost");
            }
        }
    }
}
