//! A method applied to a prepared scene: the reduced scenes a backend runs, and how their
//! results add up to the image and the gradients.

use crate::Backend;
use crate::envmap::EnvMap;
use crate::error::Result;
use crate::prepare::{PixelRec, Prepared};
use crate::scene::{Gradients, Image};

use super::Method;
use super::light::{Lights, lights};
use super::table::{Grid, Table};

/// The scenes of an approximation and what each is for.
struct Parts {
    lights: Lights,
    /// Every scene a pass runs; the fields below index into it.
    scenes: Vec<Prepared>,
    /// The block lights on the pixels evaluated one by one (all without a table).
    blocks: usize,
    /// The kept texels on every pixel.
    kept: Option<usize>,
    /// The table and its nodes (with the block lights).
    table: Option<(Table, usize)>,
}

/// What a method makes of one prepared scene.
pub(crate) struct Plan<'a> {
    prep: &'a Prepared,
    parts: Option<Parts>,
}

impl<'a> Plan<'a> {
    /// `method` on `prep` (whose map is `env`). A table's grid spans `grid_pixels` (the
    /// scene's pixels, of which `prep`'s may be a sample, so that a sample sees the grid
    /// the whole image would).
    pub fn new(
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
    ) -> Self {
        if method.is_exact() {
            return Plan { prep, parts: None };
        }
        Plan::with_lights(
            prep,
            env,
            method,
            grid_pixels,
            lights(env, method.env_factor, method.keep),
        )
    }

    /// [`Plan::new`] for the texels in `mask` alone (one flag per texel of the map): only
    /// the blocks holding some of them, only the kept texels among them. dLoss/dL of those
    /// texels is as with every texel (the layer is linear in L); the rest is not.
    pub fn masked(
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
        mask: &[bool],
    ) -> Self {
        let mut l = lights(env, method.env_factor, method.keep);
        let mut used = vec![false; l.blocks.len()];
        for (&(b, _), _) in l.share.iter().zip(mask).filter(|(_, m)| **m) {
            used[b as usize] = true;
        }
        l.blocks.retain(|b| used[b.index]);
        l.kept.retain(|k| mask[k.index]);
        Plan::with_lights(prep, env, method, grid_pixels, l)
    }

    fn with_lights(
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
        lights: Lights,
    ) -> Self {
        let (w, h) = (prep.width, prep.height);
        let block_scene = |pixels: Vec<PixelRec>| {
            Prepared::from_lights(
                w,
                h,
                pixels,
                lights.rows,
                lights.cols,
                &lights.blocks,
                &prep.ctrl,
                prep.camera,
            )
        };
        let mut scenes = Vec::new();
        let table = method.table.map(|r| {
            let grid = Grid::new(r, grid_pixels);
            Table::new(&grid, &prep.pixels)
        });
        let per_pixel: Vec<PixelRec> = match &table {
            Some(t) => t.left.iter().map(|&k| prep.pixels[k]).collect(),
            None => prep.pixels.clone(),
        };
        scenes.push(block_scene(per_pixel));
        let blocks = 0;
        let table = table.map(|t| {
            scenes.push(t.nodes_scene(&scenes[blocks]));
            (t, scenes.len() - 1)
        });
        let kept = (!lights.kept.is_empty()).then(|| {
            scenes.push(Prepared::from_lights(
                w,
                h,
                prep.pixels.clone(),
                env.height,
                env.width,
                &lights.kept,
                &prep.ctrl,
                prep.camera,
            ));
            scenes.len() - 1
        });
        Plan {
            prep,
            parts: Some(Parts {
                lights,
                scenes,
                blocks,
                kept,
                table,
            }),
        }
    }

    /// The image.
    pub fn forward(&self, backend: &dyn Backend) -> Result<Image> {
        let Some(p) = &self.parts else {
            return Ok(backend
                .render_prepared(std::slice::from_ref(self.prep))?
                .remove(0));
        };
        let images = backend.render_prepared(&p.scenes)?;
        let mut image = images[p.blocks].clone();
        if let Some((t, nodes)) = &p.table {
            t.interpolate(&images[*nodes].pixels, &mut image.pixels);
        }
        if let Some(k) = p.kept {
            add(&mut image.pixels, &images[k].pixels);
        }
        Ok(image)
    }

    /// The gradients for upstream dLoss/dImage `upstream`: the exact vector-Jacobian
    /// product of the approximation.
    pub fn backward(&self, backend: &dyn Backend, upstream: &Image) -> Result<Gradients> {
        let Some(p) = &self.parts else {
            return Ok(backend
                .backward_prepared(
                    std::slice::from_ref(self.prep),
                    std::slice::from_ref(upstream),
                )?
                .remove(0));
        };
        let ups: Vec<Image> = (0..p.scenes.len())
            .map(|i| match &p.table {
                Some((t, nodes)) if i == *nodes => Image {
                    width: t.normals.len(),
                    height: 1,
                    pixels: t.scatter(&upstream.pixels),
                },
                _ => upstream.clone(),
            })
            .collect();
        let grads = backend.backward_prepared(&p.scenes, &ups)?;
        let a = &grads[p.blocks];
        let mut d_blocks = a.d_env.clone();
        let mut d_normals = a.d_normals.clone();
        let mut d_ctrl = a.d_ctrl;
        if let Some((t, nodes)) = &p.table {
            let g = &grads[*nodes];
            add(&mut d_blocks, &g.d_env);
            add_ctrl(&mut d_ctrl, &g.d_ctrl);
            let jac = backend
                .normal_jacobians(std::slice::from_ref(&p.scenes[*nodes]))?
                .remove(0);
            t.normal_gradients(&upstream.pixels, &jac, &mut d_normals);
        }
        let d_kept = p.kept.map(|k| {
            let g = &grads[k];
            add(&mut d_normals, &g.d_normals);
            add_ctrl(&mut d_ctrl, &g.d_ctrl);
            g.d_env.as_slice()
        });
        Ok(Gradients {
            d_env: p.lights.adjoint(&d_blocks, d_kept),
            d_normals,
            d_ctrl,
        })
    }
}

fn add(a: &mut [[f32; 3]], b: &[[f32; 3]]) {
    for (x, y) in a.iter_mut().zip(b) {
        for k in 0..3 {
            x[k] += y[k];
        }
    }
}

fn add_ctrl(a: &mut [f32], b: &[f32]) {
    for (x, y) in a.iter_mut().zip(b) {
        *x += y;
    }
}

/// `prep` restricted to the pixels at positions `sample`.
pub(crate) fn sampled(prep: &Prepared, sample: &[usize]) -> Prepared {
    let pixels = sample.iter().map(|&k| prep.pixels[k]).collect();
    prep.with_pixels(prep.width, prep.height, pixels)
}
