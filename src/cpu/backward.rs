//! dLoss/dL, dLoss/dn and dLoss/dctrl, f32 SIMD. Mirrors src/reference/backward_texel.rs
//! (per texel: dL and the shares of dctrl) and src/reference/backward_normal.rs (per pixel:
//! dn) in one pass over the pairs, texels in SIMD lanes.

use pulp::{Simd, WithSimd};

use super::forward::GROUP_TEXELS;
use super::math::{exp2, exp2m1};
use super::pair::{Cols, Setup, add_jacobian, coef, dpow, geo, underflows};
use super::table::{Px, TexelTable};
use crate::material::idx;
use crate::scene::Wanted;
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
    /// The gradients to compute: the terms of the others are left out (their sums stay
    /// as they were).
    pub wanted: Wanted,
    /// With it, also dI^k/dn per pixel of `px` (index k * 3 + axis), added into: the
    /// normals' Jacobian, in the same pass (orthographic cameras).
    pub jac: Option<&'a mut [[f64; 9]]>,
}

impl WithSimd for Backward<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        match (self.setup.perspective, self.jac.is_some()) {
            (true, _) => self.run::<S, true, false>(s),
            (false, false) => self.run::<S, false, false>(s),
            (false, true) => self.run::<S, false, true>(s),
        }
    }
}

