//! Floor textures: albedo as a function of the floor's own coordinates (x, z), in the
//! object's units (the placed object's bounding sphere has radius 1). Procedural ones
//! (`wood`, `tiles`, `cloth`) are drawn per sample from the sample's generator: colours
//! within plausible ranges, a random scale and in-plane rotation; image textures (a folder
//! of photos of surfaces) are tiled at a random scale and rotation.
//!
//! Each texture knows its mean albedo and the size of its finest detail, so that the floor
//! fades a texture to its mean where a pixel's footprint is larger than that detail (far
//! towards the horizon), instead of aliasing.

use std::f64::consts::TAU;
use std::sync::Arc;

use serde_json::{Value, json};

use crate::splitmix::SplitMix;

/// The procedural kinds, as the spec names them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kind {
    /// Planks with grain, staggered, a dark gap between them.
    Wood,
    /// A grid of tiles with grout, each tile's colour jittered.
    Tiles,
    /// A plain weave of two thread colours, sometimes a plaid.
    Cloth,
}

impl Kind {
    /// The kinds by name.
    pub const ALL: [(&'static str, Kind); 3] = [
        ("wood", Kind::Wood),
        ("tiles", Kind::Tiles),
        ("cloth", Kind::Cloth),
    ];

    /// `wood`, `tiles` or `cloth`.
    pub fn parse(s: &str) -> Option<Kind> {
        Kind::ALL.iter().find(|(n, _)| *n == s).map(|(_, k)| *k)
    }

    fn name(self) -> &'static str {
        Kind::ALL
            .iter()
            .find(|(_, k)| *k == self)
            .map_or("", |(n, _)| n)
    }
}

/// An image tiled over the floor: linear RGB albedo.
#[derive(Clone, Debug)]
pub struct TileImage {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Albedo, rows first, clamped to [0, 0.9].
    pub pixels: Vec<[f32; 3]>,
}

/// A floor texture drawn for one sample.
#[derive(Clone, Debug)]
pub struct Texture {
    pattern: Pattern,
    /// Rotation in the plane (cos, sin) and offset.
    cos: f64,
    sin: f64,
    offset: [f64; 2],
    /// The size of a pattern unit (plank width, tile, thread, image tile).
    scale: f64,
    /// Per-texture seed of the noise.
    seed: u64,
    mean: [f32; 3],
}

#[derive(Clone, Debug)]
enum Pattern {
    Wood {
        base: [f64; 3],
        plank_length: f64,
        rings: f64,
    },
    Tiles {
        tile: [f64; 3],
        other: Option<[f64; 3]>,
        grout: [f64; 3],
        grout_width: f64,
    },
    Cloth {
        warp: [f64; 3],
        weft: [f64; 3],
        plaid: Option<([f64; 3], usize)>,
    },
    Image(Arc<TileImage>),
}

fn between(rng: &mut SplitMix, lo: f64, hi: f64) -> f64 {
    lo + (hi - lo) * rng.uniform()
}

/// A hash of a lattice point to [0, 1).
fn hash(i: i64, j: i64, seed: u64) -> f64 {
    let mut r = SplitMix(
        seed ^ (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15) ^ (j as u64).rotate_left(32),
    );
    r.uniform()
}

/// Value noise in [0, 1): smoothstep between lattice hashes.
fn noise(x: f64, y: f64, seed: u64) -> f64 {
    let (i, j) = (x.floor(), y.floor());
    let (fx, fy) = (x - i, y - j);
    let (sx, sy) = (fx * fx * (3.0 - 2.0 * fx), fy * fy * (3.0 - 2.0 * fy));
    let (i, j) = (i as i64, j as i64);
    let a = hash(i, j, seed) + sx * (hash(i + 1, j, seed) - hash(i, j, seed));
    let b = hash(i, j + 1, seed) + sx * (hash(i + 1, j + 1, seed) - hash(i, j + 1, seed));
    a + sy * (b - a)
}

