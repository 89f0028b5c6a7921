//! The cheapest method for an error budget.
//!
//! The estimate runs the layer exactly on a stratified sample of the pixels (1 in 64, at
//! least 256 and at most 2048 of them) and each candidate method on the same pixels; a
//! table's grid is the one the whole image gets, and only the nodes the sample's stencils
//! need are evaluated. A candidate's estimated error is its largest error on the sample,
//! relative to the sample's largest exact value (for the image and, when an upstream
//! gradient is given, for each gradient). A candidate is taken when three times its
//! estimate is within the tolerance: the factor covers the pixels the sample misses (in
//! the benchmark the measured error was up to 5.8 times the estimate, 1.4 times at the
//! median). Scenes of fewer than [`MIN_PAIRS`] pixel-light pairs are rendered exactly.
//!
//! Candidates are tried in order of their predicted cost (pairs of a pixel and a lit light
//! evaluated, counted from the scene), and only while they are cheaper than the best one
//! found so far, so the estimate costs a few percent of an exact render:
//! - environment levels (blocks of 8, 4 and 2 texels a side) with 0, 16 or 64 texels
//!   kept, evaluated per pixel (images only);
//! - for orthographic cameras, normal tables of growing resolution over the cheapest of
//!   those lights whose own error is within half the budget. After a table misses, the
//!   next resolution tried is the one its error predicts (Catmull-Rom's error falls as the
//!   cube of the node spacing).

use std::collections::HashMap;

use crate::Backend;
use crate::envmap::EnvMap;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Scene};

use super::plan::Plan;
use super::table::{Grid, Table};
use super::{Method, TABLE_SIZES};

/// A taken candidate's estimate times this is within the tolerance.
pub const SAFETY: f64 = 3.0;
/// Pixels sampled: 1 in this many ...
const SAMPLE_EVERY: usize = 64;
/// ... at least this many (or all) ...
const SAMPLE_MIN: usize = 256;
/// ... and at most this many.
const SAMPLE_MAX: usize = 2048;
/// About this many texels for the estimates of dLoss/dL and dLoss/dctrl.
const SAMPLE_TEXELS: usize = 128;
/// Block sides tried, coarsest first.
const ENV_FACTORS: [usize; 4] = [8, 4, 2, 1];
/// Kept texels tried.
const KEEPS: [usize; 3] = [0, 16, 64];
/// Kept texels for the tables, in the order tried.
const KEEPS_FOR_TABLES: [usize; 3] = [16, 64, 0];
/// An approximation is taken only if its predicted work is below this share of the exact
/// layer's.
const MAX_COST_SHARE: f64 = 0.5;
/// The trials may spend this share of the exact layer's work.
const ESTIMATE_BUDGET: f64 = 0.1;
/// Scenes of fewer pixel-light pairs are rendered exactly, unestimated (a 128 x 128
/// sphere against a 64 x 128 map has 1.1e8).
pub const MIN_PAIRS: f64 = 2e8;
/// The first table resolution tried.
const FIRST_TABLE: usize = 32;
/// The cost of interpolating one pixel from a table, in pair evaluations.
const INTERP_PAIRS: f64 = 4.0;
/// The cost of a pair in the normals' Jacobian (a table's dLoss/dn), in forward pair
/// evaluations.
const JACOBIAN_PAIR: f64 = 1.5;
/// The cost of a pair in the backward pass, in forward pair evaluations.
const BACKWARD_PAIR: f64 = 3.0;

/// Estimated errors of a method on a scene: max |x - x_exact| over max |x_exact| on the
/// sampled pixels, per output.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Estimate {
    /// The image.
    pub image: f64,
    /// dLoss/dL (when an upstream gradient was given).
    pub d_env: Option<f64>,
    /// dLoss/dn.
    pub d_normals: Option<f64>,
    /// dLoss/dctrl.
    pub d_ctrl: Option<f64>,
    /// Pixels in the sample.
    pub pixels: usize,
}

impl Estimate {
    /// The largest of the estimated errors.
    pub fn max(&self) -> f64 {
        [self.d_env, self.d_normals, self.d_ctrl]
            .into_iter()
            .flatten()
            .fold(self.image, f64::max)
    }
}

