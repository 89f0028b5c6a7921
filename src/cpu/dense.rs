//! Kernels for materials with nothing to share, orthographic cameras: every channel has the
//! same number L of lobes, each with its own exponent curve and a scale (what a network, a
//! fit or a random draw produces). The plan loops of [`super::forward`] and
//! [`super::backward`] pay for their generality there: per lobe a branch on underflow, a
//! branch in 2^u - 1, bounds-checked column reads and, in the backward pass, read-modify-
//! writes of per-texel sums in memory. Here the lobes are a compile-time count (L = 1, 2
//! or 3 per channel), each block's texel data is one record, the lobes' work has no branch
//! and the backward pass runs texel blocks outside pixels, so that a block's sums stay in
//! registers while the pixels stream past.
//!
//! The same formulas as the plan kernels, rearranged exactly: per-texel factors (L d_omega,
//! the scale a, ln 2) leave the pair loop and multiply the texel sums once per block, and
//! m1 x^(m1 - 1) = m1 x^m1 / x is summed over a channel's lobes before the division.

use pulp::{Simd, WithSimd};

use super::backward::TEXEL_SUMS;
use super::math::{EXP2M1_Q, any, exp2, exp2m1_reduced, horner};
use super::pair::{add_jacobian, dot3, underflows, x_terms};
use super::table::{LobePlan, Px, TexelTable};
use crate::material::{N_PARAMS, idx};

/// Fields of a block record before the lobes': w (3), h (3), d_pad, L d_omega (3) and the
/// constant lobes' f (3).
const HEAD: usize = 13;
/// Fields per lobe: m1, a log2(e) and a m1 (a the scale, m1 the exponent at the texel).
const PER_LOBE: usize = 3;
/// Blocks per f32 group of a pixel's lane sums (as [`super::forward::GROUP_TEXELS`] for
/// 16 lanes; fewer, so that a group's records stay in the first-level cache).
const GROUP_BLOCKS: usize = 8;

/// The lobes of a dense material, channel by channel: lobe `k * l + i` is channel k's i-th.
#[derive(Clone, Debug)]
pub struct Dense {
    /// Lobes per channel.
    pub l: usize,
    /// Per lobe: (k, s), its exponent column and its scale column.
    pub lobes: Vec<((usize, usize), usize, usize)>,
    /// Per lobe: whether its exponent reaches [`SHARP_EXPONENT`], so that x^m1 is often 0
    /// in every lane of a pair block and the lobe is worth a test that skips it.
    pub sharp: Vec<bool>,
    /// Per lobe: whether |a log2(e)| < [`SMALL_SCALE`] at every control point, so that
    /// |a log2(e) x^m1| < 1/2 at every pair and 2^u - 1 needs no range reduction.
    pub small: Vec<bool>,
}

/// A bound on |a log2(e)| under which a lobe's 2^u - 1 skips its range reduction: u = a
/// log2(e) x^m1 with x^m1 <= 1 (up to the rounding of 2^t, 1.1e-7) stays within 1/2, where
/// the reduction takes k = 0 and f = u, and its result is bitwise the polynomial's alone.
/// The scale's curve is a convex combination of its control points (the B-spline basis is
/// non-negative and sums to 1), so the control points bound it.
pub const SMALL_SCALE: f64 = 0.49;

/// Exponent groups from which a backward pass runs every lobe through the dense kernels
/// rather than the plan kernels. Measured on the presets (sphere 128, 64 x 128 sky, the
/// backward call's time, plan / dense): 6 to 9 groups 1.27x to 2.08x, 2 to 4 groups 0.84x
/// to 1.21x, 0 and 1 group 0.58x and 0.89x (`cargo xtask cpu_kernels`).
pub const ALL_LOBES_FROM_GROUPS: usize = 5;

/// An exponent from which a lobe is tested for underflow per pair block: x^m1 = 0 in f32
/// for x < 2^(-127 / m1), below 0.41 at m1 = 100. Measured on the presets (sphere 128):
/// without the test the plan kernels were up to 1.3x faster on the sharpest.
pub const SHARP_EXPONENT: f64 = 100.0;

