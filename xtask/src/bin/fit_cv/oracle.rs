//! The oracle of `fit_cv`: a fit moved by Adam through the layer towards the measured
//! images, to show how far the DSBRDF itself can go from the fit's start.

use matedit::{Device, EnvMap, Image, Material, NormalMap, Renderer};

use crate::under_maps;

/// Adam steps of the oracle (`--oracle-steps`).
pub const ORACLE_STEPS: usize = 150;

/// The oracle: `material` moved by Adam through the layer towards the measured images
/// `refs` under every map, the held-out one included, on the mean over the maps of MSE /
/// peak^2. No fitter may see those images: its PSNR bounds what the DSBRDF reaches here
/// from the fit's start, it is not a fit. Scales are free (sign included), exponents move
/// as logarithms (from at least 1e-3); the step decays from 0.01 (scales) and 0.03 (log
/// exponents) to a tenth; the best iterate is kept.
pub fn oracle(
    material: &Material,
    maps: &[(String, EnvMap)],
    normals: &NormalMap,
    mask: &[bool],
    refs: &[Image],
    steps: usize,
) -> Result<Material, String> {
    use matedit::material::{MAX_ABS_SCALE, MAX_EXPONENT, N_PARAMS, idx};
    let err = |e: matedit::Error| e.to_string();
    let renderer = Renderer::new(Device::Cpu).map_err(err)?;
    let mut exponent = [false; N_PARAMS];
    for k in 0..3 {
        for s in 0..3 {
            for j in 0..6 {
                exponent[idx(k, s, 1, j)] = true;
            }
        }
    }
    let mut x: Vec<f64> = (0..N_PARAMS)
        .map(|i| match exponent[i] {
            true => material.ctrl[i].max(1e-3).ln(),
            false => material.ctrl[i],
        })
        .collect();
    let of = |x: &[f64]| -> Result<Material, String> {
        let c: Vec<f64> = (0..N_PARAMS)
            .map(|i| match exponent[i] {
                true => x[i].exp().min(MAX_EXPONENT),
                false => x[i].clamp(-MAX_ABS_SCALE, MAX_ABS_SCALE),
            })
            .collect();
        let c: [f64; N_PARAMS] = c.try_into().expect("108 points");
        Material::new(material.name.clone(), &c).map_err(err)
    };
    let peaks: Vec<f64> = refs
        .iter()
        .map(|r| {
            r.pixels
                .iter()
                .zip(mask)
                .filter(|(_, m)| **m)
                .fold(0.0f64, |p, (v, _)| {
                    p.max(v.iter().fold(0.0f64, |a, &b| a.max(b.into())))
                })
        })
        .collect();
    let n = 3 * mask.iter().filter(|&&m| m).count();
    let wanted = matedit::Wanted {
        env: false,
        normals: false,
        ctrl: true,
    };
    let mut adam = matedit::edit::adam::Adam::new(N_PARAMS);
    let mut best = (material.clone(), f64::INFINITY);
    for step in 0..=steps {
        let m = of(&x)?;
        let batch = under_maps(&m, maps, normals)?;
        let images = renderer.render(&batch).map_err(err)?;
        let mut loss = 0.0;
        let mut ups = Vec::with_capacity(images.len());
        for ((img, r), &peak) in images.iter().zip(refs).zip(&peaks) {
            let scale = 1.0 / (n as f64 * peak * peak * maps.len() as f64);
            let mut pixels = vec![[0.0f32; 3]; img.pixels.len()];
            for (((a, b), &on), up) in img.pixels.iter().zip(&r.pixels).zip(mask).zip(&mut pixels) {
                if on {
                    for k in 0..3 {
                        let d = f64::from(a[k]) - f64::from(b[k]);
                        loss += d * d * scale;
                        up[k] = (2.0 * d * scale) as f32;
                    }
                }
            }
            ups.push(Image {
                width: img.width,
                height: img.height,
                pixels,
            });
        }
        if loss < best.1 {
            best = (m.clone(), loss);
        }
        if step == steps {
            break;
        }
        let (grads, _) = renderer
            .backward_with(&batch, &ups, &matedit::Accuracy::Exact, wanted)
            .map_err(err)?;
        let g: Vec<f64> = (0..N_PARAMS)
            .map(|i| {
                let d: f64 = grads.iter().map(|g| f64::from(g.d_ctrl[i])).sum();
                if exponent[i] { d * m.ctrl[i] } else { d }
            })
            .collect();
        let decay = 0.1f64.powf(step as f64 / steps as f64);
        let rates: Vec<f64> = (0..N_PARAMS)
            .map(|i| if exponent[i] { 0.03 } else { 0.01 } * decay)
            .collect();
        adam.step(&mut x, &g, &rates);
    }
    Ok(best.0)
}
