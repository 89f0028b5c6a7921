//! Environment-map sizes: parsing `HxW` / `full`, and downsampling a map by an integer
//! factor per axis with a solid-angle-weighted box filter.
//!
//! Each output texel's radiance is sum(L d_omega) / sum(d_omega) over its block of input
//! texels, d_omega being the input texel's solid angle under the map's convention
//! ([`Convention::texel`](crate::envmap::Convention::texel)). The filter keeps every
//! block's power (radiance times solid angle), so the rendered image barely changes.

use std::fmt;
use std::path::Path;

use crate::envmap::EnvMap;
use crate::error::{Error, Result};
use crate::raster;

/// Largest environment-map side accepted on the command line and in manifests.
pub const MAX_ENV_SIDE: usize = 16384;

/// The size an environment map is rendered at.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvSize {
    /// The file's own size (for the procedural default, [`crate::envmap::DEFAULT_ENV_SIZE`]).
    Full,
    /// `height` rows x `width` columns.
    Size {
        /// Rows.
        height: usize,
        /// Columns.
        width: usize,
    },
}

impl Default for EnvSize {
    fn default() -> Self {
        let (height, width) = crate::envmap::DEFAULT_ENV_SIZE;
        EnvSize::Size { height, width }
    }
}

impl fmt::Display for EnvSize {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EnvSize::Full => write!(f, "full"),
            EnvSize::Size { height, width } => write!(f, "{height}x{width}"),
        }
    }
}

impl std::str::FromStr for EnvSize {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        if s == "full" {
            return Ok(EnvSize::Full);
        }
        let bad = || format!("env size '{s}' is not HEIGHTxWIDTH (e.g. 64x128) or 'full'");
        let (h, w) = s.split_once(['x', 'X']).ok_or_else(bad)?;
        let height: usize = h.trim().parse().map_err(|_| bad())?;
        let width: usize = w.trim().parse().map_err(|_| bad())?;
        if height == 0 || width == 0 || height > MAX_ENV_SIDE || width > MAX_ENV_SIDE {
            return Err(format!(
                "env size '{s}': each side must be between 1 and {MAX_ENV_SIDE}"
            ));
        }
        Ok(EnvSize::Size { height, width })
    }
}

fn divisors(n: usize) -> Vec<usize> {
    (1..=n).filter(|&d| n.is_multiple_of(d)).collect()
}

fn list(v: &[usize]) -> String {
    v.iter()
        .map(|d| d.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// Why `height` x `width` cannot be made from a `h` x `w` map, and which sizes can.
fn size_error(h: usize, w: usize, height: usize, width: usize) -> String {
    let mut same_aspect: Vec<String> = divisors(gcd(h, w))
        .into_iter()
        .rev()
        .skip(1) // the largest factor gives the smallest map; list the useful ones first
        .map(|d| format!("{}x{}", h / d, w / d))
        .collect();
    same_aspect.reverse();
    same_aspect.truncate(6);
    let examples = if same_aspect.is_empty() {
        String::new()
    } else {
        format!(", e.g. {}", same_aspect.join(", "))
    };
    format!(
        "cannot make a {height}x{width} map from this {h}x{w} map: sizes are reduced by a \
         whole factor per axis, so the height must be one of {} and the width one of {} \
         (or use 'full'){examples}",
        list(&divisors(h)),
        list(&divisors(w))
    )
}

fn gcd(a: usize, b: usize) -> usize {
    if b == 0 { a } else { gcd(b, a % b) }
}

/// Downsamples `env` to `height` x `width` (each a divisor of the map's side) with the
/// solid-angle-weighted box filter. The error message (without a file name) says which
/// sizes would work.
pub fn downsample(
    env: &EnvMap,
    height: usize,
    width: usize,
) -> std::result::Result<EnvMap, String> {
    let (h, w) = (env.height, env.width);
    if height == 0 || width == 0 || h % height != 0 || w % width != 0 {
        return Err(size_error(h, w, height, width));
    }
    if (height, width) == (h, w) {
        return Ok(env.clone());
    }
    let (fy, fx) = (h / height, w / width);
    // d_omega depends on the row alone in both conventions, but ask per texel anyway: it
    // costs nothing next to decoding the file and stays right if a convention changes.
    let out = raster::reduce((w, h), (fx, fy), (width, height), |block| {
        let mut sum = [0.0f64; 3];
        let mut plain = [0.0f64; 3];
        let mut weight = 0.0f64;
        for i in block {
            let (_, d_omega) = env.convention.texel(i / w, i % w, h, w);
            let l = env.texels[i];
            for k in 0..3 {
                sum[k] += l[k] as f64 * d_omega;
                plain[k] += l[k] as f64;
            }
            weight += d_omega;
        }
        // A block of zero solid angle (the top row of a 'paper' map, one row high)
        // falls back to the plain mean.
        if weight > 0.0 {
            sum.map(|v| (v / weight) as f32)
        } else {
            plain.map(|v| (v / (fy * fx) as f64) as f32)
        }
    });
    Ok(EnvMap {
        height,
        width,
        convention: env.convention,
        texels: out,
    })
}

/// Brings a loaded map to `size`: `Full` keeps it; a smaller size downsamples it; a size
/// that does not divide the map is an error naming `path` and the sizes that would work.
pub fn fit(env: EnvMap, size: EnvSize, path: &Path) -> Result<EnvMap> {
    match size {
        EnvSize::Full => Ok(env),
        EnvSize::Size { height, width } => {
            downsample(&env, height, width).map_err(|m| Error::file(path, m))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::Convention;

    #[test]
    fn parse() {
        assert_eq!(
            "8x16".parse::<EnvSize>(),
            Ok(EnvSize::Size {
                height: 8,
                width: 16
            })
        );
        assert_eq!("full".parse::<EnvSize>(), Ok(EnvSize::Full));
        assert!("8".parse::<EnvSize>().is_err());
        assert!("0x16".parse::<EnvSize>().is_err());
    }

    #[test]
    fn keeps_power_and_constants() {
        for conv in [Convention::Equirect, Convention::Paper] {
            let (h, w) = (64, 128);
            let texels: Vec<[f32; 3]> = (0..h * w)
                .map(|i| [i as f32, (i % 5) as f32, 1.0])
                .collect();
            let env = EnvMap::new(h, w, conv, texels).unwrap();
            let small = downsample(&env, 16, 32).unwrap();
            let power = |e: &EnvMap| -> f64 {
                (0..e.height * e.width)
                    .map(|i| {
                        e.texels[i][0] as f64
                            * e.convention
                                .texel(i / e.width, i % e.width, e.height, e.width)
                                .1
                    })
                    .sum()
            };
            // Equirect solid angles of a block add up to the coarse texel's only
            // approximately (sin is not linear over the block), so compare loosely.
            let (p0, p1) = (power(&env), power(&small));
            if conv == Convention::Equirect {
                assert!((p0 - p1).abs() < 0.02 * p0, "{p0} vs {p1}");
            }
            assert!(small.texels.iter().all(|t| (t[2] - 1.0).abs() < 1e-6));
        }
    }

    #[test]
    fn error_lists_sizes() {
        let env = EnvMap::constant(8, 16, Convention::Equirect, [1.0; 3]).unwrap();
        let e = downsample(&env, 3, 16).unwrap_err();
        assert!(e.contains("1, 2, 4, 8"), "{e}");
        assert!(e.contains("4x8"), "{e}");
    }
}
