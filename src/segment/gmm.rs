//! Colour models: a mixture of a few Gaussians with full covariance over display colours
//! (as GrabCut's, Rother et al. 2004), fitted by k-means and then refitted from each
//! colour's most likely component.

/// Added to each covariance's diagonal, so that a component of one flat colour still has
/// a finite density (colours in [0, 1]: a standard deviation of about 0.014).
const FLOOR: f64 = 2e-4;

/// One Gaussian of a mixture, ready to evaluate.
#[derive(Clone, Debug)]
struct Component {
    mean: [f64; 3],
    /// The inverse covariance.
    inv: [[f64; 3]; 3],
    /// ln(weight) - ln(det covariance) / 2 - 3 ln(2 pi) / 2.
    log_scale: f64,
}

/// A mixture of Gaussians over colours.
#[derive(Clone, Debug)]
pub struct ColourModel {
    components: Vec<Component>,
}

impl ColourModel {
    /// A mixture of at most `k` components fitted to `colours` by k-means (seeded at
    /// quantiles of their brightness). `None` without colours.
    pub fn fit(colours: &[[f32; 3]], k: usize) -> Option<ColourModel> {
        if colours.is_empty() {
            return None;
        }
        // k-means on at most ~20 000 of them
        let stride = colours.len().div_ceil(20_000);
        let sample: Vec<[f32; 3]> = colours.iter().step_by(stride).copied().collect();
        let mut order: Vec<usize> = (0..sample.len()).collect();
        order.sort_by(|&a, &b| luma(&sample[a]).total_cmp(&luma(&sample[b])));
        let k = k.clamp(1, sample.len());
        let mut centres: Vec<[f32; 3]> = (0..k)
            .map(|c| sample[order[(2 * c + 1) * sample.len() / (2 * k)]])
            .collect();
        let mut labels = vec![0; sample.len()];
        for _ in 0..6 {
            for (l, c) in labels.iter_mut().zip(&sample) {
                *l = nearest(&centres, c);
            }
            let mut sums = vec![([0.0f64; 3], 0usize); k];
            for (&l, c) in labels.iter().zip(&sample) {
                for ch in 0..3 {
                    sums[l].0[ch] += f64::from(c[ch]);
                }
                sums[l].1 += 1;
            }
            for (centre, (s, n)) in centres.iter_mut().zip(&sums) {
                if *n > 0 {
                    *centre = s.map(|v| (v / *n as f64) as f32);
                }
            }
        }
        let labels: Vec<usize> = colours.iter().map(|c| nearest(&centres, c)).collect();
        Self::from_labels(colours, &labels, k)
    }

    /// The mixture refitted to `colours`, each given to its most likely component.
    pub fn refit(&self, colours: &[[f32; 3]]) -> Option<ColourModel> {
        let labels: Vec<usize> = colours.iter().map(|c| self.most_likely(c)).collect();
        Self::from_labels(colours, &labels, self.components.len())
    }

    /// -ln of the mixture's density at `c`.
    pub fn cost(&self, c: &[f32; 3]) -> f32 {
        let logs = self.components.iter().map(|g| g.log_density(c));
        let top = logs.clone().fold(f64::NEG_INFINITY, f64::max);
        let sum: f64 = logs.map(|l| (l - top).exp()).sum();
        (-(top + sum.ln())) as f32
    }

    fn most_likely(&self, c: &[f32; 3]) -> usize {
        let mut best = (0, f64::NEG_INFINITY);
        for (i, g) in self.components.iter().enumerate() {
            let l = g.log_density(c);
            if l > best.1 {
                best = (i, l);
            }
        }
        best.0
    }

