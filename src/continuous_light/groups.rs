//! The corrections of one level: pixels grouped by the texel that holds their specular
//! peak, and for each group the texels around it as s x s sub-texel lights (the area
//! light) and as the layer's point lights, whose difference is what the group's pixels
//! gain from the continuous light.

use std::collections::BTreeMap;
use std::f64::consts::PI;

use rayon::prelude::*;

use crate::Backend;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::prepare::{self, PixelRec, PointLight, Prepared};
use crate::scene::{Gradients, Image, Wanted};

/// Largest split of a texel per axis.
pub const MAX_SPLIT: usize = 8;
/// Largest distance, in rows, of a split texel from a pixel's peak texel.
pub const MAX_RADIUS: usize = 8;
/// Lobe widths (the narrowest, see [`lobe_width`]) on either side of a peak that are split.
const WIDTHS: f64 = 3.0;
/// Pixels whose peaks fall in the same CELL x CELL block of texels form one group.
const CELL: usize = 4;
/// Groups (each one scene) per call of the backend.
const CHUNK: usize = 64;

/// The narrowest angular width, in light directions, of the sharpest lobe of a pixel at
/// its peak (h = n): x^m1 = exp(m1 ln cos(a)) ~ exp(-m1 a^2 / 2) has width 1/sqrt(m1) in
/// the half vector's angle a, which turns the light direction by 2 a in the plane of w_p
/// and h and by 2 a cos(theta_d) across it. `None` where no lobe depends on x there.
pub fn lobe_width(ctrl: &[f64; crate::N_PARAMS], cos_d: f64) -> Option<f64> {
    let coef = prepare::coefficients(ctrl, cos_d.clamp(-1.0, 1.0).acos());
    let m = (0..9)
        .filter(|&ks| coef[ks * 2] != 0.0)
        .map(|ks| coef[ks * 2 + 1])
        .fold(0.0f64, f64::max);
    (m > 0.0).then(|| 2.0 * cos_d / m.sqrt())
}

/// The split s of the texels near a pixel's peak at level `q` (a lobe width spans about
/// q sub-texels), and how many rows around the peak are split; `None` for s = 1.
fn split_of(
    env: &EnvMap,
    ctrl: &[f64; crate::N_PARAMS],
    p: &PixelRec,
    q: u32,
    max_split: usize,
) -> Option<Key> {
    let (n, c) = facing(p)?;
    if q == 0 {
        return None;
    }
    let sigma = lobe_width(ctrl, c)?;
    let texel = PI / env.height as f64;
    // a power of two, so that a split and a detail map's factor divide one another
    let split = ((f64::from(q) * texel / sigma).ceil() as usize)
        .clamp(1, max_split)
        .next_power_of_two();
    if split == 1 {
        return None;
    }
    let radius = ((WIDTHS * sigma / texel + 0.5).ceil() as usize).min(MAX_RADIUS);
    let (row, col) = mirror_texel(env, p, n, c);
    Some(Key {
        cell: (row / CELL, col / CELL),
        split,
        radius,
    })
}

/// A pixel's unit normal and cos(theta_d) = n.w_p at its peak (h = n); `None` where the
/// normal faces away from the viewer.
fn facing(p: &PixelRec) -> Option<([f64; 3], f64)> {
    let len = prepare::dot(p.n, p.n).sqrt();
    let n = p.n.map(|v| v / len);
    let c = prepare::dot(n, p.wp);
    (c > 0.0).then_some((n, c))
}

/// The texel (row, column) of a pixel's specular peak, the mirror direction of w_p about
/// its normal; `None` where the normal faces away from the viewer.
pub fn peak_texel(env: &EnvMap, p: &PixelRec) -> Option<(usize, usize)> {
    let (n, c) = facing(p)?;
    Some(mirror_texel(env, p, n, c))
}

/// The texel of the mirror direction 2 c n - w_p.
fn mirror_texel(env: &EnvMap, p: &PixelRec, n: [f64; 3], c: f64) -> (usize, usize) {
    let r = [0, 1, 2].map(|k| 2.0 * c * n[k] - p.wp[k]);
    let theta = r[1].clamp(-1.0, 1.0).acos();
    let phi = r[2].atan2(r[0]).rem_euclid(2.0 * PI);
    let row = ((theta / PI * env.height as f64) as usize).min(env.height - 1);
    let col = ((phi / (2.0 * PI) * env.width as f64) as usize).min(env.width - 1);
    (row, col)
}

