//! `matedit transfer`: one fit's shape and light rendered with another fit's material.

use std::path::PathBuf;

use matedit::edit::{dir, transfer};
use matedit::io::{self, Format, Preview};
use matedit::{Device, Renderer};

use super::shared::{Failure, runtime};

/// Shown after the options by `matedit help transfer`.
pub const EXAMPLES: &str = "\
Examples:
  matedit transfer --shape-light fits/jade --material fits/metal -o jade_as_metal.png";

/// The options of `matedit transfer`.
#[derive(clap::Args)]
pub struct Args {
    /// The fit folder whose normals, light and camera are kept.
    #[arg(long, value_name = "DIR")]
    shape_light: PathBuf,
    /// The fit folder (or material .json file) whose material is used.
    #[arg(long, value_name = "DIR|FILE")]
    material: PathBuf,
    /// Output image (.exr, .npy or .png).
    #[arg(short, long, value_name = "OUT")]
    output: PathBuf,
    /// Backend, as for `render`.
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
}

/// Runs `matedit transfer`.
pub fn run(args: &Args) -> Result<(), Failure> {
    io::check_output(&args.output, &[Format::Exr, Format::Npy, Format::Png])?;
    let a = dir::read(&args.shape_light)?;
    let material = dir::read_material(&args.material)?;
    let renderer = Renderer::new(args.device)?;
    let image = transfer::transfer(&renderer, &a, &material)?;
    let bytes = io::encode_image(&args.output, &image, &Preview::default())?;
    io::write_atomic(&args.output, &bytes).map_err(runtime)?;
    eprintln!("matedit: wrote {}", args.output.display());
    Ok(())
}
