//! Short polynomial exp2, 2^u - 1 and ln for the fast CPU path, generic over the SIMD width,
//! and the lane-mask test [`any`] that they and the per-pair terms share.
//!
//! No special cases beyond what a valid input reaches: arguments are clamped into range
//! instead of producing inf or NaN, and ln is only taken of x > 0 (its callers handle
//! x = 0). Coefficients are near-minimax fits (relative error) computed for this file; the
//! bound beside each is the fit's error in exact arithmetic, and `tests/it/cpu_math.rs` sweeps
//! the f32 implementations (fit plus rounding) against f64 and asserts the `*_MAX_REL`
//! bounds.

use pulp::Simd;

/// 1.5 * 2^23: `(t + MAGIC) - MAGIC` rounds |t| < 2^22 to the nearest integer, and the low
/// bits of `t + MAGIC` hold that integer.
const MAGIC: f32 = 12_582_912.0;
/// The bits of [`MAGIC`].
const MAGIC_BITS: u32 = 0x4B40_0000;
const LN2: f32 = std::f32::consts::LN_2;

/// 2^f = 1 + f P(f) on [-1/2, 1/2], P of degree 4: relative error 1.1e-7 (fit).
#[expect(
    clippy::approx_constant,
    reason = "a fitted coefficient near ln 2, not ln 2"
)]
const EXP2_P: [f32; 5] = [
    0.693_147,
    0.240_222_42,
    0.055_507_34,
    0.009_671_514,
    0.001_326_471_5,
];
/// 2^f - 1 = f Q(f) on [-1/2, 1/2], Q of degree 5: relative error 2.1e-8 (fit). The
/// shaders' `exp2m1` (shaders/common.wgsl) uses the same coefficients.
#[expect(
    clippy::approx_constant,
    reason = "a fitted coefficient near ln 2, not ln 2"
)]
pub const EXP2M1_Q: [f32; 6] = [
    0.693_147_2,
    0.240_226_49,
    0.055_503_573,
    0.009_618_238,
    0.001_339_073_6,
    0.000_154_035_03,
];

/// ln(1 + f) = f - f^2/2 + f^3 R(f) on [sqrt(1/2) - 1, sqrt(2) - 1], R of degree 6:
/// relative error 3.5e-8 (fit).
const LN1P_R: [f32; 7] = [
    0.333_339_1,
    -0.250_013_38,
    0.199_630_57,
    -0.165_775_9,
    0.149_148_54,
    -0.142_674_57,
    0.087_001_23,
];

/// Bound on the relative error of [`exp2`] over [-126, 126], f32 rounding included
/// (measured: 1.67e-7 with fused multiply-adds, 1.88e-7 without, on the scalar level).
pub const EXP2_MAX_REL: f64 = 2.5e-7;
/// Bound on the relative error of [`exp2m1`] over [-126, 126] and for |u| down to 1e-30:
/// the result keeps its digits for small |u| (measured: 1.45e-7).
pub const EXP2M1_MAX_REL: f64 = 2e-7;
/// Bound on the relative error of [`ln`] over [1e-30, 1e4] and of [`ln_1m`] for d from
/// 1e-12 to 1 (measured: 1.35e-7 and 2.41e-7; the latter is the f32 rounding of x = 1 - d
/// where d > 1 - sqrt(1/2), since only x is used there).
pub const LN_MAX_REL: f64 = 3e-7;

#[inline(always)]
pub(super) fn horner<S: Simd, const N: usize>(s: S, x: S::f32s, c: &[f32; N]) -> S::f32s {
    let mut p = s.splat_f32s(c[N - 1]);
    for i in (0..N - 1).rev() {
        p = s.mul_add_e_f32s(p, x, s.splat_f32s(c[i]));
    }
    p
}

/// 2^k for an integer-valued k in [-127, 127] given as the bits of `k + MAGIC`; 0 for -127.
#[inline(always)]
fn pow2_from_magic<S: Simd>(s: S, z: S::f32s) -> S::f32s {
    let k = s.sub_u32s(s.transmute_u32s_f32s(z), s.splat_u32s(MAGIC_BITS - 127));
    s.transmute_f32s_u32s(s.wrapping_dyn_shl_u32s(k, s.splat_u32s(23)))
}

