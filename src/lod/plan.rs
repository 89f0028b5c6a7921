//! A method applied to a prepared scene: the reduced scenes a backend runs, and how their
//! results add up to the image and the gradients.

use crate::Backend;
use crate::envmap::EnvMap;
use crate::error::Result;
use crate::prepare::{PixelRec, Prepared};
use crate::scene::{Gradients, Image};

use super::Method;
use super::light::{Lights, lights};
use super::table::{Grid, Table, with_pixels};

/// The scenes of an approximation and what each is for.
struct Parts {
    lights: Lights,
    /// Every scene a pass runs; the fields below index into it.
    scenes: Vec<Prepared>,
    /// The block lights on the pixels evaluated one by one (all without a table).
    blocks: usize,
    /// The kept texels on every pixel.
    kept: Option<usize>,
    /// The block lights on the table's nodes, and on three copies of them (for dI/dn per
    /// channel) when a backward pass is planned.
    table: Option<(Table, usize, Option<usize>)>,
}

/// What a method makes of one prepared scene.
pub(crate) struct Plan<'a> {
    prep: &'a Prepared,
    parts: Option<Parts>,
}

impl<'a> Plan<'a> {
    /// `method` on `prep` (whose map is `env`). A table's grid spans `grid_pixels` (the
    /// scene's pixels, of which `prep`'s may be a sample, so that a sample sees the grid
    /// the whole image would). `backward`: whether [`Plan::backward`] will be called.
    pub fn new(
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
        backward: bool,
    ) -> Self {
        if method.is_exact() {
            return Plan { prep, parts: None };
        }
        let lights = lights(env, method.env_factor, method.keep);
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
            scenes.push(t.nodes_scene(&scenes[blocks], 1));
            let nodes = scenes.len() - 1;
            let jac = backward.then(|| {
                scenes.push(t.nodes_scene(&scenes[blocks], 3));
                scenes.len() - 1
            });
            (t, nodes, jac)
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
        // the Jacobian copies are for the backward pass
        let run: Vec<usize> = (0..p.scenes.len())
            .filter(|&i| !matches!(p.table, Some((_, _, Some(j))) if j == i))
            .collect();
        let images = if run.len() == p.scenes.len() {
            backend.render_prepared(&p.scenes)?
        } else {
            let scenes: Vec<Prepared> = run.iter().map(|&i| p.scenes[i].clone()).collect();
            backend.render_prepared(&scenes)?
        };
        let at = |i: usize| &images[run.iter().position(|&r| r == i).unwrap_or(0)];
        let mut image = at(p.blocks).clone();
        if let Some((t, nodes, _)) = &p.table {
            t.interpolate(&at(*nodes).pixels, &mut image.pixels);
        }
        if let Some(k) = p.kept {
            add(&mut image.pixels, &at(k).pixels);
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
                Some((t, nodes, _)) if i == *nodes => Image {
                    width: t.normals.len(),
                    height: 1,
                    pixels: t.scatter(&upstream.pixels),
                },
                Some((t, _, Some(jac))) if i == *jac => {
                    let n = t.normals.len();
                    let mut pixels = vec![[0.0f32; 3]; 3 * n];
                    for (j, px) in pixels.iter_mut().enumerate() {
                        px[j / n] = 1.0;
                    }
                    Image {
                        width: 3 * n,
                        height: 1,
                        pixels,
                    }
                }
                _ => upstream.clone(),
            })
            .collect();
        let grads = backend.backward_prepared(&p.scenes, &ups)?;
        let a = &grads[p.blocks];
        let mut d_blocks = a.d_env.clone();
        let mut d_normals = a.d_normals.clone();
        let mut d_ctrl = a.d_ctrl;
        if let Some((t, nodes, jac)) = &p.table {
            let g = &grads[*nodes];
            add(&mut d_blocks, &g.d_env);
            add_ctrl(&mut d_ctrl, &g.d_ctrl);
            let jac = jac.expect("a plan for the backward pass has the Jacobian scene");
            t.normal_gradients(&upstream.pixels, &grads[jac].d_normals, &mut d_normals);
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
    with_pixels(prep, prep.width, prep.height, pixels)
}
