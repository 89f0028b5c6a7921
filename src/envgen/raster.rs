//! From a radiance function to an `equirect` map: each texel the solid-angle-weighted mean
//! of the function over a grid of sub-texel samples, and small bright discs (the sun) placed
//! by their power, so that a source smaller than a texel keeps its power at every size.

use std::f64::consts::PI;

use rayon::prelude::*;

use crate::envmap::{Convention, EnvMap};
use crate::error::{Result, invalid};
use crate::io::resample::MAX_ENV_SIDE;

/// Sub-samples per texel side: enough that a small map still sees edges and small
/// features, at least 2 so that every map is filtered.
fn subsamples(height: usize) -> usize {
    (512 / height.max(1)).clamp(2, 8)
}

/// Checks a requested size.
pub fn check_size(height: usize, width: usize) -> Result<()> {
    if height == 0 || width == 0 || height > MAX_ENV_SIDE || width > MAX_ENV_SIDE {
        return Err(invalid!(
            "env: size {height}x{width}: each side must be between 1 and {MAX_ENV_SIDE}"
        ));
    }
    Ok(())
}

/// Radiance of `f` averaged over each texel of a `height` x `width` equirect map,
/// weighted by the sub-samples' solid angles; row-major.
pub fn rasterise<F>(height: usize, width: usize, f: F) -> Vec<[f64; 3]>
where
    F: Fn([f64; 3]) -> [f64; 3] + Sync,
{
    let s = subsamples(height);
    let (hs, ws) = (height * s, width * s);
    (0..height)
        .into_par_iter()
        .flat_map_iter(|r| {
            let f = &f;
            (0..width).map(move |c| {
                let mut sum = [0.0f64; 3];
                let mut om = 0.0;
                for i in 0..s {
                    for j in 0..s {
                        let (dir, d) = Convention::Equirect.texel(r * s + i, c * s + j, hs, ws);
                        let l = f(dir);
                        for k in 0..3 {
                            sum[k] += l[k] * d;
                        }
                        om += d;
                    }
                }
                sum.map(|v| v / om)
            })
        })
        .collect()
}

/// A disc of constant radiance on the sphere, small enough to be placed by its power.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Disc {
    /// Unit direction of its centre.
    pub dir: [f64; 3],
    /// Angular radius, radians.
    pub radius: f64,
    /// Radiance, linear RGB.
    pub radiance: [f64; 3],
}

/// Points on a disc that carry its power: a Fibonacci spiral, evenly spread by area.
const DISC_POINTS: usize = 4096;

impl Disc {
    /// Its solid angle, 2 pi (1 - cos radius).
    pub fn solid_angle(&self) -> f64 {
        2.0 * PI * (1.0 - self.radius.cos())
    }

    /// Its power: radiance times solid angle.
    pub fn power(&self) -> [f64; 3] {
        self.radiance.map(|v| v * self.solid_angle())
    }

    /// `DISC_POINTS` directions spread evenly over the disc.
    fn points(&self) -> impl Iterator<Item = [f64; 3]> + '_ {
        let (t1, t2) = tangents(self.dir);
        let golden = PI * (3.0 - 5f64.sqrt());
        (0..DISC_POINTS).map(move |k| {
            // equal areas on the cap: 1 - cos(rho) uniform in [0, 1 - cos(radius)]
            let u = (k as f64 + 0.5) / DISC_POINTS as f64;
            let cos_rho = 1.0 - u * (1.0 - self.radius.cos());
            let sin_rho = (1.0 - cos_rho * cos_rho).max(0.0).sqrt();
            let a = k as f64 * golden;
            [0, 1, 2].map(|i| cos_rho * self.dir[i] + sin_rho * (a.cos() * t1[i] + a.sin() * t2[i]))
        })
    }
}

/// Two unit vectors perpendicular to unit `d` and to each other.
pub fn tangents(d: [f64; 3]) -> ([f64; 3], [f64; 3]) {
    let up = if d[1].abs() < 0.9 {
        [0.0, 1.0, 0.0]
    } else {
        [1.0, 0.0, 0.0]
    };
    let t1 = normalize(cross(up, d));
    (t1, cross(d, t1))
}

