//! A room seen from inside: a box with a window on one wall that shows a clear sky (and
//! lets the sun in when it faces it), lit walls, floor and ceiling, and optionally a
//! ceiling lamp.
//!
//! Each surface is Lambertian, its radiance albedo / pi times the irradiance it gets: from
//! the window (a polygon of the sky's mean radiance, by Lambert's formula for polygonal
//! sources, so walls brighten towards the window), from the sun through the window (the
//! sun patch), from the lamp (a small downward-facing disc) and an ambient term for the
//! bounces (albedo times the light let in, spread over the room's area, over 1 - albedo).
//! The map is scaled so that its mean radiance (power over 4 pi) is 1.

use std::f64::consts::PI;

use super::colour::{add, luminance, mix, mul, scale, temperature_rgb};
use super::raster::{self, cross, direction, dot, normalize};
use super::sky::{Model, SunSky};
use crate::envmap::EnvMap;
use crate::error::{Result, invalid};
use crate::splitmix::SplitMix;

/// A room: a box around the viewer (at the origin), in metres.
#[derive(Clone, Debug, PartialEq)]
pub struct Indoor {
    /// The box's lower corner (x, y, z); y is the floor, below the viewer.
    pub min: [f64; 3],
    /// The box's upper corner; y is the ceiling.
    pub max: [f64; 3],
    /// Which wall holds the window: 0: x = max, 1: x = min, 2: z = max, 3: z = min.
    pub window_wall: usize,
    /// The window along its wall: (centre, half-width) in the wall's horizontal
    /// coordinate (z for x walls, x for z walls), and (bottom, top) heights in y.
    pub window: ((f64, f64), (f64, f64)),
    /// The sky outside.
    pub sky: SunSky,
    /// Albedo of walls, floor and ceiling, linear RGB.
    pub albedo: [[f64; 3]; 3],
    /// A ceiling lamp straight above the viewer: (radius in metres, radiance RGB).
    pub lamp: Option<(f64, [f64; 3])>,
}

/// A surface hit: which (0..4 walls as in `window_wall`, 4 ceiling, 5 floor) and where.
fn hit(min: [f64; 3], max: [f64; 3], w: [f64; 3]) -> (usize, [f64; 3]) {
    let mut best = (f64::INFINITY, 0);
    let planes = [
        (0, max[0], 0),
        (0, min[0], 1),
        (2, max[2], 2),
        (2, min[2], 3),
    ];
    for (axis, at, id) in planes.into_iter().chain([(1, max[1], 4), (1, min[1], 5)]) {
        if w[axis] != 0.0 {
            let t = at / w[axis];
            if t > 0.0 && t < best.0 {
                best = (t, id);
            }
        }
    }
    (best.1, w.map(|v| v * best.0))
}

/// Inward normal of surface `id`.
fn normal(id: usize) -> [f64; 3] {
    [
        [-1.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0],
        [0.0, 0.0, 1.0],
        [0.0, -1.0, 0.0],
        [0.0, 1.0, 0.0],
    ][id]
}

/// What the light computation needs, worked out once.
struct Lit<'a> {
    room: &'a Indoor,
    sky: Model,
    corners: [[f64; 3]; 4],
    /// Mean radiance seen through the window from inside, RGB (scaled as the sky).
    window_radiance: [f64; 3],
    /// The sun's normal irradiance, RGB, where it comes through the window.
    sun: [f64; 3],
    sun_dir: [f64; 3],
    ambient: [f64; 3],
}

