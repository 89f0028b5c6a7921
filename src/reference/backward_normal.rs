//! dLoss/dn, in f64. Mirrors shaders/backward_normal.wgsl.

use rayon::prelude::*;

use super::common::{lobe_dpow, lobe_pow, lobe_x, pair_terms, stable_expm1};
use crate::prepare::{Prepared, dot};

/// dLoss/dn per pixel (row-major, 0 on background) for upstream `g` (row-major).
pub fn backward_normal(prep: &Prepared, g: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let perspective = !prep.camera.is_orthographic();
    let vals: Vec<[f64; 3]> = prep
        .pixels
        .par_iter()
        .map(|px| {
            let n = px.n;
            let gp = g[px.index];
            let mut acc = [0.0; 3];
            for &ti in &prep.lit {
                let t = &prep.texels[ti];
                let w = t.w;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let (h, m, _) = pair_terms(&prep.ctrl, perspective, t, px);
                let (x, lnx) = lobe_x(h, n, px.nn_m1);
                let mut along_w = 0.0;
                let mut along_h = 0.0;
                for k in 0..3 {
                    // constant lobes (no dependence on x): summed per texel for
                    // orthographic cameras, per pair for perspective ones; lobes with
                    // scale 0 are left out
                    let mut f = if perspective {
                        let consts = prep.const_lobes.iter();
                        consts.map(|&s| stable_expm1(m[(k * 3 + s) * 2])).sum()
                    } else {
                        t.fconst[k]
                    };
                    let mut dx = 0.0;
                    for &s in &prep.active_lobes {
                        let (m0, m1) = (m[(k * 3 + s) * 2], m[(k * 3 + s) * 2 + 1]);
                        let e = stable_expm1(m0 * lobe_pow(x, lnx, m1));
                        f += e;
                        dx += (e + 1.0) * m0 * lobe_dpow(x, lnx, m1);
                    }
                    let gl = gp[k] * t.ld[k];
                    along_w += gl * f;
                    along_h += gl * dx;
                }
                for a in 0..3 {
                    acc[a] += along_w * w[a] + c * along_h * h[a];
                }
            }
            acc
        })
        .collect();
    let mut out = vec![[0.0; 3]; prep.width * prep.height];
    for (px, v) in prep.pixels.iter().zip(vals) {
        out[px.index] = v;
    }
    out
}