/// The texel of an equirect `height` x `width` map that direction `w` falls in.
pub fn texel_of(w: [f64; 3], height: usize, width: usize) -> usize {
    let theta = w[1].clamp(-1.0, 1.0).acos();
    let phi = w[2].atan2(w[0]).rem_euclid(2.0 * PI);
    let r = ((theta / PI * height as f64) as usize).min(height - 1);
    let c = ((phi / (2.0 * PI) * width as f64) as usize).min(width - 1);
    r * width + c
}

/// Adds `disc`'s power to the texels it covers, in proportion to how much of it each
/// covers, as radiance (power over the texel's solid angle). Parts of the disc where
/// `visible` is false (behind the ground, outside a window) are left out.
pub fn add_disc(
    texels: &mut [[f64; 3]],
    height: usize,
    width: usize,
    disc: &Disc,
    visible: impl Fn([f64; 3]) -> bool,
) {
    let share = disc.power().map(|p| p / DISC_POINTS as f64);
    for p in disc.points() {
        if !visible(p) {
            continue;
        }
        let i = texel_of(p, height, width);
        let d_omega = Convention::Equirect
            .texel(i / width, i % width, height, width)
            .1;
        for k in 0..3 {
            texels[i][k] += share[k] / d_omega;
        }
    }
}

/// Sum of radiance times solid angle over an equirect map, per channel.
pub fn power(texels: &[[f64; 3]], height: usize, width: usize) -> [f64; 3] {
    let mut sum = [0.0; 3];
    for (i, t) in texels.iter().enumerate() {
        let d = Convention::Equirect
            .texel(i / width, i % width, height, width)
            .1;
        for k in 0..3 {
            sum[k] += t[k] * d;
        }
    }
    sum
}

/// `texels` scaled so that their mean radiance (luminance power over 4 pi) is 1.
pub fn normalise(texels: Vec<[f64; 3]>, height: usize, width: usize) -> Vec<[f64; 3]> {
    let p = super::colour::luminance(power(&texels, height, width));
    let s = if p > 0.0 { 4.0 * PI / p } else { 1.0 };
    texels.into_iter().map(|t| t.map(|v| v * s)).collect()
}

/// The texels as a validated `EnvMap`.
pub fn finish(height: usize, width: usize, texels: Vec<[f64; 3]>) -> Result<EnvMap> {
    EnvMap::new(
        height,
        width,
        Convention::Equirect,
        texels.into_iter().map(|t| t.map(|v| v as f32)).collect(),
    )
}

/// Dot product.
pub fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Cross product.
pub fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

/// `a` at unit length (unchanged if it is 0).
pub fn normalize(a: [f64; 3]) -> [f64; 3] {
    let l = dot(a, a).sqrt();
    if l > 0.0 { a.map(|v| v / l) } else { a }
}

/// The unit direction at `elevation` above the horizon and `azimuth` (radians), azimuth
/// being the equirect map's phi: 0 at +x, pi/2 at +z (towards the viewer).
pub fn direction(elevation: f64, azimuth: f64) -> [f64; 3] {
    let (st, ct) = (elevation.cos(), elevation.sin());
    [azimuth.cos() * st, ct, azimuth.sin() * st]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_of_finds_each_texel_centre() {
        for (h, w) in [(1, 2), (7, 13), (64, 128)] {
            for i in 0..h * w {
                let (dir, _) = Convention::Equirect.texel(i / w, i % w, h, w);
                assert_eq!(texel_of(dir, h, w), i, "{h}x{w}");
            }
        }
    }

    #[test]
    fn disc_points_lie_on_the_disc_and_spread_evenly() {
        let disc = Disc {
            dir: normalize([0.3, 0.8, -0.5]),
            radius: 0.1,
            radiance: [1.0; 3],
        };
        let (mut inner, mut n) = (0, 0);
        for p in disc.points() {
            let angle = dot(p, disc.dir).clamp(-1.0, 1.0).acos();
            assert!(angle <= 0.1 + 1e-12 && (dot(p, p) - 1.0).abs() < 1e-12);
            // half the cap's area lies within 1 - cos(rho) = (1 - cos(radius)) / 2
            if 1.0 - angle.cos() <= (1.0 - 0.1f64.cos()) / 2.0 {
                inner += 1;
            }
            n += 1;
        }
        assert_eq!(n, DISC_POINTS);
        assert_eq!(inner, DISC_POINTS / 2);
    }
}
