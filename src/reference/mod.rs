//! The f64 CPU reference: one function per shader, same loop order and helper names, so
//! that it can be read line by line against shaders/*.wgsl and serve as ground truth for
//! the f32 GPU path. Pixels (forward, dn) and texels (dL, dctrl shares) run in parallel;
//! every output element has one writer, so results do not depend on the thread count.

mod backward_normal;
mod backward_texel;
pub mod common;
mod forward;
mod reduce_ctrl;

pub use backward_normal::backward_normal;
pub use backward_texel::backward_texel;
pub use forward::forward;
pub use reduce_ctrl::reduce_ctrl;

use crate::backend::Scenes;
use crate::material::N_PARAMS;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Wanted};
use crate::{Backend, Result};

/// The backward pass in f64.
#[derive(Clone, Debug, PartialEq)]
pub struct GradientsF64 {
    /// dLoss/dL per texel of the map (0 where d_omega = 0).
    pub d_env: Vec<[f64; 3]>,
    /// dLoss/dn per pixel (0 on background).
    pub d_normals: Vec<[f64; 3]>,
    /// dLoss/dctrl.
    pub d_ctrl: [f64; N_PARAMS],
}

/// The whole backward pass of a prepared scene for upstream `g` (row-major, one RGB per pixel).
pub fn backward(prep: &Prepared, g: &[[f64; 3]]) -> GradientsF64 {
    let per_texel = backward_texel(prep, g);
    let mut d_env = vec![[0.0; 3]; prep.env_height * prep.env_width];
    for (t, (dl, _)) in prep.texels.iter().zip(&per_texel) {
        d_env[t.index] = *dl;
    }
    let shares: Vec<[f64; N_PARAMS]> = per_texel.iter().map(|(_, s)| *s).collect();
    GradientsF64 {
        d_env,
        d_normals: backward_normal(prep, g),
        d_ctrl: reduce_ctrl(&shares),
    }
}

/// The CPU reference as a [`Backend`].
#[derive(Clone, Copy, Debug, Default)]
pub struct Reference;

fn to_f32(v: &[[f64; 3]]) -> Vec<[f32; 3]> {
    v.iter().map(|p| p.map(|x| x as f32)).collect()
}

impl Backend for Reference {
    fn describe(&self) -> String {
        format!(
            "cpu: f64 reference on {} threads",
            rayon::current_num_threads()
        )
    }

    // a batch scene by scene, so that one scene's preparation is in memory at a time;
    // every gradient, whichever are wanted
    fn render(&self, scenes: Scenes<'_>) -> Result<Vec<Image>> {
        match scenes {
            Scenes::Batch(batch) => batch
                .scenes()
                .iter()
                .map(|s| Ok(render_one(&Prepared::new(s))))
                .collect(),
            Scenes::Prepared(preps) => Ok(preps.iter().map(render_one).collect()),
        }
    }

    fn backward(
        &self,
        scenes: Scenes<'_>,
        upstream: &[Image],
        _wanted: Wanted,
    ) -> Result<Vec<Gradients>> {
        match scenes {
            Scenes::Batch(batch) => {
                batch.check_upstream(upstream)?;
                Ok(batch
                    .scenes()
                    .iter()
                    .zip(upstream)
                    .map(|(s, u)| backward_one(&Prepared::new(s), u))
                    .collect())
            }
            Scenes::Prepared(preps) => Ok(preps
                .iter()
                .zip(upstream)
                .map(|(p, u)| backward_one(p, u))
                .collect()),
        }
    }
}

/// The image of one prepared scene, in f32.
fn render_one(prep: &Prepared) -> Image {
    prep.image(to_f32(&forward(prep)))
}

/// The gradients of one prepared scene for upstream `up`, in f32.
fn backward_one(prep: &Prepared, up: &Image) -> Gradients {
    let g: Vec<[f64; 3]> = up.pixels.iter().map(|v| v.map(f64::from)).collect();
    let r = backward(prep, &g);
    Gradients {
        d_env: to_f32(&r.d_env),
        d_normals: to_f32(&r.d_normals),
        d_ctrl: r.d_ctrl.map(|x| x as f32),
    }
}