impl Backward<'_> {
    /// The pass for a perspective (`P`) or orthographic camera, with the normals'
    /// Jacobian (`J`, orthographic only) or without.
    #[inline(always)]
    fn run<S: Simd, const P: bool, const J: bool>(mut self, s: S) {
        let lanes = S::F32_LANES;
        let cols = Cols::<S>::new(self.table);
        let plan = self.setup.plan;
        let n_blocks = self.table.blocks(lanes);
        let per_group = (GROUP_TEXELS / lanes).max(1);
        let zero = s.splat_f32s(0.0);
        let one = s.splat_f32s(1.0);
        let (want_dn, want_ctrl) = (self.wanted.normals, self.wanted.ctrl);
        // the lobes' dI/dx, for dLoss/dn or the Jacobian
        let want_dx = want_dn || J;
        let mut no_jac = Vec::new();
        let jac_out = match self.jac.take() {
            Some(j) => j,
            None => &mut no_jac[..],
        };
        // per block of the group: dL/d_omega (3), then per (k, s, t) one sum (orthographic)
        // or one per spline point j (perspective)
        let per_t = if P { N_CTRL_POINTS } else { 1 };
        let stride = 3 + 18 * per_t;
        let mut tacc = vec![zero; per_group * stride];
        // where each lobe's (k, s) sums start in a block's slice of `tacc`
        let offsets: Vec<Vec<[usize; 3]>> = plan
            .groups
            .iter()
            .map(|grp| {
                let lobe_offsets = grp.lobes.iter();
                lobe_offsets
                    .map(|l| std::array::from_fn(|k| 3 + (k * 3 + l.slot[k]) * 2 * per_t))
                    .collect()
            })
            .collect();
        // orthographic: each lobe's scale column, resolved once
        let no_col: &[S::f32s] = &[];
        let a_cols: Vec<Vec<&[S::f32s]>> = plan
            .groups
            .iter()
            .map(|grp| {
                let col = |c: usize| cols.coef.get(c).copied().unwrap_or(no_col);
                grp.lobes
                    .iter()
                    .map(|l| if P { no_col } else { col(l.a_col) })
                    .collect()
            })
            .collect();
        for g0 in (0..n_blocks).step_by(per_group) {
            let g1 = (g0 + per_group).min(n_blocks);
            tacc.iter_mut().for_each(|v| *v = zero);
            for (q, ((p, gp), dn_out)) in self
                .px
                .iter()
                .zip(self.g)
                .zip(self.dn.iter_mut())
                .enumerate()
            {
                let mut dn = [zero; 3];
                let mut jac = [zero; 9];
                for b in g0..g1 {
                    let Some(g) = geo::<S, P>(s, &cols, p, b) else {
                        continue;
                    };
                    let acc = &mut tacc[(b - g0) * stride..(b - g0 + 1) * stride];
                    let inv_x = if want_dx {
                        s.div_f32s(one, s.max_f32s(g.x, s.splat_f32s(1e-30)))
                    } else {
                        zero
                    };
                    let gl: [S::f32s; 3] =
                        std::array::from_fn(|k| s.mul_f32s(s.splat_f32s(gp[k]), cols.ld[k][b]));
                    // weights of this pair in the texel's sums for dctrl
                    let wk = gl.map(|v| s.mul_f32s(v, g.c));
                    let wk_ln = wk.map(|v| s.mul_f32s(v, g.lnx));
                    let mut f = [zero; 3];
                    let mut dx = [zero; 3];
                    for ((grp, offsets), a_cols) in plan.groups.iter().zip(&offsets).zip(&a_cols) {
                        // x^m1 and m1 x^(m1 - 1) (clamped, 0 at x = 0) of the group
                        let (xb, dp) = match grp.exp_col {
                            Some(col) => {
                                let m1 = coef::<S, P>(s, &cols, self.setup, &g, b, col);
                                let t = s.mul_f32s(m1, g.l2);
                                if underflows(s, t, g.up) {
                                    continue;
                                }
                                let xb = exp2(s, t);
                                let dp = if want_dx {
                                    dpow(s, m1, xb, inv_x, g.pos)
                                } else {
                                    zero
                                };
                                (Some(xb), dp)
                            }
                            None => (None, zero),
                        };
                        for ((lobe, off), a_col) in grp.lobes.iter().zip(offsets).zip(a_cols) {
                            if lobe.zero_scale {
                                if !want_ctrl {
                                    continue;
                                }
                                // E = 1: only dLoss/dm0 = x^m1
                                let t1 = xb.unwrap_or(one);
                                for k in 0..3 {
                                    if lobe.channels & (1 << k) != 0 {
                                        let i0 = off[k];
                                        let d0 = s.mul_f32s(wk[k], t1);
                                        add_share::<S, P>(s, &g.basis, acc, i0, d0);
                                    }
                                }
                                continue;
                            }
                            // the scale columns hold a log2(e)
                            let a2 = if P {
                                coef::<S, P>(s, &cols, self.setup, &g, b, lobe.a_col)
                            } else {
                                a_col[b]
                            };
                            let em1 = match xb {
                                Some(xb) => exp2m1(s, s.mul_f32s(a2, xb)),
                                // a constant lobe: exp(m0) - 1 depends on the texel alone
                                None if !P => cols.em1[lobe.a_col][b],
                                None => exp2m1(s, a2),
                            };
                            let a = s.mul_f32s(a2, s.splat_f32s(std::f32::consts::LN_2));
                            let e1 = s.add_f32s(em1, one);
                            // E x^m1, E m0 x^m1 and E m0 m1 x^(m1 - 1) (0 for x^0)
                            let t1 = xb.map_or(e1, |xb| s.mul_f32s(e1, xb));
                            let u = s.mul_f32s(t1, a);
                            let ead = xb
                                .filter(|_| want_dx)
                                .map(|_| s.mul_f32s(s.mul_f32s(e1, a), dp));
                            for k in 0..3 {
                                if lobe.channels & (1 << k) == 0 {
                                    continue;
                                }
                                f[k] = s.add_f32s(f[k], em1);
                                if let Some(ead) = ead {
                                    dx[k] = s.add_f32s(dx[k], ead);
                                }
                                if !want_ctrl {
                                    continue;
                                }
                                let i0 = off[k];
                                let d0 = s.mul_f32s(wk[k], t1);
                                let d1 = s.mul_f32s(wk_ln[k], u);
                                add_share::<S, P>(s, &g.basis, acc, i0, d0);
                                add_share::<S, P>(s, &g.basis, acc, i0 + per_t, d1);
                            }
                        }
                    }
                    for k in 0..3 {
                        acc[k] =
                            s.mul_add_e_f32s(s.mul_f32s(s.splat_f32s(gp[k]), g.c), f[k], acc[k]);
                    }
                    if J {
                        let ld = [0, 1, 2].map(|k| cols.ld[k][b]);
                        let w = [0, 1, 2].map(|a| cols.w[a][b]);
                        let c_dx = dx.map(|d| s.mul_f32s(g.c, d));
                        add_jacobian(s, g.up, ld, &f, c_dx, w, &g.h, &mut jac);
                    }
                    if !want_dn {
                        continue;
                    }
                    let mut along_w = zero;
                    let mut along_h = zero;
                    for k in 0..3 {
                        along_w = s.mul_add_e_f32s(gl[k], f[k], along_w);
                        along_h = s.mul_add_e_f32s(gl[k], dx[k], along_h);
                    }
                    let along_w = s.select_f32s(g.up, along_w, zero);
                    let ch = s.mul_f32s(g.c, along_h);
                    let w = [cols.w[0][b], cols.w[1][b], cols.w[2][b]];
                    for a in 0..3 {
                        dn[a] =
                            s.mul_add_e_f32s(along_w, w[a], s.mul_add_e_f32s(ch, g.h[a], dn[a]));
                    }
                }
                for a in 0..3 {
                    dn_out[a] += s.reduce_sum_f32s(dn[a]) as f64;
                }
                if J {
                    for (o, v) in jac_out[q].iter_mut().zip(jac) {
                        *o += s.reduce_sum_f32s(v) as f64;
                    }
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
                    if !P && want_ctrl {
                        for q in 3..TEXEL_SUMS {
                            t[q] += vals[q * lanes + lane] as f64;
                        }
                    }
                }
                if P && want_ctrl {
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
fn add_share<S: Simd, const P: bool>(
    s: S,
    basis: &[S::f32s; N_CTRL_POINTS],
    acc: &mut [S::f32s],
    at: usize,
    v: S::f32s,
) {
    if P {
        for (j, bj) in basis.iter().enumerate() {
            acc[at + j] = s.mul_add_e_f32s(v, *bj, acc[at + j]);
        }
    } else {
        acc[at] = s.add_f32s(acc[at], v);
    }
}
