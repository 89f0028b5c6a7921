//! Adam (Kingma and Ba, 2015) on a flat parameter vector, with a learning rate per
//! parameter.

/// The optimiser's state: first and second moment estimates and the step count.
#[derive(Clone, Debug)]
pub struct Adam {
    m: Vec<f64>,
    v: Vec<f64>,
    t: i32,
}

const BETA1: f64 = 0.9;
const BETA2: f64 = 0.999;
const EPS: f64 = 1e-12;

impl Adam {
    /// State for `n` parameters.
    pub fn new(n: usize) -> Self {
        Adam {
            m: vec![0.0; n],
            v: vec![0.0; n],
            t: 0,
        }
    }

    /// One step: `x -= lr * m_hat / (sqrt(v_hat) + eps)` for gradient `g`, `lr[i]` per
    /// parameter.
    pub fn step(&mut self, x: &mut [f64], g: &[f64], lr: &[f64]) {
        self.t += 1;
        let c1 = 1.0 - BETA1.powi(self.t);
        let c2 = 1.0 - BETA2.powi(self.t);
        for i in 0..x.len() {
            self.m[i] = BETA1 * self.m[i] + (1.0 - BETA1) * g[i];
            self.v[i] = BETA2 * self.v[i] + (1.0 - BETA2) * g[i] * g[i];
            let (mh, vh) = (self.m[i] / c1, self.v[i] / c2);
            x[i] -= lr[i] * mh / (vh.sqrt() + EPS);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn minimises_a_badly_scaled_quadratic() {
        // f = 1e4 (x0 - 1)^2 + 1e-2 (x1 + 2)^2: Adam's steps do not depend on the scale
        let mut x = [0.0, 0.0];
        let mut adam = Adam::new(2);
        for k in 0..3000 {
            let lr = 0.1 * 0.998f64.powi(k);
            let g = [2e4 * (x[0] - 1.0), 2e-2 * (x[1] + 2.0)];
            adam.step(&mut x, &g, &[lr, lr]);
        }
        assert!((x[0] - 1.0).abs() < 1e-3, "{x:?}");
        assert!((x[1] + 2.0).abs() < 1e-2, "{x:?}");
    }
}