/// A method chosen for an error budget.
#[derive(Clone, Debug, PartialEq)]
pub struct Choice {
    /// The method.
    pub method: Method,
    /// Its estimated errors (0 for the exact layer).
    pub estimate: Estimate,
    /// Its predicted work relative to the exact layer's (pair evaluations).
    pub cost: f64,
    /// The tolerance asked for.
    pub tolerance: f64,
}

impl std::fmt::Display for Choice {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.method.is_exact() {
            return write!(
                f,
                "method exact (no approximation was estimated within tolerance {:.0e} at under half the work)",
                self.tolerance
            );
        }
        write!(
            f,
            "method {} (estimated error {:.2e} on {} sampled pixels, tolerance {:.0e}, predicted work {:.1}% of exact)",
            self.method,
            self.estimate.max(),
            self.estimate.pixels,
            self.tolerance,
            100.0 * self.cost
        )
    }
}

/// The cheapest method for `scene` whose estimated error is within `tol` (relative); with
/// `upstream`, every gradient's too.
pub fn choose(
    backend: &dyn Backend,
    scene: &Scene,
    tol: f64,
    upstream: Option<&Image>,
) -> Result<Choice> {
    Chooser::default().choose(backend, scene, tol, upstream)
}

/// Settings of the choice.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chooser {
    /// Scenes of fewer pixel-light pairs are rendered exactly without an estimate, which
    /// would cost more than it could save ([`MIN_PAIRS`] by default; 0 always estimates).
    pub min_pairs: f64,
}

impl Default for Chooser {
    fn default() -> Self {
        Chooser {
            min_pairs: MIN_PAIRS,
        }
    }
}

impl Chooser {
    /// [`choose`] with these settings.
    pub fn choose(
        &self,
        backend: &dyn Backend,
        scene: &Scene,
        tol: f64,
        upstream: Option<&Image>,
    ) -> Result<Choice> {
        let prep = Prepared::new(scene);
        Ok(choose_plan(self, backend, &prep, scene, tol, upstream)?.0)
    }
}

/// The pixels at `positions` of `prep.pixels`, as a one-row image of them.
fn compact(prep: &Prepared, positions: &[usize]) -> Prepared {
    let pixels = positions
        .iter()
        .enumerate()
        .map(|(i, &k)| crate::prepare::PixelRec {
            index: i,
            ..prep.pixels[k]
        })
        .collect();
    prep.with_pixels(positions.len(), 1, pixels)
}

/// max |a - b| over max |b|.
fn rel(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let (mut diff, mut scale) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
        diff = diff.max((f64::from(*x) - f64::from(*y)).abs());
        scale = scale.max(f64::from(*y).abs());
    }
    ratio(diff, scale)
}

fn ratio(diff: f64, scale: f64) -> f64 {
    if diff == 0.0 {
        0.0
    } else if scale > 0.0 {
        diff / scale
    } else {
        f64::INFINITY
    }
}

fn rel_ctrl(a: &[f32], b: &[f32]) -> f64 {
    let diff = a
        .iter()
        .zip(b)
        .map(|(x, y)| (f64::from(*x) - f64::from(*y)).abs())
        .fold(0.0, f64::max);
    let scale = b.iter().map(|y| f64::from(*y).abs()).fold(0.0, f64::max);
    ratio(diff, scale)
}

/// The sample: one pixel in each of `n` equal strata of the pixel list, at a
/// pseudo-random position in it.
fn sample_positions(len: usize) -> Vec<usize> {
    let n = (len / SAMPLE_EVERY).clamp(SAMPLE_MIN, SAMPLE_MAX).min(len);
    (0..n)
        .map(|k| {
            let (lo, hi) = (k * len / n, (k + 1) * len / n);
            let mut z = (k as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15);
            z = (z ^ (z >> 31)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            lo + (z >> 11) as usize % (hi - lo).max(1)
        })
        .collect()
}

/// The texels the gradients' estimate runs on: about [`SAMPLE_TEXELS`] of them on a
/// regular grid (every texel of a small map).
fn texel_mask(env: &EnvMap) -> Vec<bool> {
    let (h, w) = (env.height, env.width);
    let stride = ((h * w) as f64 / SAMPLE_TEXELS as f64)
        .sqrt()
        .floor()
        .max(1.0) as usize;
    let on = |i: usize| i % stride == stride / 2;
    (0..h * w).map(|i| on(i / w) && on(i % w)).collect()
}

/// [`rel`] over the elements in `mask`.
fn rel_masked(a: &[[f32; 3]], b: &[[f32; 3]], mask: &[bool]) -> f64 {
    let pick = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
        v.iter()
            .zip(mask)
            .filter(|(_, m)| **m)
            .map(|(x, _)| *x)
            .collect()
    };
    rel(&pick(a), &pick(b))
}