/// A random colour: a hue family picked from `families` of (lo, hi) RGB bounds.
fn colour(rng: &mut SplitMix, families: &[([f64; 3], [f64; 3])]) -> [f64; 3] {
    let (lo, hi) = families[rng.below(families.len())];
    let t = rng.uniform();
    let jitter = [rng.uniform(), rng.uniform(), rng.uniform()];
    [0, 1, 2].map(|c| lo[c] + (hi[c] - lo[c]) * (0.7 * t + 0.3 * jitter[c]))
}

impl Texture {
    /// A procedural texture of `kind` drawn from `rng`, and what the sample records of it.
    pub fn procedural(kind: Kind, rng: &mut SplitMix) -> (Texture, Value) {
        let (pattern, scale) = match kind {
            Kind::Wood => {
                let r = between(rng, 0.22, 0.6);
                let g = r * between(rng, 0.5, 0.72);
                let b = g * between(rng, 0.4, 0.75);
                let pattern = Pattern::Wood {
                    base: [r, g, b],
                    plank_length: between(rng, 4.0, 10.0),
                    rings: between(rng, 2.0, 6.0),
                };
                (pattern, between(rng, 0.15, 0.45))
            }
            Kind::Tiles => {
                let families = [
                    ([0.55, 0.55, 0.52], [0.85, 0.85, 0.8]),  // white and cream
                    ([0.35, 0.12, 0.06], [0.6, 0.3, 0.15]),   // terracotta
                    ([0.12, 0.12, 0.12], [0.45, 0.45, 0.45]), // greys
                    ([0.05, 0.15, 0.18], [0.25, 0.45, 0.5]),  // blue-green
                ];
                let tile = colour(rng, &families);
                let other = (rng.uniform() < 0.3).then(|| colour(rng, &families));
                let grey = between(rng, 0.15, 0.7);
                let pattern = Pattern::Tiles {
                    tile,
                    other,
                    grout: [grey, grey * 0.97, grey * 0.92],
                    grout_width: between(rng, 0.02, 0.07),
                };
                (pattern, between(rng, 0.3, 1.0))
            }
            Kind::Cloth => {
                let families = [
                    ([0.05, 0.05, 0.15], [0.2, 0.25, 0.6]),   // blues
                    ([0.3, 0.03, 0.03], [0.7, 0.15, 0.1]),    // reds
                    ([0.4, 0.35, 0.25], [0.8, 0.75, 0.6]),    // linen
                    ([0.05, 0.15, 0.05], [0.2, 0.45, 0.2]),   // greens
                    ([0.03, 0.03, 0.03], [0.25, 0.25, 0.25]), // dark
                ];
                let warp = colour(rng, &families);
                let weft = if rng.uniform() < 0.5 {
                    warp.map(|c| c * between(rng, 0.7, 1.0))
                } else {
                    colour(rng, &families)
                };
                let plaid =
                    (rng.uniform() < 0.35).then(|| (colour(rng, &families), 4 + rng.below(12)));
                let pattern = Pattern::Cloth { warp, weft, plaid };
                (pattern, between(rng, 0.012, 0.04))
            }
        };
        let record = json!({ "procedural": kind.name(), "scale": scale });
        Texture::finish(pattern, scale, rng, record)
    }

    /// `image` tiled with a tile `between(0.6, 2.5)` object units wide, drawn from `rng`.
    pub fn image(image: Arc<TileImage>, label: &str, rng: &mut SplitMix) -> (Texture, Value) {
        let scale = between(rng, 0.6, 2.5);
        let record = json!({ "file": label, "scale": scale });
        Texture::finish(Pattern::Image(image), scale, rng, record)
    }

