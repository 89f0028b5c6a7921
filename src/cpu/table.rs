//! What the fast path's kernels read: the texels as structure-of-arrays f32 columns in
//! 4 x 4 tiles of the map (so that the texels of one SIMD block are close on the sphere and
//! mostly on the same side of a pixel's horizon), the pixels as f32 records, and the
//! material reduced to the lobe terms a scene needs ([`LobePlan`]). Built from a
//! [`Prepared`] scene, whose f64 per-texel work (directions, solid angles, orthographic half
//! vectors and spline coefficients) it reuses.

use crate::material::{N_PARAMS, idx};
use crate::prepare::{N_COEF_VALUES, Prepared};
use crate::spline::N_CTRL_POINTS;

/// Texel columns are padded to a multiple of this (the widest SIMD block, AVX-512).
pub const PAD: usize = 16;

/// Added to 1 - x for texels whose half vector is undefined (w_i = -w_p), so that x = 0.
const NO_HALF_VECTOR: f32 = 1.0;

/// Which lobe terms one pair needs, with terms shared where the material repeats itself:
/// channels whose lobe has the same exponent control points share x^m1 (one group), and
/// channels with the same scale and exponent points share the whole lobe.
#[derive(Clone, Debug, Default)]
pub struct LobePlan {
    /// Lobes grouped by their exponent curve.
    pub groups: Vec<ExpGroup>,
}

/// The lobes that share one exponent curve.
#[derive(Clone, Debug)]
pub struct ExpGroup {
    /// Coefficient column (k * 3 + s) * 2 + 1 of the exponent, or None for an exponent
    /// that is 0 everywhere (x^0 = 1).
    pub exp_col: Option<usize>,
    /// Its unique lobes.
    pub lobes: Vec<PlanLobe>,
}

/// One unique lobe: exp(a x^b) - 1, evaluated once for every (k, s) it stands for.
#[derive(Clone, Copy, Debug)]
pub struct PlanLobe {
    /// Coefficient column (k * 3 + s) * 2 of its scale a.
    pub a_col: usize,
    /// Bit k set: channel k has this lobe, as lobe `slot[k]`.
    pub channels: u8,
    /// The lobe index s for each channel in `channels`.
    pub slot: [usize; 3],
    /// Every scale point is 0: the lobe adds nothing to f (exp(0) - 1), only its x^b to
    /// the gradient of its scale.
    pub zero_scale: bool,
}

fn curve(ctrl: &[f64; N_PARAMS], k: usize, s: usize, t: usize) -> [f64; N_CTRL_POINTS] {
    std::array::from_fn(|j| ctrl[idx(k, s, t, j)])
}

impl LobePlan {
    /// The plan for the lobes whose (k, s) `keep` accepts: a (k, s) joins an existing
    /// unique lobe when both its curves are equal to that lobe's, and an existing group
    /// when its exponent curve is.
    pub fn new(ctrl: &[f64; N_PARAMS], keep: impl Fn(usize, usize) -> bool) -> Self {
        let mut plan = LobePlan::default();
        let mut exp_curves: Vec<[f64; N_CTRL_POINTS]> = Vec::new();
        for s in 0..3 {
            for k in 0..3 {
                if !keep(k, s) {
                    continue;
                }
                let (sc, ex) = (curve(ctrl, k, s, 0), curve(ctrl, k, s, 1));
                let zero_exp = ex.iter().all(|&v| v == 0.0);
                let g = match exp_curves.iter().position(|c| *c == ex) {
                    Some(g) => g,
                    None => {
                        exp_curves.push(ex);
                        plan.groups.push(ExpGroup {
                            exp_col: (!zero_exp).then_some((k * 3 + s) * 2 + 1),
                            lobes: Vec::new(),
                        });
                        plan.groups.len() - 1
                    }
                };
                let lobes = &mut plan.groups[g].lobes;
                let same = lobes.iter().position(|l| {
                    let (lk, ls) = (
                        l.channels.trailing_zeros() as usize,
                        l.slot[l.channels.trailing_zeros() as usize],
                    );
                    curve(ctrl, lk, ls, 0) == sc && l.channels & (1 << k) == 0
                });
                match same {
                    Some(l) => {
                        lobes[l].channels |= 1 << k;
                        lobes[l].slot[k] = s;
                    }
                    None => {
                        let mut slot = [0; 3];
                        slot[k] = s;
                        lobes.push(PlanLobe {
                            a_col: (k * 3 + s) * 2,
                            channels: 1 << k,
                            slot,
                            zero_scale: sc.iter().all(|&v| v == 0.0),
                        });
                    }
                }
            }
        }
        plan
    }

    /// The scale columns of the lobes whose exponent is 0 everywhere.
    pub fn const_columns(&self) -> Vec<usize> {
        let consts = self.groups.iter().filter(|g| g.exp_col.is_none());
        consts
            .flat_map(|g| g.lobes.iter().map(|l| l.a_col))
            .collect()
    }

    /// The coefficient columns the plan reads.
    pub fn columns(&self) -> Vec<usize> {
        let mut cols = Vec::new();
        for g in &self.groups {
            cols.extend(g.exp_col);
            cols.extend(g.lobes.iter().map(|l| l.a_col));
        }
        cols
    }
}

/// A lobe contributes to the image when some scale control point is not 0.
pub fn has_scale(ctrl: &[f64; N_PARAMS], k: usize, s: usize) -> bool {
    curve(ctrl, k, s, 0).iter().any(|&v| v != 0.0)
}