/// Sampled pixels and the exact layer's results on them.
struct Truth {
    /// The sample as a one-row image, pixel k at column k.
    sample: Prepared,
    /// The upstream gradient on it.
    upstream: Option<Image>,
    image: Image,
    grads: Option<Gradients>,
}

/// The samples, their exact results, and the scene the candidates run on.
struct Trial<'a> {
    backend: &'a dyn Backend,
    scene: &'a Scene,
    full: &'a Prepared,
    upstream: Option<&'a Image>,
    /// For the per-pixel methods.
    pixels: Truth,
    /// For the tables, which cost 16 nodes per sampled pixel: a part of the sample.
    tables: Truth,
    /// For dLoss/dL and dLoss/dctrl (with an upstream gradient): every pixel, but a
    /// sample of the texels. These are sums over pixels whose errors cancel between
    /// neighbours (a texel's horizon is a kink that a table's errors straddle with both
    /// signs), so a sample of pixels would overstate them; the layer is linear in L, so
    /// dLoss/dL of a texel needs no other texel.
    /// Made when a candidate first gets that far.
    texels: std::cell::OnceCell<TexelTruth>,
}

/// The exact gradients for a sample of texels, on every pixel.
struct TexelTruth {
    mask: Vec<bool>,
    grads: Gradients,
}

impl<'a> Trial<'a> {
    fn new(
        backend: &'a dyn Backend,
        scene: &'a Scene,
        full: &'a Prepared,
        upstream: Option<&'a Image>,
    ) -> Result<Self> {
        let truth = |positions: &[usize]| -> Result<Truth> {
            let sample = compact(full, positions);
            let upstream = upstream.map(|u| Image {
                width: positions.len(),
                height: 1,
                pixels: positions
                    .iter()
                    .map(|&k| u.pixels[full.pixels[k].index])
                    .collect(),
            });
            let exact = Plan::new(backend, &sample, &scene.env, &Method::EXACT, &full.pixels)?;
            let image = exact.forward(backend)?;
            let grads = upstream
                .as_ref()
                .map(|u| exact.backward(backend, u))
                .transpose()?;
            Ok(Truth {
                sample,
                upstream,
                image,
                grads,
            })
        };
        let positions = sample_positions(full.pixels.len());
        let pixels = truth(&positions)?;
        // for the tables: every 8th sampled pixel, and as many again of the brightest
        // others, where a table's error concentrates (the highlights)
        let mut table_positions: Vec<usize> = positions.iter().copied().step_by(8).collect();
        let mut rest: Vec<(f32, usize)> = positions
            .iter()
            .enumerate()
            .filter(|(j, _)| j % 8 != 0)
            .map(|(j, &k)| {
                let v = pixels.image.pixels[j];
                (v[0].max(v[1]).max(v[2]), k)
            })
            .collect();
        rest.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let brightest = table_positions.len();
        table_positions.extend(rest.iter().take(brightest).map(|&(_, k)| k));
        table_positions.sort_unstable();
        Ok(Trial {
            backend,
            scene,
            full,
            upstream,
            pixels,
            tables: truth(&table_positions)?,
            texels: std::cell::OnceCell::new(),
        })
    }

