//! The image, in f64. Mirrors shaders/forward.wgsl.

use rayon::prelude::*;

use super::common::{lobe_pow, lobe_x, pair_terms, stable_expm1};
use crate::prepare::{Prepared, dot};

/// The image of a prepared scene, row-major, 0 on background pixels.
pub fn forward(prep: &Prepared) -> Vec<[f64; 3]> {
    let perspective = !prep.camera.is_orthographic();
    let vals: Vec<[f64; 3]> = prep
        .pixels
        .par_iter()
        .map(|px| {
            let n = px.n;
            let mut acc = [0.0; 3];
            for &ti in &prep.lit {
                let t = &prep.texels[ti];
                let c = dot(n, t.w);
                if c <= 0.0 {
                    continue;
                }
                let (h, m, _) = pair_terms(&prep.ctrl, perspective, t, px);
                let (x, lnx) = lobe_x(h, n, px.nn_m1);
                for k in 0..3 {
                    // constant lobes (x^0 = 1): summed per texel for orthographic cameras,
                    // per pair for perspective ones; lobes with scale 0 are left out
                    let mut f = if perspective {
                        let consts = prep.const_lobes.iter();
                        consts.map(|&s| stable_expm1(m[(k * 3 + s) * 2])).sum()
                    } else {
                        t.fconst[k]
                    };
                    for &s in &prep.active_lobes {
                        let (m0, m1) = (m[(k * 3 + s) * 2], m[(k * 3 + s) * 2 + 1]);
                        f += stable_expm1(m0 * lobe_pow(x, lnx, m1));
                    }
                    acc[k] += f * t.ld[k] * c;
                }
            }
            acc
        })
        .collect();
    let mut image = vec![[0.0; 3]; prep.width * prep.height];
    for (px, v) in prep.pixels.iter().zip(vals) {
        image[px.index] = v;
    }
    image
}
