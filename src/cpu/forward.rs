//! The image, f32 SIMD. Mirrors src/reference/forward.rs: per pixel, the sum over lit
//! texels of f^k L^k d_omega max(0, n.w), with texels in SIMD lanes.

use pulp::{Simd, WithSimd};

use super::math::{exp2, exp2m1};
use super::pair::{Cols, Setup, add_channels, add_jacobian, coef, dpow, geo, underflows};
use super::table::{Px, TexelTable};

/// Texels per group: each pixel's lane sums run over one group in f32 and are then added
/// to the pixel's f64 total, so that f32 sums stay short.
pub const GROUP_TEXELS: usize = 256;

/// The forward pass of the pixels `px` against `table` (lit texels), adding into `out`.
pub struct Forward<'a> {
    pub table: &'a TexelTable,
    pub setup: &'a Setup<'a>,
    pub px: &'a [Px],
    pub out: &'a mut [[f64; 3]],
    /// With it, also dI^k/dn per pixel (index k * 3 + axis), added into: the normals'
    /// Jacobian, in the same pass.
    pub jac: Option<&'a mut [[f64; 9]]>,
}

impl WithSimd for Forward<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        match (self.setup.perspective, self.jac.is_some()) {
            (true, false) => self.run::<S, true, false>(s),
            (false, false) => self.run::<S, false, false>(s),
            (true, true) => self.run::<S, true, true>(s),
            (false, true) => self.run::<S, false, true>(s),
        }
    }
}

impl Forward<'_> {
    /// The pass for a perspective (`P`) or orthographic camera, with the Jacobian (`J`) or
    /// without.
    #[inline(always)]
    fn run<S: Simd, const P: bool, const J: bool>(self, s: S) {
        let cols = Cols::<S>::new(self.table);
        let n_blocks = self.table.blocks(S::F32_LANES);
        let per_group = (GROUP_TEXELS / S::F32_LANES).max(1);
        let zero = s.splat_f32s(0.0);
        let one = s.splat_f32s(1.0);
        let mut no_jac = vec![[0.0f64; 9]; if J { 0 } else { self.px.len() }];
        let jac_out = self.jac.unwrap_or(&mut no_jac);
        for g0 in (0..n_blocks).step_by(per_group) {
            let g1 = (g0 + per_group).min(n_blocks);
            for ((p, out), jac_out) in self
                .px
                .iter()
                .zip(self.out.iter_mut())
                .zip(jac_out.iter_mut())
            {
                let mut acc = [zero; 3];
                let mut jac = [zero; 9];
                for b in g0..g1 {
                    let Some(g) = geo::<S, P>(s, &cols, p, b) else {
                        continue;
                    };
                    let mut f = if P {
                        [zero; 3]
                    } else {
                        [cols.fconst[0][b], cols.fconst[1][b], cols.fconst[2][b]]
                    };
                    // J: E m0 m1 x^(m1 - 1) summed per channel, the lobes' dI/dx
                    let mut dx = [zero; 3];
                    // 1 / x, J only
                    let inv_x = if J {
                        s.div_f32s(one, s.max_f32s(g.x, s.splat_f32s(1e-30)))
                    } else {
                        zero
                    };
                    for grp in &self.setup.plan.groups {
                        let (xb, dp) = match grp.exp_col {
                            Some(col) => {
                                let m1 = coef::<S, P>(s, &cols, self.setup, &g, b, col);
                                let t = s.mul_f32s(m1, g.l2);
                                if underflows(s, t, g.up) {
                                    continue;
                                }
                                let xb = exp2(s, t);
                                let dp = if J {
                                    dpow(s, m1, xb, inv_x, g.pos)
                                } else {
                                    zero
                                };
                                (Some(xb), dp)
                            }
                            None => (None, zero),
                        };
                        for lobe in &grp.lobes {
                            if lobe.zero_scale {
                                continue;
                            }
                            // a log2(e): the scale columns are stored so
                            let a2 = coef::<S, P>(s, &cols, self.setup, &g, b, lobe.a_col);
                            let u = xb.map_or(a2, |xb| s.mul_f32s(a2, xb));
                            let em1 = exp2m1(s, u);
                            add_channels(s, lobe.channels, em1, &mut f);
                            if J && xb.is_some() {
                                let a = s.mul_f32s(a2, s.splat_f32s(std::f32::consts::LN_2));
                                let ead = s.mul_f32s(s.mul_f32s(s.add_f32s(em1, one), a), dp);
                                add_channels(s, lobe.channels, ead, &mut dx);
                            }
                        }
                    }
                    for k in 0..3 {
                        acc[k] = s.mul_add_e_f32s(s.mul_f32s(f[k], g.c), cols.ld[k][b], acc[k]);
                    }
                    if J {
                        let ld = [0, 1, 2].map(|k| cols.ld[k][b]);
                        let w = [0, 1, 2].map(|a| cols.w[a][b]);
                        let c_dx = dx.map(|d| s.mul_f32s(g.c, d));
                        add_jacobian(s, g.up, ld, &f, c_dx, w, &g.h, &mut jac);
                    }
                }
                for k in 0..3 {
                    out[k] += s.reduce_sum_f32s(acc[k]) as f64;
                }
                if J {
                    for (o, v) in jac_out.iter_mut().zip(jac) {
                        *o += s.reduce_sum_f32s(v) as f64;
                    }
                }
            }
        }
    }
}
