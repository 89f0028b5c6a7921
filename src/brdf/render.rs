//! Brute-force f64 rendering with any isotropic BRDF: the image of a normal map lit by an
//! environment map, summed over every texel, with the BRDF evaluated in Rusinkiewicz
//! coordinates about each pixel's normal. It shares nothing with the DSBRDF layer's
//! renderers, so it is the independent check of a fitted material against the measured
//! BRDF it was fitted to (`xtask/src/bin/merl_report.rs`).

use rayon::prelude::*;

use super::{Isotropic, to_rusinkiewicz};
use crate::camera::Camera;
use crate::envmap::EnvMap;
use crate::error::Result;
use crate::scene::{Image, NormalMap};

/// I_p^k = sum_i f^k(w_i, w_p) L^k(i) max(0, n.w_i) d_omega_i, summed in f64 in texel
/// order (deterministic). Background pixels (|n| < 1e-6) and pixels that face away from
/// the viewer (n.w_p <= 0, where a measured BRDF has no value) are 0. Normals are
/// normalised first.
pub fn render_measured(
    brdf: &dyn Isotropic,
    normals: &NormalMap,
    env: &EnvMap,
    camera: Camera,
) -> Result<Image> {
    normals.validate()?;
    env.validate()?;
    camera.validate()?;
    // Texels that carry light, with their direction and L d_omega.
    let mut lights: Vec<([f64; 3], [f64; 3])> = Vec::with_capacity(env.texels.len());
    for r in 0..env.height {
        for c in 0..env.width {
            let l = env.texels[r * env.width + c];
            if l.iter().all(|&v| v == 0.0) {
                continue;
            }
            let (dir, d_omega) = env.convention.texel(r, c, env.height, env.width);
            lights.push((dir, l.map(|v| f64::from(v) * d_omega)));
        }
    }
    let (w, h) = (normals.width, normals.height);
    let pixels = normals
        .normals
        .par_iter()
        .enumerate()
        .map(|(p, n)| {
            let n = n.map(f64::from);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if len < 1e-6 {
                return [0.0f32; 3];
            }
            let n = n.map(|v| v / len);
            let w_o = camera.view_dir(p % w, p / w, w, h);
            if n[0] * w_o[0] + n[1] * w_o[1] + n[2] * w_o[2] <= 0.0 {
                return [0.0; 3];
            }
            let mut sum = [0.0f64; 3];
            for (w_i, l) in &lights {
                let cos_i = n[0] * w_i[0] + n[1] * w_i[1] + n[2] * w_i[2];
                if cos_i <= 0.0 {
                    continue;
                }
                let Some([th, td, pd]) = to_rusinkiewicz(n, *w_i, w_o) else {
                    continue;
                };
                let f = brdf.eval(th, td, pd);
                for k in 0..3 {
                    sum[k] += f[k] * l[k] * cos_i;
                }
            }
            sum.map(|v| v as f32)
        })
        .collect();
    Ok(Image {
        width: w,
        height: h,
        pixels,
    })
}
