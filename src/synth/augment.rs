//! Per-sample augmentations of shapes and lights: how a mesh or shape is turned towards the
//! camera (`views`), and how a map is turned, exposed and white-balanced.

use serde_json::{Value, json};

use crate::envgen::augment::{self, WhiteBalance};
use crate::envmap::EnvMap;
use crate::error::Result;
use crate::shapes::Rotation;
use crate::splitmix::SplitMix;

/// Largest tilt of an upright view towards the camera, degrees.
pub const UPRIGHT_TILT: f64 = 30.0;

/// How a mesh or a shape is turned for each sample.
#[derive(Clone, Debug, PartialEq)]
pub enum Views {
    /// A uniformly random rotation (the default).
    Random,
    /// Standing as the file has it (+y up), turned about +y uniformly and tilted towards
    /// the camera by up to [`UPRIGHT_TILT`] degrees (seen from a little above), no roll:
    /// objects as people photograph them.
    Upright,
    /// One of these rotations (yaw, pitch, roll in degrees), picked uniformly.
    Listed(Vec<Rotation>),
}

impl Views {
    /// `"random"`, `"upright"` or a list of `[yaw, pitch, roll]`; absent: random.
    pub fn parse(v: Option<&Value>) -> std::result::Result<Views, String> {
        match v {
            None => Ok(Views::Random),
            Some(Value::String(s)) if s == "random" => Ok(Views::Random),
            Some(Value::String(s)) if s == "upright" => Ok(Views::Upright),
            Some(Value::Array(list)) if !list.is_empty() => list
                .iter()
                .enumerate()
                .map(|(i, r)| {
                    let a: Option<Vec<f64>> = r
                        .as_array()
                        .map(|a| a.iter().filter_map(Value::as_f64).collect());
                    match a.as_deref() {
                        Some(&[yaw, pitch, roll]) => {
                            let r = Rotation { yaw, pitch, roll };
                            r.validate().map_err(|e| format!("views[{i}]: {e}"))?;
                            Ok(r)
                        }
                        _ => Err(format!(
                            "views[{i}]: {r} is not [yaw, pitch, roll] in degrees"
                        )),
                    }
                })
                .collect::<std::result::Result<_, _>>()
                .map(Views::Listed),
            Some(other) => Err(format!(
                "views: {other} is not \"random\", \"upright\" or a list of [yaw, pitch, roll]"
            )),
        }
    }

    /// The rotation of one sample, drawn from `rng`.
    pub fn draw(&self, rng: &mut SplitMix) -> Rotation {
        match self {
            Views::Random => Rotation::random(rng.next_u64()),
            Views::Upright => Rotation {
                yaw: 360.0 * rng.uniform(),
                pitch: UPRIGHT_TILT * rng.uniform(),
                roll: 0.0,
            },
            Views::Listed(list) => list[rng.below(list.len())],
        }
    }
}

/// How each sample changes its map: a turn about the vertical axis by an angle uniform in
/// [0, 360) (linear in phi, power kept: [`augment::turn`]), an exposure uniform in a range
/// of stops, a white balance uniform in a range of kelvin.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EnvAugment {
    /// Turn by a random angle.
    pub turn: bool,
    /// Exposure range, stops.
    pub exposure: Option<[f64; 2]>,
    /// White balance range, kelvin.
    pub white_balance: Option<[f64; 2]>,
}

impl EnvAugment {
    /// Checks the ranges.
    pub fn validate(&self) -> std::result::Result<(), String> {
        if let Some([lo, hi]) = self.exposure
            && !(lo.is_finite()
                && hi.is_finite()
                && lo <= hi
                && lo.abs() <= 20.0
                && hi.abs() <= 20.0)
        {
            return Err(format!(
                "exposure: [{lo}, {hi}] must be a range of stops within [-20, 20] with lo <= hi"
            ));
        }
        if let Some([lo, hi]) = self.white_balance {
            let (min, max) = crate::envgen::colour::TEMPERATURE_RANGE;
            if !(lo.is_finite() && hi.is_finite() && lo <= hi && lo >= min && hi <= max) {
                return Err(format!(
                    "white_balance: [{lo}, {hi}] must be a range of kelvin within [{min}, {max}] with lo <= hi"
                ));
            }
        }
        Ok(())
    }

    /// `env` changed by one draw from `rng`, and what the sample records of it.
    pub fn apply(&self, env: EnvMap, rng: &mut SplitMix) -> Result<(EnvMap, Value)> {
        let mut env = env;
        let mut record = serde_json::Map::new();
        if self.turn {
            let degrees = 360.0 * rng.uniform();
            env = augment::turn(&env, degrees)?;
            record.insert("turn_degrees".into(), json!(degrees));
        }
        if let Some([lo, hi]) = self.exposure {
            let stops = lo + (hi - lo) * rng.uniform();
            env = augment::exposure(&env, stops)?;
            record.insert("exposure_stops".into(), json!(stops));
        }
        if let Some([lo, hi]) = self.white_balance {
            let kelvin = lo + (hi - lo) * rng.uniform();
            env = augment::white_balance(&env, WhiteBalance::Temperature(kelvin))?;
            record.insert("white_balance_kelvin".into(), json!(kelvin));
        }
        Ok((env, Value::Object(record)))
    }
}
