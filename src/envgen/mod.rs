//! Procedural HDR lights for training data: lat-long `equirect` environment maps of four
//! kinds, each a pure function of (kind, seed, size), and augmentations of any map.
//!
//! - [`LightKind::SunSky`]: a clear sky (Preetham et al. 1999) with a sun disc of its true size
//!   and a ground ([`sky::SunSky`]);
//! - [`LightKind::Overcast`]: the CIE standard overcast sky ([`sky::Overcast`]);
//! - [`LightKind::Studio`]: one to four area lights over a dark or grey surround
//!   ([`studio::Studio`]);
//! - [`LightKind::Indoor`]: a room with a window, lit walls and an optional lamp
//!   ([`indoor::Indoor`]).
//!
//! Every texel is the solid-angle-weighted mean of the light over sub-texel samples, and
//! the sun's power is spread over the texels its disc covers, so that it is the same at
//! every size. [`augment`] turns, exposes and white-balances maps. docs/environments.md shows
//! each kind.
//!
//! ```
//! use matedit::envgen::{self, LightKind};
//! let env = envgen::generate(LightKind::SunSky, 7, 32, 64)?;
//! let turned = envgen::turn(&env, 45.0)?;
//! # Ok::<(), matedit::Error>(())
//! ```

pub mod augment;
pub mod colour;
pub mod indoor;
pub mod raster;
pub mod sky;
pub mod studio;

use std::fmt;

use crate::envmap::EnvMap;
use crate::error::Result;
use crate::splitmix::SplitMix;

pub use augment::{WhiteBalance, exposure, turn, white_balance};

/// The kinds of procedural light.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightKind {
    /// A clear sky with a sun and a ground.
    SunSky,
    /// The CIE overcast sky over a ground.
    Overcast,
    /// Area lights over a surround.
    Studio,
    /// A room with a window.
    Indoor,
}

impl LightKind {
    /// Every kind.
    pub const ALL: [LightKind; 4] = [
        LightKind::SunSky,
        LightKind::Overcast,
        LightKind::Studio,
        LightKind::Indoor,
    ];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            LightKind::SunSky => "sun-sky",
            LightKind::Overcast => "overcast",
            LightKind::Studio => "studio",
            LightKind::Indoor => "indoor",
        }
    }

    /// A different random stream per kind from the same seed.
    fn stream(self, seed: u64) -> SplitMix {
        let salt = match self {
            LightKind::SunSky => 0x5eed_0001,
            LightKind::Overcast => 0x5eed_0002,
            LightKind::Studio => 0x5eed_0003,
            LightKind::Indoor => 0x5eed_0004,
        };
        let mut rng = SplitMix(seed ^ (salt << 32));
        rng.next_u64();
        rng
    }
}

impl std::str::FromStr for LightKind {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        LightKind::ALL
            .into_iter()
            .find(|k| k.name() == s)
            .ok_or_else(|| {
                format!("unknown light kind '{s}': expected sun-sky, overcast, studio or indoor")
            })
    }
}

impl fmt::Display for LightKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// The parameters of one procedural light.
#[derive(Clone, Debug, PartialEq)]
pub enum Params {
    /// A clear sky.
    SunSky(sky::SunSky),
    /// An overcast sky.
    Overcast(sky::Overcast),
    /// A studio.
    Studio(studio::Studio),
    /// A room.
    Indoor(indoor::Indoor),
}

impl Params {
    /// The parameters that `seed` draws for `kind`.
    pub fn draw(kind: LightKind, seed: u64) -> Params {
        let mut rng = kind.stream(seed);
        match kind {
            LightKind::SunSky => Params::SunSky(sky::SunSky {
                elevation: 2.0 + 83.0 * rng.uniform(),
                azimuth: 360.0 * rng.uniform(),
                // mostly clear skies, some hazy
                turbidity: 2.0 + 8.0 * rng.uniform().powi(2),
                ground: ground_albedo(&mut rng),
                sun: true,
            }),
            LightKind::Overcast => {
                let kelvin = 5500.0 + 3000.0 * rng.uniform();
                let tint = colour::mix([1.0; 3], colour::temperature_rgb(kelvin), 0.4);
                Params::Overcast(sky::Overcast {
                    tint: colour::unit_luminance(tint),
                    ground: ground_albedo(&mut rng),
                })
            }
            LightKind::Studio => Params::Studio(studio::Studio::draw(&mut rng)),
            LightKind::Indoor => Params::Indoor(indoor::Indoor::draw(&mut rng)),
        }
    }

    /// The light as a `height` x `width` equirect map.
    pub fn env(&self, height: usize, width: usize) -> Result<EnvMap> {
        match self {
            Params::SunSky(p) => p.env(height, width),
            Params::Overcast(p) => p.env(height, width),
            Params::Studio(p) => p.env(height, width),
            Params::Indoor(p) => p.env(height, width),
        }
    }
}

impl fmt::Display for Params {
    /// One line naming the parameters that matter most.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Params::SunSky(p) => write!(
                f,
                "sun at elevation {:.1}, azimuth {:.1} degrees, turbidity {:.2}",
                p.elevation, p.azimuth, p.turbidity
            ),
            Params::Overcast(p) => write!(
                f,
                "tint ({:.3}, {:.3}, {:.3}), ground albedo {:.2}",
                p.tint[0],
                p.tint[1],
                p.tint[2],
                colour::luminance(p.ground)
            ),
            Params::Studio(p) => write!(
                f,
                "{} light{} over a surround of radiance {:.3} (before scaling)",
                p.lights.len(),
                if p.lights.len() == 1 { "" } else { "s" },
                p.surround[0]
            ),
            Params::Indoor(p) => write!(
                f,
                "room {:.1} x {:.1} x {:.1} m, window on wall {}, {}; {}",
                p.max[0] - p.min[0],
                p.max[2] - p.min[2],
                p.max[1] - p.min[1],
                p.window_wall,
                if p.lamp.is_some() {
                    "a lamp"
                } else {
                    "no lamp"
                },
                Params::SunSky(p.sky)
            ),
        }
    }
}

/// A ground between grey and brown (grass, soil, asphalt), albedo 0.05 to 0.2.
fn ground_albedo(rng: &mut SplitMix) -> [f64; 3] {
    let brown = [1.0, 0.8, 0.6];
    let tint = colour::mix([1.0; 3], brown, rng.uniform());
    colour::scale(colour::unit_luminance(tint), 0.05 + 0.15 * rng.uniform())
}

/// The light of `kind` that `seed` draws, as a `height` x `width` equirect map: the same
/// texels for the same (kind, seed, size) on every machine.
pub fn generate(kind: LightKind, seed: u64, height: usize, width: usize) -> Result<EnvMap> {
    raster::check_size(height, width)?;
    Params::draw(kind, seed).env(height, width)
}
