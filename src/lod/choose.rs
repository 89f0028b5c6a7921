//! The cheapest method for an error budget.
//!
//! The estimate runs the layer exactly on a stratified sample of the pixels (1 in 64, at
//! least 256 and at most 2048 of them) and each candidate method on the same pixels; a
//! table's grid is the one the whole image gets, and only the nodes the sample's stencils
//! need are evaluated. A candidate's estimated error is its largest error on the sample,
//! relative to the sample's largest exact value (for the image and, when an upstream
//! gradient is given, for dLoss/dn). dLoss/dL and dLoss/dctrl are sums over pixels, judged
//! on every pixel for a sample of the texels. A candidate is taken when each estimate
//! times its safety factor ([`SAFETY`], [`SAFETY_SUMS`]; [`Chooser`] changes them) is
//! within the tolerance: the factor covers what the samples miss. Scenes of fewer than
//! [`MIN_PAIRS`] pixel-light pairs are rendered exactly.
//!
//! Candidates are tried in order of their predicted cost (pairs of a pixel and a lit light
//! evaluated, counted from the scene), and only while they are cheaper than the best one
//! found so far and the trials' work (the exact layer on the samples included) stays within
//! [`ESTIMATE_BUDGET`] of the exact layer's:
//! - environment levels (blocks of 8, 4 and 2 texels a side) with 0, 16 or 64 texels
//!   kept, evaluated per pixel (images only);
//! - for orthographic cameras, normal tables of growing resolution over the cheapest of
//!   those lights (with 16, 64, 256 or no texels kept; with gradients 64 first) whose own
//!   error is within half the budget. After a table misses, the next resolution tried is
//!   the one its error predicts (taken to fall as the fourth power of the node spacing: the
//!   interpolation's own error falls as the sixth, the kinks of texels' horizons left in
//!   the table slower); after one passes, the next light starts a step below it; a
//!   resolution whose dLoss/dL missed is not tried again with other kept texels (dLoss/dL
//!   does not depend on the radiance); a light whose finer table missed by more than
//!   `FLOOR` of its last miss goes no finer.
//!
//! With an upstream gradient, the finest table within the work allowed is first judged on
//! dLoss/dL alone (where that trial costs at most a third of the budget): dLoss/dL does not
//! depend on the radiance and falls as tables grow finer, so where it misses, no table
//! can pass and no other candidate is tried. With an upstream gradient, too:
//! - only tables over the full-resolution map are tried (blocks of texels give each texel
//!   its block's dLoss/dL, never close);
//! - once the texels' exact gradients are made, a candidate's dLoss/dL and dLoss/dctrl are
//!   judged before its dLoss/dn, the dearer trial (the nodes' Jacobians on the sample);
//! - the best table's resolution with other texels kept is tried only where it could save
//!   more work than its trial costs.
//!
//! With `MATEDIT_LOD_TRACE` set, each trial's estimate and time go to stderr.

use std::collections::HashMap;

use crate::Backend;
use crate::envmap::EnvMap;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Scene, Wanted};

use super::plan::Plan;
use super::table::{Footprint, STENCIL};
use super::{Method, TABLE_SIZES};

/// The gradients judged on the sampled pixels ...
const NORMALS: Wanted = Wanted {
    env: false,
    normals: true,
    ctrl: false,
};
/// ... and on the sampled texels.
const SUMS: Wanted = Wanted {
    env: true,
    normals: false,
    ctrl: true,
};

