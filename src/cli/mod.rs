//! The commands, one file each (as cargo's `src/bin/cargo/commands/<name>.rs`): its clap
//! `Args`, its examples and a `run` that parses, calls the library and reports. What
//! several commands share (the scene, the device and threads, outputs, progress, the
//! failure and its exit code) is in [`shared`]; what a command computes is in the library.

mod edit;
mod env;
mod fit;
mod fit_brdf;
mod grad;
mod grid;
mod info;
mod job;
mod normals;
mod presets;
mod render;
#[cfg(feature = "serve")]
mod serve;
mod shared;
mod synth;
mod transfer;

use clap::{Parser, Subcommand};

pub use shared::Failure;

const TOP_EXAMPLES: &str = "\
Examples:
  matedit render -o sphere.png                       (the default scene)
  matedit grad -o grads/ --upstream dloss_dimage.npy
  matedit info sky.exr
  matedit presets
  matedit env --kind sun-sky --seed 3 -o sky.exr     (a procedural light)
  matedit normals --shape blobby --seed 7 -o blob.png   (a normal map from a shape or mesh)
  matedit synth spec.json -o dataset/                (a dataset of rendered samples)
  matedit edit photo.jpg --material gold -o out/     (the object in a photo, made of gold)
  matedit serve                                      (the editor in a browser, on loopback)

Run `matedit help COMMAND` for a command's options and examples.";

/// Render and differentiate the rendering layer of Liu et al., ICCV 2017: per-pixel
/// normals lit by a lat-long HDR environment map through a 108-number Directional
/// Statistics BRDF.
#[derive(Parser)]
#[command(name = "matedit", version, propagate_version = true, after_help = TOP_EXAMPLES)]
pub struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render an image (or a batch of images) to EXR, NPY or PNG.
    #[command(after_help = render::EXAMPLES)]
    Render(render::Args),
    /// Differentiate: dLoss/d(env, normals, material) for an upstream dLoss/dImage.
    #[command(after_help = grad::EXAMPLES)]
    Grad(grad::Args),
    /// Generate a procedural HDR environment map, or turn, expose and white-balance one.
    #[command(after_help = env::EXAMPLES)]
    Env(env::Args),
    /// Describe an input file and say what matedit can use it as.
    #[command(after_help = info::EXAMPLES)]
    Info(info::Args),
    /// Fit the DSBRDF to a measured BRDF (a MERL table or NBRDF networks).
    #[command(after_help = fit_brdf::EXAMPLES)]
    FitBrdf(fit_brdf::Args),
    /// Fit a material (and the light) to an image by inverse rendering.
    #[command(after_help = fit::EXAMPLES)]
    Fit(fit::Args),
    /// Render one fit's shape and light with another fit's material.
    #[command(after_help = transfer::EXAMPLES)]
    Transfer(transfer::Args),
    /// The object in a photo made of another material: predicted, refined, composited.
    #[command(after_help = edit::EXAMPLES)]
    Edit(edit::Args),
    /// The material editor as a local web page: drop a photo, pick materials, turn the light.
    #[cfg(feature = "serve")]
    #[command(after_help = serve::EXAMPLES)]
    Serve(serve::Args),
    /// Every fit's shape and light with every fit's material, as one picture.
    #[command(after_help = grid::EXAMPLES)]
    Grid(grid::Args),
    /// Synthesise a dataset: samples drawn from a spec, rendered, written as tar chunks.
    #[command(after_help = synth::EXAMPLES)]
    Synth(synth::Args),
    /// A normal map and mask from a mesh file or a seeded procedural shape.
    #[command(after_help = normals::EXAMPLES)]
    Normals(normals::Args),
    /// List the built-in materials, or print one as a material JSON file.
    #[command(after_help = presets::EXAMPLES)]
    Presets(presets::Args),
}

impl Cli {
    /// Runs the command.
    pub fn run(&self) -> Result<(), Failure> {
        match &self.command {
            Command::Render(args) => render::run(args),
            Command::Grad(args) => grad::run(args),
            Command::Info(args) => info::run(args),
            Command::Env(args) => env::run(args),
            Command::FitBrdf(args) => fit_brdf::run(args),
            Command::Fit(args) => fit::run(args),
            Command::Transfer(args) => transfer::run(args),
            Command::Edit(args) => edit::run(args),
            #[cfg(feature = "serve")]
            Command::Serve(args) => serve::run(args),
            Command::Grid(args) => grid::run(args),
            Command::Synth(args) => synth::run(args),
            Command::Normals(args) => normals::run(args),
            Command::Presets(args) => presets::run(args),
        }
    }
}
