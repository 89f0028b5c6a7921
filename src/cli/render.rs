//! `matedit render`: an image, or a manifest's batch of images, to EXR, NPY or PNG.

use std::path::PathBuf;
use std::time::Instant;

use matedit::{builtin_sky, continuous_light, io};

use super::shared::{
    Failure, PreviewArgs, SceneArgs, check_method, light_details, print_timings, renderer, report,
    report_light, report_light_level, runtime, with_progress,
};

/// Shown after the options by `matedit help render`.
pub const EXAMPLES: &str = "\
Examples:
  matedit render -o sphere.png
  matedit render -o glossy.exr --preset chrome-ish --env studio.exr --light-tolerance 1e-3
  matedit render -o gold.exr --preset gold --env studio.exr --env-size 128x256
  matedit render -o face.npy --normals face_normals.png --material mat.json --fov 40
  matedit render --batch scenes.json -o renders/

Outputs by extension: .exr (linear float32 RGB), .npy (float32, H x W x 3),
.png (8-bit sRGB preview: value * 2^exposure, then the tonemap, clamped to [0, 1],
then sRGB-encoded). See docs/FORMATS.md for every file format and the manifest.";

/// The options of `matedit render`.
#[derive(clap::Args)]
pub struct Args {
    /// Output image (.exr, .npy or .png); with --batch, the folder that relative outputs go to.
    #[arg(short, long, value_name = "OUT", required_unless_present = "batch")]
    output: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    preview: PreviewArgs,
}

/// Runs `matedit render`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let plan = args.scene.plan(args.output.as_deref(), None)?;
    io::outputs::check_images(&plan.outputs())?;
    let loaded = plan.load()?;
    for n in &loaded.notes {
        eprintln!("matedit: {n}");
    }
    let accuracy = args.scene.accuracy();
    check_method(&accuracy, &loaded.batch)?;
    // the built-in sky is a picture to look at: its default is the continuous light
    let builtin = args.scene.env.is_none() && args.scene.batch.is_none();
    let light = args.scene.light(if builtin {
        continuous_light::Integration::Level(builtin_sky::LIGHT_LEVEL)
    } else {
        continuous_light::Integration::Discrete
    });
    for s in loaded.batch.scenes() {
        light.validate(s)?;
    }
    let details = light_details(&plan, &loaded.batch, light)?;
    let renderer = renderer(args.scene.device, args.scene.threads)?;
    let start = Instant::now();
    let (images, (choices, light_choices)) = with_progress("rendering", || {
        continuous_light::render(&renderer, &loaded.batch, &accuracy, light, &details)
    })?;
    if args.scene.timings {
        print_timings(&renderer, start.elapsed());
    }
    report(&accuracy, &choices);
    report_light(&light_choices);
    report_light_level(light, &details);
    let written = io::outputs::write_images(&plan.outputs(), &images, &args.preview.preview())
        .map_err(runtime)?;
    for (p, image) in written.iter().zip(&images) {
        eprintln!(
            "matedit: wrote {} ({}x{})",
            p.display(),
            image.width,
            image.height
        );
    }
    Ok(())
}