impl Dense {
    /// The dense shape of `plan`, if it has one: every group one lobe of one channel with
    /// an exponent and a scale, and as many lobes in every channel.
    pub fn of(plan: &LobePlan, ctrl: &[f64; N_PARAMS]) -> Option<Dense> {
        let mut lobes = Vec::new();
        for g in &plan.groups {
            let [lobe] = g.lobes.as_slice() else {
                return None;
            };
            let exp_col = g.exp_col?;
            if lobe.zero_scale || lobe.channels.count_ones() != 1 {
                return None;
            }
            let k = lobe.channels.trailing_zeros() as usize;
            lobes.push(((k, lobe.slot[k]), exp_col, lobe.a_col));
        }
        lobes.sort_by_key(|&(ks, _, _)| ks);
        let l = lobes.len() / 3;
        let even = (0..3).all(|k| lobes.iter().filter(|((kk, _), _, _)| *kk == k).count() == l);
        (l > 0 && even).then(|| Dense::new(l, lobes, ctrl))
    }

    fn new(l: usize, lobes: Vec<((usize, usize), usize, usize)>, ctrl: &[f64; N_PARAMS]) -> Self {
        let sharp = lobes
            .iter()
            .map(|&((k, s), _, _)| (0..6).any(|j| ctrl[idx(k, s, 1, j)] >= SHARP_EXPONENT))
            .collect();
        let small = lobes
            .iter()
            .map(|&((k, s), _, _)| {
                (0..6).all(|j| ctrl[idx(k, s, 0, j)].abs() * std::f64::consts::LOG2_E < SMALL_SCALE)
            })
            .collect();
        Dense {
            l,
            lobes,
            sharp,
            small,
        }
    }

    /// The dense kernels for the backward pass of `plan` (every lobe): its own lobes when
    /// it is dense, else every lobe when it has at least [`ALL_LOBES_FROM_GROUPS`] exponent
    /// groups, else none (the plan kernels).
    pub fn for_backward(plan: &LobePlan, ctrl: &[f64; N_PARAMS]) -> Option<Dense> {
        let groups = plan.groups.iter().filter(|g| g.exp_col.is_some()).count();
        Dense::of(plan, ctrl)
            .or_else(|| (groups >= ALL_LOBES_FROM_GROUPS).then(|| Dense::all(ctrl)))
    }

    /// Every lobe of every channel, whatever its curves: exact for any material (a lobe
    /// with exponent 0 has x^0 = 1, one with scale 0 adds 0 to f and its x^m1 to dLoss/dm0).
    pub fn all(ctrl: &[f64; N_PARAMS]) -> Dense {
        let lobes = (0..3)
            .flat_map(|k| (0..3).map(move |s| ((k, s), (k * 3 + s) * 2 + 1, (k * 3 + s) * 2)))
            .collect();
        Dense::new(3, lobes, ctrl)
    }

    /// The coefficient columns the records read.
    pub fn columns(&self) -> Vec<usize> {
        self.lobes.iter().flat_map(|&(_, e, a)| [e, a]).collect()
    }

    /// Fields per block record.
    pub fn stride(&self) -> usize {
        HEAD + PER_LOBE * self.lobes.len()
    }

    /// The block records of `table` for `lanes`-wide blocks: per block, each field's
    /// `lanes` values.
    pub fn records(&self, table: &TexelTable, lanes: usize) -> Vec<f32> {
        let n_blocks = table.blocks(lanes);
        let stride = self.stride();
        let mut out = vec![0.0f32; n_blocks * stride * lanes];
        let head: [&[f32]; HEAD] = [
            &table.w[0],
            &table.w[1],
            &table.w[2],
            &table.h[0],
            &table.h[1],
            &table.h[2],
            &table.d_pad,
            &table.ld[0],
            &table.ld[1],
            &table.ld[2],
            &table.fconst[0],
            &table.fconst[1],
            &table.fconst[2],
        ];
        let ln2 = std::f32::consts::LN_2;
        for b in 0..n_blocks {
            let rec = &mut out[b * stride * lanes..(b + 1) * stride * lanes];
            let texels = b * lanes..(b + 1) * lanes;
            for (f, col) in head.iter().enumerate() {
                rec[f * lanes..(f + 1) * lanes].copy_from_slice(&col[texels.clone()]);
            }
            for (u, &(_, e, a)) in self.lobes.iter().enumerate() {
                for (lane, t) in texels.clone().enumerate() {
                    let (m1, a2) = (table.coef[e][t], table.coef[a][t]);
                    let f = HEAD + PER_LOBE * u;
                    rec[f * lanes + lane] = m1;
                    rec[(f + 1) * lanes + lane] = a2;
                    rec[(f + 2) * lanes + lane] = a2 * ln2 * m1;
                }
            }
        }
        out
    }
}

/// One pair block's geometry: the pixel's normal against a block record.
struct Pair<S: Simd> {
    /// max(0, n.w).
    c: S::f32s,
    up: S::m32s,
    /// x = max(0, h.n).
    x: S::f32s,
    lnx: S::f32s,
    l2: S::f32s,
}

