//! Levenberg-Marquardt on one channel's lobes: the control points of lobe s are
//! exp(p) (scales m0 and exponents m1 both stay positive, and exponents spanning 1 to 1e4
//! are equally well scaled), the residual of sample i is
//! sqrt(w_i) (g(f_i) - g(t_i)) with g(v) = c ln(1 + v / c), linear for values small
//! against c and logarithmic above, so that a specular peak cannot drown the rest.

use super::samples::Plane;
use crate::spline::N_CTRL_POINTS;

/// Parameters per lobe: 6 log-scales then 6 log-exponents.
pub const PER_LOBE: usize = 2 * N_CTRL_POINTS;

/// Bounds of the log-parameters: scales in [1e-8, 40], exponents in [1e-3, 1e4].
pub const SCALE_BOUNDS: (f64, f64) = (-18.420680743952367, 3.6888794541139363);
/// See [`SCALE_BOUNDS`].
pub const EXPONENT_BOUNDS: (f64, f64) = (-6.907755278982137, 9.210340371976184);

/// How much a negative model value costs: a sample that is below 0 by the targets' RMS
/// costs as much as (NEGATIVE_WEIGHT)^2 / samples, i.e. 1e4 times an even share.
const NEGATIVE_WEIGHT: f64 = 100.0;

/// One channel's least-squares problem over the plane.
#[derive(Clone)]
pub struct Problem<'a> {
    plane: &'a Plane,
    /// g(target) per sample.
    g_target: Vec<f64>,
    /// sqrt(weight) per sample, normalised so that sum w g(t)^2 = 1.
    sqrt_w: Vec<f64>,
    /// The scale c of g; infinite for a linear loss.
    c: f64,
    /// Upper bound of the log-scales: no lobe may peak above 4 times the largest target,
    /// which keeps lobes from growing spikes at theta_h ~ 0, where the measure gives
    /// samples little weight but a point-sampled render can land on them.
    scale_max: f64,
    /// The sign of each lobe's scales (+1 or -1; missing: +1): a lobe with negative
    /// scales dips below its neighbours near theta_h = 0 and, with a small exponent,
    /// lets the sum rise towards grazing theta_h, as fabrics' BRDFs do.
    signs: Vec<f64>,
    /// Weight of the residual min(f, 0) per sample: a sum of lobes with negative scales
    /// must not go below 0 where the BRDF is seen, even where the cosines give that place
    /// little weight (a negative BRDF is no material).
    sqrt_negative: f64,
    /// Scales as free control points (any sign per point, bounded by +-exp(scale_max))
    /// rather than exp(p) with one sign per lobe; exponents stay exp(p).
    free_scales: bool,
}

impl<'a> Problem<'a> {
    /// The problem for `target` (one value per plane sample) with loss scale `c`.
    pub fn new(plane: &'a Plane, target: &[f64], c: f64) -> Self {
        let g_target: Vec<f64> = target.iter().map(|&t| g(t, c)).collect();
        let norm: f64 = plane
            .weight
            .iter()
            .zip(&g_target)
            .map(|(w, t)| w * t * t)
            .sum::<f64>()
            .max(1e-300);
        let sqrt_w = plane.weight.iter().map(|w| (w / norm).sqrt()).collect();
        let peak = target.iter().fold(0.0f64, |m, &t| m.max(t));
        let scale_max = (4.0 * peak).ln_1p().max(1e-6).ln().min(SCALE_BOUNDS.1);
        let n = target.len().max(1) as f64;
        let g_rms = (g_target.iter().map(|t| t * t).sum::<f64>() / n)
            .sqrt()
            .max(1e-300);
        Problem {
            sqrt_negative: NEGATIVE_WEIGHT / (n.sqrt() * g_rms),
            plane,
            g_target,
            sqrt_w,
            c,
            scale_max,
            signs: Vec::new(),
            free_scales: false,
        }
    }

    /// The same problem with free scales: a lobe's scale control points are parameters
    /// themselves, each of either sign (the signs of [`Problem::with_signs`] are then
    /// unused), within +-(1 + 4 max target) in exp(m0) - 1.
    pub fn with_free_scales(mut self) -> Self {
        self.free_scales = true;
        self
    }

    /// The control points of the parameters `p`: exp(p), except free scales.
    fn values(&self, p: &[f64]) -> Vec<f64> {
        p.iter()
            .enumerate()
            .map(|(i, &v)| {
                if self.free_scales && i % PER_LOBE < N_CTRL_POINTS {
                    v
                } else {
                    v.exp()
                }
            })
            .collect()
    }