/// 2^t for finite t <= 126: within [`EXP2_MAX_REL`] (relative) from -126 up, where 2^t is
/// a normal f32, within 2^-126 (absolute) below, never negative or NaN; exactly 0 from
/// -127 down (AVX2, scalar) or from -151 down (AVX-512, whose subnormals in between are
/// 2^t's). Its callers take x^b = 2^(b log2 x) for x <= 1 (up to rounding), so t <= 0 but
/// for rounding: only the lower end is clamped.
#[inline(always)]
pub fn exp2<S: Simd>(s: S, t: S::f32s) -> S::f32s {
    #[cfg(target_arch = "x86_64")]
    if let Some(v) = v4::get(s) {
        return v4::exp2(s, v, t);
    }
    let t = s.max_f32s(t, s.splat_f32s(-127.0));
    let z = s.add_f32s(t, s.splat_f32s(MAGIC));
    let f = s.sub_f32s(t, s.sub_f32s(z, s.splat_f32s(MAGIC)));
    let p = s.mul_add_e_f32s(horner(s, f, &EXP2_P), f, s.splat_f32s(1.0));
    // p 2^k by adding k to p's exponent field: the low 9 bits of `z` hold k (two's
    // complement; MAGIC's are 0), shifted there. Exact while p 2^k is normal (t >= -126);
    // below, the sum's bits are a subnormal (2p - 1 or p - 1) 2^-126, off by less than
    // 2^-126 (k = -127 has f >= 0, so p >= 1: never a negative sum); at t = -127, f = 0,
    // p = 1 and the bits are 0
    s.transmute_f32s_u32s(s.add_u32s(
        s.transmute_u32s_f32s(p),
        s.wrapping_dyn_shl_u32s(s.transmute_u32s_f32s(z), s.splat_u32s(23)),
    ))
}

/// Whether any lane of `m` is set. pulp's `first_true_m32s` walks the lanes one by one
/// where masks are vectors (AVX2, NEON); AVX2 has one instruction for it.
#[inline(always)]
pub fn any<S: Simd>(s: S, m: S::m32s) -> bool {
    #[cfg(target_arch = "x86_64")]
    if let Some(v3) = (&s as &dyn std::any::Any).downcast_ref::<pulp::x86::V3>() {
        let bits: S::u32s = s.select_u32s(m, s.splat_u32s(!0), s.splat_u32s(0));
        let v: std::arch::x86_64::__m256 = bytemuck::cast(bits);
        return v3.avx._mm256_movemask_ps(v) != 0;
    }
    s.first_true_m32s(m) < S::F32_LANES
}

/// 2^u - 1 without cancellation for small |u|, u clamped to [-126, 126]: u = k + f with
/// |f| <= 1/2 (exact in f32), 2^u - 1 = 2^k (2^f - 1) + (2^k - 1). The lobes are
/// exp(a x^b) - 1 = 2^(a log2(e) x^b) - 1 with a log2(e) folded into the scale columns,
/// which saves expm1's two-step reduction by ln 2. When every lane has |u| < 1/2 the
/// reduction is skipped; the result is bitwise the same.
#[inline(always)]
pub fn exp2m1<S: Simd>(s: S, u: S::f32s) -> S::f32s {
    let abs = s.and_f32s(u, s.transmute_f32s_u32s(s.splat_u32s(0x7FFF_FFFF)));
    let big = s.greater_than_or_equal_f32s(abs, s.splat_f32s(0.5));
    if !any(s, big) {
        return s.mul_f32s(u, horner(s, u, &EXP2M1_Q));
    }
    exp2m1_reduced(
        s,
        s.min_f32s(s.max_f32s(u, s.splat_f32s(-126.0)), s.splat_f32s(126.0)),
    )
}

