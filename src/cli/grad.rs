//! `matedit grad`: dLoss/d(env, normals, material) for an upstream dLoss/dImage, as files
//! in a folder per scene.

use std::path::PathBuf;
use std::time::Instant;

use matedit::io;
use matedit::{Wanted, continuous_light};

use super::shared::{
    Failure, SceneArgs, check_method, light_details, print_timings, renderer, report, report_light,
    report_light_level, runtime, with_progress,
};

/// Shown after the options by `matedit help grad`.
pub const EXAMPLES: &str = "\
Examples:
  matedit grad -o grads/ --upstream dloss_dimage.npy
  matedit grad -o grads/ --sphere 64 --env sky.exr --preset clay --upstream up.exr
  matedit grad --batch scenes.json -o grads/
  matedit grad -o grads/ --upstream up.npy --only ctrl

Writes DIR/d_env.npy (H_L x W_L x 3), DIR/d_normals.npy (H x W x 3) and
DIR/d_material.json ({\"ctrl\": [108 numbers]}); --only ctrl (or env, normals, a
comma-separated list) computes and writes only those, in less time. With --batch, each
scene's 'output' is its folder and 'upstream' its gradient file.";

/// The options of `matedit grad`.
#[derive(clap::Args)]
pub struct Args {
    /// Output folder (created if missing); with --batch, the folder that relative outputs go to.
    #[arg(short, long, value_name = "DIR", required_unless_present = "batch")]
    output: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    /// Upstream gradient dLoss/dImage, H x W x 3, .npy or .exr.
    #[arg(long, value_name = "FILE", required_unless_present = "batch")]
    upstream: Option<PathBuf>,
    /// Compute and write only these gradients (comma-separated) [default: all three].
    #[arg(long, value_name = "LIST", value_delimiter = ',')]
    only: Vec<GradKind>,
}

/// One of the three gradients `grad` writes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum GradKind {
    /// dLoss/dL: d_env.npy.
    Env,
    /// dLoss/dn: d_normals.npy.
    Normals,
    /// dLoss/dctrl: d_material.json.
    Ctrl,
}

impl Args {
    fn wanted(&self) -> Wanted {
        if self.only.is_empty() {
            return Wanted::ALL;
        }
        Wanted {
            env: self.only.contains(&GradKind::Env),
            normals: self.only.contains(&GradKind::Normals),
            ctrl: self.only.contains(&GradKind::Ctrl),
        }
    }
}

/// Runs `matedit grad`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let plan = args
        .scene
        .plan(args.output.as_deref(), args.upstream.as_deref())?;
    io::outputs::check_gradient_folders(&plan.outputs())?;
    let loaded = plan.load()?;
    let upstream = plan.load_upstream(&loaded.batch)?;
    for n in &loaded.notes {
        eprintln!("matedit: {n}");
    }
    let accuracy = args.scene.accuracy();
    check_method(&accuracy, &loaded.batch)?;
    let light = args.scene.light(continuous_light::Integration::Discrete);
    for s in loaded.batch.scenes() {
        light.validate(s)?;
    }
    let details = light_details(&plan, &loaded.batch, light)?;
    let renderer = renderer(args.scene.device, args.scene.threads)?;
    let start = Instant::now();
    let (grads, (choices, light_choices)) = with_progress("differentiating", || {
        continuous_light::backward(
            &renderer,
            &loaded.batch,
            &upstream,
            &accuracy,
            light,
            args.wanted(),
            &details,
        )
    })?;
    if args.scene.timings {
        print_timings(&renderer, start.elapsed());
    }
    report(&accuracy, &choices);
    report_light(&light_choices);
    report_light_level(light, &details);
    let written =
        io::outputs::write_gradients(&plan.outputs(), &loaded.batch, &grads, args.wanted())
            .map_err(runtime)?;
    for p in written {
        eprintln!("matedit: wrote {}", p.display());
    }
    Ok(())
}
