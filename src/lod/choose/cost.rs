//! The cost model: a method's predicted work and a trial's, counted in forward pair
//! evaluations (a pixel against a lit light), from the scene alone.

use std::collections::HashMap;

use crate::envmap::EnvMap;
use crate::prepare::Prepared;

use super::super::Method;
use super::super::table::{Footprint, STENCIL};

/// Block sides tried, coarsest first.
const ENV_FACTORS: [usize; 4] = [8, 4, 2, 1];
/// Kept texels tried.
const KEEPS: [usize; 4] = [0, 16, 64, 256];
/// The cost of interpolating one pixel from a table (its stencil's nodes), in pair
/// evaluations: four nodes to a pair.
const INTERP_PAIRS: f64 = STENCIL as f64 / 4.0;
/// The cost of a pair in the normals' Jacobian (a table's dLoss/dn) on its own (the
/// trials' pass), in forward pair evaluations.
const JACOBIAN_PAIR: f64 = 2.0;
/// The same in the nodes' backward pass, which sums the Jacobian from its own lobe terms:
/// measured, the upper end of the presets' range (docs/lod.md, "Tuned constants").
const FUSED_JACOBIAN_PAIR: f64 = 1.3;
/// The cost of a pair in the backward pass, in forward pair evaluations.
const BACKWARD_PAIR: f64 = 3.0;

/// A candidate light: the map in blocks of `env_factor` texels a side, `keep` texels kept
/// at full resolution, and how many of each are lit (blocks whose lit texels are all kept
/// count as lit: a cost model).
#[derive(Clone, Copy, Debug)]
pub(super) struct Light {
    pub env_factor: usize,
    pub keep: usize,
    /// Lit blocks (at full resolution: lit texels not kept).
    pub blocks: f64,
    /// Lit texels kept.
    pub kept: f64,
}

impl Light {
    /// The key of the light's own error.
    pub fn key(&self) -> (usize, usize) {
        (self.env_factor, self.keep)
    }

    /// The method over this light, with a table of resolution `table` or per pixel.
    pub fn method(&self, table: Option<usize>) -> Method {
        Method {
            env_factor: self.env_factor,
            keep: self.keep,
            table,
            cull: None,
        }
    }
}

/// Every candidate light of `env` (per block side in [`ENV_FACTORS`], per kept texels in
/// [`KEEPS`]), and how many texels are lit.
pub(super) fn lights(env: &EnvMap) -> (Vec<Light>, usize) {
    let lit_texels: Vec<bool> = env
        .texels
        .iter()
        .map(|l| l.iter().any(|&v| v != 0.0))
        .collect();
    let n_lit = lit_texels.iter().filter(|&&l| l).count();
    let mut lights = Vec::new();
    for f in ENV_FACTORS {
        if f > 1 && f >= env.height.max(env.width) {
            continue;
        }
        let cols = env.width.div_ceil(f);
        let mut lit_block = vec![false; env.height.div_ceil(f) * cols];
        for (i, _) in lit_texels.iter().enumerate().filter(|(_, l)| **l) {
            lit_block[(i / env.width / f) * cols + (i % env.width) / f] = true;
        }
        let blocks = lit_block.iter().filter(|&&l| l).count();
        for k in KEEPS {
            let kept = k.min(n_lit);
            let blocks = if f == 1 { n_lit - kept } else { blocks };
            lights.push(Light {
                env_factor: f,
                keep: k,
                blocks: blocks as f64,
                kept: kept as f64,
            });
        }
    }
    (lights, n_lit)
}

/// The work of the scene's layer and of what approximates it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Costs {
    /// With an upstream gradient (the backward pass's work counted too).
    pub backward: bool,
    /// Pixels.
    pub n: f64,
    /// Lit lights of the exact layer.
    pub lit_total: f64,
    /// A pair's cost in forward pair evaluations.
    pair: f64,
    /// The exact layer's work.
    pub exact: f64,
}

impl Costs {
    /// The costs of `prep`'s layer (with `backward`, forward and backward).
    pub fn new(prep: &Prepared, backward: bool) -> Self {
        let n = prep.pixels.len() as f64;
        let lit_total = prep.lit.len() as f64;
        let pair = if backward { BACKWARD_PAIR } else { 1.0 };
        Costs {
            backward,
            n,
            lit_total,
            pair,
            exact: n * lit_total * pair,
        }
    }