/// 2^u - 1 for |u| <= 126 through the reduction u = k + f, without a branch: as
/// [`exp2m1`] where the caller knows the range (bitwise the same result).
#[inline(always)]
pub fn exp2m1_reduced<S: Simd>(s: S, u: S::f32s) -> S::f32s {
    #[cfg(target_arch = "x86_64")]
    if let Some(v) = v4::get(s) {
        return v4::exp2m1_reduced(s, v, u);
    }
    let z = s.add_f32s(u, s.splat_f32s(MAGIC));
    let f = s.sub_f32s(u, s.sub_f32s(z, s.splat_f32s(MAGIC)));
    let p = s.mul_f32s(f, horner(s, f, &EXP2M1_Q));
    let two_k = pow2_from_magic(s, z);
    s.mul_add_e_f32s(two_k, p, s.sub_f32s(two_k, s.splat_f32s(1.0)))
}

/// ln(1 + f) for f in [sqrt(1/2) - 1, sqrt(2) - 1].
#[inline(always)]
fn ln1p_reduced<S: Simd>(s: S, f: S::f32s) -> S::f32s {
    let f2 = s.mul_f32s(f, f);
    let r = horner(s, f, &LN1P_R);
    let head = s.mul_add_e_f32s(f2, s.splat_f32s(-0.5), f);
    s.mul_add_e_f32s(s.mul_f32s(f2, f), r, head)
}

/// ln x for a normal x > 0 (the caller handles x = 0), as k ln2 + ln(1 + f) with
/// 1 + f in [sqrt(1/2), sqrt(2)).
#[inline(always)]
pub fn ln<S: Simd>(s: S, x: S::f32s) -> S::f32s {
    ln_1m_or(s, x, None)
}

/// ln(1 - d) for x = 1 - d > 0, keeping its digits where x is near 1: there the reduced
/// argument f is -d itself (exact) rather than the rounded x - 1.
#[inline(always)]
pub fn ln_1m<S: Simd>(s: S, x: S::f32s, d: S::f32s) -> S::f32s {
    ln_1m_or(s, x, Some(d))
}

#[inline(always)]
fn ln_1m_or<S: Simd>(s: S, x: S::f32s, d: Option<S::f32s>) -> S::f32s {
    #[cfg(target_arch = "x86_64")]
    if let Some(v) = v4::get(s) {
        let (ef, m) = v4::split(s, v, x);
        return ln_finish(s, ef, m, d);
    }
    const SQRT_HALF_BITS: u32 = 0x3F35_04F3;
    // x = 2^k m with m in [sqrt(1/2), sqrt(2)): shift the bits so that the exponent field
    // counts from sqrt(1/2)
    let ix = s.sub_u32s(s.transmute_u32s_f32s(x), s.splat_u32s(SQRT_HALF_BITS));
    let e = s.wrapping_dyn_shr_u32s(ix, s.splat_u32s(23));
    // k as a float: e is k + 256 (mod 512) after the unsigned shift; (e + MAGIC) - MAGIC
    let ef = s.sub_f32s(
        s.transmute_f32s_u32s(s.add_u32s(
            s.and_u32s(s.add_u32s(e, s.splat_u32s(256)), s.splat_u32s(511)),
            s.splat_u32s(MAGIC_BITS),
        )),
        s.splat_f32s(MAGIC + 256.0),
    );
    let m = s.transmute_f32s_u32s(s.add_u32s(
        s.and_u32s(ix, s.splat_u32s(0x007F_FFFF)),
        s.splat_u32s(SQRT_HALF_BITS),
    ));
    ln_finish(s, ef, m, d)
}

/// -a. pulp's `neg_f32s` is only `#[inline]`; left out of line in the kernels' target-feature
/// context it made the nine-lobe backward a third slower (measured: 0.26 s vs 0.33-0.37 s).
#[inline(always)]
fn neg<S: Simd>(s: S, a: S::f32s) -> S::f32s {
    s.xor_f32s(a, s.splat_f32s(-0.0))
}

