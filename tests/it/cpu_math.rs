//! The fast path's polynomial exp2, 2^u - 1 (the lobes' exp(y) - 1) and ln, swept against f64 over the whole range a
//! valid input reaches, at every SIMD level this machine has, asserting the error bounds
//! stated in src/cpu/math.rs.

use matedit::cpu::math::{EXP2_MAX_REL, EXP2M1_MAX_REL, LN_MAX_REL, MathFn, eval};
use matedit::cpu::{FastCpu, SimdLevel};

fn levels() -> Vec<FastCpu> {
    SimdLevel::ALL
        .into_iter()
        .filter_map(FastCpu::with_level)
        .collect()
}

/// `n` points evenly spaced in [lo, hi], rounded to f32.
fn linspace(lo: f64, hi: f64, n: usize) -> Vec<f32> {
    (0..n)
        .map(|i| (lo + (hi - lo) * i as f64 / (n - 1) as f64) as f32)
        .collect()
}

/// `n` points log-spaced in [lo, hi] (lo, hi > 0), rounded to f32.
fn logspace(lo: f64, hi: f64, n: usize) -> Vec<f32> {
    let (a, b) = (lo.ln(), hi.ln());
    (0..n)
        .map(|i| (a + (b - a) * i as f64 / (n - 1) as f64).exp() as f32)
        .collect()
}

/// The largest |got - want| / |want| over `xs`, with the worst argument.
fn worst_rel(cpu: &FastCpu, f: MathFn, xs: &[f32], want: impl Fn(f64) -> f64) -> (f64, f32) {
    let got = eval(cpu, f, xs);
    let mut worst = (0.0, 0.0);
    for (&x, &g) in xs.iter().zip(&got) {
        let w = want(x as f64);
        assert!(g.is_finite(), "{f:?}({x}) = {g}");
        let e = if w == 0.0 {
            (g as f64).abs()
        } else {
            (g as f64 - w).abs() / w.abs()
        };
        if e > worst.0 {
            worst = (e, x);
        }
    }
    worst
}

#[test]
fn exp2_within_its_bound_over_the_valid_range() {
    let xs = linspace(-126.0, 126.0, 2_000_001);
    for cpu in levels() {
        let (e, x) = worst_rel(&cpu, MathFn::Exp2, &xs, f64::exp2);
        eprintln!("exp2 {}: max rel error {e:.3e} at {x}", cpu.level().name());
        assert!(e <= EXP2_MAX_REL, "{}: {e:e} at {x}", cpu.level().name());
    }
    for cpu in levels() {
        // far below the range: exactly 0 (x^m1 underflows), never NaN
        let got = eval(&cpu, MathFn::Exp2, &[-151.0, -500.0, -3.0e38]);
        assert_eq!(got, vec![0.0; 3], "{}", cpu.level().name());
        // where 2^t is subnormal: within 2^-126, never negative
        let xs = linspace(-151.0, -126.0, 100_001);
        for (&x, g) in xs.iter().zip(eval(&cpu, MathFn::Exp2, &xs)) {
            let e = (g as f64 - (x as f64).exp2()).abs();
            assert!(
                g >= 0.0 && e < 2f64.powi(-126),
                "{}: exp2({x}) = {g:e}",
                cpu.level().name()
            );
        }
    }
}

#[test]
fn exp2m1_within_its_bound_and_keeps_small_arguments() {
    let mut xs = linspace(-126.0, 126.0, 2_000_001);
    for v in logspace(1e-30, 1.0, 200_001) {
        xs.push(v);
        xs.push(-v);
    }
    for cpu in levels() {
        let (e, x) = worst_rel(&cpu, MathFn::Exp2m1, &xs, |u| {
            (u * std::f64::consts::LN_2).exp_m1()
        });
        eprintln!(
            "exp2m1 {}: max rel error {e:.3e} at {x}",
            cpu.level().name()
        );
        assert!(e <= EXP2M1_MAX_REL, "{}: {e:e} at {x}", cpu.level().name());
    }
}

#[test]
fn ln_within_its_bound_over_the_valid_range() {
    // x = max(0, h.n) of a valid pair: from the smallest x the kernels take a log of up to
    // |n|^2 for normals longer than 1; away from x = 1, where ln x has no small values
    let mut xs = logspace(1e-30, 0.99, 1_000_001);
    xs.extend(logspace(1.01, 1e4, 200_001));
    for cpu in levels() {
        let (e, x) = worst_rel(&cpu, MathFn::Ln, &xs, f64::ln);
        eprintln!("ln {}: max rel error {e:.3e} at {x}", cpu.level().name());
        assert!(e <= LN_MAX_REL, "{}: {e:e} at {x}", cpu.level().name());
    }
}

#[test]
fn ln_1m_keeps_its_digits_near_one() {
    // ln(1 - d) for d from 1e-12 (x = 1 to f32 precision) to 1 - 1e-7, and negative d
    // (x > 1, normals longer than 1)
    let mut ds = logspace(1e-12, 1.0 - 1e-7, 1_000_001);
    ds.extend(logspace(1e-12, 0.4, 100_001).iter().map(|d| -d));
    for cpu in levels() {
        let got = eval(&cpu, MathFn::Ln1m, &ds);
        let mut worst = (0.0, 0.0);
        for (&d, &g) in ds.iter().zip(&got) {
            // the kernels see x rounded to f32; the f64 truth is ln(1 - d) for the exact d
            let w = (-(d as f64)).ln_1p();
            let e = (g as f64 - w).abs() / w.abs();
            if e > worst.0 {
                worst = (e, d);
            }
        }
        eprintln!(
            "ln_1m {}: max rel error {:.3e} at d = {}",
            cpu.level().name(),
            worst.0,
            worst.1
        );
        assert!(
            worst.0 <= LN_MAX_REL,
            "{}: {:e} at d = {}",
            cpu.level().name(),
            worst.0,
            worst.1
        );
    }
}

#[test]
fn plain_ln_of_a_rounded_x_loses_digits_that_ln_1m_keeps() {
    // why ln_1m exists: with d = 1e-6, x = 1 - d rounds to f32 and ln x is off by ~3e-2
    // relative; a lobe with m1 = 1e4 would carry that error into x^m1
    let cpu = FastCpu::best();
    let d = 1.0e-6f32;
    let plain = eval(&cpu, MathFn::Ln, &[1.0 - d])[0] as f64;
    let kept = eval(&cpu, MathFn::Ln1m, &[d])[0] as f64;
    let want = (-(d as f64)).ln_1p();
    assert!(
        (plain - want).abs() / want.abs() > 1e-2,
        "{plain} vs {want}"
    );
    assert!((kept - want).abs() / want.abs() < 1e-6, "{kept} vs {want}");
}

#[test]
fn below_one_half_the_reduction_is_the_identity() {
    // the dense forward kernel leaves out 2^u - 1's range reduction for lobes whose
    // |u| stays below 1/2: the same bits, at every level
    let mut xs = linspace(-0.4999, 0.4999, 200_001);
    xs.extend(logspace(1e-30, 0.4999, 10_001));
    xs.extend(logspace(1e-30, 0.4999, 10_001).iter().map(|v| -v));
    for cpu in levels() {
        let a = eval(&cpu, MathFn::Exp2m1Reduced, &xs);
        let b = eval(&cpu, MathFn::Exp2m1Poly, &xs);
        for ((x, a), b) in xs.iter().zip(&a).zip(&b) {
            assert_eq!(a.to_bits(), b.to_bits(), "{}: u = {x}", cpu.level().name());
        }
    }
}
