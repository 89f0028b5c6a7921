//! The per-pair terms shared by the fast path's passes, for one pixel against one block of
//! texels (one texel per SIMD lane): the horizon test, the half vector, x and ln x
//! without cancellation, the spline basis (perspective) and the lobe values. Mirrors
//! `pair_terms`, `lobe_x` and `lobe_grads` of the f64 reference (src/reference/common.rs).

use pulp::Simd;

use super::math::{any, ln_1m};
use super::table::{LobePlan, Px, TexelTable};

use crate::prepare::HALF_VECTOR_EPS;
use crate::spline::N_CTRL_POINTS;

/// log2 x stand-in at x = 0: b * NEG_BIG is finite for every exponent b <= 1e4 (the
/// material's bound; [`super::math::exp2`] takes finite arguments) and gives 2^(b NEG_BIG)
/// = 0 for b > 4e-33, and 0 * NEG_BIG = 0 gives x^0 = 1.
const NEG_BIG: f32 = -3.0e34;
/// The clamp of m1 x^(m1 - 1) in dL/dn, as in the reference.
pub const DPOW_MAX: f32 = 1e10;

/// The texel columns of one table, split into SIMD blocks.
pub struct Cols<'a, S: Simd> {
    pub w: [&'a [S::f32s]; 3],
    pub h: [&'a [S::f32s]; 3],
    pub d_pad: &'a [S::f32s],
    pub ld: [&'a [S::f32s]; 3],
    pub fconst: [&'a [S::f32s]; 3],
    pub coef: Vec<&'a [S::f32s]>,
    pub em1: Vec<&'a [S::f32s]>,
}

fn blocks<S: Simd>(v: &[f32]) -> &[S::f32s] {
    S::as_simd_f32s(v).0
}

impl<'a, S: Simd> Cols<'a, S> {
    pub fn new(t: &'a TexelTable) -> Self {
        Cols {
            w: t.w.each_ref().map(|v| blocks::<S>(v)),
            h: t.h.each_ref().map(|v| blocks::<S>(v)),
            d_pad: blocks::<S>(&t.d_pad),
            ld: t.ld.each_ref().map(|v| blocks::<S>(v)),
            fconst: t.fconst.each_ref().map(|v| blocks::<S>(v)),
            coef: t.coef.iter().map(|v| blocks::<S>(v)).collect(),
            em1: t.em1.iter().map(|v| blocks::<S>(v)).collect(),
        }
    }
}

/// What a pass needs besides the table: the plan, the control points (perspective) and
/// the camera.
pub struct Setup<'a> {
    pub plan: &'a LobePlan,
    /// The control points, scales times log2(e) (see [`super::table::column_scale`]).
    pub ctrl: &'a [f32; crate::N_PARAMS],
    pub perspective: bool,
}

/// The geometric terms of one pair block.
pub struct Geo<S: Simd> {
    /// max(0, n.w), 0 where the texel is below the horizon.
    pub c: S::f32s,
    /// Lanes where n.w > 0.
    pub up: S::m32s,
    /// x = max(0, h.n).
    pub x: S::f32s,
    /// Lanes where x > 0.
    pub pos: S::m32s,
    /// ln x where x > 0, else 0 (x^m1 ln x is taken as 0 at x = 0).
    pub lnx: S::f32s,
    /// log2 x where x > 0, else NEG_BIG.
    pub l2: S::f32s,
    /// The half vector.
    pub h: [S::f32s; 3],
    /// Perspective: the spline basis at the pair's theta_d.
    pub basis: [S::f32s; N_CTRL_POINTS],
}

/// m1 x^(m1 - 1) from m1, x^m1 and 1 / x: clamped at [`DPOW_MAX`], 0 where x = 0 (lanes
/// not in `pos`).
#[inline(always)]
pub fn dpow<S: Simd>(s: S, m1: S::f32s, xb: S::f32s, inv_x: S::f32s, pos: S::m32s) -> S::f32s {
    let dp = s.min_f32s(
        s.mul_f32s(s.mul_f32s(m1, xb), inv_x),
        s.splat_f32s(DPOW_MAX),
    );
    s.select_f32s(pos, dp, s.splat_f32s(0.0))
}

#[inline(always)]
pub fn dot3<S: Simd>(s: S, a: &[S::f32s; 3], b: &[S::f32s; 3]) -> S::f32s {
    s.mul_add_e_f32s(
        a[0],
        b[0],
        s.mul_add_e_f32s(a[1], b[1], s.mul_f32s(a[2], b[2])),
    )
}

/// atan(t) for t in [0, 1]: t P(t^2), P of degree 7, near-minimax: absolute error 4.7e-8
/// (fit), below f32 rounding of theta_d.
#[expect(
    clippy::excessive_precision,
    reason = "coefficients as fitted; the f32 rounding is part of the measured bound"
)]
const ATAN_P: [f32; 8] = [
    0.999_999_3,
    -0.333_298_62,
    0.199_465_66,
    -0.139_086_31,
    0.096_421_95,
    -0.055_912_256,
    0.021_862_89,
    -0.004_054_544_5,
];

