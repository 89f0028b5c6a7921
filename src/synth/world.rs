//! The object's world, for photo-like samples: a field of view drawn from a range, the
//! camera's elevation, a floor the object stands on ([`super::floor`]) and the shadows it
//! casts ([`super::shadow`]). Every option is off unless the spec gives it; their draws
//! come from a generator of their own ([`World::rng`]), so that a spec without them draws
//! exactly what it drew before.
//!
//! Elevation `e` looks down at the object: the world (object, floor and light) is pitched
//! towards the camera by `e` about the camera's x axis. The object's rotation gets the
//! extra pitch; the map is resampled so that it holds the light in the tilted camera frame
//! (what the layer renders, and what `env.npy` holds); the floor's normal is the world's
//! up in the camera frame, (0, cos e, sin e).

use std::path::Path;

use serde_json::Value;
use sha2::Sha256;

use super::floor::FloorSource;
use super::sources::{SampleNormals, Weighted};
use crate::camera::Camera;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::shapes::Rotation;
use crate::splitmix::SplitMix;

/// Highest elevation, degrees.
pub const MAX_ELEVATION: f64 = 80.0;

/// The photo-like options of a spec.
#[derive(Clone, Debug, Default)]
pub struct World {
    /// A range of vertical fields of view, degrees (`fov: [LO, HI]`).
    pub fov: Option<[f64; 2]>,
    /// A range of elevations, degrees.
    pub elevation: Option<[f64; 2]>,
    /// Floor sources (`None`: no floor key).
    pub floors: Option<Vec<Weighted<FloorSource>>>,
    /// Shadows on the floor and on the object.
    pub shadows: bool,
}

/// What one sample drew of its world.
#[derive(Clone, Copy, Debug)]
pub struct SampleView {
    /// The camera.
    pub camera: Camera,
    /// Elevation, degrees.
    pub elevation: f64,
    /// The share of the frame left empty around the object ([`crate::shapes::View`]'s
    /// margin): drawn in [`FLOOR_MARGIN`] with a floor, so that the floor shows around it.
    pub margin: f64,
}

/// The range of margins around an object on a floor.
pub const FLOOR_MARGIN: [f64; 2] = [0.15, 0.45];

/// The raw keys of a spec that [`World::parse`] reads.
pub(super) struct RawWorld<'a> {
    pub fov: Option<&'a Value>,
    pub elevation: Option<&'a Value>,
    pub floor: Option<&'a [Value]>,
    pub shadows: Option<bool>,
}

fn range(v: &Value) -> Option<[f64; 2]> {
    match v
        .as_array()
        .map(|a| a.iter().map(Value::as_f64).collect::<Vec<_>>())
    {
        Some(a) if a.len() == 2 => Some([a[0]?, a[1]?]),
        _ => None,
    }
}

impl World {
    /// The spec's camera (perspective at the low end of a range) and its photo-like
    /// options, checked; errors name the key or item.
    pub(super) fn parse(
        raw: RawWorld,
        normals: &[Weighted<SampleNormals>],
        convention: Convention,
        base: &Path,
        hasher: &mut Sha256,
        err: &dyn Fn(String) -> Error,
    ) -> Result<(Camera, World)> {
        let mut world = World::default();
        let fov_ok = |f: f64| f.is_finite() && f > 0.0 && f < 180.0;
        let camera = match raw.fov {
            None => Camera::Orthographic,
            Some(v) => {
                let (lo, hi) = if let Some(f) = v.as_f64() {
                    (f, f)
                } else if let Some([lo, hi]) = range(v) {
                    world.fov = Some([lo, hi]);
                    (lo, hi)
                } else {
                    return Err(err(format!(
                        "fov: {v} is not a number of degrees or a range [LO, HI]"
                    )));
                };
                if !(fov_ok(lo) && fov_ok(hi) && lo <= hi) {
                    return Err(err(format!(
                        "fov: {v} degrees must be in (0, 180), lo <= hi"
                    )));
                }
                Camera::Perspective { fov_y_deg: lo }
            }
        };
        if let Some(v) = raw.elevation {
            let Some([lo, hi]) = range(v) else {
                return Err(err(format!(
                    "elevation: {v} is not a range [LO, HI] of degrees"
                )));
            };
            if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && hi <= MAX_ELEVATION && lo <= hi) {
                return Err(err(format!(
                    "elevation: [{lo}, {hi}] must be within [0, {MAX_ELEVATION}] degrees, lo <= hi"
                )));
            }
            if camera.is_orthographic() {
                return Err(err(
                    "elevation: needs a perspective camera: give \"fov\"".into()
                ));
            }
            if convention != Convention::Equirect {
                return Err(err("elevation: needs the equirect convention".into()));
            }
            world.elevation = Some([lo, hi]);
        }
        if let Some(items) = raw.floor {
            world.floors = Some(super::floor::floors(
                items, normals, camera, convention, base, hasher, err,
            )?);
        }
        if let Some(s) = raw.shadows {
            if s && world.floors.is_none() {
                return Err(err("shadows: needs a \"floor\"".into()));
            }
            world.shadows = s;
        }
        Ok((camera, world))
    }

    /// The generator of sample `k`'s world draws: a stream apart from the sample's own.
    pub fn rng(seed: u64, k: u64) -> SplitMix {
        SplitMix::for_sample(seed ^ 0x6c8e_9cf5_7032_1ab3, k.rotate_left(7))
    }

    /// Sample's camera and elevation, drawn from `rng` (nothing drawn for what the spec
    /// does not give).
    pub fn draw_view(&self, camera: Camera, rng: &mut SplitMix) -> SampleView {
        let camera = match self.fov {
            Some([lo, hi]) => Camera::Perspective {
                fov_y_deg: lo + (hi - lo) * rng.uniform(),
            },
            None => camera,
        };
        let elevation = match self.elevation {
            Some([lo, hi]) => lo + (hi - lo) * rng.uniform(),
            None => 0.0,
        };
        let margin = match self.floors {
            Some(_) => FLOOR_MARGIN[0] + (FLOOR_MARGIN[1] - FLOOR_MARGIN[0]) * rng.uniform(),
            None => crate::shapes::DEFAULT_MARGIN,
        };
        SampleView {
            camera,
            elevation,
            margin,
        }
    }
}

