//! dLoss/dL, dLoss/dn and dLoss/dctrl, f32 SIMD. Mirrors src/reference/backward_texel.rs
//! (per texel: dL and the shares of dctrl) and src/reference/backward_normal.rs (per pixel:
//! dn) in one pass over the pairs, texels in SIMD lanes.

use pulp::{Simd, WithSimd};

use super::forward::GROUP_TEXELS;
use super::pair::{Cols, DPOW_MAX, Setup, geo, lobes};
use super::table::{Px, TexelTable};
use crate::material::idx;
use crate::spline::N_CTRL_POINTS;

/// Per-texel f64 sums of one orthographic pass: dLoss/dL / d_omega (3), then
/// dLoss/dm_{k,s,t} at the texel's theta_d, index 3 + (k * 3 + s) * 2 + t.
pub const TEXEL_SUMS: usize = 3 + 18;

/// The backward pass of the pixels `px` (upstream `g`) against `table` (all texels).
pub struct Backward<'a> {
    pub table: &'a TexelTable,
    pub setup: &'a Setup<'a>,
    pub px: &'a [Px],
    pub g: &'a [[f32; 3]],
    /// dLoss/dn per pixel of `px`, added into.
    pub dn: &'a mut [[f64; 3]],
    /// Per texel of the table, [`TEXEL_SUMS`] sums (perspective: only the first 3).
    pub tex: &'a mut [f64],
    /// Perspective: dLoss/dctrl, added into.
    pub ctrl: &'a mut [f64; crate::N_PARAMS],
}

