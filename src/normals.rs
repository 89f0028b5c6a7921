//! Normal maps: per-pixel normals in camera coordinates, their checks (length, background)
//! and the generated ones (a sphere, a seeded bumpy surface).

use crate::error::{Result, invalid};

/// Longest normal accepted: 1 and the rounding of a normalised f32 vector, with room. A
/// longer normal makes x = h.n exceed 1, and x^m1 (m1 up to 1e4) overflow: at |n| = 1 + 1e-5
/// x^1e4 is at most e^0.1, so exp(40 x^m1) stays far inside f32.
pub const MAX_NORMAL_LENGTH: f64 = 1.0 + 1e-5;

/// A normal whose length is below this is background: it renders 0 and gets no gradient.
pub const BACKGROUND_EPS: f64 = 1e-6;

/// A `width` x `height` map of normals in camera coordinates, row 0 at the top. The layer
/// uses them exactly as given (not re-normalised); loaders normalise.
#[derive(Clone, Debug, PartialEq)]
pub struct NormalMap {
    /// Columns.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// (n.x, n.y, n.z) per pixel, row-major.
    pub normals: Vec<[f32; 3]>,
}

impl NormalMap {
    /// A validated normal map: the right number of pixels, every component finite.
    pub fn new(width: usize, height: usize, normals: Vec<[f32; 3]>) -> Result<Self> {
        let m = NormalMap {
            width,
            height,
            normals,
        };
        m.validate()?;
        Ok(m)
    }

    /// A unit sphere filling an `n` x `n` image, background outside the disc.
    pub fn sphere(n: usize) -> Self {
        let mut normals = Vec::with_capacity(n * n);
        for y in 0..n {
            for x in 0..n {
                let u = (x as f64 + 0.5) / n as f64 * 2.0 - 1.0;
                let v = 1.0 - (y as f64 + 0.5) / n as f64 * 2.0;
                let r2 = u * u + v * v;
                normals.push(if r2 < 1.0 {
                    [u as f32, v as f32, (1.0 - r2).sqrt() as f32]
                } else {
                    [0.0; 3]
                });
            }
        }
        NormalMap {
            width: n,
            height: n,
            normals,
        }
    }

    /// A bumpy sphere: a unit sphere of radius 0.95 x half the image's shorter side,
    /// centred, whose surface is raised by a deterministic height field, a sum of 8
    /// plane waves with directions, frequencies (2 to 14 cycles across the sphere) and
    /// phases drawn from `seed`; background outside the disc. Normals are unit length, and
    /// the loaders' normalisation leaves them unchanged.
    ///
    /// With z = sqrt(1 - u^2 - v^2) on the disc and height h(u, v), the surface
    /// z + h has normal (u - z h_u, v - z h_v, z), normalised: the bumps fade out at the
    /// silhouette, and every normal faces the camera (n.z > 0). Useful as a test and
    /// benchmark input with more varied normals than [`NormalMap::sphere`].
    pub fn bumpy(width: usize, height: usize, seed: u64) -> Self {
        let mut rng = crate::splitmix::SplitMix(seed);
        let mut uniform = move || rng.uniform();
        const WAVES: usize = 8;
        let tau = 2.0 * std::f64::consts::PI;
        // (kx, ky, amplitude, phase) per wave; each wave's slope is 0.25 (amplitude x
        // wave number), so the summed slope is about 0.5 (RMS)
        let waves: Vec<[f64; 4]> = (0..WAVES)
            .map(|_| {
                let angle = uniform() * tau;
                let cycles = 1.0 + 6.0 * uniform(); // per unit length: 2 to 14 across the disc
                let k = cycles * tau;
                let amp = 0.25 / k;
                [k * angle.cos(), k * angle.sin(), amp, uniform() * tau]
            })
            .collect();
        let half = width.min(height) as f64 / 2.0;
        let radius = 0.95 * half;
        let mut normals = Vec::with_capacity(width * height);
        for y in 0..height {
            for x in 0..width {
                let u = (x as f64 + 0.5 - width as f64 / 2.0) / radius;
                let v = (height as f64 / 2.0 - (y as f64 + 0.5)) / radius;
                let r2 = u * u + v * v;
                if r2 >= 1.0 {
                    normals.push([0.0; 3]);
                    continue;
                }
                let z = (1.0 - r2).sqrt();
                let (mut hu, mut hv) = (0.0, 0.0);
                for &[kx, ky, amp, phase] in &waves {
                    let c = amp * (kx * u + ky * v + phase).cos();
                    hu += c * kx;
                    hv += c * ky;
                }
                normals.push(loader_stable_unit([u - z * hu, v - z * hv, z]));
            }
        }
        NormalMap {
            width,
            height,
            normals,
        }
    }

    /// Whether pixel `i` is background (|n| < 1e-6).
    pub fn is_background(&self, i: usize) -> bool {
        let n = self.normals[i];
        let len2: f64 = n.iter().map(|&v| (v as f64) * (v as f64)).sum();
        len2 < BACKGROUND_EPS * BACKGROUND_EPS
    }