/// atan2(y, x) for y, x >= 0, in [0, pi/2].
#[inline(always)]
fn atan2_pos<S: Simd>(s: S, y: S::f32s, x: S::f32s) -> S::f32s {
    let swap = s.greater_than_f32s(y, x);
    let hi = s.max_f32s(s.max_f32s(y, x), s.splat_f32s(1e-30));
    let t = s.div_f32s(s.min_f32s(y, x), hi);
    let t2 = s.mul_f32s(t, t);
    let mut p = s.splat_f32s(ATAN_P[7]);
    for i in (0..7).rev() {
        p = s.mul_add_e_f32s(p, t2, s.splat_f32s(ATAN_P[i]));
    }
    let a = s.mul_f32s(p, t);
    s.select_f32s(
        swap,
        s.sub_f32s(s.splat_f32s(std::f32::consts::FRAC_PI_2), a),
        a,
    )
}

/// The 6 quadratic B-spline basis functions at theta_d (closed form per span, as
/// `spline_basis_closed`), each lane in its own span.
#[inline(always)]
fn basis<S: Simd>(s: S, theta_d: S::f32s) -> [S::f32s; N_CTRL_POINTS] {
    let one = s.splat_f32s(1.0);
    let zero = s.splat_f32s(0.0);
    let half = s.splat_f32s(0.5);
    // tau in [0, 4]: knot spans of width 1
    let tau = s.min_f32s(
        s.max_f32s(
            s.mul_f32s(theta_d, s.splat_f32s(4.0 / std::f32::consts::FRAC_PI_2)),
            zero,
        ),
        s.splat_f32s(4.0),
    );
    let sq = |v: S::f32s| s.mul_f32s(v, v);
    let in_span = |lo: f32, hi: f32| {
        s.and_m32s(
            s.greater_than_or_equal_f32s(tau, s.splat_f32s(lo)),
            s.less_than_f32s(tau, s.splat_f32s(hi)),
        )
    };
    let (s0, s1, s2) = (in_span(0.0, 1.0), in_span(1.0, 2.0), in_span(2.0, 3.0));
    let s3 = s.greater_than_or_equal_f32s(tau, s.splat_f32s(3.0));
    // B_0: (1 - tau)^2 on [0, 1)
    let b0 = s.select_f32s(s0, sq(s.sub_f32s(one, tau)), zero);
    // B_1: tau (4 - 3 tau) / 2 on [0, 1), (2 - tau)^2 / 2 on [1, 2)
    let b1 = s.select_f32s(
        s0,
        s.mul_f32s(
            s.mul_f32s(half, tau),
            s.mul_add_e_f32s(s.splat_f32s(-3.0), tau, s.splat_f32s(4.0)),
        ),
        s.select_f32s(
            s1,
            s.mul_f32s(half, sq(s.sub_f32s(s.splat_f32s(2.0), tau))),
            zero,
        ),
    );
    // uniform quadratic pieces for u = tau - start in [0, 1): u^2/2, 1/2 + u - u^2, (1-u)^2/2
    let rise = |u: S::f32s| s.mul_f32s(half, sq(u));
    let mid = |u: S::f32s| s.sub_f32s(s.add_f32s(half, u), sq(u));
    let fall = |u: S::f32s| s.mul_f32s(half, sq(s.sub_f32s(one, u)));
    // B_2: knots 0, 1, 2, 3 (uniform; in tau the knot vector is 0,0,0,1,2,3,4,4,4)
    let b2 = s.select_f32s(
        s0,
        rise(tau),
        s.select_f32s(
            s1,
            mid(s.sub_f32s(tau, one)),
            s.select_f32s(s2, fall(s.sub_f32s(tau, s.splat_f32s(2.0))), zero),
        ),
    );
    // B_3: knots 1,2,3,4 (uniform)
    let b3 = s.select_f32s(
        s1,
        rise(s.sub_f32s(tau, one)),
        s.select_f32s(
            s2,
            mid(s.sub_f32s(tau, s.splat_f32s(2.0))),
            s.select_f32s(s3, fall(s.sub_f32s(tau, s.splat_f32s(3.0))), zero),
        ),
    );
    // B_4 and B_5 mirror B_1 and B_0 with sigma = 4 - tau
    let sigma = s.sub_f32s(s.splat_f32s(4.0), tau);
    let b4 = s.select_f32s(
        s3,
        s.mul_f32s(
            s.mul_f32s(half, sigma),
            s.mul_add_e_f32s(s.splat_f32s(-3.0), sigma, s.splat_f32s(4.0)),
        ),
        s.select_f32s(
            s2,
            s.mul_f32s(half, sq(s.sub_f32s(s.splat_f32s(2.0), sigma))),
            zero,
        ),
    );
    let b5 = s.select_f32s(s3, sq(s.sub_f32s(one, sigma)), zero);
    [b0, b1, b2, b3, b4, b5]
}

