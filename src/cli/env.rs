//! `matedit env`: a procedural HDR environment map (sun-sky, overcast, studio, indoor), or
//! a map from a file, turned, exposed and white-balanced, to EXR, NPY or a PNG preview.

use std::path::PathBuf;

use matedit::envgen::{self, LightKind, Params, WhiteBalance};
use matedit::io::{self, EnvSize, Format, Preview, Tonemap};
use matedit::{Convention, Error};

use super::shared::{Failure, runtime};

/// Shown after the options by `matedit help env`.
pub const EXAMPLES: &str = "\
Examples:
  matedit env --kind sun-sky --seed 3 -o sky.exr
  matedit env --kind sun-sky --sun-elevation 10 --sun-azimuth 90 --turbidity 4 -o dusk.exr
  matedit env --kind studio --seed 12 --size 128x256 --turn 30 -o studio.npy
  matedit env --kind indoor --seed 5 -o room.png               (a tone-mapped preview)
  matedit env --input forest.exr --turn 12.5 --exposure -1 --white-balance 3200K -o warm.exr
  matedit render --env sky.exr -o sphere.png

Kinds: sun-sky (Preetham clear sky, sun disc, ground), overcast (CIE overcast sky),
studio (1-4 area lights over a surround), indoor (a room with a window, lamp optional).
The same kind, seed and size give the same map. --turn moves what is at azimuth phi to
phi + DEG (any angle: linear interpolation along each row, power kept). See docs/environments.md.";

/// The options of `matedit env`.
#[derive(clap::Args)]
pub struct Args {
    /// Output map: .exr (linear float32 RGB), .npy (float32, H x W x 3) or .png (8-bit tone-mapped preview).
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// The kind of light to generate.
    #[arg(
        long,
        value_name = "sun-sky|overcast|studio|indoor",
        required_unless_present = "input",
        conflicts_with = "input"
    )]
    kind: Option<LightKind>,
    /// An environment map (.exr or .npy, equirect) to augment instead of generating one.
    #[arg(long, value_name = "FILE")]
    input: Option<PathBuf>,
    /// Seed of the random parameters.
    #[arg(long, value_name = "S", default_value_t = 0)]
    seed: u64,
    /// Size HxW; with --input a divisor of the file's size ('full' keeps it) [default: 64x128; with --input: full].
    #[arg(long, value_name = "HxW")]
    size: Option<EnvSize>,
    /// sun-sky: the sun's elevation above the horizon, degrees in [0, 90] [default: drawn from the seed].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    sun_elevation: Option<f64>,
    /// sun-sky: the sun's azimuth, degrees (the map's phi: 0 at +x, 90 towards the viewer) [default: drawn].
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    sun_azimuth: Option<f64>,
    /// sun-sky: turbidity in [2, 10] (2 clear, 10 hazy) [default: drawn].
    #[arg(long, value_name = "T", allow_negative_numbers = true)]
    turbidity: Option<f64>,
    /// Turn the map about the vertical axis by DEG degrees (any angle).
    #[arg(long, value_name = "DEG", allow_negative_numbers = true)]
    turn: Option<f64>,
    /// Multiply the radiance by 2^EV.
    #[arg(long, value_name = "EV", allow_negative_numbers = true)]
    exposure: Option<f64>,
    /// White balance: a colour temperature (e.g. 3200K: the light as if from a 3200 K source instead of 6500 K) or per-channel gains R,G,B.
    #[arg(long, value_name = "KELVIN|R,G,B")]
    white_balance: Option<WhiteBalance>,
    /// PNG only: 'reinhard' maps x to x / (1 + x), 'clamp' clips above 1; then sRGB encoding.
    #[arg(long, value_name = "clamp|reinhard", default_value = "reinhard")]
    tonemap: Tonemap,
}

/// Runs `matedit env`.
pub fn run(args: &Args) -> Result<(), Failure> {
    io::check_output(&args.output, &[Format::Exr, Format::Npy, Format::Png])?;
    let sun_options =
        args.sun_elevation.is_some() || args.sun_azimuth.is_some() || args.turbidity.is_some();
    let (env, what) = match (&args.input, args.kind) {
        (Some(path), _) => {
            if sun_options {
                return Err(Error::Invalid(
                    "--sun-elevation, --sun-azimuth and --turbidity need --kind sun-sky".into(),
                )
                .into());
            }
            let loaded = io::load_env(path, Convention::Equirect)?;
            if loaded.clamped > 0 {
                eprintln!(
                    "matedit: {}: clamped {} negative values to 0",
                    path.display(),
                    loaded.clamped
                );
            }
            let env = io::resample::fit(loaded.env, args.size.unwrap_or(EnvSize::Full), path)?;
            (env, format!("from {}", path.display()))
        }
        (None, Some(kind)) => {
            let (height, width) = match args.size.unwrap_or_default() {
                EnvSize::Size { height, width } => (height, width),
                EnvSize::Full => {
                    return Err(Error::Invalid(
                        "--size full needs --input; give HxW, e.g. 64x128".into(),
                    )
                    .into());
                }
            };
            let mut params = Params::draw(kind, args.seed);
            match &mut params {
                Params::SunSky(p) => {
                    p.elevation = args.sun_elevation.unwrap_or(p.elevation);
                    p.azimuth = args.sun_azimuth.unwrap_or(p.azimuth);
                    p.turbidity = args.turbidity.unwrap_or(p.turbidity);
                }
                _ if sun_options => {
                    return Err(Error::Invalid(format!(
                        "--sun-elevation, --sun-azimuth and --turbidity are for --kind sun-sky, not {kind}"
                    ))
                    .into());
                }
                _ => {}
            }
            let env = params.env(height, width)?;
            (env, format!("{kind}, seed {}: {params}", args.seed))
        }
        (None, None) => return Err(Error::Invalid("give --kind or --input".into()).into()),
    };
    let mut env = env;
    if let Some(deg) = args.turn {
        env = envgen::turn(&env, deg)?;
    }
    if let Some(ev) = args.exposure {
        env = envgen::exposure(&env, ev)?;
    }
    if let Some(wb) = args.white_balance {
        env = envgen::white_balance(&env, wb)?;
    }
    let preview = Preview {
        exposure: 0.0,
        tonemap: args.tonemap,
    };
    io::write_env(&args.output, &env, &preview).map_err(runtime)?;
    eprintln!(
        "matedit: wrote {} ({}x{}, {what})",
        args.output.display(),
        env.height,
        env.width
    );
    Ok(())
}
