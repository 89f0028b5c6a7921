//! The illumination: a lat-long HDR environment map, its two texel conventions, and the
//! per-texel geometry (direction, solid angle) they define.

use std::f64::consts::PI;

use crate::error::{Result, invalid};

/// Default environment-map size (rows x columns).
pub const DEFAULT_ENV_SIZE: (usize, usize) = (64, 128);

/// Largest radiance accepted: keeps every sum far from f32 overflow.
pub const MAX_RADIANCE: f32 = 1.0e12;

/// How texel (r, c) maps to a direction and a solid angle. See CONVENTIONS "Illumination".
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Convention {
    /// theta = (r + 0.5) / H pi, phi = (c + 0.5) / W 2pi, d_omega = sin(theta) (pi/H)(2pi/W).
    #[default]
    Equirect,
    /// The supplemental's equations taken literally: theta = r / H pi, phi = c / W pi,
    /// d_omega = sin(theta).
    Paper,
}

impl Convention {
    /// The name used on the command line and in files.
    pub fn name(&self) -> &'static str {
        match self {
            Convention::Equirect => "equirect",
            Convention::Paper => "paper",
        }
    }

    /// Direction w_i and solid angle d_omega_i of texel (r, c) of an `h` x `w` map.
    pub fn texel(&self, r: usize, c: usize, h: usize, w: usize) -> ([f64; 3], f64) {
        let (theta, phi, d_omega) = match self {
            Convention::Equirect => {
                let theta = (r as f64 + 0.5) / h as f64 * PI;
                let phi = (c as f64 + 0.5) / w as f64 * 2.0 * PI;
                (
                    theta,
                    phi,
                    theta.sin() * (PI / h as f64) * (2.0 * PI / w as f64),
                )
            }
            Convention::Paper => {
                let theta = r as f64 / h as f64 * PI;
                let phi = c as f64 / w as f64 * PI;
                (theta, phi, theta.sin())
            }
        };
        let dir = [
            phi.cos() * theta.sin(),
            theta.cos(),
            phi.sin() * theta.sin(),
        ];
        (dir, d_omega)
    }
}

impl std::str::FromStr for Convention {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "equirect" => Ok(Convention::Equirect),
            "paper" => Ok(Convention::Paper),
            _ => Err(format!(
                "unknown convention '{s}': expected 'equirect' or 'paper'"
            )),
        }
    }
}

/// A lat-long HDR environment map: `height` rows x `width` columns of linear RGB radiance,
/// row 0 at the top (+y).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvMap {
    /// Rows (H_L).
    pub height: usize,
    /// Columns (W_L).
    pub width: usize,
    /// How texels map to directions.
    pub convention: Convention,
    /// Radiance, row-major, `height * width` texels.
    pub texels: Vec<[f32; 3]>,
}

impl EnvMap {
    /// A validated map. Radiance must be finite and in [0, [`MAX_RADIANCE`]]; use
    /// [`EnvMap::clamp_negative`] first for real HDR files, which have small negative texels.
    pub fn new(
        height: usize,
        width: usize,
        convention: Convention,
        texels: Vec<[f32; 3]>,
    ) -> Result<Self> {
        let m = EnvMap {
            height,
            width,
            convention,
            texels,
        };
        m.validate()?;
        Ok(m)
    }

    /// The same radiance in every direction.
    pub fn constant(
        height: usize,
        width: usize,
        convention: Convention,
        rgb: [f32; 3],
    ) -> Result<Self> {
        EnvMap::new(height, width, convention, vec![rgb; height * width])
    }

    /// Sets negative texel channels to 0 and returns how many channels were clamped.
    pub fn clamp_negative(texels: &mut [[f32; 3]]) -> usize {
        let mut n = 0;
        for v in texels.iter_mut().flatten() {
            if *v < 0.0 {
                *v = 0.0;
                n += 1;
            }
        }
        n
    }

    /// Checks the size and every texel.
    pub fn validate(&self) -> Result<()> {
        if self.height == 0 || self.width == 0 {
            return Err(invalid!(
                "env: size {}x{} is empty",
                self.height,
                self.width
            ));
        }
        if self.texels.len() != self.height * self.width {
            return Err(invalid!(
                "env: {} texels given for a {}x{} map",
                self.texels.len(),
                self.height,
                self.width
            ));
        }
        for (i, t) in self.texels.iter().enumerate() {
            for (ch, &v) in t.iter().enumerate() {
                if !(v.is_finite() && (0.0..=MAX_RADIANCE).contains(&v)) {
                    let (r, c) = (i / self.width, i % self.width);
                    let why = if v.is_nan() {
                        "is NaN".to_string()
                    } else if v < 0.0 {
                        format!("is {v}; radiance must be >= 0 (loaders clamp negative texels)")
                    } else {
                        format!("is {v}; radiance must be finite and <= {MAX_RADIANCE}")
                    };
                    return Err(invalid!(
                        "env: texel (row {r}, column {c}) channel {} {why}",
                        ["R", "G", "B"][ch]
                    ));
                }
            }
        }
        Ok(())
    }
}
