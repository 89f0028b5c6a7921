// common.wgsl: what every pass shares: the layouts of the buffers (kept in sync with
// src/gpu/layout.rs, checked by tests/shaders.rs), the spline basis (mirrors src/spline.rs),
// the half vector and the lobe math (mirror src/reference/common.rs). No entry point.

// Threads per workgroup in every pass, and records per workgroup-memory tile.
const WG: u32 = 64u;
const HALF_PI: f32 = 1.5707963267948966;
// log(x) is taken of max(x, TINY) so that it is finite; x <= 0 is handled by selects.
const TINY: f32 = 1e-30;
// m1 x^(m1 - 1) diverges as x -> 0 for m1 < 1; the dn term clamps it here.
const DPOW_MAX: f32 = 1e10;
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
    // cc[(k * 2 + t) * 6 + j] = (ctrl[idx(k, 0, t, j)], ctrl[idx(k, 1, t, j)], ctrl[idx(k, 2, t, j)], 0)
    cc: array<vec4<f32>, 36>,
    // lc[(q * 2 + t) * 6 + j]: the same over channels (R, G, B) for the q-th lobe of the
    // active then the constant lobes
    lc: array<vec4<f32>, 36>,
}

// One environment texel. Kept in sync with `Texel` in src/gpu/layout.rs.
struct Texel {
    // xyz: direction w_i; w: d_omega_i
    w: vec4<f32>,
    // orthographic camera: xyz the half vector, w theta_d
    h: vec4<f32>,
    // xyz: L^k(i) d_omega_i
    ld: vec4<f32>,
    // orthographic camera, xyz: per channel, the constant lobes' share of f
    fconst: vec4<f32>,
    // orthographic camera: coef[k * 2 + t] = (m_{0,t}^k, m_{1,t}^k, m_{2,t}^k, 0) at theta_d
    coef: array<vec4<f32>, 6>,
    // orthographic camera, the active lobes over channels: lobes[2a] = m0 (R, G, B), lobes[2a + 1] = m1
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

// Half vector of w and wp (xyz) and theta_d (w); h = 0 where w = -wp.
// theta_d = acos(w.h) is computed as atan2(|w - wp|, |w + wp|), the same angle (h bisects
// w and wp), because acos near 1 loses most of its digits in f32.
fn half_vector(w: vec3<f32>, wp: vec3<f32>) -> vec4<f32> {
    let s = w + wp;
    let len = length(s);
    var h = vec3<f32>(0.0);
    if len >= HALF_VECTOR_EPS {
        h = s / len;
    }
    return vec4<f32>(h, atan2(length(w - wp), len));
}

// exp(y) - 1 without cancellation: a degree-8 Taylor polynomial where |y| < 0.5
// (truncation error < 1.1e-8 relative), exp(y) - 1 elsewhere.
// Multiplications by reciprocals, not divisions: divisions are several times dearer.
fn stable_expm1(y: vec3<f32>) -> vec3<f32> {
    let series = y * (1.0 + y * 0.5 * (1.0 + y * (1.0 / 3.0) * (1.0 + y * 0.25
        * (1.0 + y * 0.2 * (1.0 + y * (1.0 / 6.0) * (1.0 + y * (1.0 / 7.0)
        * (1.0 + y * 0.125)))))));
    return select(exp(y) - 1.0, series, abs(y) < vec3<f32>(0.5));
}

// log(x) for the lobe powers; finite for every x.
fn lobe_log(x: f32) -> f32 {
    return log(max(x, TINY));
}

// The lobe argument x = max(0, dot(h, n)) and ln x (x: .x, ln x: .y) for the unit half
// vector h (h = 0 where it is undefined: then x = 0) and the normal n, with
// nn_m1 = |n|^2 - 1 from the host. x^m1 = exp(m1 ln x) with m1 up to 1e4 multiplies any
// absolute error of ln x by m1, so where x is near 1 neither 1 - x nor ln x may lose digits:
// - dot(h, n) = 1 - d with d = (|h - n|^2 - nn_m1) / 2: h - n is exact where h is near n,
//   so d keeps its digits, and an error of |h| off 1 counts only times |h - n|;
// - ln x = log1p(-d) = -2 atanh(z), z = d / (2 - d), by its series where |z| <= 1/3
//   (-1 <= d <= 1/2; truncation < 2e-9 relative), because log(u) itself is only held to an
//   absolute error of 2^-21 for u in [0.5, 2] (WGSL, Vulkan), which is 5e-3 of x^m1 at
//   m1 = 1e4; elsewhere log(max(x, TINY)) (relative error bound there; 1 - d is exact for
//   1/2 <= d <= 1).
// Mirrors `lobe_x` in src/reference/common.rs, which takes ln x as log1p(-d) in f64.
fn lobe_x(h: vec3<f32>, n: vec3<f32>, nn_m1: f32) -> vec2<f32> {
    let v = h - n;
    let d = 0.5 * (dot(v, v) - nn_m1);
    let x = select(0.0, max(0.0, 1.0 - d), any(h != vec3<f32>(0.0)));
    let z = d / (2.0 - d);
    let z2 = z * z;
    let series = -2.0 * z * (1.0 + z2 * ((1.0 / 3.0) + z2 * (0.2 + z2 * ((1.0 / 7.0)
        + z2 * ((1.0 / 9.0) + z2 * ((1.0 / 11.0) + z2 * ((1.0 / 13.0)
        + z2 * (1.0 / 15.0))))))));
    let near_one = x > 0.0 && d >= -1.0 && d <= 0.5;
    return vec2<f32>(x, select(lobe_log(x), series, near_one));
}

// x^e per lobe, with x^e = 0 at x = 0 for e > 0 and x^0 = 1.
fn lobe_pow(x: f32, lnx: f32, e: vec3<f32>) -> vec3<f32> {
    let p = select(exp(e * lnx), vec3<f32>(0.0), vec3<bool>(x <= 0.0));
    return select(p, vec3<f32>(1.0), e == vec3<f32>(0.0));
}

// x^e ln x per lobe (given p = x^e), 0 at x = 0.
fn lobe_pow_log(x: f32, lnx: f32, p: vec3<f32>) -> vec3<f32> {
    return select(p * lnx, vec3<f32>(0.0), vec3<bool>(x <= 0.0));
}

// e x^(e - 1) per lobe, 0 at x = 0 and for e = 0, clamped to DPOW_MAX.
fn lobe_dpow(x: f32, lnx: f32, e: vec3<f32>) -> vec3<f32> {
    let d = min(e * exp((e - 1.0) * lnx), vec3<f32>(DPOW_MAX));
    let zero = vec3<bool>(x <= 0.0) | (e == vec3<f32>(0.0));
    return select(d, vec3<f32>(0.0), zero);
}

// One channel's BRDF and its derivatives with respect to the lobes' coefficients.
struct LobeGrads {
    // sum_s exp(m0_s x^m1_s) - 1
    f: f32,
    // d f / d m0_s = E_s x^m1_s
    d0: vec3<f32>,
    // d f / d m1_s = E_s m0_s x^m1_s ln x
    d1: vec3<f32>,
}

fn lobe_grads(x: f32, lnx: f32, m0: vec3<f32>, m1: vec3<f32>) -> LobeGrads {
    let pw = lobe_pow(x, lnx, m1);
    let e = stable_expm1(m0 * pw);
    let big_e = e + 1.0;
    return LobeGrads(e.x + e.y + e.z, big_e * pw, big_e * m0 * lobe_pow_log(x, lnx, pw));
}
