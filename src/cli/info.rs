//! `matedit info`: what a file holds and what matedit can use it as.

use std::path::PathBuf;

use matedit::io;

use super::shared::Failure;

/// Shown after the options by `matedit help info`.
pub const EXAMPLES: &str = "\
Examples:
  matedit info sky.exr
  matedit info normals.npy
  matedit info material.json";

/// The options of `matedit info`.
#[derive(clap::Args)]
pub struct Args {
    /// An .exr, .npy, .png or .json file.
    file: PathBuf,
}

/// Runs `matedit info`.
pub fn run(args: &Args) -> Result<(), Failure> {
    print!("{}", io::info::describe(&args.file)?);
    Ok(())
}
