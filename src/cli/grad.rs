//! `matedit grad`: dLoss/d(env, normals, material) for an upstream dLoss/dImage, as files
//! in a folder per scene.

use std::path::{Path, PathBuf};
use std::time::Instant;

use matedit::io::{self, job::Plan};
use matedit::{Batch, Error, Gradients, Wanted};

use super::shared::{
    Failure, SceneArgs, check_method, print_timings, renderer, report, runtime, with_progress,
};

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

fn check_grad_dir(dir: &Path) -> Result<(), Failure> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::file(dir, "exists and is not a folder").into());
    }
    if !dir.exists() {
        io::check_parent(dir)?;
    }
    Ok(())
}

pub fn run(args: &Args) -> Result<(), Failure> {
    let plan = args
        .scene
        .plan(args.output.as_deref(), args.upstream.as_deref())?;
    for s in &plan.scenes {
        check_grad_dir(&s.output)?;
    }
    let loaded = plan.load()?;
    let upstream = plan.load_upstream(&loaded.batch)?;
    for n in &loaded.notes {
        eprintln!("matedit: {n}");
    }
    let accuracy = args.scene.accuracy();
    check_method(&accuracy, &loaded.batch)?;
    let renderer = renderer(args.scene.device, args.scene.threads)?;
    let start = Instant::now();
    let (grads, choices) = with_progress("differentiating", || {
        renderer.backward_wanted_with(&loaded.batch, &upstream, &accuracy, args.wanted())
    })?;
    if args.scene.timings {
        print_timings(&renderer, start.elapsed());
    }
    report(&accuracy, &choices);
    // every scene's files are staged before any is put in place; on a failure the files
    // already in place and the folders this run created are removed: a batch is written
    // whole or not at all
    let mut created = Vec::new();
    let result = write_grads(&plan, &loaded.batch, &grads, args.wanted(), &mut created);
    if result.is_err() {
        io::remove_created(&created);
    }
    result
}

fn write_grads(
    plan: &Plan,
    batch: &Batch,
    grads: &[Gradients],
    wanted: Wanted,
    created: &mut Vec<PathBuf>,
) -> Result<(), Failure> {
    let mut staged = Vec::new();
    for ((spec, scene), g) in plan.scenes.iter().zip(batch.scenes()).zip(grads) {
        let dir = &spec.output;
        created.extend(io::create_dirs(dir).map_err(runtime)?);
        let env = &scene.env;
        let n = &scene.normals;
        let mut files = Vec::new();
        if wanted.env {
            let bytes = io::npy::encode_rgb(env.width, env.height, &g.d_env);
            files.push(("d_env.npy", bytes));
        }
        if wanted.normals {
            let bytes = io::npy::encode_rgb(n.width, n.height, &g.d_normals);
            files.push(("d_normals.npy", bytes));
        }
        if wanted.ctrl {
            files.push(("d_material.json", io::json::encode_gradient(&g.d_ctrl)));
        }
        for (name, bytes) in &files {
            staged.push(io::stage(&dir.join(name), bytes).map_err(runtime)?);
        }
    }
    for p in io::commit_all(staged).map_err(runtime)? {
        eprintln!("matedit: wrote {}", p.display());
    }
    Ok(())
}
