//! dLoss/dctrl as the sum of the texels' shares, in the shader's order. Mirrors
//! shaders/reduce_ctrl.wgsl.

use crate::material::N_PARAMS;

/// Threads per workgroup in the shader.
const WG: usize = 64;

/// Sums `shares` per control point: 64 strided partial sums, then a tree.
pub fn reduce_ctrl(shares: &[[f64; N_PARAMS]]) -> [f64; N_PARAMS] {
    let mut out = [0.0; N_PARAMS];
    for col in 0..N_PARAMS {
        let mut partial = [0.0; WG];
        for li in 0..WG {
            let mut s = 0.0;
            let mut i = li;
            while i < shares.len() {
                s += shares[i][col];
                i += WG;
            }
            partial[li] = s;
        }
        let mut stride = WG / 2;
        while stride > 0 {
            for li in 0..stride {
                partial[li] += partial[li + stride];
            }
            stride /= 2;
        }
        out[col] = partial[0];
    }
    out
}