impl Indoor {
    /// A random room from `rng`.
    pub fn draw(rng: &mut SplitMix) -> Indoor {
        let half = [1.5 + 2.0 * rng.uniform(), 0.0, 1.5 + 2.0 * rng.uniform()];
        let off = [
            0.5 * (2.0 * rng.uniform() - 1.0),
            0.0,
            0.5 * (2.0 * rng.uniform() - 1.0),
        ];
        let height = 2.4 + rng.uniform();
        let eye = 1.0 + 0.7 * rng.uniform();
        let min = [
            -half[0] - off[0] * half[0],
            -eye,
            -half[2] - off[2] * half[2],
        ];
        let max = [
            half[0] - off[0] * half[0],
            height - eye,
            half[2] - off[2] * half[2],
        ];
        let window_wall = rng.below(4);
        let axis = if window_wall < 2 { 2 } else { 0 };
        let (lo, hi) = (min[axis], max[axis]);
        let half_w = (0.08 + 0.17 * rng.uniform()) * (hi - lo);
        let centre = lo + half_w + 0.2 + (hi - lo - 2.0 * half_w - 0.4) * rng.uniform();
        let bottom = min[1] + 0.5 + 0.5 * rng.uniform();
        let top = (bottom + 0.9 + 0.9 * rng.uniform()).min(max[1] - 0.2);
        // the window faces out along -normal; the sun often shines in through it
        let out = normal(window_wall).map(|v| -v);
        let facing = out[2].atan2(out[0]).to_degrees();
        let azimuth = if rng.uniform() < 0.6 {
            facing + 120.0 * (rng.uniform() - 0.5)
        } else {
            360.0 * rng.uniform()
        };
        let sky = SunSky {
            elevation: 5.0 + 50.0 * rng.uniform(),
            azimuth: azimuth.rem_euclid(360.0),
            turbidity: 2.0 + 4.0 * rng.uniform(),
            ground: [0.2, 0.18, 0.14],
            sun: true,
        };
        let warm = [1.0, 0.93, 0.82];
        let wall = scale(
            mix([1.0; 3], warm, rng.uniform()),
            0.5 + 0.35 * rng.uniform(),
        );
        let wood = [0.75, 0.5, 0.3];
        let floor = scale(
            mix([0.6; 3], wood, rng.uniform()),
            0.3 + 0.5 * rng.uniform(),
        );
        let ceiling = [0.75 + 0.15 * rng.uniform(); 3];
        let lamp = (rng.uniform() < 0.5).then(|| {
            let radius = 0.1 + 0.15 * rng.uniform();
            let kelvin = 2700.0 + 1300.0 * rng.uniform();
            (
                radius,
                scale(temperature_rgb(kelvin), 3.0 + 12.0 * rng.uniform()),
            )
        });
        Indoor {
            min,
            max,
            window_wall,
            window: ((centre, half_w), (bottom, top)),
            sky,
            albedo: [wall, floor, ceiling],
            lamp,
        }
    }

    /// Checks the room.
    pub fn validate(&self) -> Result<()> {
        if !(0..3).all(|k| self.min[k] < 0.0 && self.max[k] > 0.0 && self.max[k].is_finite())
            || !self.min.iter().all(|v| v.is_finite())
        {
            return Err(invalid!(
                "indoor: the room must surround the viewer (min < 0 < max)"
            ));
        }
        if self.window_wall > 3 {
            return Err(invalid!(
                "indoor: window wall {} is not 0..3",
                self.window_wall
            ));
        }
        let ((c, hw), (b, t)) = self.window;
        let axis = if self.window_wall < 2 { 2 } else { 0 };
        let across = hw > 0.0 && c - hw >= self.min[axis] && c + hw <= self.max[axis];
        let up = b < t && b >= self.min[1] && t <= self.max[1];
        if !(across && up) {
            return Err(invalid!("indoor: the window does not fit on its wall"));
        }
        let albedo_ok = self.albedo.iter().flatten().all(|a| (0.0..1.0).contains(a));
        let lamp_ok = self.lamp.is_none_or(|(r, l)| {
            r > 0.0 && r.is_finite() && l.iter().all(|v| v.is_finite() && *v >= 0.0)
        });
        if !(albedo_ok && lamp_ok) {
            return Err(invalid!(
                "indoor: albedos must be in [0, 1) and the lamp's radius and radiance positive"
            ));
        }
        self.sky.validate()
    }

    /// The map, `height` x `width`, equirect, scaled to a mean radiance of 1.
    pub fn env(&self, height: usize, width: usize) -> Result<EnvMap> {
        raster::check_size(height, width)?;
        self.validate()?;
        let lit = self.lit()?;
        let mut texels = raster::rasterise(height, width, |w| lit.radiance(w));
        if self.sky.sun {
            raster::add_disc(&mut texels, height, width, &lit.sky.sun_disc(), |w| {
                lit.through_window([0.0; 3], w)
            });
        }
        raster::finish(height, width, raster::normalise(texels, height, width))
    }