/// A taken candidate's estimate of the image and of dLoss/dn (judged on sampled pixels)
/// times this is within the tolerance: the pixels the sample misses may be worse (in the
/// benchmark the measured error was 1.4-1.8 times the estimate at the median, and up to 6
/// times; examples/lod_estimates.rs on 48 tables: the image 2.1 at the median and up to
/// 5.0, dLoss/dn 2.8 and up to 7.9).
pub const SAFETY: f64 = 3.0;
/// The same for dLoss/dL and dLoss/dctrl, judged on every pixel and a sample of the
/// texels: in the benchmark the measured error of dLoss/dL was 1.5 times the estimate at
/// the median and up to 2.2 times (examples/lod_estimates.rs: 1.4 and 2.0); that of
/// dLoss/dctrl at most 0.7 times (0.4).
pub const SAFETY_SUMS: f64 = 3.0;
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
const KEEPS: [usize; 4] = [0, 16, 64, 256];
/// So many kept texels are tried with tables only (per pixel they cost too much).
const TABLE_ONLY_KEEP: usize = 256;
/// Kept texels for the tables, in the order tried: for images ...
const KEEPS_FOR_TABLES: [usize; 4] = [16, 64, 256, 0];
/// ... and with gradients, where 64 come first: dI/dn jumps on the horizon of every texel
/// left in the table, and where bright texels' horizons crowd together the interpolated
/// Jacobians miss by more than the sampled pixels show (512 sphere under `studio`,
/// `random-1`, table128: dLoss/dn 1.2e-3 with 16 texels kept, estimated 3.3e-4, on a row of
/// pixels at the horizons of texels ranked 23rd to 58th by energy; 5.0e-5 with 64 kept,
/// whose 48 more texels per pixel made forward + backward 0.511 s against 0.495 s: `cargo
/// bench --bench lod -- --scenes sphere512 --envs studio --materials random-1 --methods
/// exact,table128+keep16,table128+keep64 --tols none --peers none`).
const KEEPS_FOR_GRADIENTS: [usize; 4] = [64, 16, 256, 0];
/// An approximation is taken only if its predicted work is below this share of the exact
/// layer's.
const MAX_COST_SHARE: f64 = 0.5;
/// The trials may spend this share of the exact layer's work (counted in pairs; the exact
/// layer on the samples included): what a scene that no approximation suits loses.
pub const ESTIMATE_BUDGET: f64 = 0.15;
/// Scenes of fewer pixel-light pairs are rendered exactly, unestimated (a 128 x 128
/// sphere against a 64 x 128 map has 1.1e8).
pub const MIN_PAIRS: f64 = 2e8;
/// A table's miss at a finer size above this share of its last miss: no finer size tried.
const FLOOR: f64 = 0.75;
/// The first table resolution tried.
const FIRST_TABLE: usize = 32;
/// The cost of interpolating one pixel from a table (its stencil's nodes), in pair
/// evaluations: four nodes to a pair.
const INTERP_PAIRS: f64 = STENCIL as f64 / 4.0;
/// The cost of a pair in the normals' Jacobian (a table's dLoss/dn) on its own (the
/// trials' pass), in forward pair evaluations.
const JACOBIAN_PAIR: f64 = 2.0;
/// The same in the nodes' backward pass, which sums the Jacobian from its own lobe terms
/// (measured on the 512 sphere under studio at table256: 0.2 forward passes of the nodes
/// for random-1 and 0.6 to 1.3 for the three presets).
const FUSED_JACOBIAN_PAIR: f64 = 1.3;
/// The cost of a pair in the backward pass, in forward pair evaluations.
const BACKWARD_PAIR: f64 = 3.0;

/// With `MATEDIT_LOD_TRACE` set, each trial's method, estimate and time go to stderr.
fn trace(what: &str, start: std::time::Instant) {
    if std::env::var_os("MATEDIT_LOD_TRACE").is_some() {
        eprintln!("lod: {:8.1} ms {what}", start.elapsed().as_secs_f64() * 1e3);
    }
}

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

    /// The largest of the estimated errors, each times its safety factor: what must be
    /// within the tolerance.
    pub fn scaled(&self, chooser: &Chooser) -> f64 {
        let pixels = self.d_normals.unwrap_or(0.0).max(self.image) * chooser.safety;
        let sums = self.d_env.unwrap_or(0.0).max(self.d_ctrl.unwrap_or(0.0)) * chooser.safety_sums;
        pixels.max(sums)
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
    /// How many candidates the estimate judged (0: none, the scene too small).
    pub trials: usize,
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
    /// The safety factor of the estimates on sampled pixels ([`SAFETY`]).
    pub safety: f64,
    /// The safety factor of the estimates on sampled texels ([`SAFETY_SUMS`]).
    pub safety_sums: f64,
}

