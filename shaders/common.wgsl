// common.wgsl: what every pass shares: the layouts of the buffers (kept in sync with
// src/gpu/layout.rs, checked by tests/shaders.rs), the spline basis (mirrors src/spline.rs),
// the half vector and the lobe math (mirror src/reference/common.rs). No entry point.

// Threads per workgroup in every pass, and records per workgroup-memory tile.
const WG: u32 = 64u;
const HALF_PI: f32 = 1.5707963267948966;
// 1 / x is taken of max(x, TINY) so that it is finite; x <= 0 is handled by a select.
const TINY: f32 = 1e-30;
const HALF_VECTOR_EPS: f32 = 1e-6;

// One dispatch's (or one scene's, in a batched dispatch) parameters. Kept in sync with
// `Params` in src/gpu/layout.rs.
struct Params {
    // pixels bound (per-pixel passes: one invocation each; backward_texel: looped over);
    // reduce_slices: the vec4 elements of one slice
    n_pixels: u32,
    // texels bound (per-pixel passes: looped over; backward_texel: one invocation each;
    // reduce_ctrl: summed)
    n_texels: u32,
    // 1: the first range of a sum, so write instead of add
    first: u32,
    // 1: perspective camera, so h, theta_d and the coefficients depend on the pair
    perspective: u32,
    // orthographic camera: the number of active lobes in Texel.lobes
    n_lobes: u32,
    // perspective camera: the number of constant lobes after the active ones in lc
    n_const: u32,
    // records of the looped-over list in one slice (slice = workgroup_id.y)
    slice_len: u32,
    // slices (reduce_slices: the partial sums per element)
    n_slices: u32,
    // the scene's first pixel in the pixel buffers (a batch's scenes are concatenated)
    pixel_base: u32,
    // the scene's first texel in the texel buffers
    texel_base: u32,
    // elements between two slices' partial sums (all scenes' outputs)
    slice_stride: u32,
    _pad: u32,
    // cc[(k * 2 + t) * 6 + j] = (ctrl[idx(k, 0, t, j)], ctrl[idx(k, 1, t, j)], ctrl[idx(k, 2, t, j)], 0),
    // scales (t = 0) times log2(e)
    cc: array<vec4<f32>, 36>,
    // lc[(q * 2 + t) * 6 + j]: the same over channels (R, G, B) for the q-th lobe of the
    // active then the constant lobes, scales times log2(e)
    lc: array<vec4<f32>, 36>,
}

// One environment texel. Kept in sync with `Texel` in src/gpu/layout.rs.
struct Texel {
    // xyz: direction w_i; w: d_omega_i
    w: vec4<f32>,
    // orthographic camera: xyz the half vector, w theta_d
    h: vec4<f32>,
    // xyz: L^k(i) d_omega_i; w: orthographic camera, the pad of `lobe_x` (1 where the half
    // vector is undefined)
    ld: vec4<f32>,
    // orthographic camera, xyz: per channel, the constant lobes' share of f
    fconst: vec4<f32>,
    // orthographic camera, at theta_d: coef[2k].xyz = (m_{0,0}^k, m_{1,0}^k, m_{2,0}^k) log2(e),
    // coef[2k + 1] = (m_{0,1}^k, m_{1,1}^k, m_{2,1}^k, the least of the three); coef[0].w:
    // SHARES_LOBE where the three channels have the same lobes, else 0
    coef: array<vec4<f32>, 6>,
    // orthographic camera, the active lobes over channels (R, G, B): lobes[2a] = m0 log2(e)
    // with w what the channels share (SHARES_*), lobes[2a + 1] = m1 with w the least of the
    // three
    lobes: array<vec4<f32>, 6>,
}

// One foreground pixel. Kept in sync with `Pixel` in src/gpu/layout.rs.
struct Pixel {
    // the normal as given
    n: vec3<f32>,
    // |n|^2 - 1, computed on the host in f64 (for lobe_x)
    nn_m1: f32,
    // xyz: the view direction w_p
    wp: vec4<f32>,
    // xyz: the upstream gradient dLoss/dI (backward passes)
    g: vec4<f32>,
}