impl WithSimd for Backward<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        let lanes = S::F32_LANES;
        let cols = Cols::<S>::new(self.table);
        let plan = self.setup.plan;
        let perspective = self.setup.perspective;
        let n_blocks = self.table.blocks(lanes);
        let per_group = (GROUP_TEXELS / lanes).max(1);
        let zero = s.splat_f32s(0.0);
        let one = s.splat_f32s(1.0);
        // per block of the group: dL/d_omega (3), then per (k, s, t) one sum (orthographic)
        // or one per spline point j (perspective)
        let per_t = if perspective { N_CTRL_POINTS } else { 1 };
        let stride = 3 + 18 * per_t;
        let mut tacc = vec![zero; per_group * stride];
        for g0 in (0..n_blocks).step_by(per_group) {
            let g1 = (g0 + per_group).min(n_blocks);
            tacc.iter_mut().for_each(|v| *v = zero);
            for ((p, gp), dn_out) in self.px.iter().zip(self.g).zip(self.dn.iter_mut()) {
                let mut dn = [zero; 3];
                for b in g0..g1 {
                    let Some(g) = geo(s, &cols, self.setup, p, b) else {
                        continue;
                    };
                    let lv = lobes(s, &cols, self.setup, &g, b);
                    let acc = &mut tacc[(b - g0) * stride..(b - g0 + 1) * stride];
                    let inv_x = s.div_f32s(one, s.max_f32s(g.x, s.splat_f32s(1e-30)));
                    let mut along_w = zero;
                    let mut along_h = zero;
                    for k in 0..3 {
                        let gk = s.splat_f32s(gp[k]);
                        let gl = s.mul_f32s(gk, cols.ld[k][b]);
                        // weight of this pair in the texel's sums for dctrl
                        let wk = s.mul_f32s(gl, g.c);
                        let wk_ln = s.mul_f32s(wk, g.lnx);
                        let mut f = zero;
                        let mut dx = zero;
                        for sl in 0..3 {
                            let Some(l) = plan.lobe_of[k][sl] else {
                                continue;
                            };
                            let lobe = &plan.lobes[l];
                            let e1 = s.add_f32s(lv.em1[l], one);
                            f = s.add_f32s(f, lv.em1[l]);
                            // E x^m1
                            let t1 = match lobe.exp {
                                Some(e) => s.mul_f32s(e1, lv.xb[e]),
                                None => e1,
                            };
                            let i0 = 3 + (k * 3 + sl) * 2 * per_t;
                            let i1 = i0 + per_t;
                            let d0 = s.mul_f32s(wk, t1);
                            if lobe.zero_scale {
                                add_share(s, perspective, &g.basis, &mut acc[i0..i1], d0);
                                continue;
                            }
                            // E m0 x^m1
                            let u = s.mul_f32s(t1, lv.a[l]);
                            let d1 = s.mul_f32s(wk_ln, u);
                            add_share(s, perspective, &g.basis, &mut acc[i0..i1], d0);
                            add_share(s, perspective, &g.basis, &mut acc[i1..i1 + per_t], d1);
                            if let Some(e) = lobe.exp {
                                // m1 x^(m1 - 1), clamped, 0 at x = 0
                                let dp = s.min_f32s(
                                    s.mul_f32s(s.mul_f32s(lv.b[e], lv.xb[e]), inv_x),
                                    s.splat_f32s(DPOW_MAX),
                                );
                                let dp = s.select_f32s(g.pos, dp, zero);
                                dx = s.mul_add_f32s(s.mul_f32s(e1, lv.a[l]), dp, dx);
                            }
                        }
                        acc[k] = s.mul_add_f32s(s.mul_f32s(gk, g.c), f, acc[k]);
                        along_w = s.mul_add_f32s(gl, f, along_w);
                        along_h = s.mul_add_f32s(gl, dx, along_h);
                    }
                    let along_w = s.select_f32s(g.up, along_w, zero);
                    let ch = s.mul_f32s(g.c, along_h);
                    let w = [cols.w[0][b], cols.w[1][b], cols.w[2][b]];
                    for a in 0..3 {
                        dn[a] = s.mul_add_f32s(along_w, w[a], s.mul_add_f32s(ch, g.h[a], dn[a]));
                    }
                }
                for a in 0..3 {
                    dn_out[a] += s.reduce_sum_f32s(dn[a]) as f64;
                }
            }
            // flush the group's lane sums in a fixed order
            for b in g0..g1 {
                let acc = &tacc[(b - g0) * stride..(b - g0 + 1) * stride];
                let vals: &[f32] = bytemuck::cast_slice(acc);
                for lane in 0..lanes {
                    let ti = b * lanes + lane;
                    if ti >= self.table.len {
                        break;
                    }
                    let t = &mut self.tex[ti * TEXEL_SUMS..(ti + 1) * TEXEL_SUMS];
                    for q in 0..3 {
                        t[q] += vals[q * lanes + lane] as f64;
                    }
                    if !perspective {
                        for q in 3..TEXEL_SUMS {
                            t[q] += vals[q * lanes + lane] as f64;
                        }
                    }
                }
                if perspective {
                    for k in 0..3 {
                        for sl in 0..3 {
                            for t in 0..2 {
                                for j in 0..N_CTRL_POINTS {
                                    let q = 3 + ((k * 3 + sl) * 2 + t) * per_t + j;
                                    let v = &vals[q * lanes..(q + 1) * lanes];
                                    let sum: f64 = v.iter().map(|&x| x as f64).sum();
                                    self.ctrl[idx(k, sl, t, j)] += sum;
                                }
                            }
                        }
                    }
                }
            }
        }
    }
}

/// Adds a pair's dLoss/dm to the texel sums: as is (orthographic, where the basis is the
/// texel's and applied at the end) or times each spline basis value (perspective).
#[inline(always)]
fn add_share<S: Simd>(
    s: S,
    perspective: bool,
    basis: &[S::f32s; N_CTRL_POINTS],
    acc: &mut [S::f32s],
    v: S::f32s,
) {
    if perspective {
        for j in 0..N_CTRL_POINTS {
            acc[j] = s.mul_add_f32s(v, basis[j], acc[j]);
        }
    } else {
        acc[0] = s.add_f32s(acc[0], v);
    }
}