/// What a group shares: the cell of texels its peaks are in, the split and the radius.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Key {
    cell: (usize, usize),
    split: usize,
    radius: usize,
}

/// The texels within `radius` rows of the cell (and as many columns' worth of angle in
/// each row; all columns where a row is that close to a pole), lit ones only.
fn neighbourhood(env: &EnvMap, cell: (usize, usize), radius: usize) -> Vec<usize> {
    let (h, w) = (env.height, env.width);
    let (row, col) = (cell.0 * CELL, cell.1 * CELL);
    let mut out = Vec::new();
    for r in row.saturating_sub(radius)..(row + CELL + radius).min(h) {
        // the row's narrowest column, at its edge nearer the pole
        let sin = (r as f64 * PI / h as f64)
            .sin()
            .min(((r + 1) as f64 * PI / h as f64).sin());
        let col_angle = sin * 2.0 * PI / w as f64;
        let half = (radius as f64 * PI / h as f64 / col_angle.max(1e-12)).ceil();
        let cols: Vec<usize> = if 2.0 * half + CELL as f64 >= w as f64 {
            (0..w).collect()
        } else {
            let half = half as usize;
            (0..2 * half + CELL)
                .map(|k| (col + w + k - half) % w)
                .collect()
        };
        for c in cols {
            let t = r * w + c;
            if env.texels[t].iter().any(|&v| v != 0.0) {
                out.push(t);
            }
        }
    }
    out
}

/// One group's texels, and its scene: the texels as s x s sub-texels, then as points of
/// negated radiance, so that the scene's image is what the split adds.
fn group(
    prep: &Prepared,
    env: &EnvMap,
    detail: Option<&EnvMap>,
    key: Key,
    pixels: &[&PixelRec],
) -> Option<(Group, Prepared)> {
    let texels = neighbourhood(env, key.cell, key.radius);
    if texels.is_empty() {
        return None;
    }
    let s = key.split;
    let local: Vec<PixelRec> = pixels
        .iter()
        .enumerate()
        .map(|(k, p)| PixelRec { index: k, ..**p })
        .collect();
    let ss = texels.len() * s * s;
    let (mut area, mut point) = (Vec::with_capacity(ss + texels.len()), Vec::new());
    let mut rho = Vec::with_capacity(ss);
    for (t, &i) in texels.iter().enumerate() {
        let (r, c) = (i / env.width, i % env.width);
        let l = env.texels[i].map(f64::from);
        let shares = detail.map(|d| shares(d, env.height, r, c, s));
        let (w, d_omega) = Convention::Equirect.texel(r, c, env.height, env.width);
        point.push(PointLight {
            index: ss + t,
            w,
            d_omega,
            l: l.map(|v| -v),
        });
        for a in 0..s {
            for b in 0..s {
                let (w, d_omega) =
                    Convention::Equirect.texel(r * s + a, c * s + b, env.height * s, env.width * s);
                let share = shares.as_ref().map_or([1.0; 3], |v| v[a * s + b]);
                rho.push(share.map(|x| x as f32));
                area.push(PointLight {
                    index: (t * s + a) * s + b,
                    w,
                    d_omega,
                    l: [0, 1, 2].map(|k| l[k] * share[k]),
                });
            }
        }
    }
    area.extend(point);
    let scene = Prepared::from_lights(
        local.len(),
        1,
        local,
        1,
        area.len(),
        &area,
        &prep.ctrl,
        prep.camera,
    );
    Some((
        Group {
            pixels: pixels.iter().map(|p| p.index).collect(),
            texels,
            split: s,
            rho,
        },
        scene,
    ))
}

