//! A method applied to a prepared scene: the reduced scenes a backend runs, and how their
//! results add up to the image and the gradients.

use crate::Backend;
use crate::envmap::EnvMap;
use crate::error::Result;
use crate::prepare::{PixelRec, Prepared};
use crate::scene::{Gradients, Image, Wanted};

use super::Method;
use super::cull::Groups;
use super::light::{Lights, lights};
use super::table::{Grid, Table};

/// The scenes of an approximation and what each is for.
struct Parts {
    lights: Lights,
    /// Every scene a pass runs; the fields below index into it.
    scenes: Vec<Prepared>,
    /// The block lights on the pixels evaluated one by one (all without a table): one
    /// scene, or one per group of normals when lights are culled.
    blocks: Vec<usize>,
    /// The kept texels on every pixel.
    kept: Option<usize>,
    /// The table and its nodes with the block lights (one scene, or one per group).
    table: Option<(Table, Vec<usize>)>,
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
        backend: &dyn Backend,
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
    ) -> Result<Self> {
        if method.is_exact() {
            return Ok(Plan { prep, parts: None });
        }
        let lights = lights(env, method.env_factor, method.keep);
        Plan::with_lights(backend, prep, env, method, grid_pixels, lights)
    }

    /// [`Plan::new`] for the texels in `mask` alone (one flag per texel of the map): only
    /// the blocks holding some of them, only the kept texels among them. dLoss/dL of those
    /// texels is as with every texel (the layer is linear in L); the rest is not.
    pub fn masked(
        backend: &dyn Backend,
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
        mask: &[bool],
    ) -> Result<Self> {
        let mut l = lights(env, method.env_factor, method.keep);
        let mut used = vec![false; l.blocks.len()];
        for (&(b, _), _) in l.share.iter().zip(mask).filter(|(_, m)| **m) {
            used[b as usize] = true;
        }
        l.blocks.retain(|b| used[b.index]);
        l.kept.retain(|k| mask[k.index]);
        Plan::with_lights(backend, prep, env, method, grid_pixels, l)
    }

    fn with_lights(
        backend: &dyn Backend,
        prep: &'a Prepared,
        env: &EnvMap,
        method: &Method,
        grid_pixels: &[PixelRec],
        lights: Lights,
    ) -> Result<Self> {
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
        let block_scene = block_scene(per_pixel);
        let nodes = table.as_ref().map(|t| t.nodes_scene(&block_scene));
        let kept_scene = (!lights.kept.is_empty()).then(|| {
            Prepared::from_lights(
                w,
                h,
                prep.pixels.clone(),
                env.height,
                env.width,
                &lights.kept,
                &prep.ctrl,
                prep.camera,
            )
        });
        // culling: each scene of block lights as groups of normals, each with its lights
        let (block_scenes, node_scenes) = match method.cull {
            None => (vec![block_scene], nodes.map(|n| vec![n])),
            Some(_) => {
                let full = prep.with_pixels(w, h, grid_pixels.to_vec());
                let groups = Groups::new();
                let largest =
                    groups.largest_value(backend, &full, &block_scene, kept_scene.as_ref())?;
                let budget = method.cull_budget() * largest;
                let block_groups = groups.cull(&block_scene, budget);
                let node_groups = nodes.as_ref().map(|n| groups.cull(n, budget));
                (block_groups, node_groups)
            }
        };
        let mut blocks = Vec::new();
        for s in block_scenes {
            scenes.push(s);
            blocks.push(scenes.len() - 1);
        }
        let table = table.map(|t| {
            let mut at = Vec::new();
            for s in node_scenes.unwrap_or_default() {
                scenes.push(s);
                at.push(scenes.len() - 1);
            }
            (t, at)
        });
        let kept = kept_scene.map(|s| {
            scenes.push(s);
            scenes.len() - 1
        });
        Ok(Plan {
            prep,
            parts: Some(Parts {
                lights,
                scenes,
                blocks,
                kept,
                table,
            }),
        })
    }

    /// The image.
    pub fn forward(&self, backend: &dyn Backend) -> Result<Image> {
        let Some(p) = &self.parts else {
            return Ok(backend.render(self.prep.into())?.remove(0));
        };
        let images = backend.render((&p.scenes).into())?;
        let mut image = Image::zeros(self.prep.width, self.prep.height);
        for &b in &p.blocks {
            add(&mut image.pixels, &images[b].pixels);
        }
        if let Some((t, nodes)) = &p.table {
            let mut values = vec![[0.0f32; 3]; t.normals.len()];
            for &n in nodes {
                add(&mut values, &images[n].pixels);
            }
            t.interpolate(&values, &mut image.pixels);
        }
        if let Some(k) = p.kept {
            add(&mut image.pixels, &images[k].pixels);
        }
        Ok(image)
    }

    /// The gradients for upstream dLoss/dImage `upstream`: the exact vector-Jacobian
    /// product of the approximation, for the gradients `wanted` asks for; the others are
    /// zero (or partial: they are for the caller to ignore).
    pub fn backward(
        &self,
        backend: &dyn Backend,
        upstream: &Image,
        wanted: Wanted,
    ) -> Result<Gradients> {
        let Some(p) = &self.parts else {
            return Ok(backend
                .backward(self.prep.into(), std::slice::from_ref(upstream), wanted)?
                .remove(0));
        };
        let node_up = p.table.as_ref().map(|(t, _)| Image {
            width: t.normals.len(),
            height: 1,
            pixels: t.scatter(&upstream.pixels),
        });
        let ups: Vec<Image> = (0..p.scenes.len())
            .map(|i| match &p.table {
                Some((_, nodes)) if nodes.contains(&i) => node_up.clone().expect("a table"),
                _ => upstream.clone(),
            })
            .collect();
        // a table's dLoss/dn comes from the nodes' Jacobians, not from their backward pass;
        // with dLoss/dn wanted, the nodes' backward pass and Jacobians are one call below
        let node_wants = Wanted {
            normals: false,
            ..wanted
        };
        let nodes: &[usize] = p.table.as_ref().map_or(&[], |(_, n)| n);
        let wants: Vec<Wanted> = (0..p.scenes.len())
            .map(|i| match nodes.contains(&i) {
                true if wanted.normals => Wanted::NONE,
                true => node_wants,
                false => wanted,
            })
            .collect();
        let mut grads = backward_each(backend, &p.scenes, &ups, &wants)?;
        let mut jacs = Vec::new();
        if wanted.normals {
            for &n in nodes {
                let scene = std::slice::from_ref(&p.scenes[n]);
                let with = node_wants
                    .any()
                    .then(|| (std::slice::from_ref(&ups[n]), node_wants));
                let (j, g) = backend.normal_jacobians(scene, with)?.remove(0);
                if let Some(g) = g {
                    grads[n] = g;
                }
                jacs.push(j);
            }
        }
        let mut d_blocks = vec![[0.0f32; 3]; p.lights.rows * p.lights.cols];
        let mut d_normals = vec![[0.0f32; 3]; self.prep.width * self.prep.height];
        let mut d_ctrl = [0.0f32; crate::N_PARAMS];
        for &b in &p.blocks {
            let g = &grads[b];
            add(&mut d_blocks, &g.d_env);
            add(&mut d_normals, &g.d_normals);
            add_ctrl(&mut d_ctrl, &g.d_ctrl);
        }
        if let Some((t, nodes)) = &p.table {
            let mut jac = vec![[[0.0f32; 3]; 3]; t.normals.len()];
            for (&n, js) in nodes
                .iter()
                .zip(jacs.iter().map(Some).chain(std::iter::repeat(None)))
            {
                let g = &grads[n];
                add(&mut d_blocks, &g.d_env);
                add_ctrl(&mut d_ctrl, &g.d_ctrl);
                for (px, j) in p.scenes[n].pixels.iter().zip(js.into_iter().flatten()) {
                    jac[px.index] = *j;
                }
            }
            if wanted.normals {
                t.normal_gradients(&upstream.pixels, &jac, &mut d_normals);
            }
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

/// Each scene's backward pass for its own `wants`: one batch when they all want the same,
/// else scene by scene (zeros for a scene that wants nothing).
fn backward_each(
    backend: &dyn Backend,
    scenes: &[Prepared],
    ups: &[Image],
    wants: &[Wanted],
) -> Result<Vec<Gradients>> {
    match wants.first() {
        Some(&w) if w.any() && wants.iter().all(|&x| x == w) => {
            backend.backward(scenes.into(), ups, w)
        }
        _ => scenes
            .iter()
            .zip(ups)
            .zip(wants)
            .map(|((s, u), &w)| {
                if w.any() {
                    Ok(backend
                        .backward(s.into(), std::slice::from_ref(u), w)?
                        .remove(0))
                } else {
                    Ok(Gradients::zeros(
                        s.env_height * s.env_width,
                        s.width * s.height,
                    ))
                }
            })
            .collect(),
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