#[inline(always)]
fn pair<S: Simd>(s: S, r: &[S::f32s], n: &[S::f32s; 3], nn_m1: S::f32s) -> Option<Pair<S>> {
    let zero = s.splat_f32s(0.0);
    let c = dot3(s, n, &[r[0], r[1], r[2]]);
    let up = s.greater_than_f32s(c, zero);
    if !any(s, up) {
        return None;
    }
    let xt = x_terms(s, &[r[3], r[4], r[5]], n, nn_m1, r[6]);
    Some(Pair {
        c: s.select_f32s(up, c, zero),
        up,
        x: xt.x,
        lnx: xt.lnx,
        l2: xt.l2,
    })
}

/// Lobe `u`'s exponent of x^m1 = 2^t at this pair: t = m1 log2 x.
#[inline(always)]
fn lobe_t<S: Simd>(s: S, r: &[S::f32s], u: usize, l2: S::f32s) -> S::f32s {
    s.mul_f32s(r[HEAD + PER_LOBE * u], l2)
}

/// Lobe `u`'s x^m1 = 2^t and 2^(a log2(e) x^m1) - 1; `small`: |a log2(e)| < 1/2 (see
/// [`SMALL_SCALE`]), where the range reduction is the identity and is left out.
#[inline(always)]
fn lobe<S: Simd>(s: S, r: &[S::f32s], u: usize, t: S::f32s, small: bool) -> (S::f32s, S::f32s) {
    let xb = exp2(s, t);
    let v = s.mul_f32s(r[HEAD + PER_LOBE * u + 1], xb);
    // |a log2(e) x^m1| <= 40 log2(e) < 126: the scale's bound, x^m1 <= 1
    let em1 = if small {
        s.mul_f32s(v, horner(s, v, &EXP2M1_Q))
    } else {
        exp2m1_reduced(s, v)
    };
    (xb, em1)
}

/// A dense kernel, instantiated per lobe count and underflow test.
trait Kernel: Sized {
    fn dense(&self) -> &Dense;
    fn run<S: Simd, const L: usize, const SKIP: bool>(self, s: S);
}

/// Runs `k` with `L` lobes per channel, with the underflow test where a lobe is sharp.
#[inline(always)]
fn run<K: Kernel, S: Simd>(k: K, s: S) {
    match (k.dense().l, k.dense().sharp.contains(&true)) {
        (1, false) => k.run::<S, 1, false>(s),
        (2, false) => k.run::<S, 2, false>(s),
        (_, false) => k.run::<S, 3, false>(s),
        (1, true) => k.run::<S, 1, true>(s),
        (2, true) => k.run::<S, 2, true>(s),
        (_, true) => k.run::<S, 3, true>(s),
    }
}

/// The image sums of pixels `px` against every block of `records` (see [`Dense::records`]).
pub struct DenseForward<'a> {
    pub dense: &'a Dense,
    pub records: &'a [f32],
    pub px: &'a [Px],
    pub out: &'a mut [[f64; 3]],
}

impl WithSimd for DenseForward<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        run(self, s)
    }
}

impl Kernel for DenseForward<'_> {
    fn dense(&self) -> &Dense {
        self.dense
    }

    #[inline(always)]
    fn run<S: Simd, const L: usize, const SKIP: bool>(self, s: S) {
        let stride = HEAD + PER_LOBE * 3 * L;
        let recs = S::as_simd_f32s(self.records).0;
        let n_blocks = recs.len() / stride;
        let zero = s.splat_f32s(0.0);
        let sharp: [bool; 9] = std::array::from_fn(|u| self.dense.sharp.get(u) == Some(&true));
        let small: [bool; 9] = std::array::from_fn(|u| self.dense.small.get(u) == Some(&true));
        for g0 in (0..n_blocks).step_by(GROUP_BLOCKS) {
            let group = &recs[g0 * stride..(g0 + GROUP_BLOCKS).min(n_blocks) * stride];
            for (p, out) in self.px.iter().zip(self.out.iter_mut()) {
                let n = p.n.map(|v| s.splat_f32s(v));
                let nn_m1 = s.splat_f32s(p.nn_m1);
                let mut acc = [zero; 3];
                for r in group.chunks_exact(stride) {
                    let Some(g) = pair(s, r, &n, nn_m1) else {
                        continue;
                    };
                    for k in 0..3 {
                        let mut f = r[10 + k];
                        for i in 0..L {
                            let u = k * L + i;
                            let t = lobe_t(s, r, u, g.l2);
                            // a sharp lobe whose x^m1 is 0 in every lit lane adds 0
                            if SKIP && sharp[u] && underflows(s, t, g.up) {
                                continue;
                            }
                            f = s.add_f32s(f, lobe(s, r, u, t, small[u]).1);
                        }
                        acc[k] = s.mul_add_e_f32s(s.mul_f32s(f, g.c), r[7 + k], acc[k]);
                    }
                }
                for k in 0..3 {
                    out[k] += s.reduce_sum_f32s(acc[k]) as f64;
                }
            }
        }
    }
}