    /// Checks the size, that every component is finite and that no normal is longer than
    /// [`MAX_NORMAL_LENGTH`].
    pub fn validate(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(invalid!(
                "normals: size {}x{} is empty",
                self.width,
                self.height
            ));
        }
        if self.normals.len() != self.width * self.height {
            return Err(invalid!(
                "normals: {} pixels given for a {}x{} map",
                self.normals.len(),
                self.width,
                self.height
            ));
        }
        for (i, n) in self.normals.iter().enumerate() {
            if let Some(v) = n.iter().find(|v| !v.is_finite()) {
                let what = if v.is_nan() { "NaN" } else { "infinite" };
                return Err(invalid!(
                    "normals: pixel ({}, {}) is {what}",
                    i % self.width,
                    i / self.width
                ));
            }
            let len = n
                .iter()
                .map(|&v| f64::from(v) * f64::from(v))
                .sum::<f64>()
                .sqrt();
            if len > MAX_NORMAL_LENGTH {
                return Err(invalid!(
                    "normals: pixel ({}, {}) has length {len}; normals may not be longer than 1 \
                     (+1e-5): normalise them (the file loaders do)",
                    i % self.width,
                    i / self.width
                ));
            }
        }
        Ok(())
    }
}

/// `n` / |n| in f32, chosen among the nearest f32 triples so that normalising it again in
/// f64 and rounding to f32 (as the file loaders do) gives it back bit for bit: a map of
/// such normals renders the same after a round trip through a file.
pub(crate) fn loader_stable_unit(n: [f64; 3]) -> [f32; 3] {
    let unit = |v: [f64; 3]| {
        let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        v.map(|c| (c / len) as f32)
    };
    let stable = |f: [f32; 3]| unit(f.map(f64::from)) == f;
    let first = unit(n);
    if stable(first) {
        return first;
    }
    // one ulp either way per component; the closest stable triple to the exact direction
    let step = |x: f32, d: i32| match d {
        -1 => x.next_down(),
        1 => x.next_up(),
        _ => x,
    };
    let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
    let mut best: Option<([f32; 3], f64)> = None;
    for d in 0..27 {
        let ds = [d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1];
        let f = [0, 1, 2].map(|k| step(first[k], ds[k]));
        if stable(f) {
            let dist: f64 = (0..3).map(|k| (f[k] as f64 - n[k] / len).powi(2)).sum();
            if best.is_none_or(|(_, b)| dist < b) {
                best = Some((f, dist));
            }
        }
    }
    best.map_or(first, |(f, _)| f)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bumpy_normals_are_unit_varied_and_deterministic() {
        let (w, h) = (96, 64);
        let m = NormalMap::bumpy(w, h, 7);
        m.validate().unwrap();
        assert_eq!((m.width, m.height, m.normals.len()), (w, h, w * h));
        assert_eq!(m, NormalMap::bumpy(w, h, 7));
        assert_ne!(m, NormalMap::bumpy(w, h, 8));

        // a round disc of radius 0.95 x 32 pixels in the middle, background around it
        let fg: Vec<usize> = (0..w * h).filter(|&i| !m.is_background(i)).collect();
        let disc = std::f64::consts::PI * (0.95 * 32.0f64).powi(2);
        assert!(
            (fg.len() as f64 - disc).abs() < 0.03 * disc,
            "{} foreground pixels, disc {disc}",
            fg.len()
        );
        assert!(m.is_background(0) && m.is_background(w / 2) && m.is_background(w * h - 1));
        assert!(!m.is_background(h / 2 * w + w / 2));

        // unit normals facing the camera, and bumps: they differ from the smooth sphere's
        let mut max_dev = 0.0f64;
        for &i in &fg {
            let n = m.normals[i].map(f64::from);
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            assert!((len - 1.0).abs() < 1e-6, "pixel {i}: |n| = {len}");
            // what the file loaders make of it: the same bits
            assert_eq!(n.map(|c| (c / len) as f32), m.normals[i], "pixel {i}");
            assert!(n[2] > 0.0, "pixel {i}: {n:?}");
            let u = (i % w) as f64 + 0.5 - w as f64 / 2.0;
            let v = h as f64 / 2.0 - ((i / w) as f64 + 0.5);
            let (u, v) = (u / (0.95 * 32.0), v / (0.95 * 32.0));
            let smooth = [u, v, (1.0 - u * u - v * v).max(0.0).sqrt()];
            let dot: f64 = (0..3).map(|c| n[c] * smooth[c]).sum();
            max_dev = max_dev.max(dot.clamp(-1.0, 1.0).acos());
        }
        assert!(max_dev > 0.3, "largest tilt from the sphere {max_dev} rad");

        // the layer bench's map too: every normal survives the loaders' normalisation
        let big = NormalMap::bumpy(256, 256, 1);
        for (i, n) in big.normals.iter().enumerate() {
            let v = n.map(f64::from);
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if len > 0.0 {
                assert_eq!(v.map(|c| (c / len) as f32), *n, "256 x 256 pixel {i}");
            }
        }
    }
}
