//! Culling by bound: per group of pixels with similar normals, the lights whose largest
//! possible contribution to any pixel of the group, summed, stays within a budget are
//! left out. A sharp lobe needs only the lights near its peak; a dark texel matters only
//! under a bright lobe; a light below every normal's horizon adds nothing.
//!
//! Groups are the cells of an 8 x 8 grid over the stereographic plane of normals
//! (u, v) = (n.x, n.y) / (1 + n.z) on [-2, 2]^2, and one group for the normals beyond it.
//! A cell's normals lie in a cone (axis c, half-angle a) fixed by the cell alone, so the
//! same pixel is culled the same way whichever other pixels run with it. In a cone, with
//! normals up to length r, a light (direction w, half vector h, radiance x solid angle ld,
//! coefficients m at its theta_d) adds at most, per channel k,
//! |ld_k| r cos+(angle(w, c) - a) sum_s |exp(m0 x^m1) - 1| with x = r cos+(angle(h, c) - a),
//! where cos+(t) is cos(max(0, t)), and 0 past pi/2: f grows with x (exponents are >= 0),
//! and the cosine and x can be no larger anywhere in the cone. Orthographic cameras only
//! (the half vector is then the light's own).
//!
//! Culling is for images: a culled light's dLoss/dL is 0 (the vector-Jacobian product of
//! the culled layer, which the light does not enter), where the exact layer's is not.
//! Lights below the horizon of a whole group (whose exact dLoss/dL there is 0) and unlit
//! texels are never culled by bound.

use crate::Backend;
use crate::error::Result;
use crate::prepare::{PixelRec, Prepared, dot};

/// Cells per axis of the stereographic grid.
const CELLS: usize = 8;
/// The grid spans [-RADIUS, RADIUS]^2 (n.z > -0.6 on its inscribed disc).
const RADIUS: f64 = 2.0;
/// Culling is dropped when it would keep more than this share of the pairs.
const WORTH: f64 = 0.7;

/// A cone of normal directions.
#[derive(Clone, Copy, Debug)]
struct Cone {
    axis: [f64; 3],
    half_angle: f64,
}

/// The groups of normals.
pub(crate) struct Groups {
    cones: Vec<Cone>,
}

fn from_stereo(u: f64, v: f64) -> [f64; 3] {
    let q = u * u + v * v;
    [
        2.0 * u / (1.0 + q),
        2.0 * v / (1.0 + q),
        (1.0 - q) / (1.0 + q),
    ]
}

fn angle(a: [f64; 3], b: [f64; 3]) -> f64 {
    (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt())
        .clamp(-1.0, 1.0)
        .acos()
}

/// The group of a normal: its cell, or the last group.
fn group_of(n: [f64; 3]) -> usize {
    let len = dot(n, n).sqrt();
    let z = n[2] / len;
    if z <= -0.6 {
        return CELLS * CELLS;
    }
    let (u, v) = (n[0] / len / (1.0 + z), n[1] / len / (1.0 + z));
    if u.abs() >= RADIUS || v.abs() >= RADIUS {
        return CELLS * CELLS;
    }
    let cell = |x: f64| (((x + RADIUS) / (2.0 * RADIUS) * CELLS as f64) as usize).min(CELLS - 1);
    cell(v) * CELLS + cell(u)
}

impl Groups {
    /// The cells' cones, and the whole sphere for the last group.
    pub fn new() -> Self {
        let side = 2.0 * RADIUS / CELLS as f64;
        let mut cones = Vec::with_capacity(CELLS * CELLS + 1);
        for j in 0..CELLS {
            for i in 0..CELLS {
                let (u0, v0) = (-RADIUS + i as f64 * side, -RADIUS + j as f64 * side);
                let axis = from_stereo(u0 + side / 2.0, v0 + side / 2.0);
                // the farthest point of the cell's boundary from the axis, on a fine walk
                let mut half_angle: f64 = 0.0;
                for t in 0..=16 {
                    let f = t as f64 / 16.0 * side;
                    for (u, v) in [
                        (u0 + f, v0),
                        (u0 + f, v0 + side),
                        (u0, v0 + f),
                        (u0 + side, v0 + f),
                    ] {
                        half_angle = half_angle.max(angle(axis, from_stereo(u, v)));
                    }
                }
                cones.push(Cone {
                    axis,
                    // the walk's spacing, and rounding
                    half_angle: half_angle * 1.01 + 1e-6,
                });
            }
        }
        cones.push(Cone {
            axis: [0.0, 0.0, 1.0],
            half_angle: std::f64::consts::PI,
        });
        Groups { cones }
    }

