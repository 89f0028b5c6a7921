//! The BRDF tabulated where the fitter looks at it, and the weights that say how much
//! each place is seen.
//!
//! Samples sit at cell centres of a (theta_h, theta_d, phi_d) grid: theta_h uniform in
//! sqrt(theta_h) (dense near the specular peak, like the MERL tables), theta_d and phi_d
//! uniform, phi_d over [0, pi) (reciprocity gives the rest). A sample's weight is
//! cos theta_i cos theta_o (how often an image sees that pair: the light's cosine and the
//! sphere's pixel density) times the measure of its cell in the space of direction pairs,
//! 4 cos theta_d sin theta_d sin theta_h dtheta_h dtheta_d dphi_d; pairs with either
//! direction below the surface weigh nothing.

use std::f64::consts::{FRAC_PI_2, PI};

use crate::brdf::{Isotropic, from_rusinkiewicz};
use crate::spline::{N_CTRL_POINTS, spline_basis};

/// Grid resolution: theta_h, theta_d and phi_d cells.
#[derive(Clone, Copy, Debug)]
pub struct Grid {
    /// theta_h cells (uniform in sqrt(theta_h)).
    pub theta_h: usize,
    /// theta_d cells.
    pub theta_d: usize,
    /// phi_d cells over [0, pi).
    pub phi_d: usize,
}

impl Default for Grid {
    fn default() -> Self {
        Grid {
            theta_h: 90,
            theta_d: 45,
            phi_d: 24,
        }
    }
}

/// The (theta_h, theta_d) plane after averaging over phi_d, which the DSBRDF cannot
/// represent: the average is weighted by the same cosines, which makes the fit's squared
/// error over the plane equal to that over the full grid up to a constant.
#[derive(Clone, Debug)]
pub struct Plane {
    /// x = cos theta_h per sample.
    pub x: Vec<f64>,
    /// ln x per sample.
    pub ln_x: Vec<f64>,
    /// The spline basis at the sample's theta_d.
    pub basis: Vec<[f64; N_CTRL_POINTS]>,
    /// The weighted mean over phi_d of the BRDF, per channel.
    pub target: Vec<[f64; 3]>,
    /// The sample's total weight.
    pub weight: Vec<f64>,
    /// The sample's theta_d cell (0 to [`Grid::theta_d`] - 1).
    pub row: Vec<usize>,
}

impl Plane {
    /// The same samples with each theta_d row's weights divided by the row's weighted
    /// energy sum w t^2 (t: the channels' mean), so that every row counts alike: an image
    /// under a small bright light sees one theta_d, and its PSNR is relative to that
    /// light's highlight, whatever the BRDF does at other theta_d (grazing rows, where
    /// many BRDFs are largest, would otherwise drown the rest).
    pub fn rows_alike(&self) -> Plane {
        let rows = self.row.iter().max().map_or(0, |r| r + 1);
        let mut energy = vec![0.0; rows];
        for ((w, t), &r) in self.weight.iter().zip(&self.target).zip(&self.row) {
            let grey = (t[0] + t[1] + t[2]) / 3.0;
            energy[r] += w * grey * grey;
        }
        let floor = energy.iter().fold(0.0f64, |m, &e| m.max(e)) * 1e-12 + 1e-300;
        let mut p = self.clone();
        for (w, &r) in p.weight.iter_mut().zip(&self.row) {
            *w /= energy[r].max(floor);
        }
        p
    }
}

/// The BRDF on the full grid, as flat per-sample records; `weight` 0 marks pairs that
/// are never seen or not known.
#[derive(Clone, Debug)]
pub struct Tabulated {
    grid: Grid,
    /// (theta_h, theta_d) per plane cell, phi_d innermost in `values`.
    angles: Vec<(f64, f64)>,
    values: Vec<[f64; 3]>,
    weights: Vec<f64>,
}

