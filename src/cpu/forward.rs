//! The image, f32 SIMD. Mirrors src/reference/forward.rs: per pixel, the sum over lit
//! texels of f^k L^k d_omega max(0, n.w), with texels in SIMD lanes.

use pulp::{Simd, WithSimd};

use super::math::{exp2, exp2m1};
use super::pair::{Cols, Setup, add_channels, coef, geo, underflows};
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
}

impl WithSimd for Forward<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        if self.setup.perspective {
            self.run::<S, true>(s)
        } else {
            self.run::<S, false>(s)
        }
    }
}

impl Forward<'_> {
    /// The pass for a perspective (`P`) or orthographic camera.
    #[inline(always)]
    fn run<S: Simd, const P: bool>(self, s: S) {
        let cols = Cols::<S>::new(self.table);
        let n_blocks = self.table.blocks(S::F32_LANES);
        let per_group = (GROUP_TEXELS / S::F32_LANES).max(1);
        let zero = s.splat_f32s(0.0);
        for g0 in (0..n_blocks).step_by(per_group) {
            let g1 = (g0 + per_group).min(n_blocks);
            for (p, out) in self.px.iter().zip(self.out.iter_mut()) {
                let mut acc = [zero; 3];
                for b in g0..g1 {
                    let Some(g) = geo::<S, P>(s, &cols, p, b) else {
                        continue;
                    };
                    let mut f = if P {
                        [zero; 3]
                    } else {
                        [cols.fconst[0][b], cols.fconst[1][b], cols.fconst[2][b]]
                    };
                    for grp in &self.setup.plan.groups {
                        let xb = match grp.exp_col {
                            Some(col) => {
                                let t = s
                                    .mul_f32s(coef::<S, P>(s, &cols, self.setup, &g, b, col), g.l2);
                                if underflows(s, t, g.up) {
                                    continue;
                                }
                                Some(exp2(s, t))
                            }
                            None => None,
                        };
                        for lobe in &grp.lobes {
                            if lobe.zero_scale {
                                continue;
                            }
                            // a log2(e): the scale columns are stored so
                            let a2 = coef::<S, P>(s, &cols, self.setup, &g, b, lobe.a_col);
                            let u = xb.map_or(a2, |xb| s.mul_f32s(a2, xb));
                            add_channels(s, lobe.channels, exp2m1(s, u), &mut f);
                        }
                    }
                    for k in 0..3 {
                        acc[k] = s.mul_add_e_f32s(s.mul_f32s(f[k], g.c), cols.ld[k][b], acc[k]);
                    }
                }
                for k in 0..3 {
                    out[k] += s.reduce_sum_f32s(acc[k]) as f64;
                }
            }
        }
    }
}