    /// The mixture of the components with colours; `None` if none has any.
    fn from_labels(colours: &[[f32; 3]], labels: &[usize], k: usize) -> Option<ColourModel> {
        let mut n = vec![0usize; k];
        let mut sum = vec![[0.0f64; 3]; k];
        let mut sq = vec![[[0.0f64; 3]; 3]; k];
        for (c, &l) in colours.iter().zip(labels) {
            let c = c.map(f64::from);
            n[l] += 1;
            for i in 0..3 {
                sum[l][i] += c[i];
                for j in 0..3 {
                    sq[l][i][j] += c[i] * c[j];
                }
            }
        }
        let total = colours.len() as f64;
        let components: Vec<Component> = (0..k)
            .filter(|&l| n[l] > 0)
            .filter_map(|l| {
                let m = n[l] as f64;
                let mean = sum[l].map(|s| s / m);
                let cov: [[f64; 3]; 3] = std::array::from_fn(|i| {
                    std::array::from_fn(|j| {
                        sq[l][i][j] / m - mean[i] * mean[j] + if i == j { FLOOR } else { 0.0 }
                    })
                });
                let (inv, det) = invert(&cov)?;
                Some(Component {
                    mean,
                    inv,
                    log_scale: (m / total).ln()
                        - 0.5 * det.ln()
                        - 1.5 * (2.0 * std::f64::consts::PI).ln(),
                })
            })
            .collect();
        (!components.is_empty()).then_some(ColourModel { components })
    }
}

impl Component {
    fn log_density(&self, c: &[f32; 3]) -> f64 {
        let d: [f64; 3] = std::array::from_fn(|i| f64::from(c[i]) - self.mean[i]);
        let mut q = 0.0;
        for i in 0..3 {
            for j in 0..3 {
                q += d[i] * self.inv[i][j] * d[j];
            }
        }
        self.log_scale - 0.5 * q
    }
}

fn luma(c: &[f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

fn nearest(centres: &[[f32; 3]], c: &[f32; 3]) -> usize {
    let d = |m: &[f32; 3]| (0..3).map(|i| (c[i] - m[i]).powi(2)).sum::<f32>();
    let mut best = (0, f32::INFINITY);
    for (i, m) in centres.iter().enumerate() {
        let e = d(m);
        if e < best.1 {
            best = (i, e);
        }
    }
    best.0
}

/// The inverse and the determinant of a symmetric 3 x 3 matrix, if it is positive.
fn invert(m: &[[f64; 3]; 3]) -> Option<([[f64; 3]; 3], f64)> {
    let c = |i: usize, j: usize| {
        let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
        let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
        m[i1][j1] * m[i2][j2] - m[i1][j2] * m[i2][j1]
    };
    let det = m[0][0] * c(0, 0) + m[0][1] * c(0, 1) + m[0][2] * c(0, 2);
    if det.is_nan() || det <= 1e-30 {
        return None;
    }
    Some((
        std::array::from_fn(|i| std::array::from_fn(|j| c(j, i) / det)),
        det,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn two_colours_are_told_apart() {
        let mut cs = Vec::new();
        for i in 0..500 {
            let e = (i % 7) as f32 * 0.004;
            cs.push([0.8 + e, 0.1, 0.1 - e]);
            cs.push([0.1, 0.2 + e, 0.8]);
        }
        let red = ColourModel::fit(
            &cs[..1000].iter().step_by(2).copied().collect::<Vec<_>>(),
            3,
        )
        .unwrap();
        let both = ColourModel::fit(&cs, 5).unwrap().refit(&cs).unwrap();
        assert!(red.cost(&[0.81, 0.1, 0.09]) < red.cost(&[0.1, 0.2, 0.8]) - 10.0);
        let (a, b) = (both.cost(&[0.81, 0.1, 0.09]), both.cost(&[0.1, 0.21, 0.8]));
        // both colours are half the mixture: their densities are alike
        assert!((a - b).abs() < 2.0, "{a} {b}");
        assert!(both.cost(&[0.5, 0.9, 0.5]) > a + 10.0);
        assert!(ColourModel::fit(&[], 5).is_none());
    }

    #[test]
    fn the_inverse_is_one() {
        let m = [[2.0, 0.3, 0.1], [0.3, 1.0, 0.2], [0.1, 0.2, 0.5]];
        let (inv, det) = invert(&m).unwrap();
        for i in 0..3 {
            for j in 0..3 {
                let p: f64 = (0..3).map(|k| m[i][k] * inv[k][j]).sum();
                assert!((p - f64::from(u8::from(i == j))).abs() < 1e-12);
            }
        }
        assert!(det > 0.0);
    }
}