    /// A lower bound of the image's largest value: the exact layer (block lights plus kept
    /// texels) at one pixel of each group of `full`.
    pub fn largest_value(
        &self,
        backend: &dyn Backend,
        full: &Prepared,
        blocks: &Prepared,
        kept: Option<&Prepared>,
    ) -> Result<f64> {
        let mut seen = vec![false; self.cones.len()];
        let reps: Vec<PixelRec> = full
            .pixels
            .iter()
            .filter(|p| !std::mem::replace(&mut seen[group_of(p.n)], true))
            .enumerate()
            .map(|(i, p)| PixelRec { index: i, ..*p })
            .collect();
        let n = reps.len();
        let mut scenes = vec![blocks.with_pixels(n, 1, reps.clone())];
        if let Some(k) = kept {
            scenes.push(k.with_pixels(n, 1, reps));
        }
        let images = backend.render((&scenes).into())?;
        let mut largest: f64 = 0.0;
        for i in 0..n {
            for c in 0..3 {
                let v: f64 = images.iter().map(|im| f64::from(im.pixels[i][c])).sum();
                largest = largest.max(v);
            }
        }
        Ok(largest)
    }

    /// `scene` as one scene per group of its pixels, each with the lights the group cannot
    /// do without, so that each pixel's error is at most `budget` per channel; or `scene`
    /// itself when that would keep most of the pairs above the horizon (those below cost
    /// the kernels little: they skip them by blocks).
    pub fn cull(&self, scene: &Prepared, budget: f64) -> Vec<Prepared> {
        let mut members: Vec<Vec<PixelRec>> = vec![Vec::new(); self.cones.len()];
        for p in &scene.pixels {
            members[group_of(p.n)].push(*p);
        }
        let lit = |t: &crate::prepare::TexelRec| t.ld.iter().any(|&v| v != 0.0);
        let mut all_pairs = 0;
        let mut pairs = 0;
        let mut groups = Vec::new();
        for (g, pixels) in members.into_iter().enumerate() {
            if pixels.is_empty() {
                continue;
            }
            let r = pixels
                .iter()
                .map(|p| dot(p.n, p.n).sqrt())
                .fold(0.0, f64::max);
            let (keep, above) = needed(scene, self.cones[g], r, budget);
            all_pairs += pixels.len() * above;
            let texels: Vec<_> = keep.iter().map(|&t| scene.texels[t]).collect();
            let lit_at: Vec<usize> = (0..texels.len()).filter(|&i| lit(&texels[i])).collect();
            pairs += pixels.len() * lit_at.len();
            groups.push(Prepared {
                width: scene.width,
                height: scene.height,
                env_height: scene.env_height,
                env_width: scene.env_width,
                camera: scene.camera,
                ctrl: scene.ctrl,
                pixels,
                texels,
                lit: lit_at,
                active_lobes: scene.active_lobes.clone(),
                const_lobes: scene.const_lobes.clone(),
            });
        }
        if pairs as f64 > WORTH * all_pairs as f64 {
            return vec![scene.clone()];
        }
        groups
    }
}

/// Positions in `scene.texels` of the lights a group in `cone` (normals up to length `r`)
/// keeps: all but the smallest bounds that sum to at most `budget`; and how many lit
/// lights are above the horizon of some normal of the cone.
fn needed(scene: &Prepared, cone: Cone, r: f64, budget: f64) -> (Vec<usize>, usize) {
    let cos_plus = |v: [f64; 3]| {
        let t = (angle(v, cone.axis) - cone.half_angle).max(0.0);
        if t >= std::f64::consts::FRAC_PI_2 {
            0.0
        } else {
            t.cos()
        }
    };
    let mut bounds: Vec<(f64, usize)> = (0..scene.texels.len())
        .map(|i| {
            let t = &scene.texels[i];
            let c = cos_plus(t.w);
            if c == 0.0 {
                // below every normal's horizon: no light, and no dLoss/dL either
                return (0.0, i);
            }
            if t.ld.iter().all(|&v| v == 0.0) {
                // unlit: costs the image nothing, and keeps its dLoss/dL exact
                return (f64::INFINITY, i);
            }
            // the half vector is undefined where w = -w_p: any x in [0, r]
            let x = if dot(t.h, t.h) > 0.0 {
                r * cos_plus(t.h)
            } else {
                r
            };
            let mut worst: f64 = 0.0;
            for k in 0..3 {
                let f: f64 = (0..3)
                    .map(|s| {
                        let m0 = t.coef[(k * 3 + s) * 2];
                        let m1 = t.coef[(k * 3 + s) * 2 + 1];
                        (m0 * x.powf(m1)).exp_m1().abs()
                    })
                    .sum();
                worst = worst.max(t.ld[k].abs() * f);
            }
            (worst * r * c, i)
        })
        .collect();
    let above = bounds
        .iter()
        .filter(|&&(b, i)| b > 0.0 && b.is_finite() && scene.texels[i].ld.iter().any(|&v| v != 0.0))
        .count();
    bounds.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let mut spent = 0.0;
    let mut keep: Vec<usize> = Vec::new();
    for &(b, i) in &bounds {
        if keep.is_empty() && spent + b <= budget {
            spent += b;
        } else {
            keep.push(i);
        }
    }
    keep.sort_unstable();
    (keep, above)
}
