//! A photo studio: one to four area lights (rectangles or discs, with an optional soft
//! edge) of random size, colour temperature and power over a dark or grey surround.
//!
//! The lights together give several times the surround's power, and each is at least ten
//! times brighter than the surround. The whole map is scaled so that its mean radiance
//! (power over 4 pi) is 1.

use std::f64::consts::PI;

use super::colour::{add, mix, scale, temperature_rgb};
use super::raster::{self, direction, dot, tangents};
use crate::envmap::EnvMap;
use crate::error::{Result, invalid};
use crate::splitmix::SplitMix;

/// The outline of an area light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Outline {
    /// A rectangle of half-widths (u, v) in radians, measured as angles from the centre
    /// along two perpendicular great circles; u is horizontal.
    Rect(f64, f64),
    /// A disc of this angular radius, radians.
    Disc(f64),
}

/// One area light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AreaLight {
    /// Unit direction of its centre.
    pub dir: [f64; 3],
    /// Its outline.
    pub shape: Outline,
    /// Radiance inside, linear RGB.
    pub radiance: [f64; 3],
    /// Width of the soft edge as a fraction of the light's size (0: a hard edge).
    pub softness: f64,
}

impl AreaLight {
    /// How much of the light's radiance reaches direction `w`: 1 inside, 0 outside, a
    /// smooth step across the soft edge.
    pub fn coverage(&self, w: [f64; 3]) -> f64 {
        let c = dot(w, self.dir);
        if c <= 0.0 {
            return 0.0;
        }
        // distance from the centre in units of the light's size: 1 on the outline
        let d = match self.shape {
            Outline::Disc(r) => c.clamp(-1.0, 1.0).acos() / r,
            Outline::Rect(hu, hv) => {
                let (t1, t2) = tangents(self.dir);
                let u = dot(w, t1).atan2(c);
                let v = dot(w, t2).atan2(c);
                (u.abs() / hu).max(v.abs() / hv)
            }
        };
        if self.softness <= 0.0 {
            return if d <= 1.0 { 1.0 } else { 0.0 };
        }
        let (lo, hi) = (1.0 - self.softness, 1.0 + self.softness);
        let x = ((d - lo) / (hi - lo)).clamp(0.0, 1.0);
        1.0 - x * x * (3.0 - 2.0 * x)
    }

    /// Its solid angle (approximate for rectangles: the product of the angular widths
    /// times the centre's cosine term, exact in the small-size limit).
    pub fn solid_angle(&self) -> f64 {
        match self.shape {
            Outline::Disc(r) => 2.0 * PI * (1.0 - r.cos()),
            Outline::Rect(hu, hv) => 4.0 * hu.sin() * hv.sin(),
        }
    }
}

/// A studio: lights over a surround.
#[derive(Clone, Debug, PartialEq)]
pub struct Studio {
    /// The area lights, one to four.
    pub lights: Vec<AreaLight>,
    /// Radiance of the surround above the horizon, linear RGB.
    pub surround: [f64; 3],
    /// Radiance of the floor (below the horizon), linear RGB.
    pub floor: [f64; 3],
}

impl Studio {
    /// A random studio from `rng`.
    pub fn draw(rng: &mut SplitMix) -> Studio {
        let n = 1 + rng.below(4);
        let grey = rng.uniform() < 0.5;
        let level = if grey {
            0.1 + 0.3 * rng.uniform()
        } else {
            0.005 + 0.03 * rng.uniform()
        };
        let surround = [level; 3];
        let floor = scale(surround, 0.4 + 0.6 * rng.uniform());
        // the lights' power is `ratio` times the surround's
        let ratio = 3.0 * (20.0f64 / 3.0).powf(rng.uniform());
        let surround_power = 4.0 * PI * level;
        let mut weights: Vec<f64> = (0..n).map(|_| 0.15 + rng.uniform()).collect();
        weights[0] += 1.0; // a key light
        let total: f64 = weights.iter().sum();
        let mut lights = Vec::with_capacity(n);
        for wgt in weights {
            let elevation = (-10.0 + 75.0 * rng.uniform()).to_radians();
            let azimuth = 2.0 * PI * rng.uniform();
            let size = (4.0 + 21.0 * rng.uniform()).to_radians();
            let shape = if rng.uniform() < 0.6 {
                let aspect = 0.3 + 0.7 * rng.uniform();
                if rng.uniform() < 0.5 {
                    Outline::Rect(size, size * aspect)
                } else {
                    Outline::Rect(size * aspect, size)
                }
            } else {
                Outline::Disc(size)
            };
            let softness = if rng.uniform() < 0.5 {
                0.0
            } else {
                0.3 * rng.uniform()
            };
            let kelvin = 2700.0 + 4800.0 * rng.uniform();
            let mut light = AreaLight {
                dir: direction(elevation, azimuth),
                shape,
                radiance: temperature_rgb(kelvin),
                softness,
            };
            let power = ratio * surround_power * wgt / total;
            let l = (power / light.solid_angle()).max(10.0 * level);
            light.radiance = scale(light.radiance, l);
            lights.push(light);
        }
        Studio {
            lights,
            surround,
            floor,
        }
    }

    /// Radiance in direction `w`, before scaling.
    fn radiance(&self, w: [f64; 3]) -> [f64; 3] {
        // the walls darken a little towards the zenith
        let back = if w[1] >= 0.0 {
            scale(self.surround, 1.0 - 0.3 * w[1])
        } else {
            mix(self.floor, self.surround, (1.0 + w[1] * 4.0).max(0.0))
        };
        self.lights.iter().fold(back, |acc, l| {
            let c = l.coverage(w);
            if c > 0.0 {
                add(acc, scale(l.radiance, c))
            } else {
                acc
            }
        })
    }

    /// Checks the lights and the surround.
    pub fn validate(&self) -> Result<()> {
        if !(1..=4).contains(&self.lights.len()) {
            return Err(invalid!(
                "studio: {} lights; a studio has one to four",
                self.lights.len()
            ));
        }
        let ok = |c: &[f64; 3]| c.iter().all(|v| v.is_finite() && *v >= 0.0);
        if !(ok(&self.surround) && ok(&self.floor) && self.lights.iter().all(|l| ok(&l.radiance))) {
            return Err(invalid!("studio: a radiance is negative or not finite"));
        }
        Ok(())
    }

    /// The map, `height` x `width`, equirect, scaled to a mean radiance of 1.
    pub fn env(&self, height: usize, width: usize) -> Result<EnvMap> {
        raster::check_size(height, width)?;
        self.validate()?;
        let texels = raster::rasterise(height, width, |w| self.radiance(w));
        raster::finish(height, width, raster::normalise(texels, height, width))
    }
}