    fn finish(pattern: Pattern, scale: f64, rng: &mut SplitMix, record: Value) -> (Texture, Value) {
        let angle = TAU * rng.uniform();
        let offset = [between(rng, 0.0, 100.0), between(rng, 0.0, 100.0)];
        let seed = rng.next_u64();
        let mut t = Texture {
            pattern,
            cos: angle.cos(),
            sin: angle.sin(),
            offset,
            scale,
            seed,
            mean: [0.0; 3],
        };
        // the mean of a fixed grid of points over many pattern units
        let mut sum = [0.0f64; 3];
        let n = 48;
        for i in 0..n {
            for j in 0..n {
                let a = t.albedo_exact(i as f64 * 0.37 * scale, j as f64 * 0.41 * scale);
                for c in 0..3 {
                    sum[c] += f64::from(a[c]);
                }
            }
        }
        t.mean = sum.map(|s| (s / (n * n) as f64) as f32);
        let mut record = record;
        if let Value::Object(o) = &mut record {
            o.insert("rotation_degrees".into(), json!(angle.to_degrees()));
        }
        (t, record)
    }

    /// The texture's mean albedo.
    pub fn mean(&self) -> [f32; 3] {
        self.mean
    }

    /// The albedo at floor point (x, z) seen by a pixel whose footprint there is
    /// `footprint` units wide: the pattern, faded to its mean as the footprint grows past
    /// the pattern's finest detail.
    pub fn albedo(&self, x: f64, z: f64, footprint: f64) -> [f32; 3] {
        let detail = match self.pattern {
            Pattern::Cloth { .. } => self.scale,
            Pattern::Image(ref im) => self.scale / im.width.max(1) as f64 * 2.0,
            _ => self.scale * 0.06,
        };
        let fade = ((footprint / detail - 1.0) / 3.0).clamp(0.0, 1.0) as f32;
        if fade >= 1.0 {
            return self.mean;
        }
        let a = self.albedo_exact(x, z);
        [0, 1, 2].map(|c| a[c] + fade * (self.mean[c] - a[c]))
    }

    fn albedo_exact(&self, x: f64, z: f64) -> [f32; 3] {
        let u = (self.cos * x - self.sin * z) / self.scale + self.offset[0];
        let v = (self.sin * x + self.cos * z) / self.scale + self.offset[1];
        let c = match &self.pattern {
            Pattern::Wood {
                base,
                plank_length,
                rings,
            } => {
                // planks across v, staggered along u
                let j = v.floor();
                let stagger = hash(j as i64, 7, self.seed) * plank_length;
                let along = (u + stagger) / plank_length;
                let i = along.floor();
                let tone = 0.8 + 0.4 * hash(i as i64, j as i64, self.seed);
                let (fu, fv) = (along - i, v - j);
                let wobble = 1.5 * noise(u * 0.8, v * 3.0, self.seed ^ 1);
                let grain = (TAU * (fv * rings + wobble)).sin();
                let streak = noise(u * 2.0, v * 40.0, self.seed ^ 2);
                let k = tone * (0.85 + 0.12 * grain - 0.15 * streak);
                let gap = fv.min(1.0 - fv) < 0.03 || fu.min(1.0 - fu) * plank_length < 0.03;
                let k = if gap { k * 0.35 } else { k };
                base.map(|b| b * k)
            }
            Pattern::Tiles {
                tile,
                other,
                grout,
                grout_width,
            } => {
                let (i, j) = (u.floor(), v.floor());
                let (fu, fv) = (u - i, v - j);
                if fu.min(1.0 - fu).min(fv.min(1.0 - fv)) < grout_width / 2.0 {
                    *grout
                } else {
                    let (i, j) = (i as i64, j as i64);
                    let base = match other {
                        Some(o) if (i + j).rem_euclid(2) == 1 => o,
                        _ => tile,
                    };
                    let mottle = 0.93 + 0.1 * noise(u * 6.0, v * 6.0, self.seed ^ 3);
                    [0, 1, 2].map(|c| {
                        let jitter = 0.88 + 0.24 * hash(i, j, self.seed ^ (c as u64 + 10));
                        base[c] * jitter * mottle
                    })
                }
            }
            Pattern::Cloth { warp, weft, plaid } => {
                let (i, j) = (u.floor(), v.floor());
                let (fu, fv) = (u - i, v - j);
                let over = (i as i64 + j as i64).rem_euclid(2) == 0;
                let warp = match plaid {
                    Some((p, band)) if (i as i64).div_euclid(*band as i64) % 2 == 0 => p,
                    _ => warp,
                };
                let weft = match plaid {
                    Some((p, band)) if (j as i64).div_euclid(*band as i64) % 2 == 0 => p,
                    _ => weft,
                };
                // a thread is brightest along its middle
                let (thread, across) = if over { (warp, fu) } else { (weft, fv) };
                let shade = 0.55 + 0.45 * (std::f64::consts::PI * across).sin().sqrt();
                let fold = 0.85 + 0.3 * noise(u * 0.05, v * 0.05, self.seed ^ 4);
                thread.map(|t| t * shade * fold)
            }
            Pattern::Image(im) => {
                let x = u.rem_euclid(1.0) * im.width as f64;
                let y = v.rem_euclid(1.0) * im.width as f64 % im.height as f64;
                return wrap_bilinear(im, x - 0.5, y - 0.5);
            }
        };
        c.map(|v| v.clamp(0.0, 0.9) as f32)
    }
}