    fn lit(&self) -> Result<Lit<'_>> {
        let sky = self.sky.model()?;
        let ((c, hw), (b, t)) = self.window;
        let plane = [self.max[0], self.min[0], self.max[2], self.min[2]][self.window_wall];
        let at = |u: f64, y: f64| {
            if self.window_wall < 2 {
                [plane, y, u]
            } else {
                [u, y, plane]
            }
        };
        let corners = [at(c - hw, b), at(c + hw, b), at(c + hw, t), at(c - hw, t)];
        let out = normal(self.window_wall).map(|v| -v);
        // cosine-weighted mean of the sky over the window's outward hemisphere
        let (nt, np) = (16, 32);
        let mut sum = [0.0; 3];
        let mut weight = 0.0;
        for i in 0..nt {
            for j in 0..np {
                let w = direction(
                    ((i as f64 + 0.5) / nt as f64 - 0.5) * PI,
                    (j as f64 + 0.5) / np as f64 * 2.0 * PI,
                );
                let cos = dot(w, out);
                if cos > 0.0 {
                    let d = cos * (1.0 - w[1] * w[1]).max(0.0).sqrt();
                    sum = add(sum, scale(sky.radiance(w), d));
                    weight += d;
                }
            }
        }
        let window_radiance = scale(sum, 1.0 / weight);
        let disc = sky.sun_disc();
        let sun = if self.sky.sun && disc.dir[1] > 0.0 {
            disc.power()
        } else {
            [0.0; 3]
        };
        let area = 2.0 * hw * (t - b);
        let size = [0, 1, 2].map(|k| self.max[k] - self.min[k]);
        let areas = [
            2.0 * (size[0] + size[2]) * size[1],
            size[0] * size[2],
            size[0] * size[2],
        ];
        let total: f64 = areas.iter().sum();
        let rho = (0..3)
            .map(|s| luminance(self.albedo[s]) * areas[s])
            .sum::<f64>()
            / total;
        let mut flux = scale(window_radiance, PI * area);
        flux = add(flux, scale(sun, area * dot(disc.dir, out).max(0.0)));
        if let Some((r, l)) = self.lamp {
            flux = add(flux, scale(l, PI * PI * r * r));
        }
        Ok(Lit {
            room: self,
            corners,
            window_radiance,
            sun,
            sun_dir: disc.dir,
            ambient: scale(flux, rho / (total * (1.0 - rho))),
            sky,
        })
    }
}

impl Lit<'_> {
    /// Whether the ray from `p` along `w` leaves through the window.
    fn through_window(&self, p: [f64; 3], w: [f64; 3]) -> bool {
        let room = self.room;
        let wall = room.window_wall;
        let (axis, along) = if wall < 2 { (0, 2) } else { (2, 0) };
        let plane = [room.max[0], room.min[0], room.max[2], room.min[2]][wall];
        let out = -normal(wall)[axis];
        if w[axis] * out <= 0.0 {
            return false;
        }
        let t = (plane - p[axis]) / w[axis];
        let q = [0, 1, 2].map(|k| p[k] + t * w[k]);
        let ((c, hw), (b, top)) = room.window;
        (q[along] - c).abs() <= hw && q[1] >= b && q[1] <= top
    }

    /// Irradiance from the window at `p` on a surface of normal `n` (Lambert's formula
    /// for a polygon of constant radiance).
    fn window_irradiance(&self, p: [f64; 3], n: [f64; 3]) -> [f64; 3] {
        let v = self
            .corners
            .map(|c| normalize([c[0] - p[0], c[1] - p[1], c[2] - p[2]]));
        let mut sum = 0.0;
        for i in 0..4 {
            let (a, b) = (v[i], v[(i + 1) % 4]);
            let angle = dot(a, b).clamp(-1.0, 1.0).acos();
            sum += angle * dot(n, normalize(cross(a, b)));
        }
        scale(self.window_radiance, sum.abs() / 2.0)
    }

    /// Radiance seen in direction `w` from the viewer, before scaling.
    fn radiance(&self, w: [f64; 3]) -> [f64; 3] {
        let room = self.room;
        let (id, p) = hit(room.min, room.max, w);
        if id == room.window_wall && self.through_window([0.0; 3], w) {
            return self.sky.radiance(w);
        }
        if let (4, Some((r, l))) = (id, room.lamp)
            && p[0] * p[0] + p[2] * p[2] <= r * r
        {
            return l;
        }
        let n = normal(id);
        let mut e = add(self.window_irradiance(p, n), self.ambient);
        let cos_sun = dot(n, self.sun_dir);
        if cos_sun > 0.0 && self.through_window(p, self.sun_dir) {
            e = add(e, scale(self.sun, cos_sun));
        }
        if let Some((r, l)) = room.lamp {
            let d = [-p[0], room.max[1] - p[1], -p[2]];
            let dist2 = dot(d, d);
            if dist2 > 0.0 && id != 4 {
                let dn = normalize(d);
                let g = (dn[1] * dot(n, dn)).max(0.0) / dist2;
                e = add(e, scale(l, PI * r * r * g));
            }
        }
        let albedo = room.albedo[match id {
            0..=3 => 0,
            5 => 1,
            _ => 2,
        }];
        scale(mul(albedo, e), 1.0 / PI)
    }
}