/// ln x = k ln 2 + ln(1 + f) from x = 2^k m, m in [sqrt(1/2), sqrt(2)), taking f = -d
/// where k = 0 and d is given.
#[inline(always)]
fn ln_finish<S: Simd>(s: S, ef: S::f32s, m: S::f32s, d: Option<S::f32s>) -> S::f32s {
    let mut f = s.sub_f32s(m, s.splat_f32s(1.0));
    if let Some(d) = d {
        let near_one = s.equal_f32s(ef, s.splat_f32s(0.0));
        f = s.select_f32s(near_one, neg(s, d), f);
    }
    s.mul_add_e_f32s(ef, s.splat_f32s(LN2), ln1p_reduced(s, f))
}

/// AVX-512 has single instructions for what the portable code builds from integer steps:
/// rounding (vrndscaleps), scaling by 2^k (vscalefps, which also gives 0 below the range
/// under a mask) and splitting x into exponent and mantissa (vgetexpps, vgetmantps).
/// Same formulas and coefficients, fewer instructions.
#[cfg(target_arch = "x86_64")]
mod v4 {
    use std::any::Any;
    use std::arch::x86_64::{
        __m512, _CMP_GE_OQ, _MM_FROUND_NO_EXC, _MM_FROUND_TO_NEAREST_INT, _MM_MANT_NORM_1_2,
        _MM_MANT_SIGN_ZERO,
    };

    use pulp::x86::V4;
    use pulp::{Simd, f32x16};

    use super::{EXP2_P, EXP2M1_Q, horner};

    const ROUND: i32 = _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC;

    /// The AVX-512 token when `S` is pulp's AVX-512 level (decided at compile time).
    #[inline(always)]
    pub fn get<S: Simd>(s: S) -> Option<V4> {
        (&s as &dyn Any).downcast_ref::<V4>().copied()
    }

    #[inline(always)]
    fn m512<S: Simd>(v: S::f32s) -> __m512 {
        let v = (&v as &dyn Any).downcast_ref::<f32x16>();
        bytemuck::cast(*v.expect("AVX-512 lanes are f32x16"))
    }

    #[inline(always)]
    fn lanes<S: Simd>(v: __m512) -> S::f32s {
        let v: f32x16 = bytemuck::cast(v);
        *(&v as &dyn Any)
            .downcast_ref::<S::f32s>()
            .expect("AVX-512 lanes are f32x16")
    }

    /// 2^t for finite t: scalef's own underflow gives 0 from t = -151 down and 2^t's
    /// subnormals above (a mask making them 0 from -127, as the portable code does, cost
    /// 2-5% of the dense kernels' time).
    #[inline(always)]
    pub fn exp2<S: Simd>(s: S, v: V4, t: S::f32s) -> S::f32s {
        let a = v.avx512f;
        let t5 = m512::<S>(t);
        let k = a._mm512_roundscale_ps::<ROUND>(t5);
        let f = lanes::<S>(a._mm512_sub_ps(t5, k));
        let p = m512::<S>(s.mul_add_e_f32s(horner(s, f, &EXP2_P), f, s.splat_f32s(1.0)));
        lanes::<S>(a._mm512_scalef_ps(p, k))
    }

    /// 2^u - 1 through the reduction u = k + f, for |u| <= 126.
    #[inline(always)]
    pub fn exp2m1_reduced<S: Simd>(s: S, v: V4, u: S::f32s) -> S::f32s {
        let a = v.avx512f;
        let u5 = m512::<S>(u);
        let k = a._mm512_roundscale_ps::<ROUND>(u5);
        let f = lanes::<S>(a._mm512_sub_ps(u5, k));
        let p = s.mul_f32s(f, horner(s, f, &EXP2M1_Q));
        let two_k = lanes::<S>(a._mm512_scalef_ps(a._mm512_set1_ps(1.0), k));
        s.mul_add_e_f32s(two_k, p, s.sub_f32s(two_k, s.splat_f32s(1.0)))
    }