    /// `method`'s plan on `truth`'s sample.
    fn plan_on<'t>(&self, truth: &'t Truth, method: &Method) -> Result<Plan<'t>> {
        Plan::new(
            self.backend,
            &truth.sample,
            &self.scene.env,
            method,
            &self.full.pixels,
        )
    }

    /// The estimated error of `method`'s image alone, on the per-pixel sample.
    fn image_error(&self, method: &Method) -> Result<f64> {
        let image = self.plan_on(&self.pixels, method)?.forward(self.backend)?;
        Ok(rel(&image.pixels, &self.pixels.image.pixels))
    }

    /// The estimate of `method`; the gradients' only if the image's is within `tol`.
    fn estimate(&self, method: &Method, tol: f64) -> Result<Estimate> {
        let truth = if method.table.is_some() {
            &self.tables
        } else {
            &self.pixels
        };
        let plan = self.plan_on(truth, method)?;
        let image = plan.forward(self.backend)?;
        let mut e = Estimate {
            image: rel(&image.pixels, &truth.image.pixels),
            pixels: truth.sample.pixels.len(),
            ..Estimate::default()
        };
        if e.image * SAFETY > tol {
            return Ok(e);
        }
        if let (Some(up), Some(sample_up), Some(exact)) =
            (self.upstream, &truth.upstream, &truth.grads)
        {
            let g = plan.backward(self.backend, sample_up)?;
            e.d_normals = Some(rel(&g.d_normals, &exact.d_normals));
            if e.max() * SAFETY > tol {
                return Ok(e);
            }
            let env = &self.scene.env;
            let texels = match self.texels.get() {
                Some(t) => t,
                None => {
                    let mask = texel_mask(env);
                    let full = self.full;
                    let exact =
                        Plan::masked(self.backend, full, env, &Method::EXACT, &full.pixels, &mask)?;
                    let grads = exact.backward(self.backend, up)?;
                    self.texels.get_or_init(|| TexelTruth { mask, grads })
                }
            };
            let (mask, full) = (&texels.mask, self.full);
            let plan = Plan::masked(self.backend, full, env, method, &full.pixels, mask)?;
            let g = plan.backward(self.backend, up)?;
            e.d_env = Some(rel_masked(&g.d_env, &texels.grads.d_env, mask));
            e.d_ctrl = Some(rel_ctrl(&g.d_ctrl, &texels.grads.d_ctrl));
        }
        Ok(e)
    }
}

