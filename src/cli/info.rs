//! `matedit info`: what a file holds and what matedit can use it as.

use std::path::PathBuf;

use matedit::io;

use super::shared::Failure;

pub const EXAMPLES: &str = "\
Examples:
  matedit info sky.exr
  matedit info normals.npy
  matedit info material.json";

#[derive(clap::Args)]
pub struct Args {
    /// An .exr, .npy, .png or .json file.
    file: PathBuf,
}

pub fn run(args: &Args) -> Result<(), Failure> {
    print!("{}", io::info::describe(&args.file)?);
    Ok(())
}