fn wrap_bilinear(im: &TileImage, x: f64, y: f64) -> [f32; 3] {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
    let at = |i: f64, j: f64| {
        let c = (i as i64).rem_euclid(im.width as i64) as usize;
        let r = (j as i64).rem_euclid(im.height as i64) as usize;
        im.pixels[r * im.width + c]
    };
    let (a, b) = (at(x0, y0), at(x0 + 1.0, y0));
    let (c, d) = (at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0));
    [0, 1, 2].map(|k| {
        let top = a[k] + fx * (b[k] - a[k]);
        let bottom = c[k] + fx * (d[k] - c[k]);
        top + fy * (bottom - top)
    })
}

impl TileImage {
    /// An image as floor albedo: box-filtered to at most 256 pixels on its shorter side,
    /// clamped to [0, 0.9].
    pub fn new(image: crate::scene::Image) -> TileImage {
        let f = (image.width.min(image.height) / 256).max(1);
        let (w, h) = (image.width / f, image.height / f);
        let norm = 1.0 / (f * f) as f32;
        let pixels = crate::raster::reduce((image.width, image.height), (f, f), (w, h), |block| {
            let mut s = [0.0f32; 3];
            for i in block {
                for k in 0..3 {
                    s[k] += image.pixels[i][k];
                }
            }
            s.map(|v| (v * norm).clamp(0.0, 0.9))
        });
        TileImage {
            width: w,
            height: h,
            pixels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn textures_are_albedos_and_deterministic() {
        for (_, kind) in Kind::ALL {
            for seed in 0..20 {
                let (a, ra) = Texture::procedural(kind, &mut SplitMix(seed));
                let (b, rb) = Texture::procedural(kind, &mut SplitMix(seed));
                assert_eq!(ra, rb);
                let mut distinct = std::collections::BTreeSet::new();
                for i in 0..200 {
                    let (x, z) = (i as f64 * 0.013, (i * 7 % 13) as f64 * 0.05);
                    let v = a.albedo(x, z, 0.001);
                    assert_eq!(v, b.albedo(x, z, 0.001));
                    assert!(v.iter().all(|c| (0.0..=0.9).contains(c)), "{kind:?}: {v:?}");
                    distinct.insert(v.map(f32::to_bits));
                }
                assert!(distinct.len() > 10, "{kind:?} {seed}: a flat texture");
                // far away: the mean
                assert_eq!(a.albedo(1.0, 2.0, 100.0), a.mean());
            }
        }
    }
}