/// A lobe's share of f depends on x when it has a scale and some exponent point is not 0.
pub fn depends_on_x(ctrl: &[f64; N_PARAMS], k: usize, s: usize) -> bool {
    has_scale(ctrl, k, s) && curve(ctrl, k, s, 1).iter().any(|&v| v != 0.0)
}

/// What the kernels' copy of coefficient column `col` is multiplied by: log2(e) for the
/// scales (t = 0), so that exp(a x^b) - 1 is 2^(a log2(e) x^b) - 1, and 1 for the exponents.
pub fn column_scale(col: usize) -> f64 {
    if col.is_multiple_of(2) {
        std::f64::consts::LOG2_E
    } else {
        1.0
    }
}

/// Texels as f32 columns, tile-ordered, padded with inert texels (w = 0, so n.w = 0 and
/// they are never lit from above a pixel's horizon) to a multiple of [`PAD`].
#[derive(Clone, Debug, Default)]
pub struct TexelTable {
    /// Number of real texels (the rest is padding).
    pub len: usize,
    /// Position in `Prepared::texels` of each real texel.
    pub src: Vec<usize>,
    /// Direction towards the light.
    pub w: [Vec<f32>; 3],
    /// Orthographic: the half vector (0 where undefined).
    pub h: [Vec<f32>; 3],
    /// Orthographic: added to 1 - x (0, or 1 where the half vector is undefined).
    pub d_pad: Vec<f32>,
    /// L^k d_omega.
    pub ld: [Vec<f32>; 3],
    /// Orthographic: the constant lobes' share of f per channel (exp(m0) - 1 summed).
    pub fconst: [Vec<f32>; 3],
    /// Orthographic: the coefficient columns the plan reads (indexed by column; empty
    /// for columns no lobe needs), each times [`column_scale`].
    pub coef: Vec<Vec<f32>>,
    /// Orthographic: exp(m0) - 1 per texel for the scale columns of lobes whose exponent is
    /// 0 everywhere (indexed by the scale's column; empty for others): their value does not
    /// depend on the pixel.
    pub em1: Vec<Vec<f32>>,
}

impl TexelTable {
    /// The texels `which` (positions in `prep.texels`), tile-ordered. `cols` are the
    /// coefficient columns the kernels will read, `const_cols` the scale columns whose
    /// exp(m0) - 1 they will read, and `const_lobes` the (k, s) summed into `fconst`
    /// (orthographic cameras only).
    pub fn new(
        prep: &Prepared,
        which: &[usize],
        cols: &[usize],
        const_cols: &[usize],
        const_lobes: &[(usize, usize)],
    ) -> Self {
        let wl = prep.env_width;
        let tile = |ti: usize| {
            let i = prep.texels[ti].index;
            let (r, c) = (i / wl, i % wl);
            ((r / 4) * wl.div_ceil(4) + c / 4, (r % 4) * 4 + c % 4)
        };
        let mut src = which.to_vec();
        src.sort_by_key(|&ti| tile(ti));
        let len = src.len();
        let padded = len.div_ceil(PAD) * PAD;
        let ortho = prep.camera.is_orthographic();
        let col = |f: &dyn Fn(usize) -> f32| -> Vec<f32> {
            let mut v: Vec<f32> = src.iter().map(|&ti| f(ti)).collect();
            v.resize(padded, 0.0);
            v
        };
        let t = &prep.texels;
        let mut coef = vec![Vec::new(); N_COEF_VALUES];
        let mut em1 = vec![Vec::new(); N_COEF_VALUES];
        if ortho {
            for &c in cols {
                coef[c] = col(&|ti| (t[ti].coef[c] * column_scale(c)) as f32);
            }
            for &c in const_cols {
                em1[c] = col(&|ti| t[ti].coef[c].exp_m1() as f32);
            }
        }
        let fconst = std::array::from_fn(|k| {
            col(&|ti| {
                if !ortho {
                    return 0.0;
                }
                let m = &t[ti].coef;
                let f: f64 = const_lobes
                    .iter()
                    .filter(|&&(kk, _)| kk == k)
                    .map(|&(_, s)| m[(k * 3 + s) * 2].exp_m1())
                    .sum();
                f as f32
            })
        });
        TexelTable {
            len,
            w: std::array::from_fn(|a| col(&|ti| t[ti].w[a] as f32)),
            h: std::array::from_fn(|a| col(&|ti| t[ti].h[a] as f32)),
            d_pad: col(&|ti| {
                if t[ti].h == [0.0; 3] {
                    NO_HALF_VECTOR
                } else {
                    0.0
                }
            }),
            ld: std::array::from_fn(|k| col(&|ti| t[ti].ld[k] as f32)),
            fconst,
            coef,
            em1,
            src,
        }
    }

    /// Number of SIMD blocks of `lanes` texels.
    pub fn blocks(&self, lanes: usize) -> usize {
        self.w[0].len() / lanes
    }
}

/// One foreground pixel as the kernels read it.
#[derive(Clone, Copy, Debug, Default)]
pub struct Px {
    /// Normal.
    pub n: [f32; 3],
    /// |n|^2 - 1, from f64.
    pub nn_m1: f32,
    /// View direction (perspective).
    pub wp: [f32; 3],
}

/// The pixels of a prepared scene.
pub fn pixels(prep: &Prepared) -> Vec<Px> {
    prep.pixels
        .iter()
        .map(|p| Px {
            n: p.n.map(|v| v as f32),
            nn_m1: p.nn_m1 as f32,
            wp: p.wp.map(|v| v as f32),
        })
        .collect()
}
