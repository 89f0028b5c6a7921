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
//!
//! Here the choice itself and the per-pixel candidates; the trials in `trial`, the cost
//! model in `cost`, the tables' search in `tables`.

mod cost;
mod tables;
mod trial;

use std::collections::HashMap;
use std::time::Instant;

use crate::Backend;
use crate::error::{Error, Result};
use crate::prepare::Prepared;
use crate::scene::{Image, Scene};

use super::Method;
use super::plan::Plan;
use cost::{Costs, Light};
pub use trial::Estimate;
use trial::Trial;

/// Safety factor of the image's and dLoss/dn's estimates (sampled pixels): 3 covers the
/// median miss of the pixels left out, not the worst (docs/lod.md, "Tuned constants").
pub const SAFETY: f64 = 3.0;
/// The same for dLoss/dL and dLoss/dctrl (every pixel, sampled texels): 3 covers the
/// largest miss measured (docs/lod.md, "Tuned constants").
pub const SAFETY_SUMS: f64 = 3.0;
/// An approximation is taken only below this share of the exact layer's predicted work:
/// what it saves must be worth its estimate (docs/lod.md, "How the choice is made").
const MAX_COST_SHARE: f64 = 0.5;
/// The trials' share of the exact layer's work (pairs; the samples' exact layer included):
/// what a scene no approximation suits loses (docs/lod.md, "The estimate, made cheaper").
pub const ESTIMATE_BUDGET: f64 = 0.15;
/// Scenes of fewer pixel-light pairs are rendered exactly, unestimated: the estimate would
/// cost more than it saves (docs/lod.md, "How the choice is made").
pub const MIN_PAIRS: f64 = 2e8;
/// So many kept texels are tried with tables only (per pixel they cost too much).
const TABLE_ONLY_KEEP: usize = 256;

/// With `MATEDIT_LOD_TRACE` set, each trial's method, estimate and time go to stderr.
fn trace(what: &str, start: Instant) {
    if std::env::var_os("MATEDIT_LOD_TRACE").is_some() {
        eprintln!("lod: {:8.1} ms {what}", start.elapsed().as_secs_f64() * 1e3);
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
    /// errors it stands for (xtask/src/bin/lod_estimates.rs). As in the choice, a method without
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
    let costs = Costs::new(prep, upstream.is_some());
    let (method, estimate, cost, trials) = if !worth_estimating(chooser, prep, &costs) {
        (Method::EXACT, Estimate::default(), 1.0, 0)
    } else {
        let t0 = Instant::now();
        let trial = Trial::new(backend, scene, prep, upstream)?;
        trace("exact on the samples", t0);
        let mut search = Search::new(chooser, trial, tol, costs, t0);
        let (lights, n_lit) = cost::lights(&scene.env);
        search.per_pixel(&lights)?;
        if prep.camera.is_orthographic() {
            tables::search(&mut search, prep, &lights, n_lit)?;
        }
        let Best {
            method,
            estimate,
            cost,
        } = search.best;
        trace(&format!("chose {method}"), t0);
        (method, estimate, cost / costs.exact, search.trial.count())
    };
    let plan = Plan::new(backend, prep, &scene.env, &method, &prep.pixels)?;
    let choice = Choice {
        method,
        estimate,
        cost,
        tolerance: tol,
        trials,
    };
    Ok((choice, plan))
}

/// Whether the scene has candidates and enough work that estimating them can pay.
fn worth_estimating(chooser: &Chooser, prep: &Prepared, costs: &Costs) -> bool {
    if costs.n * costs.lit_total < chooser.min_pairs.max(f64::MIN_POSITIVE) {
        // the estimate would cost more than it could save
        return false;
    }
    // with gradients and no orthographic camera, no candidate: tables need one, and
    // environment levels are for images
    !costs.backward || prep.camera.is_orthographic()
}

/// The best method found so far.
struct Best {
    method: Method,
    estimate: Estimate,
    /// Its predicted work.
    cost: f64,
}

/// The search's state: the trials, what they may still spend, and the best method so far.
struct Search<'a> {
    chooser: &'a Chooser,
    trial: Trial<'a>,
    tol: f64,
    costs: Costs,
    /// An approximation must save at least half the work to be worth its estimate.
    most: f64,
    /// What the trials may still spend, in forward pair evaluations.
    budget: f64,
    best: Best,
    /// Each light's own image error (per pixel, no table), once judged.
    light_error: HashMap<(usize, usize), f64>,
    /// Whether the texels' exact gradients (the sums' trials) are charged to the budget.
    texels_charged: bool,
    /// When the choice began (the trace's clock).
    t0: Instant,
}

impl<'a> Search<'a> {
    fn new(chooser: &'a Chooser, trial: Trial<'a>, tol: f64, costs: Costs, t0: Instant) -> Self {
        let (s_pixels, s_tables) = (trial.pixel_count() as f64, trial.table_pixel_count() as f64);
        // what the trials may spend, less the exact layer on the samples
        let budget = costs.exact * ESTIMATE_BUDGET - costs.samples_exact(s_pixels, s_tables);
        Search {
            chooser,
            trial,
            tol,
            costs,
            most: costs.exact * MAX_COST_SHARE,
            budget,
            best: Best {
                method: Method::EXACT,
                estimate: Estimate::default(),
                cost: costs.exact,
            },
            light_error: HashMap::new(),
            texels_charged: false,
            t0,
        }
    }

    /// What a candidate must cost less than: the best so far, and [`MAX_COST_SHARE`].
    fn limit(&self) -> f64 {
        self.best.cost.min(self.most)
    }

    /// Whether an estimate, times its safety factors, is within the tolerance.
    fn passes(&self, e: &Estimate) -> bool {
        e.scaled(self.chooser) <= self.tol
    }

    /// The trial of `m`, traced.
    fn estimate(&self, m: &Method) -> Result<Estimate> {
        let t = Instant::now();
        let e = self.trial.estimate(m, self.tol, self.chooser)?;
        trace(&format!("{m}: {e:?}"), t);
        Ok(e)
    }

    /// Environment levels evaluated per pixel (images only), cheapest first, while
    /// cheaper than the best: the first that passes is the best.
    fn per_pixel(&mut self, lights: &[Light]) -> Result<()> {
        let mut candidates: Vec<(Light, f64)> = lights
            .iter()
            // blocks give each texel its block's dLoss/dL, shaped by the block's direction:
            // for gradients they were never close (errors of 0.1 and more in the benchmark)
            .filter(|l| l.env_factor > 1 && !self.costs.backward && l.keep < TABLE_ONLY_KEEP)
            .map(|&l| (l, self.costs.per_pixel(&l)))
            .collect();
        candidates.sort_by(|a, b| a.1.total_cmp(&b.1));
        let s_pixels = self.trial.pixel_count() as f64;
        for (light, cost) in candidates {
            if cost >= self.limit() {
                break;
            }
            let spend = self.costs.per_pixel_trial(cost, s_pixels);
            if spend > self.budget {
                continue;
            }
            self.budget -= spend;
            let method = light.method(None);
            let estimate = self.estimate(&method)?;
            self.light_error.insert(light.key(), estimate.image);
            if self.passes(&estimate) {
                self.best = Best {
                    method,
                    estimate,
                    cost,
                };
                break;
            }
        }
        Ok(())
    }
}