// B_0..B_5 at t: the quadratic clamped uniform B-spline on [0, pi/2] with knots
// 0, 0, 0, pi/8, pi/4, 3pi/8, pi/2, pi/2, pi/2, in closed form per span (the same values as
// Cox-de Boor in src/spline.rs, checked there by `closed_form_matches_cox_de_boor`). No
// private array is indexed: that is slow on SIMD backends such as lavapipe.
fn spline_basis(t_in: f32) -> array<f32, 6> {
    let tau = clamp(t_in, 0.0, HALF_PI) * (4.0 / HALF_PI);
    let s = min(floor(tau), 3.0);
    let r = tau - s;
    let a = (1.0 - r) * (1.0 - r);
    let c = r * r;
    let first = s == 0.0;
    let last = s == 3.0;
    // the three non-zero functions on span s: B_s, B_{s+1}, B_{s+2}
    let v0 = select(0.5 * a, a, first);
    let v1 = select(select(0.5 + r - c, 0.5 * (1.0 - r) * (3.0 * r + 1.0), last),
                    0.5 * r * (4.0 - 3.0 * r), first);
    let v2 = select(0.5 * c, c, last);
    let e0 = f32(s == 0.0);
    let e1 = f32(s == 1.0);
    let e2 = f32(s == 2.0);
    let e3 = f32(s == 3.0);
    return array<f32, 6>(
        v0 * e0,
        v0 * e1 + v1 * e0,
        v0 * e2 + v1 * e1 + v2 * e0,
        v0 * e3 + v1 * e2 + v2 * e1,
        v1 * e3 + v2 * e2,
        v2 * e3,
    );
}

// The half vector of w and wp, theta_d, and the pad `lobe_x` takes (1 where w = -wp: then
// h = 0, x = 0 and theta_d = pi/2).
struct HalfVector {
    h: vec3<f32>,
    theta_d: f32,
    pad: f32,
}

// theta_d = acos(w.h) is computed as atan2(|w - wp|, |w + wp|), the same angle (h bisects
// w and wp), because acos near 1 loses most of its digits in f32.
fn half_vector(w: vec3<f32>, wp: vec3<f32>) -> HalfVector {
    let s = w + wp;
    let len = length(s);
    var h = vec3<f32>(0.0);
    var pad = 1.0;
    if len >= HALF_VECTOR_EPS {
        h = s / len;
        pad = 0.0;
    }
    return HalfVector(h, atan2(length(w - wp), len), pad);
}

// The lobes are computed in base 2: exp(m0 x^m1) - 1 = 2^(a x^m1) - 1 with a = m0 log2(e),
// stored so by the host (every scale in Params and Texel; src/gpu/layout.rs), and
// x^m1 = 2^(m1 log2 x) with log2 x from `lobe_x`, once per pair: one exp2 for x^m1 and one
// 2^u - 1 per lobe and channel, no multiplication by log2(e) in the pair loop.
const LOG2_E: f32 = 1.4426950408889634;
const LN_2: f32 = 0.6931471805599453;
// log2 x stand-in at x = 0: m1 NO_LOG is finite for every valid exponent (<= 1e4) and far
// below UNDERFLOW for m1 > 1e-27, so x^m1 = 0; 0 NO_LOG = 0 gives x^0 = 1.
const NO_LOG: f32 = -1e30;
// 2^t for t < UNDERFLOW is under half of f32's smallest subnormal: it rounds to exactly 0,
// and a lobe whose x^m1 is 0 in every channel adds exactly 0 to f and to every gradient,
// so the passes skip it on GPUs (`underflows`, gather.wgsl). Sharp lobes underflow over
// most of a pixel's hemisphere.
const UNDERFLOW: f32 = -150.0;

// 2^u - 1 = u Q(u) for |u| < 1/2, Q of degree 5, near-minimax: relative error 2.1e-8 (fit).
// The coefficients are `EXP2M1_Q` of src/cpu/math.rs (checked by tests/shaders.rs), whose
// f32 evaluation tests/cpu_math.rs sweeps.
const EXP2M1_Q0: f32 = 0.6931472;
const EXP2M1_Q1: f32 = 0.24022649;
const EXP2M1_Q2: f32 = 0.055503573;
const EXP2M1_Q3: f32 = 0.009618238;
const EXP2M1_Q4: f32 = 0.0013390736;
const EXP2M1_Q5: f32 = 0.00015403503;

