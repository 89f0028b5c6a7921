//! The table-size search: for orthographic cameras, normal tables of growing resolution
//! over each light whose own error is within half the budget, after the per-pixel
//! methods. Each next resolution is the one the last miss predicts; with an upstream
//! gradient, dLoss/dL (which does not depend on the radiance) rules sizes out before their
//! trials.

use std::collections::HashMap;
use std::time::Instant;

use crate::error::Result;
use crate::prepare::Prepared;

use super::super::{Method, TABLE_SIZES};
use super::cost::{Light, TableCosts, TableTrial};
use super::{Best, Estimate, Search, trace};

/// Kept texels for the tables, in the order tried: for images ...
const KEEPS_FOR_TABLES: [usize; 4] = [16, 64, 256, 0];
/// ... and with gradients, where 64 come first: dI/dn jumps on the horizon of every texel
/// left in the table, which the sampled pixels can miss (docs/lod.md, "Tuned constants").
const KEEPS_FOR_GRADIENTS: [usize; 4] = [64, 16, 256, 0];
/// A finer table that missed by more than this share of its light's last miss is at the
/// light's floor (docs/lod.md, "The estimate, made cheaper"): no finer size tried.
const FLOOR: f64 = 0.75;
/// The first table resolution tried.
const FIRST_TABLE: usize = 32;

/// Tries tables over `lights` (`n_lit` texels lit) for the search `s`, after its per-pixel
/// methods.
pub(super) fn search(
    s: &mut Search,
    prep: &Prepared,
    lights: &[Light],
    n_lit: usize,
) -> Result<()> {
    let backward = s.costs.backward;
    let mut tables = Tables::new(s, prep);
    if backward && tables.finest_misses_env(n_lit)? {
        return Ok(());
    }
    for light in order(lights, backward) {
        tables.light(&light)?;
    }
    Ok(())
}

/// The lights tables are tried over, in order. Full resolution before blocks; with texels
/// kept before without: a bright texel's horizon is a kink in the image as a function of
/// the normal, which a table cannot interpolate, so a table over the rest of the map is
/// usually the cheaper. Blocks give each texel its block's dLoss/dL (see
/// `Search::per_pixel`): with gradients, tables over the full-resolution map only.
fn order(lights: &[Light], backward: bool) -> Vec<Light> {
    let keeps = if backward {
        KEEPS_FOR_GRADIENTS
    } else {
        KEEPS_FOR_TABLES
    };
    let keep_rank = |k: usize| keeps.iter().position(|&x| x == k);
    let mut lights = lights.to_vec();
    lights.sort_by_key(|l| (l.env_factor, keep_rank(l.keep)));
    if backward {
        lights.retain(|l| l.env_factor == 1);
    }
    lights
}

/// The first index of [`TABLE_SIZES`] after `i` whose size is at least `want`.
fn next_size(i: usize, want: f64) -> usize {
    let mut i = i + 1;
    while i < TABLE_SIZES.len() && (TABLE_SIZES[i] as f64) < want {
        i += 1;
    }
    i
}

/// The tables' search: its own state beside the choice's.
struct Tables<'s, 'a> {
    s: &'s mut Search<'a>,
    costs: TableCosts,
    /// Pixels in the per-pixel sample.
    s_pixels: f64,
    /// dLoss/dL's estimated error per (block side, table size): it does not depend on the
    /// radiance, so texels kept or not change it only where they are exact.
    env_errors: HashMap<(usize, usize), f64>,
    /// The finest table's size and dLoss/dL, once judged.
    finest_env: Option<(usize, f64)>,
    /// Where the last light's table passed (an index into [`TABLE_SIZES`]).
    passed_at: Option<usize>,
}

impl<'s, 'a> Tables<'s, 'a> {
    fn new(s: &'s mut Search<'a>, prep: &Prepared) -> Self {
        Tables {
            costs: TableCosts::new(
                s.costs,
                prep,
                s.trial.table_pixel_count() as f64,
                s.trial.texel_count() as f64,
            ),
            s_pixels: s.trial.pixel_count() as f64,
            env_errors: HashMap::new(),
            finest_env: None,
            passed_at: None,
            s,
        }
    }

