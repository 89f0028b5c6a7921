//! The fit's loss: the data term on the masked pixels, the light's priors, and the PSNR a
//! finished fit is judged by (see [`crate::edit`] for why each is what it is).

use super::inputs::Inputs;
use super::options::Options;
use crate::scene::Image;

/// PSNR of `render` against `target` over the mask, with the target's largest value there
/// as the peak: 10 log10(peak^2 / MSE), over the three channels.
pub fn psnr(render: &Image, target: &Image, mask: &[bool]) -> f64 {
    let (mut se, mut n, mut peak) = (0.0f64, 0usize, 0.0f64);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        for k in 0..3 {
            let (a, b) = (
                f64::from(render.pixels[i][k]),
                f64::from(target.pixels[i][k]),
            );
            se += (a - b) * (a - b);
            peak = peak.max(b);
            n += 1;
        }
    }
    10.0 * (peak * peak / (se / n.max(1) as f64).max(1e-300)).log10()
}

/// The data term's c ln(1 + x / c), extended linearly below 0, and its derivative.
fn compress(x: f64, c: f64) -> (f64, f64) {
    if x <= 0.0 {
        (x, 1.0)
    } else {
        (c * (x / c).ln_1p(), 1.0 / (1.0 + x / c))
    }
}

/// The map priors for log radiance `w` (height x width x 3): value and gradient (added to
/// `g`). Smoothness: mean squared difference of neighbours (columns wrap around); level:
/// the squared distance of each channel's mean log radiance from `level`.
pub(super) fn priors(
    w: &[f64],
    height: usize,
    width: usize,
    options: &Options,
    level: f64,
    g: &mut [f64],
) -> f64 {
    let mut pairs = Vec::with_capacity(2 * height * width);
    for r in 0..height {
        for c in 0..width {
            let i = r * width + c;
            pairs.push((i, r * width + (c + 1) % width));
            if r + 1 < height {
                pairs.push((i, i + width));
            }
        }
    }
    let n_pairs = (pairs.len() * 3) as f64;
    let mut value = 0.0;
    for &(a, b) in &pairs {
        for k in 0..3 {
            let d = w[3 * a + k] - w[3 * b + k];
            value += options.smoothness * d * d / n_pairs;
            let gd = 2.0 * options.smoothness * d / n_pairs;
            g[3 * a + k] += gd;
            g[3 * b + k] -= gd;
        }
    }
    // per channel: the light's mean colour is held neutral, so that colour goes to the
    // material (a grey light and a green material, not a magenta light and a greener one)
    let texels = (w.len() / 3) as f64;
    for k in 0..3 {
        let mean = w.iter().skip(k).step_by(3).sum::<f64>() / texels;
        let d = mean - level;
        value += options.level * d * d;
        for gi in g.iter_mut().skip(k).step_by(3) {
            *gi += 2.0 * options.level * d / texels;
        }
    }
    value
}

/// The data term and its dLoss/dImage.
pub(super) fn data_term(render: &Image, inputs: &Inputs, c: f64, n: f64) -> (f64, Image) {
    let mut up = Image::zeros(render.width, render.height);
    let mut loss = 0.0;
    for (i, _) in inputs.mask.iter().enumerate().filter(|(_, m)| **m) {
        for k in 0..3 {
            let (gi, di) = compress(f64::from(render.pixels[i][k]), c);
            let (gt, _) = compress(f64::from(inputs.target.pixels[i][k]), c);
            let r = (gi - gt) / c;
            loss += r * r / n;
            up.pixels[i][k] = (2.0 * r * di / (c * n)) as f32;
        }
    }
    (loss, up)
}

#[cfg(test)]
mod tests {
    use super::super::options::Light;
    use super::*;
    use crate::material::Material;

    #[test]
    fn priors_gradient_matches_differences() {
        let (h, w) = (3, 4);
        let opts = Options::new(
            Material::constant("m", [(0.5, 1.0), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
            Light::Fit {
                height: h,
                width: w,
            },
        );
        let x: Vec<f64> = (0..3 * h * w).map(|i| ((i * 7) % 5) as f64 * 0.3).collect();
        let mut g = vec![0.0; x.len()];
        let f0 = priors(&x, h, w, &opts, 0.2, &mut g);
        for i in [0, 5, 17, 35] {
            let mut xp = x.clone();
            xp[i] += 1e-6;
            let f1 = priors(&xp, h, w, &opts, 0.2, &mut vec![0.0; x.len()]);
            let fd = (f1 - f0) / 1e-6;
            assert!(
                (fd - g[i]).abs() < 1e-6 * (1.0 + g[i].abs()),
                "{i}: {fd} vs {}",
                g[i]
            );
        }
    }
}