    /// The same problem with lobe s's scales of sign `signs[s]`.
    pub fn with_signs(mut self, signs: &[f64]) -> Self {
        self.signs = signs.to_vec();
        self
    }

    /// The model's value and, if `jac` is given, its derivatives with respect to the
    /// parameters, at sample i.
    /// `ctrl` holds the control points themselves ([`Problem::values`]).
    fn model(&self, i: usize, ctrl: &[f64], mut jac: Option<&mut [f64]>) -> f64 {
        let b = &self.plane.basis[i];
        let (x, ln_x) = (self.plane.x[i], self.plane.ln_x[i]);
        let mut f = 0.0;
        for (s, lobe) in ctrl.chunks_exact(PER_LOBE).enumerate() {
            let (c0, c1) = lobe.split_at(N_CTRL_POINTS);
            let sign = if self.free_scales {
                1.0
            } else {
                self.signs.get(s).copied().unwrap_or(1.0)
            };
            let (mut m0, mut m1) = (0.0, 0.0);
            for j in 0..N_CTRL_POINTS {
                m0 += b[j] * sign * c0[j];
                m1 += b[j] * c1[j];
            }
            let xp = if x > 0.0 { (m1 * ln_x).exp() } else { 0.0 };
            let e = (m0 * xp).exp();
            f += e - 1.0;
            if let Some(jac) = jac.as_deref_mut() {
                let d0 = e * xp;
                let d1 = e * m0 * xp * ln_x;
                let row = &mut jac[s * PER_LOBE..(s + 1) * PER_LOBE];
                // d/dp of a free scale is 1, of a log-parameter exp(p) = the point itself
                let dp0 = |j: usize| if self.free_scales { 1.0 } else { c0[j] };
                for j in 0..N_CTRL_POINTS {
                    row[j] = d0 * b[j] * sign * dp0(j);
                    row[N_CTRL_POINTS + j] = d1 * b[j] * c1[j];
                }
            }
        }
        f
    }

    /// The cost: sum of squared residuals (1 for the zero model... up to the loss).
    pub fn cost(&self, p: &[f64]) -> f64 {
        let ctrl = self.values(p);
        (0..self.g_target.len())
            .map(|i| {
                let f = self.model(i, &ctrl, None);
                let r = self.sqrt_w[i] * (g(f, self.c) - self.g_target[i]);
                let neg = self.sqrt_negative * f.min(0.0);
                r * r + neg * neg
            })
            .sum()
    }

    /// Minimises the cost from `p` for at most `iterations` steps; returns the cost.
    pub fn solve(&self, p: &mut [f64], iterations: usize) -> f64 {
        let n = p.len();
        self.clamp(p);
        let mut cost = self.cost(p);
        let mut lambda = 1e-3;
        let mut a = vec![0.0; n * n];
        let mut grad = vec![0.0; n];
        let mut trial = vec![0.0; n];
        let mut step = vec![0.0; n];
        // the residuals and their Jacobian, a row each: every sample's, and after a sample
        // below 0 its negativity residual (the model's row times sqrt_negative)
        let mut rows: Vec<f64> = Vec::with_capacity(self.g_target.len() * n);
        let mut residuals: Vec<f64> = Vec::with_capacity(self.g_target.len());
        let mut jac = vec![0.0; n];
        let mut stalls = 0;
        for _ in 0..iterations {
            rows.clear();
            residuals.clear();
            let ctrl = self.values(p);
            for i in 0..self.g_target.len() {
                let f = self.model(i, &ctrl, Some(&mut jac));
                let dg = self.sqrt_w[i] * g_prime(f, self.c);
                residuals.push(self.sqrt_w[i] * (g(f, self.c) - self.g_target[i]));
                rows.extend(jac.iter().map(|v| v * dg));
                if f < 0.0 {
                    let k = self.sqrt_negative;
                    residuals.push(k * f);
                    rows.extend(jac.iter().map(|v| v * k));
                }
            }
            normal_equations(&rows, &residuals, n, &mut a, &mut grad);
            let mut improved = false;
            for _ in 0..12 {
                if !solve_damped(&a, &grad, lambda, n, &mut step) {
                    lambda *= 8.0;
                    continue;
                }
                for (i, (lo, hi)) in self.bounds(n).enumerate() {
                    trial[i] = (p[i] - step[i]).clamp(lo, hi);
                }
                let c = self.cost(&trial);
                if c < cost {
                    let gain = (cost - c) / cost.max(1e-300);
                    p.copy_from_slice(&trial);
                    cost = c;
                    lambda = (lambda / 3.0).max(1e-9);
                    improved = true;
                    stalls = if gain < 1e-7 { stalls + 1 } else { 0 };
                    break;
                }
                lambda *= 4.0;
            }
            if !improved || stalls >= 3 {
                break;
            }
        }
        cost
    }
}