/// One group: its pixels, its texels, and the scene whose image it adds.
struct Group {
    /// Image index of each of the group's pixels (local pixel k is `pixels[k]`).
    pixels: Vec<usize>,
    /// Map index of each split texel (local texel t is `texels[t]`).
    texels: Vec<usize>,
    split: usize,
    /// Per sub-texel (texel-major), its radiance over its texel's, per channel.
    rho: Vec<[f32; 3]>,
}

/// The radiance of texel (r, c)'s s x s sub-texels over the texel's, per channel, from
/// `detail`, a map of F x F texels for each of the `height`-row map's (F a power of two):
/// each sub-texel's solid-angle-weighted mean of the detail texels it covers (s <= F) or
/// of the one it lies in (s > F), over the mean of all F x F. 1 where the texel's mean is
/// 0. The sub-texels' radiances, weighted by their solid angles, average to the texel's.
fn shares(detail: &EnvMap, height: usize, r: usize, c: usize, s: usize) -> Vec<[f64; 3]> {
    let f = detail.height / height;
    let (dh, dw) = (detail.height, detail.width);
    let mean = |rows: std::ops::Range<usize>, cols: std::ops::Range<usize>| {
        let (mut sum, mut weight) = ([0.0f64; 3], 0.0);
        for y in rows {
            let (_, d_omega) = Convention::Equirect.texel(y, 0, dh, dw);
            for x in cols.clone() {
                let v = detail.texels[y * dw + x];
                for k in 0..3 {
                    sum[k] += d_omega * f64::from(v[k]);
                }
                weight += d_omega;
            }
        }
        sum.map(|v| v / weight)
    };
    let whole = mean(r * f..(r + 1) * f, c * f..(c + 1) * f);
    let ratio = |v: [f64; 3]| {
        [0, 1, 2].map(|k| {
            if whole[k] != 0.0 {
                v[k] / whole[k]
            } else {
                1.0
            }
        })
    };
    let mut out = Vec::with_capacity(s * s);
    for a in 0..s {
        for b in 0..s {
            let v = if s <= f {
                let k = f / s;
                let (y, x) = (r * f + a * k, c * f + b * k);
                mean(y..y + k, x..x + k)
            } else {
                let k = s / f;
                let (y, x) = (r * f + a / k, c * f + b / k);
                mean(y..y + 1, x..x + 1)
            };
            out.push(ratio(v));
        }
    }
    out
}

/// What a level adds to the layer on a scene's pixels.
pub struct Corrections {
    groups: Vec<Group>,
    /// Per group, its sub-texels and its texels' negated point lights in one scene.
    scenes: Vec<Prepared>,
}

impl Corrections {
    /// The corrections of level `q` for the pixels of `prep` (whose map is `env`, under
    /// the equirect convention).
    ///
    /// With `detail` (a finer map of the same light, [`check_detail`]), the sub-texels
    /// take their radiance's distribution within a texel from it and are never finer
    /// than its texels, so that the levels converge to the layer under the finer map;
    /// without, each texel's radiance is constant over it (the area light).
    pub fn new(prep: &Prepared, env: &EnvMap, detail: Option<&EnvMap>, q: u32) -> Self {
        // a detail map's texels are the finest the light is known at: splitting them
        // further would make them area lights, which the finer map's layer is not
        let max_split = detail.map_or(MAX_SPLIT, |d| d.height / env.height);
        // each pixel's key on all cores (a spline of the material per pixel), then the
        // groups in the pixels' order
        let keys: Vec<Option<Key>> = prep
            .pixels
            .par_iter()
            .map(|p| split_of(env, &prep.ctrl, p, q, max_split))
            .collect();
        let mut by_key: BTreeMap<Key, Vec<&PixelRec>> = BTreeMap::new();
        for (p, k) in prep.pixels.iter().zip(keys) {
            if let Some(k) = k {
                by_key.entry(k).or_default().push(p);
            }
        }
        let (groups, scenes) = by_key
            .into_par_iter()
            .filter_map(|(key, pixels)| group(prep, env, detail, key, &pixels))
            .unzip();
        Corrections { groups, scenes }
    }

    /// Whether the level changes nothing (every pixel's split is 1).
    pub fn is_empty(&self) -> bool {
        self.groups.is_empty()
    }