impl Default for Chooser {
    fn default() -> Self {
        Chooser {
            min_pairs: MIN_PAIRS,
            safety: SAFETY,
            safety_sums: SAFETY_SUMS,
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

    /// The estimate the choice makes of `method` on `scene`, with every output judged
    /// (the choice stops at the first that misses): to measure the estimate against the
    /// errors it stands for (examples/lod_estimates.rs). As in the choice, a method without
    /// a table is judged on its image alone (with an upstream gradient its dLoss/dn is
    /// infinite: the choice takes tables only then).
    pub fn estimate(
        &self,
        backend: &dyn Backend,
        scene: &Scene,
        method: &Method,
        upstream: Option<&Image>,
    ) -> Result<Estimate> {
        method.validate(scene)?;
        let prep = Prepared::new(scene);
        let trial = Trial::new(backend, scene, &prep, upstream)?;
        trial.estimate(method, f64::INFINITY, self)
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
    /// For the tables, which cost a stencil of nodes per sampled pixel: a part of the sample.
    tables: Truth,
    /// For dLoss/dL and dLoss/dctrl (with an upstream gradient): every pixel, but a
    /// sample of the texels. These are sums over pixels whose errors cancel between
    /// neighbours (a texel's horizon is a kink that a table's errors straddle with both
    /// signs), so a sample of pixels would overstate them; the layer is linear in L, so
    /// dLoss/dL of a texel needs no other texel.
    /// Made when a candidate first gets that far.
    texels: std::cell::OnceCell<TexelTruth>,
    /// Candidates judged so far.
    count: std::cell::Cell<usize>,
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
        // `image`: the exact image on the sample where it is known; `grads`: the exact
        // dLoss/dn on the sample too (per-pixel methods are judged on images alone, so the
        // per-pixel sample never needs it)
        let truth = |positions: &[usize], image: Option<Image>, grads: bool| -> Result<Truth> {
            let sample = compact(full, positions);
            let upstream = upstream.map(|u| Image {
                width: positions.len(),
                height: 1,
                pixels: positions
                    .iter()
                    .map(|&k| u.pixels[full.pixels[k].index])
                    .collect(),
            });
            let image = match image {
                Some(i) => i,
                None => Plan::new(backend, &sample, &scene.env, &Method::EXACT, &full.pixels)?
                    .forward(backend)?,
            };
            // dLoss/dn from the exact Jacobians dI/dn (a forward pass in parallel chunks,
            // where a backward pass of so few pixels is one chunk on one thread);
            // dLoss/dL and dLoss/dctrl are judged on the texels' trial
            let grads = match &upstream {
                Some(u) if grads => {
                    let jac = backend
                        .normal_jacobians(std::slice::from_ref(&sample), None)?
                        .remove(0)
                        .0;
                    let mut g = Gradients::zeros(0, sample.pixels.len());
                    for (px, j) in sample.pixels.iter().zip(jac) {
                        let up = u.pixels[px.index];
                        g.d_normals[px.index] =
                            std::array::from_fn(|a| (0..3).map(|c| up[c] * j[c][a]).sum());
                    }
                    Some(g)
                }
                _ => None,
            };
            Ok(Truth {
                sample,
                upstream,
                image,
                grads,
            })
        };
        let positions = sample_positions(full.pixels.len());
        let pixels = truth(&positions, None, false)?;
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
        // a part of the per-pixel sample (whose positions are in order): its exact image
        let table_image = Image {
            width: table_positions.len(),
            height: 1,
            pixels: table_positions
                .iter()
                .map(|k| pixels.image.pixels[positions.binary_search(k).expect("sampled")])
                .collect(),
        };
        let tables = truth(&table_positions, Some(table_image), true)?;
        Ok(Trial {
            backend,
            scene,
            full,
            upstream,
            pixels,
            tables,
            texels: std::cell::OnceCell::new(),
            count: std::cell::Cell::new(0),
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

    /// How many texels the gradients' trial runs on.
    fn texel_count(&self) -> usize {
        let env = &self.scene.env;
        texel_mask(env).iter().filter(|&&m| m).count()
    }

    /// The estimated error of `method`'s image alone, on the per-pixel sample.
    fn image_error(&self, method: &Method) -> Result<f64> {
        self.count.set(self.count.get() + 1);
        let image = self.plan_on(&self.pixels, method)?.forward(self.backend)?;
        Ok(rel(&image.pixels, &self.pixels.image.pixels))
    }

    /// The estimate of `method`; the gradients' only if the image's is within `tol`.
    fn estimate(&self, method: &Method, tol: f64, chooser: &Chooser) -> Result<Estimate> {
        self.count.set(self.count.get() + 1);
        let truth = if method.table.is_some() {
            &self.tables
        } else {
            &self.pixels
        };
        let t = std::time::Instant::now();
        let plan = self.plan_on(truth, method)?;
        trace("  plan", t);
        let image = plan.forward(self.backend)?;
        trace("  image", t);
        let mut e = Estimate {
            image: rel(&image.pixels, &truth.image.pixels),
            pixels: truth.sample.pixels.len(),
            ..Estimate::default()
        };
        if e.scaled(chooser) > tol {
            return Ok(e);
        }
        let Some(up) = self.upstream else {
            return Ok(e);
        };
        let (Some(sample_up), Some(exact)) = (&truth.upstream, &truth.grads) else {
            // a sample without the exact dLoss/dn judges images only
            e.d_normals = Some(f64::INFINITY);
            return Ok(e);
        };
        // the sums' trial is the cheaper once the texels' exact gradients are made (a
        // quarter of the nodes' Jacobians on the sample, on the 512 sphere): first then
        let sums_first = self.texels.get().is_some();
        let sums = |e: &mut Estimate| -> Result<()> {
            let (d_env, d_ctrl) = self.sums_errors(method, up)?;
            (e.d_env, e.d_ctrl) = (Some(d_env), Some(d_ctrl));
            trace("  sums", t);
            Ok(())
        };
        if sums_first {
            sums(&mut e)?;
            if e.scaled(chooser) > tol {
                return Ok(e);
            }
        }
        let g = plan.backward(self.backend, sample_up, NORMALS)?;
        e.d_normals = Some(rel(&g.d_normals, &exact.d_normals));
        trace("  dn", t);
        if !sums_first && e.scaled(chooser) <= tol {
            sums(&mut e)?;
        }
        Ok(e)
    }

    /// The estimated errors of `method`'s dLoss/dL and dLoss/dctrl for upstream `up`, on
    /// every pixel for the sampled texels.
    fn sums_errors(&self, method: &Method, up: &Image) -> Result<(f64, f64)> {
        let env = &self.scene.env;
        let texels = match self.texels.get() {
            Some(t) => t,
            None => {
                let mask = texel_mask(env);
                let full = self.full;
                let t = std::time::Instant::now();
                let exact =
                    Plan::masked(self.backend, full, env, &Method::EXACT, &full.pixels, &mask)?;
                trace("    truth plan", t);
                let grads = exact.backward(self.backend, up, SUMS)?;
                trace("    truth backward", t);
                self.texels.get_or_init(|| TexelTruth { mask, grads })
            }
        };
        let (mask, full) = (&texels.mask, self.full);
        let t = std::time::Instant::now();
        let plan = Plan::masked(self.backend, full, env, method, &full.pixels, mask)?;
        trace("    sums plan", t);
        let g = plan.backward(self.backend, up, SUMS)?;
        trace("    sums backward", t);
        Ok((
            rel_masked(&g.d_env, &texels.grads.d_env, mask),
            rel_ctrl(&g.d_ctrl, &texels.grads.d_ctrl),
        ))
    }

    /// The estimated error of `method`'s dLoss/dL alone (0 without an upstream gradient).
    fn env_error(&self, method: &Method) -> Result<f64> {
        self.count.set(self.count.get() + 1);
        match self.upstream {
            Some(up) => Ok(self.sums_errors(method, up)?.0),
            None => Ok(0.0),
        }
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
            trials: 0,
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
    if backward && !prep.camera.is_orthographic() {
        // no candidate: tables need an orthographic camera, and environment levels are
        // for images
        return done(Method::EXACT, Estimate::default(), 1.0);
    }

    let t0 = std::time::Instant::now();
    let trial = Trial::new(backend, scene, prep, upstream)?;
    trace("exact on the samples", t0);
    let mut texels_charged = false;

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
    let s_pixels = trial.pixels.sample.pixels.len() as f64;
    let s_tables = trial.tables.sample.pixels.len() as f64;
    // less the exact layer on the samples
    let mut budget = exact_cost * ESTIMATE_BUDGET
        - (s_pixels + s_tables * (1.0 + if backward { BACKWARD_PAIR } else { 0.0 })) * lit_total;
    let mut per_pixel: Vec<((usize, usize), f64)> = light_counts
        .iter()
        // blocks give each texel its block's dLoss/dL, shaped by the block's direction:
        // for gradients they were never close (errors of 0.1 and more in the benchmark)
        .filter(|((f, k), _, _)| *f > 1 && !backward && *k < TABLE_ONLY_KEEP)
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
        let t = std::time::Instant::now();
        let e = trial.estimate(&m, tol, chooser)?;
        trace(&format!("{m}: {e:?}"), t);
        light_error.insert((f, k), e.image);
        if e.scaled(chooser) <= tol {
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
        let keeps = if backward {
            KEEPS_FOR_GRADIENTS
        } else {
            KEEPS_FOR_TABLES
        };
        let keep_rank = |k: usize| keeps.iter().position(|&x| x == k);
        table_lights.sort_by_key(|&((f, k), _, _)| (f, keep_rank(k)));
        // blocks give each texel its block's dLoss/dL (see the per-pixel lights): with
        // gradients, tables over the full-resolution map only
        if backward {
            table_lights.retain(|&((f, _), _, _)| f == 1);
        }
        let mut passed_at = None;
        // dLoss/dL's estimated error per (block side, table size): it does not depend on
        // the radiance, so texels kept or not change it only where they are exact
        let mut env_errors: HashMap<(usize, usize), f64> = HashMap::new();
        let node_pair = if backward {
            BACKWARD_PAIR + FUSED_JACOBIAN_PAIR
        } else {
            1.0
        };
        // a table's predicted work over a light of `blocks` blocks and `kept` texels (its
        // nodes counted once per size)
        let counts: std::cell::RefCell<HashMap<usize, (usize, usize)>> = Default::default();
        let footprint = Footprint::new(&prep.pixels);
        let table_cost = |r: usize, blocks: f64, kept: f64| {
            let (nodes, left) = *counts
                .borrow_mut()
                .entry(r)
                .or_insert_with(|| footprint.count(r));
            let cost = nodes as f64 * blocks * node_pair
                + (left as f64 * blocks + n * kept) * pair
                + n * INTERP_PAIRS;
            (cost, nodes)
        };
        // with gradients, dLoss/dL decides most choices. It does not depend on the
        // radiance (texels kept or not; see `env_errors`) and falls as the table grows
        // finer, and blocks of texels only add their own error to it: the finest table
        // within the work allowed is judged on it first, and where it misses no table
        // can pass, so none is tried (the scene is rendered exactly, and the estimate has
        // cost the samples' exact layer and the texels' trial). Only where that trial
        // costs at most a third of what the trials may spend: on small scenes it would
        // leave too little for the others.
        let finest = TABLE_SIZES
            .iter()
            .rev()
            .copied()
            .find(|&r| table_cost(r, n_lit as f64, 0.0).0 < most);
        let texels = trial.texel_count() as f64;
        // the finest table's size and dLoss/dL, once judged
        let mut finest_env: Option<(usize, f64)> = None;
        let first_trial = |r: usize| {
            let (_, nodes) = table_cost(r, n_lit as f64, 0.0);
            (nodes as f64 + n) * texels * BACKWARD_PAIR + n * INTERP_PAIRS
        };
        if let (true, Some(r)) = (backward, finest)
            && first_trial(r) <= budget / 3.0
        {
            let m = method(1, 0, Some(r));
            let t = std::time::Instant::now();
            let e_env = trial.env_error(&m)?;
            trace(&format!("{m}: dLoss/dL {e_env:.2e}"), t);
            budget -= first_trial(r);
            texels_charged = true;
            env_errors.insert((1, r), e_env);
            finest_env = Some((r, e_env));
            if e_env * chooser.safety_sums > tol {
                table_lights.clear();
            }
        }
        for ((f, k), blocks, kept) in table_lights {
            // a light whose coarsest table costs more than the best is not worth its trial
            if table_cost(FIRST_TABLE, blocks, kept).0 >= best.2.min(most) {
                continue;
            }
            let e_light = match light_error.get(&(f, k)) {
                Some(&e) => e,
                // texels kept beside a full-resolution map are the map itself
                None if f == 1 => 0.0,
                None if s_pixels * (blocks + kept) > budget => continue,
                None => {
                    budget -= s_pixels * (blocks + kept);
                    let t = std::time::Instant::now();
                    let e = trial.image_error(&method(f, k, None))?;
                    trace(&format!("{} (image): {e:.2e}", method(f, k, None)), t);
                    light_error.insert((f, k), e);
                    e
                }
            };
            if e_light * chooser.safety > tol / 2.0 {
                continue;
            }
            // after a light's table passed, the next light starts a step below its size
            let first = TABLE_SIZES
                .iter()
                .position(|&r| r >= FIRST_TABLE)
                .unwrap_or(0);
            let mut i = passed_at.map_or(first, |p: usize| p.saturating_sub(1).max(first));
            // the last miss's scaled error with this light
            let mut last_miss: Option<f64> = None;
            while i < TABLE_SIZES.len() {
                let r = TABLE_SIZES[i];
                let (cost, nodes) = table_cost(r, blocks, kept);
                if cost >= best.2.min(most) {
                    trace(
                        &format!("table{r}: cost {:.2} of exact, stop", cost / exact_cost),
                        t0,
                    );
                    break;
                }
                // a size whose dLoss/dL missed with another light misses again; so does
                // a size coarser than the finest table's whose dLoss/dL, at least that
                // table's times the ratio of their spacings, misses (measured here: it
                // grew as the spacing to the power 1.3 to 3.6; a slower growth would only
                // skip a table that could pass)
                let from_finest = finest_env
                    .filter(|&(rf, _)| f == 1 && r < rf)
                    .map(|(rf, e)| e * rf as f64 / r as f64);
                if let Some(e_env) = env_errors.get(&(f, r)).copied().or(from_finest)
                    && e_env * chooser.safety_sums > tol
                {
                    let want = r as f64 * (e_env * chooser.safety_sums / tol).cbrt();
                    trace(
                        &format!("table{r}+keep{k} (f {f}): dLoss/dL missed before"),
                        t0,
                    );
                    i += 1;
                    while i < TABLE_SIZES.len() && (TABLE_SIZES[i] as f64) < want {
                        i += 1;
                    }
                    continue;
                }
                // the image's trial, and the gradients' if the image passes
                let node_work = nodes.min(STENCIL * s_tables as usize) as f64 * blocks;
                let spend = node_work + s_tables * kept;
                // the best's table with other texels kept saves only what the kept texels
                // cost; not worth a trial that costs more (on the 512 sphere with
                // plastic-red, keeping none instead of 16 texels would save 0.2% of the
                // exact layer's work, and its trial cost 4%)
                // the dLoss/dn trial, and the sums' on every pixel for the sampled texels
                // (the table's nodes and the kept texels; the exact side charged once)
                let dn_work = node_work * JACOBIAN_PAIR + s_tables * kept * BACKWARD_PAIR;
                let sums_work = nodes as f64 * texels * BACKWARD_PAIR + n * INTERP_PAIRS;
                let trial_work = spend + if backward { dn_work + sums_work } else { 0.0 };
                if best.0.table == Some(r) && best.0.env_factor == f && best.2 - cost < trial_work {
                    trace(
                        &format!("table{r}+keep{k} (f {f}): saves less than its trial"),
                        t0,
                    );
                    i += 1;
                    continue;
                }
                if spend > budget {
                    trace(
                        &format!(
                            "table{r}: budget {:.3} of exact left, stop",
                            budget / exact_cost
                        ),
                        t0,
                    );
                    break;
                }
                budget -= spend;
                let m = method(f, k, Some(r));
                let t = std::time::Instant::now();
                let e = trial.estimate(&m, tol, chooser)?;
                trace(&format!("{m}: {e:?}"), t);
                if e.d_normals.is_some() {
                    budget -= dn_work;
                }
                if let Some(e_env) = e.d_env {
                    env_errors.insert((f, r), e_env);
                    let first_time = if texels_charged { 0.0 } else { n * texels };
                    texels_charged = true;
                    budget -= sums_work + first_time * BACKWARD_PAIR;
                }
                if e.scaled(chooser) <= tol {
                    best = (m, e, cost);
                    passed_at = Some(i);
                    break;
                }
                // an error that a finer table did not bring down by a quarter is this
                // light's floor (the horizons of bright texels left in the table): the
                // next light, with more texels kept, may pass
                if last_miss.is_some_and(|m| e.scaled(chooser) > FLOOR * m) {
                    trace(&format!("{m}: at its floor, next light"), t0);
                    break;
                }
                last_miss = Some(e.scaled(chooser));
                // the resolution this error asks for, if the table's share falls as h^4
                // (in units of the pixels' safety factor; the interpolation's own rate is
                // h^6, the kinks of texels' horizons left in the table fall slower)
                let (safety, worst) = (chooser.safety, e.scaled(chooser) / chooser.safety);
                let share = (worst - e_light).max(worst / 2.0);
                let room = (tol / safety - e_light).max(tol / safety / 2.0);
                let want = r as f64 * (share / room).powf(0.25);
                i += 1;
                while i < TABLE_SIZES.len() && (TABLE_SIZES[i] as f64) < want {
                    i += 1;
                }
            }
        }
    }
    let (m, e, cost) = best;
    trace(&format!("chose {m}"), t0);
    let chosen = Plan::new(backend, prep, &scene.env, &m, &prep.pixels)?;

    let choice = Choice {
        method: m,
        estimate: e,
        cost: cost / exact_cost,
        tolerance: tol,
        trials: trial.count.get(),
    };
    Ok((choice, chosen))
}
