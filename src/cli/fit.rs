//! `matedit fit`: a material (and the light) fitted to an image by inverse rendering,
//! written as a fit folder.

use std::path::PathBuf;

use matedit::edit::{self, Light, ObjectNormals};
use matedit::io::EnvSize;
use matedit::{Camera, Convention, Device, Error};

use super::shared::{Failure, parse_fov, progress_bar, renderer, runtime};

/// Shown after the options by `matedit help fit`.
pub const EXAMPLES: &str = "\
Examples:
  matedit fit --image jade.exr --sphere -o fits/jade
  matedit fit --image photo.exr --normals normals.npy --mask mask.png --fit-env 8x16 -o fits/photo
  matedit fit --image ball.exr --sphere 256 --env studio.exr --init gold -o fits/ball

Optimises the 108 control points (and, without --env, a low-resolution light) with Adam
through the layer's backward pass. Writes DIR/material.json, env.exr, render.exr,
render.png, compare.png, loss.png, normals.npy, target.exr and report.json (psnr, steps, seconds).";

/// The options of `matedit fit`.
#[derive(clap::Args)]
pub struct Args {
    /// The image to fit: .exr or .npy (linear RGB, H x W x 3), .png or .jpg (sRGB, decoded to linear).
    #[arg(long, value_name = "FILE")]
    image: PathBuf,
    /// The object's normals (as for `render`), the image's size.
    #[arg(
        long,
        value_name = "FILE",
        conflicts_with = "sphere",
        required_unless_present = "sphere"
    )]
    normals: Option<PathBuf>,
    /// The object is a unit sphere filling the image (a matcap, a rendered ball); N, if given, must be the image's size.
    #[arg(long, value_name = "N", num_args = 0..=1, default_missing_value = "0")]
    sphere: Option<u32>,
    /// Pixels that count (.png, .exr or .npy, first channel above half) [default: every pixel on the object].
    #[arg(long, value_name = "FILE")]
    mask: Option<PathBuf>,
    /// The light is known: this lat-long map (only the material is fitted).
    #[arg(long, value_name = "FILE", conflicts_with = "fit_env")]
    env: Option<PathBuf>,
    /// Fit the light too, as an HxW map [default: 16x32, when no --env].
    #[arg(long, value_name = "HxW")]
    fit_env: Option<EnvSize>,
    /// With --env: its size, as for `render` [default: 64x128].
    #[arg(
        long,
        value_name = "HxW|full",
        requires = "env",
        conflicts_with = "fit_env"
    )]
    env_size: Option<EnvSize>,
    /// Texel convention: 'equirect' or 'paper' [default: equirect].
    #[arg(long, value_name = "NAME")]
    convention: Option<Convention>,
    /// Perspective camera with this vertical field of view in degrees [default: orthographic].
    #[arg(long, value_name = "DEG", value_parser = parse_fov)]
    fov: Option<f64>,
    /// The preset the material starts from (signs of its lobes are kept).
    #[arg(long, value_name = "PRESET", default_value = matedit::presets::DEFAULT, value_parser = clap::builder::PossibleValuesParser::new(matedit::presets::names()))]
    init: String,
    /// Most Adam steps (the fit stops earlier when the loss stalls).
    #[arg(long, value_name = "K", default_value_t = 600, value_parser = clap::value_parser!(u32).range(1..))]
    steps: u32,
    /// Fit on the image box-filtered to at most N pixels on its longer side (0: full size); the report's PSNR is at full size.
    #[arg(long, value_name = "N", default_value_t = 128)]
    work_size: u32,
    /// Backend, as for `render`.
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
    /// Worker threads of the CPU paths [default: one per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Output folder (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
}

/// Runs `matedit fit`.
pub fn run(args: &Args) -> Result<(), Failure> {
    edit::dir::check_folder(&args.output)?;
    let shape = match (&args.normals, args.sphere) {
        (Some(p), _) => ObjectNormals::File(p.clone()),
        (None, Some(n)) => ObjectNormals::Sphere((n != 0).then_some(n as usize)),
        (None, None) => unreachable!("clap requires --normals or --sphere"),
    };
    let inputs = edit::Inputs::load(&args.image, &shape, args.mask.as_deref())?;
    let convention = args.convention.unwrap_or_default();
    let (light, light_name) = match &args.env {
        Some(p) => (
            Light::load(p, args.env_size.unwrap_or_default(), convention)?,
            p.display().to_string(),
        ),
        None => {
            let (height, width) = match args.fit_env {
                Some(EnvSize::Size { height, width }) => (height, width),
                Some(EnvSize::Full) => {
                    return Err(Error::Invalid("--fit-env takes HxW, not 'full'".into()).into());
                }
                None => Light::DEFAULT_FIT,
            };
            (
                Light::Fit { height, width },
                format!("fitted {height}x{width}"),
            )
        }
    };
    let camera = match args.fov {
        Some(fov_y_deg) => Camera::Perspective { fov_y_deg },
        None => Camera::Orthographic,
    };
    let init = matedit::presets::lookup(&args.init).expect("clap checks preset names");
    let options = edit::Options {
        convention,
        camera,
        steps: args.steps as usize,
        work_size: args.work_size as usize,
        ..edit::Options::new(init, light)
    };
    let renderer = renderer(args.device, args.threads)?;
    let bar = progress_bar(
        u64::from(args.steps),
        "fitting {bar:30} {pos}/{len} {elapsed} {msg}",
    );
    let fitted = edit::fit(&renderer, &inputs, &options, &mut |step, loss| {
        if let Some(b) = &bar {
            b.set_position(step as u64 + 1);
            b.set_message(format!("loss {loss:.3e}"));
        }
    })?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let judged = edit::dir::judge(&renderer, &inputs, &fitted, camera)?;
    let report = edit::dir::Report {
        psnr: judged.psnr,
        steps: fitted.steps,
        seconds: fitted.seconds,
        loss: fitted.losses.last().copied().unwrap_or(f64::NAN),
        work_size: [fitted.work_size.0, fitted.work_size.1],
        image: args.image.display().to_string(),
        light: light_name,
        convention: convention.name().to_string(),
        fov: args.fov,
        init: args.init.clone(),
        device: renderer.describe(),
    };
    edit::dir::write_fit(&args.output, &inputs, &fitted, &judged, &report).map_err(runtime)?;
    eprintln!(
        "matedit: fitted in {:.1} s ({} steps at {}x{}), PSNR {:.2} dB; wrote {}",
        fitted.seconds,
        fitted.steps,
        fitted.work_size.0,
        fitted.work_size.1,
        judged.psnr,
        args.output.display()
    );
    Ok(())
}