/// x = max(0, h.n) and its logarithms.
pub struct XTerms<S: Simd> {
    /// x = max(0, h.n).
    pub x: S::f32s,
    /// Lanes where x > 0.
    pub pos: S::m32s,
    /// ln x where x > 0, else 0 (x^m1 ln x is taken as 0 at x = 0).
    pub lnx: S::f32s,
    /// log2 x where x > 0, else NEG_BIG.
    pub l2: S::f32s,
}

/// x, ln x and log2 x of half vector `h` (unit, or 0 with `d_pad` = 1 where undefined) and
/// normal `n` (|n|^2 - 1 = `nn_m1`).
#[inline(always)]
pub fn x_terms<S: Simd>(
    s: S,
    h: &[S::f32s; 3],
    n: &[S::f32s; 3],
    nn_m1: S::f32s,
    d_pad: S::f32s,
) -> XTerms<S> {
    let zero = s.splat_f32s(0.0);
    // 1 - x = (|h - n|^2 - (|n|^2 - 1)) / 2 for unit h: no cancellation near x = 1
    let hn = [0, 1, 2].map(|a| s.sub_f32s(h[a], n[a]));
    let d = s.mul_add_e_f32s(
        s.sub_f32s(dot3(s, &hn, &hn), nn_m1),
        s.splat_f32s(0.5),
        d_pad,
    );
    let x = s.max_f32s(s.sub_f32s(s.splat_f32s(1.0), d), zero);
    let pos = s.greater_than_f32s(x, zero);
    let lnx = s.select_f32s(pos, ln_1m(s, s.max_f32s(x, s.splat_f32s(1e-30)), d), zero);
    let l2 = s.select_f32s(
        pos,
        s.mul_f32s(lnx, s.splat_f32s(std::f32::consts::LOG2_E)),
        s.splat_f32s(NEG_BIG),
    );
    XTerms { x, pos, lnx, l2 }
}