/// dLoss/dL, dLoss/dn and the texel sums for dLoss/dctrl of pixels `px` (upstream `g`)
/// against every block of `records`: every gradient, texel blocks outside pixels.
pub struct DenseBackward<'a> {
    pub dense: &'a Dense,
    pub records: &'a [f32],
    /// Real texels (the rest of the last block is padding).
    pub n_texels: usize,
    pub px: &'a [Px],
    pub g: &'a [[f32; 3]],
    /// dLoss/dn per pixel of `px`, added into.
    pub dn: &'a mut [[f64; 3]],
    /// Per texel, [`super::backward::TEXEL_SUMS`] sums, added into.
    pub tex: &'a mut [f64],
    /// With it, also dI^k/dn per pixel of `px` (index k * 3 + axis), added into: the
    /// normals' Jacobian, in the same pass.
    pub jac: Option<&'a mut [[f64; 9]]>,
}

impl WithSimd for DenseBackward<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        run(self, s)
    }
}

impl Kernel for DenseBackward<'_> {
    fn dense(&self) -> &Dense {
        self.dense
    }

    #[inline(always)]
    fn run<S: Simd, const L: usize, const SKIP: bool>(self, s: S) {
        if self.jac.is_some() {
            self.body::<S, L, SKIP, true>(s)
        } else {
            self.body::<S, L, SKIP, false>(s)
        }
    }
}