impl Problem<'_> {
    /// The bounds of each parameter of a vector of length n.
    fn bounds(&self, n: usize) -> impl Iterator<Item = (f64, f64)> + '_ {
        (0..n).map(|i| {
            if i % PER_LOBE >= N_CTRL_POINTS {
                EXPONENT_BOUNDS
            } else if self.free_scales {
                let cap = self.scale_max.exp();
                (-cap, cap)
            } else {
                (SCALE_BOUNDS.0, self.scale_max)
            }
        })
    }

    /// `p` moved inside the bounds.
    pub fn clamp(&self, p: &mut [f64]) {
        let n = p.len();
        for (v, (lo, hi)) in p.iter_mut().zip(self.bounds(n)) {
            *v = v.clamp(lo, hi);
        }
    }
}

/// The Gauss-Newton system of residuals `r` with Jacobian `j` (a row of `n` per
/// residual): `a` = J^T J (n x n, whole) and `grad` = J^T r, the products by
/// matrixmultiply's blocked kernels.
fn normal_equations(j: &[f64], r: &[f64], n: usize, a: &mut [f64], grad: &mut [f64]) {
    let m = r.len();
    assert!(j.len() == m * n && a.len() == n * n && grad.len() == n);
    if m == 0 || n == 0 {
        a.fill(0.0);
        grad.fill(0.0);
        return;
    }
    // SAFETY: J is m x n row-major (so J^T is n x m with strides 1 and n), r m x 1, A
    // n x n and grad n x 1, as asserted above; the outputs do not overlap the inputs.
    unsafe {
        matrixmultiply::dgemm(
            n,
            m,
            n,
            1.0,
            j.as_ptr(),
            1,
            n as isize,
            j.as_ptr(),
            n as isize,
            1,
            0.0,
            a.as_mut_ptr(),
            n as isize,
            1,
        );
        matrixmultiply::dgemm(
            n,
            m,
            1,
            1.0,
            j.as_ptr(),
            1,
            n as isize,
            r.as_ptr(),
            1,
            1,
            0.0,
            grad.as_mut_ptr(),
            1,
            1,
        );
    }
}

/// Solves (A + lambda diag(A)) x = grad by Cholesky, A symmetric with its lower
/// triangle filled; false if the damped matrix is not positive definite.
fn solve_damped(a: &[f64], grad: &[f64], lambda: f64, n: usize, x: &mut [f64]) -> bool {
    let mut l = vec![0.0; n * n];
    for i in 0..n {
        for j in 0..=i {
            let mut s = a[i * n + j];
            if i == j {
                s += lambda * a[i * n + i] + 1e-12;
            }
            for k in 0..j {
                s -= l[i * n + k] * l[j * n + k];
            }
            if i == j {
                if s <= 0.0 || !s.is_finite() {
                    return false;
                }
                l[i * n + i] = s.sqrt();
            } else {
                l[i * n + j] = s / l[j * n + j];
            }
        }
    }
    for i in 0..n {
        let mut s = grad[i];
        for k in 0..i {
            s -= l[i * n + k] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    for i in (0..n).rev() {
        let mut s = x[i];
        for k in i + 1..n {
            s -= l[k * n + i] * x[k];
        }
        x[i] = s / l[i * n + i];
    }
    x.iter().all(|v| v.is_finite())
}

/// The loss's transform g(v) = c ln(1 + v / c) (v for infinite c); v itself below 0,
/// where only a lobe with negative scales can take the model, so that going there costs
/// as much as the slope at 0 says.
fn g(v: f64, c: f64) -> f64 {
    if c.is_finite() && v > 0.0 {
        c * (v / c).ln_1p()
    } else {
        v
    }
}

fn g_prime(v: f64, c: f64) -> f64 {
    if c.is_finite() && v > 0.0 {
        1.0 / (1.0 + v / c)
    } else {
        1.0
    }
}
