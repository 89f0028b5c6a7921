//! The guided filter (He, Sun and Tang, "Guided Image Filtering", PAMI 2013) in its fast
//! form (He and Sun, 2015): the local linear coefficients that map a guide's brightness to
//! a soft mask are fitted on a coarse grid, then brought to the fine grid bilinear and
//! applied to the fine guide, so that the mask's edges follow the photo's own.

use crate::raster::box_mean;

/// Per coarse pixel, `a` and `b` with q = a * guide + b fitted to `p` over each
/// (2r + 1)^2 window (least squares, `eps` the ridge that flattens low-contrast windows).
pub fn coefficients(
    guide: &[f32],
    p: &[f32],
    w: usize,
    h: usize,
    r: usize,
    eps: f32,
) -> (Vec<f32>, Vec<f32>) {
    let gp: Vec<f32> = guide.iter().zip(p).map(|(g, v)| g * v).collect();
    let gg: Vec<f32> = guide.iter().map(|g| g * g).collect();
    let mean_g = box_mean(guide, w, h, r);
    let mean_p = box_mean(p, w, h, r);
    let mean_gp = box_mean(&gp, w, h, r);
    let mean_gg = box_mean(&gg, w, h, r);
    let mut a = vec![0.0; w * h];
    let mut b = vec![0.0; w * h];
    for i in 0..w * h {
        let var = mean_gg[i] - mean_g[i] * mean_g[i];
        let cov = mean_gp[i] - mean_g[i] * mean_p[i];
        a[i] = cov / (var.max(0.0) + eps);
        b[i] = mean_p[i] - a[i] * mean_g[i];
    }
    (box_mean(&a, w, h, r), box_mean(&b, w, h, r))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_blurred_step_is_sharpened_to_the_guide() {
        // guide: a step at x = 10; mask: the same step smeared over 6 pixels
        let (w, h) = (20, 6);
        let guide: Vec<f32> = (0..w * h)
            .map(|i| if i % w < 10 { 0.2 } else { 0.8 })
            .collect();
        let p: Vec<f32> = (0..w * h)
            .map(|i| ((i % w) as f32 - 7.0).clamp(0.0, 6.0) / 6.0)
            .collect();
        let (a, b) = coefficients(&guide, &p, w, h, 3, 1e-3);
        let q: Vec<f32> = (0..w * h).map(|i| a[i] * guide[i] + b[i]).collect();
        for y in 0..h {
            assert!(
                q[y * w + 9] < 0.4 && q[y * w + 10] > 0.6,
                "{:?}",
                &q[y * w..y * w + w]
            );
        }
    }
}