    /// With gradients, dLoss/dL decides most choices. It does not depend on the radiance
    /// (texels kept or not; see `env_errors`) and falls as the table grows finer, and
    /// blocks of texels only add their own error to it: the finest table within the work
    /// allowed is judged on it first, and where it misses (true) no table can pass, so none
    /// is tried (the scene is rendered exactly, and the estimate has cost the samples'
    /// exact layer and the texels' trial). Only where that trial costs at most a third of
    /// what the trials may spend: on small scenes it would leave too little for the others.
    fn finest_misses_env(&mut self, n_lit: usize) -> Result<bool> {
        let most = self.s.most;
        let costs = &mut self.costs;
        let Some(r) = TABLE_SIZES
            .iter()
            .rev()
            .copied()
            .find(|&r| costs.table(r, n_lit as f64, 0.0).0 < most)
        else {
            return Ok(false);
        };
        let work = self.costs.env_trial(r, n_lit);
        if work <= self.s.budget / 3.0 {
            let m = Method {
                table: Some(r),
                ..Method::EXACT
            };
            let t = Instant::now();
            let e_env = self.s.trial.env_error(&m)?;
            trace(&format!("{m}: dLoss/dL {e_env:.2e}"), t);
            self.s.budget -= work;
            self.s.texels_charged = true;
            self.env_errors.insert((1, r), e_env);
            self.finest_env = Some((r, e_env));
            return Ok(e_env * self.s.chooser.safety_sums > self.s.tol);
        }
        Ok(false)
    }

    /// Tables over `light`, if its coarsest table could be the best and its own error is
    /// within half the budget; after a light's table passed, the next light starts a step
    /// below its size.
    fn light(&mut self, light: &Light) -> Result<()> {
        if self.costs.table(FIRST_TABLE, light.blocks, light.kept).0 >= self.s.limit() {
            return Ok(());
        }
        let Some(e_light) = self.light_error(light)? else {
            return Ok(());
        };
        if e_light * self.s.chooser.safety > self.s.tol / 2.0 {
            return Ok(());
        }
        let first = TABLE_SIZES
            .iter()
            .position(|&r| r >= FIRST_TABLE)
            .unwrap_or(0);
        let start = self
            .passed_at
            .map_or(first, |p| p.saturating_sub(1).max(first));
        self.climb(light, e_light, start)
    }

    /// `light`'s own image error (per pixel, no table), judged once; None where that trial
    /// would overspend.
    fn light_error(&mut self, light: &Light) -> Result<Option<f64>> {
        if let Some(&e) = self.s.light_error.get(&light.key()) {
            return Ok(Some(e));
        }
        // texels kept beside a full-resolution map are the map itself
        if light.env_factor == 1 {
            return Ok(Some(0.0));
        }
        if self.s_pixels * (light.blocks + light.kept) > self.s.budget {
            return Ok(None);
        }
        self.s.budget -= self.s_pixels * (light.blocks + light.kept);
        let m = light.method(None);
        let t = Instant::now();
        let e = self.s.trial.image_error(&m)?;
        trace(&format!("{m} (image): {e:.2e}"), t);
        self.s.light_error.insert(light.key(), e);
        Ok(Some(e))
    }

    /// Tables over `light` (whose own error is `e_light`) from size index `i` on, until one
    /// passes or the light is done.
    fn climb(&mut self, light: &Light, e_light: f64, mut i: usize) -> Result<()> {
        // the last miss's scaled error with this light
        let mut last_miss: Option<f64> = None;
        while i < TABLE_SIZES.len() {
            match self.size(light, e_light, i, &mut last_miss)? {
                Some(next) => i = next,
                None => break,
            }
        }
        Ok(())
    }