impl Tabulated {
    /// Evaluates `brdf` on `grid`.
    pub fn new(brdf: &dyn Isotropic, grid: Grid) -> Self {
        let mut angles = Vec::with_capacity(grid.theta_h * grid.theta_d);
        let mut values = Vec::with_capacity(grid.theta_h * grid.theta_d * grid.phi_d);
        let mut weights = Vec::with_capacity(values.capacity());
        let (nh, nd, np) = (grid.theta_h as f64, grid.theta_d as f64, grid.phi_d as f64);
        for ih in 0..grid.theta_h {
            let u = (ih as f64 + 0.5) / nh;
            let theta_h = u * u * FRAC_PI_2;
            let d_theta_h = 2.0 * u * FRAC_PI_2 / nh;
            for id in 0..grid.theta_d {
                let theta_d = (id as f64 + 0.5) / nd * FRAC_PI_2;
                let d_theta_d = FRAC_PI_2 / nd;
                let measure = 4.0
                    * theta_d.cos()
                    * theta_d.sin()
                    * theta_h.sin()
                    * d_theta_h
                    * d_theta_d
                    * (PI / np);
                angles.push((theta_h, theta_d));
                for ip in 0..grid.phi_d {
                    let phi_d = (ip as f64 + 0.5) / np * PI;
                    let (w_i, w_o) = from_rusinkiewicz(theta_h, theta_d, phi_d);
                    let seen = w_i[2] > 0.0 && w_o[2] > 0.0;
                    if seen && brdf.known(theta_h, theta_d, phi_d) {
                        values.push(brdf.eval(theta_h, theta_d, phi_d));
                        weights.push(w_i[2] * w_o[2] * measure);
                    } else {
                        values.push([0.0; 3]);
                        weights.push(0.0);
                    }
                }
            }
        }
        Tabulated {
            grid,
            angles,
            values,
            weights,
        }
    }

    /// The phi_d-averaged plane; cells that are never seen are left out.
    pub fn plane(&self) -> Plane {
        let np = self.grid.phi_d;
        let mut p = Plane {
            x: Vec::new(),
            ln_x: Vec::new(),
            basis: Vec::new(),
            target: Vec::new(),
            weight: Vec::new(),
            row: Vec::new(),
        };
        for (c, &(theta_h, theta_d)) in self.angles.iter().enumerate() {
            let w = &self.weights[c * np..(c + 1) * np];
            let v = &self.values[c * np..(c + 1) * np];
            let total: f64 = w.iter().sum();
            if total <= 0.0 {
                continue;
            }
            let mut t = [0.0; 3];
            for (wi, vi) in w.iter().zip(v) {
                for k in 0..3 {
                    t[k] += wi * vi[k];
                }
            }
            let x = theta_h.cos();
            p.x.push(x);
            p.ln_x.push(x.ln());
            p.basis.push(spline_basis(theta_d));
            p.target.push(t.map(|tk| tk / total));
            p.weight.push(total);
            p.row.push(c % self.grid.theta_d);
        }
        p
    }

    /// The smallest BRDF error any DSBRDF can reach: that of the phi_d-averaged BRDF
    /// itself, which is the best function of (theta_h, theta_d) alone in this weighting.
    /// What is left is the BRDF's dependence on phi_d.
    pub fn floor(&self) -> f64 {
        let np = self.grid.phi_d;
        let (mut num, mut den) = (0.0, 0.0);
        for c in 0..self.angles.len() {
            let w = &self.weights[c * np..(c + 1) * np];
            let v = &self.values[c * np..(c + 1) * np];
            let total: f64 = w.iter().sum();
            if total <= 0.0 {
                continue;
            }
            for k in 0..3 {
                let mean = w.iter().zip(v).map(|(w, v)| w * v[k]).sum::<f64>() / total;
                for (wi, vi) in w.iter().zip(v) {
                    num += wi * (vi[k] - mean) * (vi[k] - mean);
                    den += wi * vi[k] * vi[k];
                }
            }
        }
        if den > 0.0 { (num / den).sqrt() } else { 0.0 }
    }

    /// The relative RMSE of `model` against the tabulated BRDF over all seen samples and
    /// channels: sqrt(sum w (model - f)^2 / sum w f^2).
    pub fn error(&self, model: &dyn Isotropic) -> f64 {
        let np = self.grid.phi_d;
        let (mut num, mut den) = (0.0, 0.0);
        for (c, &(theta_h, theta_d)) in self.angles.iter().enumerate() {
            for ip in 0..np {
                let i = c * np + ip;
                let w = self.weights[i];
                if w <= 0.0 {
                    continue;
                }
                let phi_d = (ip as f64 + 0.5) / np as f64 * PI;
                let m = model.eval(theta_h, theta_d, phi_d);
                for k in 0..3 {
                    let f = self.values[i][k];
                    num += w * (m[k] - f) * (m[k] - f);
                    den += w * f * f;
                }
            }
        }
        if den > 0.0 { (num / den).sqrt() } else { 0.0 }
    }
}