/// `rotation` followed by a pitch of `elevation` degrees about the camera's x axis, as one
/// rotation (yaw, pitch, roll).
pub fn pitched(rotation: Rotation, elevation: f64) -> Rotation {
    if elevation == 0.0 {
        return rotation;
    }
    let e = Rotation {
        yaw: 0.0,
        pitch: elevation,
        roll: 0.0,
    };
    let m = crate::shapes::view::mat_mul(e.matrix(), rotation.matrix());
    // m = Rz(roll) Rx(pitch) Ry(yaw): its last row is (-cp sy, sp, cp cy), its middle
    // column (-sr cp, cr cp, sp)
    Rotation {
        yaw: (-m[2][0]).atan2(m[2][2]).to_degrees(),
        pitch: m[2][1].clamp(-1.0, 1.0).asin().to_degrees(),
        roll: (-m[0][1]).atan2(m[1][1]).to_degrees(),
    }
}

/// `env` (world frame) resampled to the camera frame of a world pitched by `elevation`
/// degrees: texel direction d (camera frame) takes the world's radiance along Rx(-e) d,
/// bilinear.
pub fn tilt(env: &EnvMap, elevation: f64) -> Result<EnvMap> {
    if elevation == 0.0 {
        return Ok(env.clone());
    }
    let (s, c) = elevation.to_radians().sin_cos();
    let mut texels = Vec::with_capacity(env.texels.len());
    for r in 0..env.height {
        for col in 0..env.width {
            let (d, _) = env.convention.texel(r, col, env.height, env.width);
            let w = [d[0], c * d[1] + s * d[2], -s * d[1] + c * d[2]];
            texels.push(super::background::env_along(env, w));
        }
    }
    EnvMap::new(env.height, env.width, env.convention, texels)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pitched_is_the_product() {
        for (i, r) in [(10.0, 20.0, 30.0), (200.0, -70.0, 5.0), (0.0, 0.0, 0.0)]
            .into_iter()
            .enumerate()
        {
            let r = Rotation {
                yaw: r.0,
                pitch: r.1,
                roll: r.2,
            };
            let e = 10.0 + 20.0 * i as f64;
            let want = crate::shapes::view::mat_mul(
                Rotation {
                    pitch: e,
                    ..Default::default()
                }
                .matrix(),
                r.matrix(),
            );
            let got = pitched(r, e).matrix();
            for a in 0..3 {
                for b in 0..3 {
                    assert!((want[a][b] - got[a][b]).abs() < 1e-12, "{r:?} {e}");
                }
            }
        }
    }

    #[test]
    fn tilting_moves_the_sky_towards_the_camera() {
        // a map bright above (y > 0): tilted by 40 degrees, the camera direction +z (up
        // in the world by 40 degrees) is lit, -z (40 degrees below the horizon) dark
        let (h, w) = (32, 64);
        let texels = (0..h * w)
            .map(|i| if i / w < h / 2 { [1.0; 3] } else { [0.0; 3] })
            .collect();
        let env = EnvMap::new(h, w, Convention::Equirect, texels).unwrap();
        let t = tilt(&env, 40.0).unwrap();
        let at = |d| super::super::background::env_along(&t, d)[0];
        assert!(at([0.0, 0.0, 1.0]) > 0.99);
        assert!(at([0.0, 0.0, -1.0]) < 0.01);
        assert_eq!(super::super::floor::up(0.0), [0.0, 1.0, 0.0]);
    }
}