impl DenseBackward<'_> {
    /// The pass, with the normals' Jacobian (`J`) or without.
    #[inline(always)]
    fn body<S: Simd, const L: usize, const SKIP: bool, const J: bool>(mut self, s: S) {
        let lanes = S::F32_LANES;
        let stride = HEAD + PER_LOBE * 3 * L;
        let recs = S::as_simd_f32s(self.records).0;
        let n_blocks = recs.len() / stride;
        let zero = s.splat_f32s(0.0);
        let sharp: [bool; 9] = std::array::from_fn(|u| self.dense.sharp.get(u) == Some(&true));
        let one = s.splat_f32s(1.0);
        // dLoss/dn lane sums per pixel over a group of blocks
        let mut dn_lanes = vec![[zero; 3]; self.px.len()];
        // J: dI^k/dn lane sums per pixel over a group of blocks
        let mut jac_lanes = vec![[zero; 9]; if J { self.px.len() } else { 0 }];
        for g0 in (0..n_blocks).step_by(GROUP_BLOCKS) {
            let g1 = (g0 + GROUP_BLOCKS).min(n_blocks);
            for b in g0..g1 {
                let r = &recs[b * stride..(b + 1) * stride];
                let w = [r[0], r[1], r[2]];
                let h = [r[3], r[4], r[5]];
                let ld = [r[7], r[8], r[9]];
                // per channel sum g c f; per lobe sums g c x^m1 E and g c ln x x^m1 E
                let mut dl = [zero; 3];
                let mut d0 = [[zero; L]; 3];
                let mut d1 = [[zero; L]; 3];
                for (q, ((p, gp), dnl)) in self
                    .px
                    .iter()
                    .zip(self.g)
                    .zip(dn_lanes.iter_mut())
                    .enumerate()
                {
                    let n = p.n.map(|v| s.splat_f32s(v));
                    let Some(g) = pair(s, r, &n, s.splat_f32s(p.nn_m1)) else {
                        continue;
                    };
                    let inv_x = s.div_f32s(one, s.max_f32s(g.x, s.splat_f32s(1e-30)));
                    let cx = s.mul_f32s(g.c, inv_x);
                    let mut along_w = zero;
                    let mut along_h = zero;
                    // J: per channel f and the lobes' dI/dx times x
                    let (mut fk, mut dxk) = ([zero; 3], [zero; 3]);
                    for k in 0..3 {
                        let gk = s.splat_f32s(gp[k]);
                        let gc = s.mul_f32s(gk, g.c);
                        let gcl = s.mul_f32s(gc, g.lnx);
                        let mut f = zero;
                        // sum of a ln2 m1 x^m1 E: times 1 / x, the lobes' dI/dx
                        let mut dx = zero;
                        for i in 0..L {
                            let u = k * L + i;
                            let t = lobe_t(s, r, u, g.l2);
                            if SKIP && sharp[u] && underflows(s, t, g.up) {
                                continue;
                            }
                            // the skipped reduction measured no gain here (46.5 against 45.9
                            // instructions per pair, random-1 at AVX2): more live registers
                            let (xb, em1) = lobe(s, r, u, t, false);
                            // E x^m1 with E = 2^u = em1 + 1
                            let t1 = s.mul_add_e_f32s(em1, xb, xb);
                            f = s.add_f32s(f, em1);
                            dx = s.mul_add_e_f32s(r[HEAD + PER_LOBE * u + 2], t1, dx);
                            d0[k][i] = s.mul_add_e_f32s(gc, t1, d0[k][i]);
                            d1[k][i] = s.mul_add_e_f32s(gcl, t1, d1[k][i]);
                        }
                        dl[k] = s.mul_add_e_f32s(gc, f, dl[k]);
                        fk[k] = f;
                        dxk[k] = dx;
                        let gl = s.mul_f32s(gk, ld[k]);
                        along_w = s.mul_add_e_f32s(gl, f, along_w);
                        along_h = s.mul_add_e_f32s(gl, dx, along_h);
                    }
                    if J {
                        let c_dx = dxk.map(|d| s.mul_f32s(cx, d));
                        add_jacobian(s, g.up, ld, &fk, c_dx, w, &h, &mut jac_lanes[q]);
                    }
                    let along_w = s.select_f32s(g.up, along_w, zero);
                    let ch = s.mul_f32s(s.mul_f32s(g.c, along_h), inv_x);
                    for a in 0..3 {
                        dnl[a] =
                            s.mul_add_e_f32s(along_w, w[a], s.mul_add_e_f32s(ch, h[a], dnl[a]));
                    }
                }
                self.flush::<S, L>(r, b * lanes, &dl, &d0, &d1);
            }
            for (out, dnl) in self.dn.iter_mut().zip(dn_lanes.iter_mut()) {
                for a in 0..3 {
                    out[a] += s.reduce_sum_f32s(dnl[a]) as f64;
                }
                *dnl = [zero; 3];
            }
            if let Some(jac) = self.jac.as_deref_mut() {
                for (out, jl) in jac.iter_mut().zip(jac_lanes.iter_mut()) {
                    for (o, v) in out.iter_mut().zip(jl.iter()) {
                        *o += s.reduce_sum_f32s(*v) as f64;
                    }
                    *jl = [zero; 9];
                }
            }
        }
    }

    /// Adds block `r`'s lane sums to the texel sums of its texels (from `first`): dLoss/dL
    /// / d_omega, and dLoss/dm0, dLoss/dm1 at the texel's theta_d with the per-texel factors
    /// L d_omega (both) and a ln 2 (dm1) applied here.
    fn flush<S: Simd, const L: usize>(
        &mut self,
        r: &[S::f32s],
        first: usize,
        dl: &[S::f32s; 3],
        d0: &[[S::f32s; L]; 3],
        d1: &[[S::f32s; L]; 3],
    ) {
        let f32s = lanes_of::<S>;
        let ln2 = std::f64::consts::LN_2;
        for lane in 0..S::F32_LANES {
            let ti = first + lane;
            if ti >= self.n_texels {
                break;
            }
            let t = &mut self.tex[ti * TEXEL_SUMS..(ti + 1) * TEXEL_SUMS];
            for k in 0..3 {
                t[k] += f32s(&dl[k])[lane] as f64;
                let ld = f32s(&r[7 + k])[lane] as f64;
                for i in 0..L {
                    let u = k * L + i;
                    let ((_, sl), _, _) = self.dense.lobes[u];
                    let a2 = f32s(&r[HEAD + PER_LOBE * u + 1])[lane] as f64;
                    let at = 3 + (k * 3 + sl) * 2;
                    t[at] += f32s(&d0[k][i])[lane] as f64 * ld;
                    t[at + 1] += f32s(&d1[k][i])[lane] as f64 * ld * a2 * ln2;
                }
            }
        }
    }
}

/// The f32 lanes of one SIMD vector.
#[inline(always)]
fn lanes_of<S: Simd>(v: &S::f32s) -> &[f32] {
    bytemuck::cast_slice(std::slice::from_ref(v))
}
