//! Environment levels and kept texels: the map's texels regrouped into block lights and
//! a few full-resolution ones, and the adjoint that takes the blocks' dLoss/dL back to
//! the map's texels.

use crate::envmap::EnvMap;
use crate::prepare::{PointLight, dot};

/// The lights of a map under a block side and a number of kept texels.
pub(crate) struct Lights {
    /// Block rows.
    pub rows: usize,
    /// Block columns.
    pub cols: usize,
    /// One light per block, `index` = block row x `cols` + block column; kept texels are
    /// left out of their block's radiance but not of its solid angle.
    pub blocks: Vec<PointLight>,
    /// The kept texels, `index` = their index in the map.
    pub kept: Vec<PointLight>,
    /// Per texel of the map: its block and d_omega(texel) / d_omega(block), the block
    /// radiance's derivative by the texel's (0 for kept texels).
    pub share: Vec<(u32, f64)>,
}

/// Sum over channels of |L| d_omega: how much a texel can light.
fn energy(l: [f32; 3], d_omega: f64) -> f64 {
    l.iter().map(|v| f64::from(v.abs())).sum::<f64>() * d_omega
}

/// The `keep` texels of `env` (solid angles `d_omega`) with the most energy (and some),
/// in map order.
fn brightest(env: &EnvMap, d_omega: &[f64], keep: usize) -> Vec<usize> {
    if keep == 0 {
        return Vec::new();
    }
    let mut ranked: Vec<(f64, usize)> = (0..env.texels.len())
        .filter_map(|i| {
            let e = energy(env.texels[i], d_omega[i]);
            (e > 0.0).then_some((e, i))
        })
        .collect();
    ranked.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let mut out: Vec<usize> = ranked.iter().take(keep).map(|&(_, i)| i).collect();
    out.sort_unstable();
    out
}

/// The map as `factor` x `factor` blocks (the last row and column of blocks may be
/// smaller) plus its `keep` brightest texels. Factor 1 keeps every texel as it is.
pub(crate) fn lights(env: &EnvMap, factor: usize, keep: usize) -> Lights {
    let (h, w) = (env.height, env.width);
    let (rows, cols) = (h.div_ceil(factor), w.div_ceil(factor));
    let geometry: Vec<([f64; 3], f64)> = (0..h * w)
        .map(|i| env.convention.texel(i / w, i % w, h, w))
        .collect();
    let d_omegas: Vec<f64> = geometry.iter().map(|g| g.1).collect();
    let kept_idx = brightest(env, &d_omegas, keep);
    let mut is_kept = vec![false; h * w];
    for &i in &kept_idx {
        is_kept[i] = true;
    }
    struct Acc {
        d_omega: f64,
        dir: [f64; 3],
        ld: [f64; 3],
    }
    let mut acc: Vec<Acc> = (0..rows * cols)
        .map(|_| Acc {
            d_omega: 0.0,
            dir: [0.0; 3],
            ld: [0.0; 3],
        })
        .collect();
    let mut kept = Vec::with_capacity(kept_idx.len());
    let mut block_of = vec![0u32; h * w];
    for r in 0..h {
        for c in 0..w {
            let i = r * w + c;
            let (dir, d_omega) = geometry[i];
            let l = env.texels[i].map(f64::from);
            let b = (r / factor) * cols + c / factor;
            block_of[i] = b as u32;
            let a = &mut acc[b];
            a.d_omega += d_omega;
            for k in 0..3 {
                a.dir[k] += dir[k] * d_omega;
            }
            if is_kept[i] {
                kept.push(PointLight {
                    index: i,
                    w: dir,
                    d_omega,
                    l,
                });
            } else {
                for k in 0..3 {
                    a.ld[k] += l[k] * d_omega;
                }
            }
        }
    }
    let blocks: Vec<PointLight> = acc
        .iter()
        .enumerate()
        .map(|(b, a)| {
            let (r, c) = (b / cols, b % cols);
            let w = if factor == 1 {
                // the texel's own direction, bit for bit
                geometry[b].0
            } else {
                let len = dot(a.dir, a.dir).sqrt();
                if len > 0.0 {
                    a.dir.map(|v| v / len)
                } else {
                    env.convention.texel(r * factor, c * factor, h, w).0
                }
            };
            let l = if a.d_omega > 0.0 {
                a.ld.map(|v| v / a.d_omega)
            } else {
                [0.0; 3]
            };
            PointLight {
                index: b,
                w,
                d_omega: a.d_omega,
                l,
            }
        })
        .collect();
    let share = (0..h * w)
        .map(|i| {
            let b = block_of[i];
            let d_block = acc[b as usize].d_omega;
            let s = if is_kept[i] || d_block <= 0.0 {
                0.0
            } else {
                d_omegas[i] / d_block
            };
            (b, s)
        })
        .collect();
    Lights {
        rows,
        cols,
        blocks,
        kept,
        share,
    }
}

impl Lights {
    /// dLoss/dL per texel of the map from the blocks' (`d_blocks`, `rows` x `cols`) and
    /// the kept texels' (`d_kept`, laid out as the map; None without kept texels).
    pub fn adjoint(&self, d_blocks: &[[f32; 3]], d_kept: Option<&[[f32; 3]]>) -> Vec<[f32; 3]> {
        let mut out: Vec<[f32; 3]> = self
            .share
            .iter()
            .map(|&(b, s)| d_blocks[b as usize].map(|v| (f64::from(v) * s) as f32))
            .collect();
        if let Some(d) = d_kept {
            for k in &self.kept {
                out[k.index] = d[k.index];
            }
        }
        out
    }
}