    /// x = 2^k m with m in [sqrt(1/2), sqrt(2)): (k, m).
    #[inline(always)]
    pub fn split<S: Simd>(_s: S, v: V4, x: S::f32s) -> (S::f32s, S::f32s) {
        let a = v.avx512f;
        let x5 = m512::<S>(x);
        let e = a._mm512_getexp_ps(x5);
        let m = a._mm512_getmant_ps::<_MM_MANT_NORM_1_2, _MM_MANT_SIGN_ZERO>(x5);
        let hi = a._mm512_cmp_ps_mask::<_CMP_GE_OQ>(m, a._mm512_set1_ps(std::f32::consts::SQRT_2));
        let m = a._mm512_mask_mul_ps(m, hi, m, a._mm512_set1_ps(0.5));
        let e = a._mm512_mask_add_ps(e, hi, e, a._mm512_set1_ps(1.0));
        (lanes::<S>(e), lanes::<S>(m))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lanes<S: Simd>(s: S, v: f32) -> S::f32s {
        s.splat_f32s(v)
    }

    fn first<S: Simd>(v: S::f32s) -> f32 {
        bytemuck::cast_slice::<S::f32s, f32>(std::slice::from_ref(&v))[0]
    }

    #[test]
    fn spot_values() {
        let s = pulp::Scalar::new();
        assert_eq!(first::<pulp::Scalar>(exp2(s, lanes(s, 0.0))), 1.0);
        assert_eq!(first::<pulp::Scalar>(exp2(s, lanes(s, 3.0))), 8.0);
        assert_eq!(first::<pulp::Scalar>(exp2(s, lanes(s, -200.0))), 0.0);
        assert_eq!(first::<pulp::Scalar>(exp2m1(s, lanes(s, 0.0))), 0.0);
        assert_eq!(first::<pulp::Scalar>(ln(s, lanes(s, 1.0))), 0.0);
        let v = first::<pulp::Scalar>(exp2m1(s, lanes(s, 1e-7)));
        assert!(
            (v as f64 / (1e-7 * std::f64::consts::LN_2) - 1.0).abs() < 1e-6,
            "{v}"
        );
        let v = first::<pulp::Scalar>(ln(s, lanes(s, 0.25)));
        assert!((v as f64 - 0.25f64.ln()).abs() < 1e-6, "{v}");
    }
}

/// A function of this module, for [`eval`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MathFn {
    /// [`exp2`] of the argument.
    Exp2,
    /// [`exp2m1`] of the argument.
    Exp2m1,
    /// [`ln`] of the argument.
    Ln,
    /// [`ln_1m`]: ln(1 - d) of the argument d, with x = 1 - d rounded to f32.
    Ln1m,
    /// [`exp2m1_reduced`] of the argument (the dense kernels' lobes).
    Exp2m1Reduced,
    /// u Q(u), the polynomial of [`exp2m1_reduced`] without its range reduction: what
    /// the dense forward kernel takes for lobes with |u| < 1/2.
    Exp2m1Poly,
}

struct Eval<'a> {
    f: MathFn,
    xs: &'a [f32],
    out: &'a mut [f32],
}

impl pulp::WithSimd for Eval<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: Simd>(self, s: S) {
        let (xs, _) = S::as_simd_f32s(self.xs);
        let (out, _) = S::as_mut_simd_f32s(self.out);
        for (x, o) in xs.iter().zip(out.iter_mut()) {
            *o = match self.f {
                MathFn::Exp2 => exp2(s, *x),
                MathFn::Exp2m1 => exp2m1(s, *x),
                MathFn::Ln => ln(s, *x),
                MathFn::Ln1m => ln_1m(s, s.sub_f32s(s.splat_f32s(1.0), *x), *x),
                MathFn::Exp2m1Reduced => exp2m1_reduced(s, *x),
                MathFn::Exp2m1Poly => s.mul_f32s(*x, horner(s, *x, &EXP2M1_Q)),
            };
        }
    }
}

/// Applies `f` to `xs` with the kernels' own SIMD code at `cpu`'s level: what the error
/// sweep in tests/it/cpu_math.rs measures.
pub fn eval(cpu: &super::FastCpu, f: MathFn, xs: &[f32]) -> Vec<f32> {
    let n = xs.len().div_ceil(16) * 16;
    let mut padded = xs.to_vec();
    padded.resize(n, 0.5);
    let mut out = vec![0.0f32; n];
    cpu.dispatch(Eval {
        f,
        xs: &padded,
        out: &mut out,
    });
    out.truncate(xs.len());
    out
}
