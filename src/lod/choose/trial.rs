//! The trials: how a candidate method's error is estimated. The layer runs exactly on a
//! stratified sample of the pixels, and each candidate on the same pixels; a candidate's
//! estimated error is its largest error on the sample relative to the sample's largest
//! exact value. dLoss/dL and dLoss/dctrl, sums over pixels, are judged on every pixel for a
//! sample of the texels.

use crate::Backend;
use crate::envmap::EnvMap;
use crate::error::Result;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Scene, Wanted};

use super::super::Method;
use super::super::plan::Plan;
use super::{Chooser, trace};

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
/// Pixels sampled: 1 in this many ...
const SAMPLE_EVERY: usize = 64;
/// ... at least this many (or all) ...
const SAMPLE_MIN: usize = 256;
/// ... and at most this many.
const SAMPLE_MAX: usize = 2048;
/// About this many texels for the estimates of dLoss/dL and dLoss/dctrl.
const SAMPLE_TEXELS: usize = 128;
/// The tables' sample: every this many of the per-pixel sample, and as many again of the
/// brightest others (a table costs a stencil of nodes per sampled pixel).
const TABLE_SAMPLE_EVERY: usize = 8;

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

/// The tables' part of the per-pixel sample `positions` (whose exact image is `image`):
/// every [`TABLE_SAMPLE_EVERY`]th, and as many again of the brightest others, where a
/// table's error concentrates (the highlights); in order.
fn table_positions(positions: &[usize], image: &Image) -> Vec<usize> {
    let mut table_positions: Vec<usize> = positions
        .iter()
        .copied()
        .step_by(TABLE_SAMPLE_EVERY)
        .collect();
    let mut rest: Vec<(f32, usize)> = positions
        .iter()
        .enumerate()
        .filter(|(j, _)| j % TABLE_SAMPLE_EVERY != 0)
        .map(|(j, &k)| {
            let v = image.pixels[j];
            (v[0].max(v[1]).max(v[2]), k)
        })
        .collect();
    rest.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
    let brightest = table_positions.len();
    table_positions.extend(rest.iter().take(brightest).map(|&(_, k)| k));
    table_positions.sort_unstable();
    table_positions
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
pub(super) struct Trial<'a> {
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
    /// The samples of `full` (the scene's pixels) and the exact layer's results on them.
    pub(super) fn new(
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
        let table_positions = table_positions(&positions, &pixels.image);
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

    /// Pixels in the per-pixel methods' sample.
    pub(super) fn pixel_count(&self) -> usize {
        self.pixels.sample.pixels.len()
    }

    /// Pixels in the tables' sample.
    pub(super) fn table_pixel_count(&self) -> usize {
        self.tables.sample.pixels.len()
    }

    /// How many texels the gradients' trial runs on.
    pub(super) fn texel_count(&self) -> usize {
        let env = &self.scene.env;
        texel_mask(env).iter().filter(|&&m| m).count()
    }

    /// Candidates judged so far.
    pub(super) fn count(&self) -> usize {
        self.count.get()
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
    pub(super) fn image_error(&self, method: &Method) -> Result<f64> {
        self.count.set(self.count.get() + 1);
        let image = self.plan_on(&self.pixels, method)?.forward(self.backend)?;
        Ok(rel(&image.pixels, &self.pixels.image.pixels))
    }

    /// The estimate of `method`; the gradients' only if the image's is within `tol`.
    pub(super) fn estimate(
        &self,
        method: &Method,
        tol: f64,
        chooser: &Chooser,
    ) -> Result<Estimate> {
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
    pub(super) fn env_error(&self, method: &Method) -> Result<f64> {
        self.count.set(self.count.get() + 1);
        match self.upstream {
            Some(up) => Ok(self.sums_errors(method, up)?.0),
            None => Ok(0.0),
        }
    }
}