// u Q(u) = 2^u - 1 for |u| < 1/2.
fn exp2m1_small(u: f32) -> f32 {
    return u * (EXP2M1_Q0 + u * (EXP2M1_Q1 + u * (EXP2M1_Q2 + u * (EXP2M1_Q3
        + u * (EXP2M1_Q4 + u * EXP2M1_Q5)))));
}

// The lobe argument x = max(0, dot(h, n)) and log2 x (x: .x, log2 x: .y, NO_LOG at x = 0)
// for the unit half vector h and the normal n, with nn_m1 = |n|^2 - 1 from the host and
// pad = 1 where h is undefined (w = -wp: then x = 0), else 0. x^m1 = 2^(m1 log2 x) with m1
// up to 1e4 multiplies any absolute error of log2 x by m1, so where x is near 1 neither
// 1 - x nor log2 x may lose digits:
// - dot(h, n) = 1 - d with d = (|h - n|^2 - nn_m1) / 2: h - n is exact where h is near n,
//   so d keeps its digits, and an error of |h| off 1 counts only times |h - n|;
// - log2 x = log1p(-d) / ln 2 = -2 atanh(z) / ln 2, z = d / (2 - d), by its series where
//   |z| <= 1/3 (-1 <= d <= 1/2; truncation < 2e-9 relative), because log2(u) itself is
//   only held to an absolute error of 2^-21 for u in [0.5, 2] (WGSL, Vulkan), which is
//   5e-3 of x^m1 at m1 = 1e4; elsewhere log2 x (relative error bound there; 1 - d is exact
//   for 1/2 <= d <= 1, and x > 0 is at least 2^-24 there).
// Mirrors `lobe_x` in src/reference/common.rs, which takes ln x as log1p(-d) in f64.
const SERIES: f32 = -2.0 * LOG2_E;
fn lobe_x(h: vec3<f32>, n: vec3<f32>, nn_m1: f32, pad: f32) -> vec2<f32> {
    let v = h - n;
    let d = 0.5 * (dot(v, v) - nn_m1) + pad;
    let x = max(0.0, 1.0 - d);
    var l2 = NO_LOG;
    if d >= -1.0 && d <= 0.5 {
        let z = d / (2.0 - d);
        let z2 = z * z;
        l2 = z * (SERIES + z2 * ((SERIES / 3.0) + z2 * ((SERIES / 5.0) + z2 * ((SERIES / 7.0)
            + z2 * ((SERIES / 9.0) + z2 * ((SERIES / 11.0) + z2 * ((SERIES / 13.0)
            + z2 * (SERIES / 15.0))))))));
    } else if x > 0.0 {
        l2 = log2(x);
    }
    return vec2<f32>(x, l2);
}

// x^m1 per lobe (or channel) from l2 = log2 x (NO_LOG at x = 0): 0 at x = 0 for m1 > 0 and
// x^0 = 1, without selects.
fn lobe_pow(l2: f32, m1: vec3<f32>) -> vec3<f32> {
    return exp2(m1 * l2);
}

// 1 / x, 0 at x = 0: the dn term's m1 x^(m1 - 1) is m1 x^m1 / x, so the pass sums
// E m0 m1 x^m1 over lobes and divides once per pair. The reference clamps m1 x^(m1 - 1) at
// 1e10 (it diverges as x -> 0 for m1 < 1), but here x > 0 is at least 2^-24 (`lobe_x`), so
// it is at most 2^24 and the clamp never binds.
fn inv_x(x: f32) -> f32 {
    return select(0.0, 1.0 / max(x, TINY), x > 0.0);
}

// What the channels of an orthographic texel's lobe share (`Texel.lobes[2a].w`, set by the
// host): nothing, the exponent, or the exponent and the scale (a grey lobe, as in most
// hand-made materials); `shared_lobe` in gather.wgsl.
const SHARES_EXPONENT: f32 = 1.0;
const SHARES_LOBE: f32 = 2.0;

// The least component of v.
fn least(v: vec3<f32>) -> f32 {
    return min(min(v.x, v.y), v.z);
}