    /// Groups, largest split, most texels in a group, most pixels in a group.
    pub fn describe(&self) -> String {
        format!(
            "{} groups, split up to {}, up to {} texels and {} pixels a group",
            self.groups.len(),
            self.groups.iter().map(|g| g.split).max().unwrap_or(1),
            self.groups
                .iter()
                .map(|g| g.texels.len())
                .max()
                .unwrap_or(0),
            self.groups
                .iter()
                .map(|g| g.pixels.len())
                .max()
                .unwrap_or(0)
        )
    }

    /// Pixel-light pairs the corrections evaluate.
    pub fn pairs(&self) -> usize {
        self.scenes
            .iter()
            .map(|s| s.pixels.len() * s.texels.len())
            .sum()
    }

    /// Adds the corrections to `image` (the layer's image of the scene).
    pub fn add_forward(&self, backend: &dyn Backend, image: &mut Image) -> Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        let images: Vec<Image> = self
            .scenes
            .par_chunks(CHUNK)
            .map(|c| backend.render(c.into()))
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .flatten()
            .collect();
        for (g, add) in self.groups.iter().zip(&images) {
            for (k, &i) in g.pixels.iter().enumerate() {
                for ch in 0..3 {
                    image.pixels[i][ch] += add.pixels[k][ch];
                }
            }
        }
        Ok(())
    }

    /// Adds the corrections' gradients for `upstream` to `grads` (the layer's): each
    /// sub-texel's dLoss/dL goes back to its texel, since they share its radiance.
    pub fn add_backward(
        &self,
        backend: &dyn Backend,
        upstream: &Image,
        grads: &mut Gradients,
    ) -> Result<()> {
        if self.is_empty() {
            return Ok(());
        }
        let ups: Vec<Image> = self
            .groups
            .iter()
            .map(|g| {
                let pixels: Vec<[f32; 3]> = g.pixels.iter().map(|&i| upstream.pixels[i]).collect();
                Image {
                    width: pixels.len(),
                    height: 1,
                    pixels,
                }
            })
            .collect();
        let gs: Vec<Gradients> = self
            .scenes
            .par_chunks(CHUNK)
            .zip(ups.par_chunks(CHUNK))
            .map(|(c, u)| backend.backward(c.into(), u, Wanted::ALL))
            .collect::<Result<Vec<_>>>()?
            .into_iter()
            .flatten()
            .collect();
        for (g, add) in self.groups.iter().zip(&gs) {
            for (k, &i) in g.pixels.iter().enumerate() {
                for ax in 0..3 {
                    grads.d_normals[i][ax] += add.d_normals[k][ax];
                }
            }
            // the point lights' radiance is the texel's negated: their dLoss/dL with the
            // sign turned
            let ss = g.split * g.split;
            let (area, point) = add.d_env.split_at(g.texels.len() * ss);
            for (t, &i) in g.texels.iter().enumerate() {
                for ch in 0..3 {
                    let sub: f32 = area[t * ss..(t + 1) * ss]
                        .iter()
                        .zip(&g.rho[t * ss..(t + 1) * ss])
                        .map(|(d, rho)| d[ch] * rho[ch])
                        .sum();
                    grads.d_env[i][ch] += sub - point[t][ch];
                }
            }
            for (d, a) in grads.d_ctrl.iter_mut().zip(&add.d_ctrl) {
                *d += a;
            }
        }
        Ok(())
    }
}

/// Checks that `detail` can refine `env`: the same convention (equirect) and F times its
/// rows and columns, F a power of two from 2 to [`MAX_SPLIT`].
pub fn check_detail(env: &EnvMap, detail: &EnvMap) -> Result<()> {
    let f = detail.height / env.height.max(1);
    let ok = detail.convention == Convention::Equirect
        && (2..=MAX_SPLIT).contains(&f)
        && f.is_power_of_two()
        && detail.height == f * env.height
        && detail.width == f * env.width;
    if ok {
        Ok(())
    } else {
        Err(Error::Invalid(format!(
            "light: a {}x{} detail map does not refine a {}x{} map (it needs 2, 4 or 8 times \
             its rows and columns, equirect)",
            detail.height, detail.width, env.height, env.width
        )))
    }
}