    /// The exact layer on the samples (of `s_pixels` and `s_tables` pixels; with an upstream
    /// gradient, the tables' sample's Jacobians too).
    pub fn samples_exact(&self, s_pixels: f64, s_tables: f64) -> f64 {
        (s_pixels + s_tables * (1.0 + if self.backward { BACKWARD_PAIR } else { 0.0 }))
            * self.lit_total
    }

    /// `light` evaluated per pixel.
    pub fn per_pixel(&self, light: &Light) -> f64 {
        self.n * (light.blocks + light.kept) * self.pair
    }

    /// The trial on `s_pixels` sampled pixels of a per-pixel method that costs `cost`.
    pub fn per_pixel_trial(&self, cost: f64, s_pixels: f64) -> f64 {
        s_pixels * cost / (self.n * self.pair)
    }
}

/// What a table's trial costs, by part.
#[derive(Clone, Copy, Debug)]
pub(super) struct TableTrial {
    /// The image's: the nodes the sample's stencils need and the kept texels per sampled pixel.
    pub image: f64,
    /// dLoss/dn's (once the image passes).
    pub d_normals: f64,
    /// dLoss/dL's and dLoss/dctrl's: every pixel for the sampled texels (the exact side
    /// charged apart, once).
    pub sums: f64,
}

impl TableTrial {
    /// The whole trial, if the image passes (with `backward`, the gradients' too).
    pub fn total(&self, backward: bool) -> f64 {
        self.image
            + if backward {
                self.d_normals + self.sums
            } else {
                0.0
            }
    }
}

/// The tables' work and their trials': per resolution, the nodes the pixels' stencils need,
/// counted once.
pub(super) struct TableCosts {
    costs: Costs,
    /// Pixels in the tables' sample.
    s_tables: f64,
    /// Texels in the sums' trials.
    texels: f64,
    footprint: Footprint,
    /// A node's pair, in forward pair evaluations (with gradients, the nodes' backward pass
    /// and their Jacobians).
    node_pair: f64,
    /// Per resolution: nodes, and pixels left to per-pixel evaluation.
    counts: HashMap<usize, (usize, usize)>,
}

impl TableCosts {
    /// The tables of `prep`'s pixels, their trials on `s_tables` sampled pixels and
    /// `texels` sampled texels.
    pub fn new(costs: Costs, prep: &Prepared, s_tables: f64, texels: f64) -> Self {
        let node_pair = if costs.backward {
            BACKWARD_PAIR + FUSED_JACOBIAN_PAIR
        } else {
            1.0
        };
        TableCosts {
            costs,
            s_tables,
            texels,
            footprint: Footprint::new(&prep.pixels),
            node_pair,
            counts: HashMap::new(),
        }
    }

    /// A table of resolution `r` over a light of `blocks` blocks and `kept` texels: its
    /// predicted work, and its nodes.
    pub fn table(&mut self, r: usize, blocks: f64, kept: f64) -> (f64, usize) {
        let footprint = &self.footprint;
        let (nodes, left) = *self.counts.entry(r).or_insert_with(|| footprint.count(r));
        let Costs { n, pair, .. } = self.costs;
        let cost = nodes as f64 * blocks * self.node_pair
            + (left as f64 * blocks + n * kept) * pair
            + n * INTERP_PAIRS;
        (cost, nodes)
    }

    /// The trial of a table of resolution `r` over the full-resolution map (`n_lit` texels
    /// lit), no texel kept, on dLoss/dL alone: the table's nodes and every pixel, for the
    /// sampled texels.
    pub fn env_trial(&mut self, r: usize, n_lit: usize) -> f64 {
        let (_, nodes) = self.table(r, n_lit as f64, 0.0);
        let (n, texels) = (self.costs.n, self.texels);
        (nodes as f64 + n) * texels * BACKWARD_PAIR + n * INTERP_PAIRS
    }

    /// The trial of a table of `nodes` nodes over `light`.
    pub fn trial(&self, nodes: usize, light: &Light) -> TableTrial {
        let (n, s_tables, texels) = (self.costs.n, self.s_tables, self.texels);
        let (blocks, kept) = (light.blocks, light.kept);
        let node_work = nodes.min(STENCIL * s_tables as usize) as f64 * blocks;
        TableTrial {
            image: node_work + s_tables * kept,
            d_normals: node_work * JACOBIAN_PAIR + s_tables * kept * BACKWARD_PAIR,
            sums: nodes as f64 * texels * BACKWARD_PAIR + n * INTERP_PAIRS,
        }
    }

    /// The exact side of the sums' trials: every pixel, for the sampled texels.
    pub fn texels_exact(&self) -> f64 {
        self.costs.n * self.texels * BACKWARD_PAIR
    }
}