/// The choice and its plan over the whole of `prep` (ready to run).
pub(crate) fn choose_plan<'a>(
    chooser: &Chooser,
    backend: &dyn Backend,
    prep: &'a Prepared,
    scene: &Scene,
    tol: f64,
    upstream: Option<&Image>,
) -> Result<(Choice, Plan<'a>)> {
    if !(tol.is_finite() && tol > 0.0) {
        return Err(Error::Invalid(format!(
            "tolerance: {tol} is not a positive number"
        )));
    }
    let backward = upstream.is_some();
    let done = |method: Method, estimate: Estimate, cost: f64| {
        let plan = Plan::new(backend, prep, &scene.env, &method, &prep.pixels)?;
        let choice = Choice {
            method,
            estimate,
            cost,
            tolerance: tol,
        };
        Ok((choice, plan))
    };
    let n = prep.pixels.len() as f64;
    let lit_total = prep.lit.len() as f64;
    let pair = if backward { BACKWARD_PAIR } else { 1.0 };
    let exact_cost = n * lit_total * pair;
    if n * lit_total < chooser.min_pairs.max(f64::MIN_POSITIVE) {
        // the estimate would cost more than it could save
        return done(Method::EXACT, Estimate::default(), 1.0);
    }

    let trial = Trial::new(backend, scene, prep, upstream)?;

    // the lights: lit blocks and lit kept texels per (block side, kept), counted
    // (blocks whose lit texels are all kept count as lit: a cost model)
    let env = &scene.env;
    let lit_texels: Vec<bool> = env
        .texels
        .iter()
        .map(|l| l.iter().any(|&v| v != 0.0))
        .collect();
    let n_lit = lit_texels.iter().filter(|&&l| l).count();
    let mut light_counts = Vec::new();
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
            light_counts.push(((f, k), blocks as f64, kept as f64));
        }
    }
    let method = |f: usize, k: usize, table: Option<usize>| Method {
        env_factor: f,
        keep: k,
        table,
        cull: None,
    };

    // per pixel
    let mut best = (Method::EXACT, Estimate::default(), exact_cost);
    // an approximation must save at least half the work to be worth its estimate
    let most = exact_cost * MAX_COST_SHARE;
    let mut light_error: HashMap<(usize, usize), f64> = HashMap::new();
    // what the trials may spend, in forward pair evaluations
    let mut budget = exact_cost * ESTIMATE_BUDGET;
    let s_pixels = trial.pixels.sample.pixels.len() as f64;
    let s_tables = trial.tables.sample.pixels.len() as f64;
    let mut per_pixel: Vec<((usize, usize), f64)> = light_counts
        .iter()
        // blocks give each texel its block's dLoss/dL, shaped by the block's direction:
        // for gradients they were never close (errors of 0.1 and more in the benchmark)
        .filter(|((f, _), _, _)| *f > 1 && !backward)
        .map(|&(fk, b, k)| (fk, n * (b + k) * pair))
        .collect();
    per_pixel.sort_by(|a, b| a.1.total_cmp(&b.1));
    for ((f, k), cost) in per_pixel {
        if cost >= best.2.min(most) {
            break;
        }
        let spend = s_pixels * cost / (n * pair);
        if spend > budget {
            continue;
        }
        budget -= spend;
        let m = method(f, k, None);
        let e = trial.estimate(&m, tol)?;
        light_error.insert((f, k), e.image);
        if e.max() * SAFETY <= tol {
            best = (m, e, cost);
            break;
        }
    }

    // tables, over each light whose own error is within half the budget
    if prep.camera.is_orthographic() {
        let mut table_lights = light_counts.clone();
        // full resolution before blocks; with texels kept before without: a bright
        // texel's horizon is a kink in the image as a function of the normal, which a table
        // cannot interpolate, so a table over the rest of the map is usually the cheaper
        let keep_rank = |k: usize| KEEPS_FOR_TABLES.iter().position(|&x| x == k);
        table_lights.sort_by_key(|&((f, k), _, _)| (f, keep_rank(k)));
        let mut passed_at = None;
        for ((f, k), blocks, kept) in table_lights {
            let e_light = match light_error.get(&(f, k)) {
                Some(&e) => e,
                // texels kept beside a full-resolution map are the map itself
                None if f == 1 => 0.0,
                None if s_pixels * (blocks + kept) > budget => continue,
                None => {
                    budget -= s_pixels * (blocks + kept);
                    let e = trial.image_error(&method(f, k, None))?;
                    light_error.insert((f, k), e);
                    e
                }
            };
            if e_light * SAFETY > tol / 2.0 {
                continue;
            }
            // after a light's table passed, the next light starts a step below its size
            let first = TABLE_SIZES
                .iter()
                .position(|&r| r >= FIRST_TABLE)
                .unwrap_or(0);
            let mut i = passed_at.map_or(first, |p: usize| p.saturating_sub(1).max(first));
            while i < TABLE_SIZES.len() {
                let r = TABLE_SIZES[i];
                let grid = Grid::new(r, &prep.pixels);
                let (nodes, left) = Table::count(&grid, &prep.pixels);
                let node_pair = if backward {
                    BACKWARD_PAIR + JACOBIAN_PAIR
                } else {
                    1.0
                };
                let cost = nodes as f64 * blocks * node_pair
                    + (left as f64 * blocks + n * kept) * pair
                    + n * INTERP_PAIRS;
                if cost >= best.2.min(most) {
                    break;
                }
                // the image's trial, and the gradients' if the image passes
                let node_work = nodes.min(16 * s_tables as usize) as f64 * blocks;
                let spend = node_work + s_tables * kept;
                if spend > budget {
                    break;
                }
                budget -= spend;
                let m = method(f, k, Some(r));
                let e = trial.estimate(&m, tol)?;
                if e.d_env.is_some() {
                    budget -= node_work * node_pair + s_tables * kept * BACKWARD_PAIR;
                }
                if e.max() * SAFETY <= tol {
                    best = (m, e, cost);
                    passed_at = Some(i);
                    break;
                }
                // the resolution this error asks for, if the table's share falls as h^3
                let share = (e.max() - e_light).max(e.max() / 2.0);
                let room = (tol / SAFETY - e_light).max(tol / SAFETY / 2.0);
                let want = r as f64 * (share / room).cbrt();
                i += 1;
                while i < TABLE_SIZES.len() && (TABLE_SIZES[i] as f64) < want {
                    i += 1;
                }
            }
        }
    }
    let (m, e, cost) = best;
    let chosen = Plan::new(backend, prep, &scene.env, &m, &prep.pixels)?;

    let choice = Choice {
        method: m,
        estimate: e,
        cost: cost / exact_cost,
        tolerance: tol,
    };
    Ok((choice, chosen))
}
