//! dLoss/dL and each texel's share of dLoss/dctrl, in f64. Mirrors
//! shaders/backward_texel.wgsl.

use rayon::prelude::*;

use super::common::{channel_coef, lobe_grads, lobe_x, pair_terms};
use crate::material::{N_PARAMS, idx};
use crate::prepare::{Prepared, dot};
use crate::spline::spline_basis;

/// For each texel of `prep.texels`: dLoss/dL (RGB) and its 108 shares of dLoss/dctrl.
pub fn backward_texel(prep: &Prepared, g: &[[f64; 3]]) -> Vec<([f64; 3], [f64; N_PARAMS])> {
    let perspective = !prep.camera.is_orthographic();
    prep.texels
        .par_iter()
        .map(|t| {
            let w = t.w;
            let mut acc_l = [0.0; 3];
            // acc[(k * 2 + t) * 6 + j][s]; orthographic cameras use j = 0 only and apply
            // the texel's basis at the end.
            let mut acc = [[0.0f64; 3]; 36];
            for px in &prep.pixels {
                let n = px.n;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let (h, m, theta_d) = pair_terms(&prep.ctrl, perspective, t, px);
                let b = if perspective {
                    spline_basis(theta_d)
                } else {
                    [0.0; 6]
                };
                let (x, lnx) = lobe_x(h, n, px.nn_m1);
                let gp = g[px.index];
                for k in 0..3 {
                    let gc = gp[k] * c;
                    let (m0, m1) = channel_coef(&m, k);
                    let lg = lobe_grads(x, lnx, m0, m1);
                    acc_l[k] += gc * lg.f;
                    for s in 0..3 {
                        if !perspective {
                            acc[(k * 2) * 6][s] += gc * lg.d0[s];
                            acc[(k * 2 + 1) * 6][s] += gc * lg.d1[s];
                        } else {
                            for j in 0..6 {
                                acc[(k * 2) * 6 + j][s] += gc * b[j] * lg.d0[s];
                                acc[(k * 2 + 1) * 6 + j][s] += gc * b[j] * lg.d1[s];
                            }
                        }
                    }
                }
            }
            let dl = [
                acc_l[0] * t.d_omega,
                acc_l[1] * t.d_omega,
                acc_l[2] * t.d_omega,
            ];
            let tb = if perspective {
                [1.0; 6]
            } else {
                spline_basis(t.theta_d)
            };
            let mut share = [0.0; N_PARAMS];
            for k in 0..3 {
                for tt in 0..2 {
                    for j in 0..6 {
                        let a = if perspective {
                            acc[(k * 2 + tt) * 6 + j]
                        } else {
                            acc[(k * 2 + tt) * 6].map(|v| v * tb[j])
                        };
                        for s in 0..3 {
                            share[idx(k, s, tt, j)] = a[s] * t.ld[k];
                        }
                    }
                }
            }
            (dl, share)
        })
        .collect()
}