    /// The table of size index `i` over `light`: the next size index to try, or None where
    /// the light is done (its table passed, or costs too much, or is at its floor).
    fn size(
        &mut self,
        light: &Light,
        e_light: f64,
        i: usize,
        last_miss: &mut Option<f64>,
    ) -> Result<Option<usize>> {
        let (f, k, r, t0) = (light.env_factor, light.keep, TABLE_SIZES[i], self.s.t0);
        let (cost, nodes) = self.costs.table(r, light.blocks, light.kept);
        if cost >= self.s.limit() {
            let share = cost / self.s.costs.exact;
            trace(&format!("table{r}: cost {share:.2} of exact, stop"), t0);
            return Ok(None);
        }
        if let Some(want) = self.env_miss(f, r) {
            trace(
                &format!("table{r}+keep{k} (f {f}): dLoss/dL missed before"),
                t0,
            );
            return Ok(Some(next_size(i, want)));
        }
        let work = self.costs.trial(nodes, light);
        if self.saves_less_than_trial(f, r, cost, &work) {
            trace(
                &format!("table{r}+keep{k} (f {f}): saves less than its trial"),
                t0,
            );
            return Ok(Some(i + 1));
        }
        if work.image > self.s.budget {
            let left = self.s.budget / self.s.costs.exact;
            trace(
                &format!("table{r}: budget {left:.3} of exact left, stop"),
                t0,
            );
            return Ok(None);
        }
        let m = light.method(Some(r));
        let e = self.judge(&m, &work)?;
        if self.s.passes(&e) {
            self.s.best = Best {
                method: m,
                estimate: e,
                cost,
            };
            self.passed_at = Some(i);
            return Ok(None);
        }
        let scaled = e.scaled(self.s.chooser);
        // an error that a finer table did not bring down by a quarter is this light's
        // floor (the horizons of bright texels left in the table): the next light, with
        // more texels kept, may pass
        if last_miss.is_some_and(|miss| scaled > FLOOR * miss) {
            trace(&format!("{m}: at its floor, next light"), t0);
            return Ok(None);
        }
        *last_miss = Some(scaled);
        Ok(Some(next_size(i, self.wanted(r, scaled, e_light))))
    }

    /// Where dLoss/dL rules the table of size `r` over blocks of side `f` out: the size it
    /// asks for. A size whose dLoss/dL missed with another light misses again; so does a
    /// size coarser than the finest table's whose dLoss/dL, at least that table's times the
    /// ratio of their spacings, misses (measured here: it grew as the spacing to the power
    /// 1.3 to 3.6; a slower growth would only skip a table that could pass).
    fn env_miss(&self, f: usize, r: usize) -> Option<f64> {
        let from_finest = self
            .finest_env
            .filter(|&(rf, _)| f == 1 && r < rf)
            .map(|(rf, e)| e * rf as f64 / r as f64);
        let e_env = self.env_errors.get(&(f, r)).copied().or(from_finest)?;
        let (tol, safety) = (self.s.tol, self.s.chooser.safety_sums);
        (e_env * safety > tol).then(|| r as f64 * (e_env * safety / tol).cbrt())
    }

    /// Whether the best's table (size `r`, blocks of side `f`) with other texels kept, at
    /// `cost`, would save less than its trial: it saves only what the kept texels cost (on
    /// the 512 sphere with plastic-red, keeping none instead of 16 texels would save 0.2%
    /// of the exact layer's work, and its trial cost 4%).
    fn saves_less_than_trial(&self, f: usize, r: usize, cost: f64, work: &TableTrial) -> bool {
        let best = &self.s.best;
        best.method.table == Some(r)
            && best.method.env_factor == f
            && best.cost - cost < work.total(self.s.costs.backward)
    }

    /// The trial of the table method `m`, whose parts cost `work`: the image's, and the
    /// gradients' where the image passes (dLoss/dn on the sample; the sums on every pixel
    /// for the sampled texels, their exact side charged once), each charged as it runs.
    fn judge(&mut self, m: &Method, work: &TableTrial) -> Result<Estimate> {
        self.s.budget -= work.image;
        let e = self.s.estimate(m)?;
        if e.d_normals.is_some() {
            self.s.budget -= work.d_normals;
        }
        if let Some(e_env) = e.d_env {
            let table = m.table.expect("a table");
            self.env_errors.insert((m.env_factor, table), e_env);
            let exact_side = if self.s.texels_charged {
                0.0
            } else {
                self.costs.texels_exact()
            };
            self.s.texels_charged = true;
            self.s.budget -= work.sums + exact_side;
        }
        Ok(e)
    }

    /// The size a miss of `scaled` at size `r` asks for, if the table's share of the error
    /// (the light's own, `e_light`, apart) falls as h^4, in units of the pixels' safety
    /// factor: the interpolation's own rate is h^6, the kinks of texels' horizons left in
    /// the table fall slower.
    fn wanted(&self, r: usize, scaled: f64, e_light: f64) -> f64 {
        let (tol, safety) = (self.s.tol, self.s.chooser.safety);
        let worst = scaled / safety;
        let share = (worst - e_light).max(worst / 2.0);
        let room = (tol / safety - e_light).max(tol / safety / 2.0);
        r as f64 * (share / room).powf(0.25)
    }
}