/// The geometric terms of pixel `p` against texel block `b`, or None when every texel of
/// the block is below the pixel's horizon. `P`: a perspective camera.
#[inline(always)]
pub fn geo<S: Simd, const P: bool>(s: S, cols: &Cols<'_, S>, p: &Px, b: usize) -> Option<Geo<S>> {
    let n = p.n.map(|v| s.splat_f32s(v));
    let w = [cols.w[0][b], cols.w[1][b], cols.w[2][b]];
    let c = dot3(s, &n, &w);
    let zero = s.splat_f32s(0.0);
    let up = s.greater_than_f32s(c, zero);
    if !any(s, up) {
        return None;
    }
    let c = s.select_f32s(up, c, zero);
    let (h, d_pad, basis_v) = if P {
        let wp = p.wp.map(|v| s.splat_f32s(v));
        let sum = [0, 1, 2].map(|a| s.add_f32s(w[a], wp[a]));
        let dif = [0, 1, 2].map(|a| s.sub_f32s(w[a], wp[a]));
        let len = s.sqrt_f32s(dot3(s, &sum, &sum));
        let dlen = s.sqrt_f32s(dot3(s, &dif, &dif));
        let bad = s.less_than_f32s(len, s.splat_f32s(HALF_VECTOR_EPS as f32));
        let inv = s.div_f32s(s.splat_f32s(1.0), s.max_f32s(len, s.splat_f32s(1e-30)));
        let h = sum.map(|v| s.select_f32s(bad, zero, s.mul_f32s(v, inv)));
        let d_pad = s.select_f32s(bad, s.splat_f32s(1.0), zero);
        (h, d_pad, basis(s, atan2_pos(s, dlen, len)))
    } else {
        (
            [cols.h[0][b], cols.h[1][b], cols.h[2][b]],
            cols.d_pad[b],
            [zero; N_CTRL_POINTS],
        )
    };
    let XTerms { x, pos, lnx, l2 } = x_terms(s, &h, &n, s.splat_f32s(p.nn_m1), d_pad);
    Some(Geo {
        c,
        up,
        x,
        pos,
        lnx,
        l2,
        h,
        basis: basis_v,
    })
}

/// Coefficient column `col` (index (k * 3 + s) * 2 + t) at this pair: from the table for
/// orthographic cameras, from the pair's spline basis for perspective ones.
#[inline(always)]
pub fn coef<S: Simd, const P: bool>(
    s: S,
    cols: &Cols<'_, S>,
    setup: &Setup,
    g: &Geo<S>,
    b: usize,
    col: usize,
) -> S::f32s {
    if P {
        let c = &setup.ctrl[col * N_CTRL_POINTS..(col + 1) * N_CTRL_POINTS];
        let mut v = s.mul_f32s(g.basis[0], s.splat_f32s(c[0]));
        for j in 1..N_CTRL_POINTS {
            v = s.mul_add_e_f32s(g.basis[j], s.splat_f32s(c[j]), v);
        }
        v
    } else {
        cols.coef[col][b]
    }
}

/// Whether x^b is exactly 0 (2^t with t <= -127) in every lane above the horizon: then
/// every lobe of the group adds exactly 0 to the image and the gradients, and the group
/// is skipped. Sharp lobes are 0 over most of a pixel's hemisphere.
#[inline(always)]
pub fn underflows<S: Simd>(s: S, t: S::f32s, up: S::m32s) -> bool {
    let live = s.and_m32s(s.greater_than_f32s(t, s.splat_f32s(-127.0)), up);
    !any(s, live)
}

/// Adds `v` to the channels whose bit is set.
#[inline(always)]
pub fn add_channels<S: Simd>(s: S, channels: u8, v: S::f32s, f: &mut [S::f32s; 3]) {
    for (k, fk) in f.iter_mut().enumerate() {
        if channels & (1 << k) != 0 {
            *fk = s.add_f32s(*fk, v);
        }
    }
}

/// One pair block's terms of the normals' Jacobian, added to `jac` (index k * 3 + axis):
/// dI^k/dn = L^k d_omega (f^k w + c dI^k/dx h), with `ld` = L^k d_omega, `up` the lanes
/// above the horizon, `w` and `h` the texel's direction and half vector, and `c_dx[k]` =
/// c dI^k/dx.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
pub fn add_jacobian<S: Simd>(
    s: S,
    up: S::m32s,
    ld: [S::f32s; 3],
    f: &[S::f32s; 3],
    c_dx: [S::f32s; 3],
    w: [S::f32s; 3],
    h: &[S::f32s; 3],
    jac: &mut [S::f32s; 9],
) {
    let zero = s.splat_f32s(0.0);
    for k in 0..3 {
        let along_w = s.select_f32s(up, s.mul_f32s(ld[k], f[k]), zero);
        let along_h = s.mul_f32s(ld[k], c_dx[k]);
        for a in 0..3 {
            jac[k * 3 + a] = s.mul_add_e_f32s(
                along_w,
                w[a],
                s.mul_add_e_f32s(along_h, h[a], jac[k * 3 + a]),
            );
        }
    }
}
