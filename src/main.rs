//! The `matedit` command line: parses the arguments, calls the library, reports.
//!
//! Exit codes: 0 success, 2 bad usage or bad input (clap's usage errors, and every
//! [`matedit::Error::is_input_error`]), 1 runtime failures (no GPU for `--device gpu`, a
//! device error, a failed write). Errors are printed as one line on stderr; no output file
//! is left behind by a failed run.

use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::{Duration, Instant};

use clap::{Args, Parser, Subcommand};
use matedit::io::job::{Plan, SceneOptions};
use matedit::io::source::{MaterialSource, NormalsSource};
use matedit::io::{self, EnvSize, Format, Preview, Tonemap};
use matedit::{Accuracy, Convention, Device, Error, Renderer, lod};

const TOP_EXAMPLES: &str = "\
Examples:
  matedit render -o sphere.png                       (the default scene)
  matedit grad -o grads/ --upstream dloss_dimage.npy
  matedit info sky.exr
  matedit presets
  matedit synth spec.json -o dataset/                (a dataset of rendered samples)

Run `matedit help COMMAND` for a command's options and examples.";

const RENDER_EXAMPLES: &str = "\
Examples:
  matedit render -o sphere.png
  matedit render -o gold.exr --preset gold --env studio.exr --env-size 128x256
  matedit render -o face.npy --normals face_normals.png --material mat.json --fov 40
  matedit render --batch scenes.json -o renders/

Outputs by extension: .exr (linear float32 RGB), .npy (float32, H x W x 3),
.png (8-bit sRGB preview: value * 2^exposure, then the tonemap, clamped to [0, 1],
then sRGB-encoded). See docs/FORMATS.md for every file format and the manifest.";

const GRAD_EXAMPLES: &str = "\
Examples:
  matedit grad -o grads/ --upstream dloss_dimage.npy
  matedit grad -o grads/ --sphere 64 --env sky.exr --preset clay --upstream up.exr
  matedit grad --batch scenes.json -o grads/
  matedit grad -o grads/ --upstream up.npy --only ctrl

Writes DIR/d_env.npy (H_L x W_L x 3), DIR/d_normals.npy (H x W x 3) and
DIR/d_material.json ({\"ctrl\": [108 numbers]}); --only ctrl (or env, normals, a
comma-separated list) computes and writes only those, in less time. With --batch, each
scene's 'output' is its folder and 'upstream' its gradient file.";

const INFO_EXAMPLES: &str = "\
Examples:
  matedit info sky.exr
  matedit info normals.npy
  matedit info material.json";

const FIT_EXAMPLES: &str = "\
Examples:
  matedit fit-brdf --merl gold-metallic-paint.binary -o gold.json
  matedit fit-brdf --nbrdf data/merl/merl_nbrdf.json --name alum-bronze -o alum.json --lobes 2
  matedit fit-brdf --nbrdf data/merl/merl_nbrdf.json -o fits/
  matedit fit-brdf --nbrdf data/merl/merl_nbrdf.json --bundle data/merl/fits.json

Fits the 108 control points to the BRDF over (theta_h, theta_d); phi_d, which the
DSBRDF cannot represent, is averaged with the weights cos theta_i cos theta_o. With
--lobes auto (the default) 1, 2 and 3 lobes are fitted and the fewest whose BRDF error
is within --tolerance of the 3-lobe fit's is kept; unused lobes have m0 = 0.
--bundle writes every fit into one file, the format of the shipped presets.";

const FIT_IMAGE_EXAMPLES: &str = "\
Examples:
  matedit fit --image jade.exr --sphere -o fits/jade
  matedit fit --image photo.exr --normals normals.npy --mask mask.png --fit-env 8x16 -o fits/photo
  matedit fit --image ball.exr --sphere 256 --env studio.exr --init gold -o fits/ball

Optimises the 108 control points (and, without --env, a low-resolution light) with Adam
through the layer's backward pass. Writes DIR/material.json, env.exr, render.exr,
render.png, compare.png, loss.png, normals.npy, target.exr and report.json (psnr, steps, seconds).";

const TRANSFER_EXAMPLES: &str = "\
Examples:
  matedit transfer --shape-light fits/jade --material fits/metal -o jade_as_metal.png";

const GRID_EXAMPLES: &str = "\
Examples:
  matedit grid fits/jade fits/metal fits/clay -o grid.png

Row i keeps fit i's shape and light, column j brings fit j's material; the diagonal
shows the images fitted to.";

const SYNTH_EXAMPLES: &str = "\
Examples:
  matedit synth spec.json -o dataset/
  matedit synth spec.json -o dataset/ --shard 3/16      (one task of an array job)
  matedit synth spec.json -o dataset/ --verify          (after the shards: check, list all)

spec.json: {\"count\": 12, \"seed\": 7, \"image_size\": 64, \"env_size\": \"32x64\",
  \"normals\": [{\"sphere\": 64}, {\"bumpy\": 64}], \"envs\": [\"sky.exr\"],
  \"materials\": [{\"preset\": \"gold\"}, {\"random\": \"merl\"}]}
Writes DIR/chunk-NNNNNN.tar (WebDataset style: KEY.env.npy, KEY.image.npy,
KEY.material.json, KEY.normals.npy, KEY.params.json per sample), a record
chunk-NNNNNN.json beside each, and DIR/manifest.json. Sample k depends on the spec,
its seed and k alone: any split into shards writes the same chunk files, bit for bit.
A re-run skips the chunks already complete. See docs/synth.md.";

const PRESETS_EXAMPLES: &str = "\
Examples:
  matedit presets
  matedit presets gold > gold.json     (then edit it and use --material gold.json)";

/// Render and differentiate the rendering layer of Liu et al., ICCV 2017: per-pixel
/// normals lit by a lat-long HDR environment map through a 108-number Directional
/// Statistics BRDF.
#[derive(Parser)]
#[command(name = "matedit", version, propagate_version = true, after_help = TOP_EXAMPLES)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render an image (or a batch of images) to EXR, NPY or PNG.
    #[command(after_help = RENDER_EXAMPLES)]
    Render(RenderArgs),
    /// Differentiate: dLoss/d(env, normals, material) for an upstream dLoss/dImage.
    #[command(after_help = GRAD_EXAMPLES)]
    Grad(GradArgs),
    /// Describe an input file and say what matedit can use it as.
    #[command(after_help = INFO_EXAMPLES)]
    Info {
        /// An .exr, .npy, .png or .json file.
        file: PathBuf,
    },
    /// Fit the DSBRDF to a measured BRDF (a MERL table or NBRDF networks).
    #[command(after_help = FIT_EXAMPLES)]
    FitBrdf(FitArgs),
    /// Fit a material (and the light) to an image by inverse rendering.
    #[command(after_help = FIT_IMAGE_EXAMPLES)]
    Fit(FitImageArgs),
    /// Render one fit's shape and light with another fit's material.
    #[command(after_help = TRANSFER_EXAMPLES)]
    Transfer(TransferArgs),
    /// Every fit's shape and light with every fit's material, as one picture.
    #[command(after_help = GRID_EXAMPLES)]
    Grid(GridArgs),
    /// Synthesise a dataset: samples drawn from a spec, rendered, written as tar chunks.
    #[command(after_help = SYNTH_EXAMPLES)]
    Synth(SynthArgs),
    /// List the built-in materials, or print one as a material JSON file.
    #[command(after_help = PRESETS_EXAMPLES)]
    Presets {
        /// Print this preset's material JSON instead of the list.
        name: Option<String>,
    },
}

#[derive(Args)]
struct FitArgs {
    /// An NBRDF network file (one or more materials), e.g. data/merl/merl_nbrdf.json.
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "merl",
        conflicts_with = "merl"
    )]
    nbrdf: Option<PathBuf>,
    /// The material of the NBRDF file to fit [default: all of them].
    #[arg(long, value_name = "NAME", requires = "nbrdf")]
    name: Option<String>,
    /// A MERL measured BRDF table (.binary).
    #[arg(long, value_name = "FILE")]
    merl: Option<PathBuf>,
    /// Output: a material .json for one material, a folder (one NAME.json each) for several.
    #[arg(short, long, value_name = "OUT", required_unless_present = "bundle")]
    output: Option<PathBuf>,
    /// Also (or only) write every fit into this one .json file, the presets' format.
    #[arg(long, value_name = "FILE")]
    bundle: Option<PathBuf>,
    /// Lobes to fit: 1, 2, 3 or auto.
    #[arg(long, value_name = "N", default_value = "auto", value_parser = parse_lobes)]
    lobes: matedit::fit::Lobes,
    /// With --lobes auto: the relative slack over the 3-lobe BRDF error allowed to fewer lobes.
    #[arg(long, value_name = "REL", default_value_t = 0.05, value_parser = parse_tolerance_slack)]
    tolerance: f64,
}

#[derive(Args)]
struct FitImageArgs {
    /// The image to fit: .exr or .npy (linear RGB, H x W x 3) or .png (sRGB, decoded to linear).
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
    #[arg(long, value_name = "HxW|full", requires = "env")]
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

#[derive(Args)]
struct TransferArgs {
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

#[derive(Args)]
struct GridArgs {
    /// Fit folders from `matedit fit`, in the grid's order.
    #[arg(value_name = "DIR", required = true, num_args = 2..)]
    fits: Vec<PathBuf>,
    /// Output picture (.png).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Pixels per cell side.
    #[arg(long, value_name = "N", default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=2048))]
    cell: u32,
    #[command(flatten)]
    preview: PreviewArgs,
    /// Backend, as for `render`.
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
}

fn parse_lobes(v: &str) -> Result<matedit::fit::Lobes, String> {
    match v {
        "auto" => Ok(matedit::fit::Lobes::Auto),
        "1" | "2" | "3" => Ok(matedit::fit::Lobes::Fixed(v.parse().expect("a digit"))),
        _ => Err(format!("'{v}' is not 1, 2, 3 or auto")),
    }
}

fn parse_tolerance_slack(v: &str) -> Result<f64, String> {
    match v.parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("'{v}' is not a number >= 0")),
    }
}

#[derive(Args)]
struct SceneArgs {
    /// Normal map: .exr (channels R, G, B = n.x, n.y, n.z), .npy (H x W x 3) or .png (8-bit, n = 2v/255 - 1).
    #[arg(long, value_name = "FILE", conflicts_with = "sphere")]
    normals: Option<PathBuf>,
    /// A unit sphere filling an N x N image [default: 256 when no --normals].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=8192))]
    sphere: Option<u32>,
    /// Lat-long HDR environment map, .exr or .npy, row 0 = top [default: a built-in procedural sky with a sun].
    #[arg(long, value_name = "FILE")]
    env: Option<PathBuf>,
    /// Environment size HxW; a larger map is downsampled by a whole factor per axis (solid-angle weighted); 'full' keeps the file's size [default: 64x128].
    #[arg(long, value_name = "HxW|full")]
    env_size: Option<EnvSize>,
    /// Texel convention: 'equirect' (physical solid angles) or 'paper' (the supplemental's equations) [default: equirect].
    #[arg(long, value_name = "NAME")]
    convention: Option<Convention>,
    /// Material JSON file: {"name": ..., "ctrl": [108 numbers]}.
    #[arg(long, value_name = "FILE", conflicts_with = "preset")]
    material: Option<PathBuf>,
    /// A built-in material (see `matedit presets`) [default: plastic-red].
    #[arg(long, value_name = "NAME", value_parser = clap::builder::PossibleValuesParser::new(matedit::presets::names()))]
    preset: Option<String>,
    /// Perspective camera with this vertical field of view in degrees [default: orthographic].
    #[arg(long, value_name = "DEG", value_parser = parse_fov)]
    fov: Option<f64>,
    /// Backend: auto (a hardware GPU if any, else cpu), gpu (any wgpu adapter, lavapipe included), cpu (the fast f32 SIMD path) or reference (the f64 reference).
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
    /// Worker threads of the CPU paths [default: RAYON_NUM_THREADS, else one per core]. Results do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Approximate: the cheapest level of detail whose estimated relative error (max |I - I_exact| over max I_exact; with `grad`, each gradient's too) is within REL, chosen per scene and printed on stderr [default: exact].
    #[arg(long, value_name = "REL", value_parser = parse_tolerance, conflicts_with = "method")]
    tolerance: Option<f64>,
    /// A level of detail by name: 'exact', or parts joined by '+': envF (the map in F x F blocks), keepK (its K brightest texels kept), tableR (an R x R table of normals), cullB (lights culled within B of the largest value); tables and culling need an orthographic camera. E.g. table128+keep16.
    #[arg(long, value_name = "METHOD")]
    method: Option<lod::Method>,
    /// A JSON manifest listing several scenes, rendered in one batch (see docs/FORMATS.md). Options above are defaults for what it leaves out.
    #[arg(long, value_name = "MANIFEST")]
    batch: Option<PathBuf>,
    /// Print on stderr the time of each pass of the last call on the device (GPU timestamps: seconds and pixel-texel pairs per second) where the adapter has timestamp queries; on other devices the call's host time.
    #[arg(long)]
    timings: bool,
}

#[derive(Args)]
struct RenderArgs {
    /// Output image (.exr, .npy or .png); with --batch, the folder that relative outputs go to.
    #[arg(short, long, value_name = "OUT", required_unless_present = "batch")]
    output: Option<PathBuf>,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    preview: PreviewArgs,
}

#[derive(Args)]
struct PreviewArgs {
    /// PNG only: exposure in stops; values are multiplied by 2^EV.
    #[arg(
        long,
        value_name = "EV",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    exposure: f32,
    /// PNG only: 'clamp' clips values above 1 (after exposure), 'reinhard' maps x to x / (1 + x); then sRGB encoding.
    #[arg(long, value_name = "clamp|reinhard", default_value = "clamp")]
    tonemap: Tonemap,
}

impl PreviewArgs {
    fn preview(&self) -> Preview {
        Preview {
            exposure: self.exposure,
            tonemap: self.tonemap,
        }
    }
}

#[derive(Args)]
struct GradArgs {
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

impl GradArgs {
    fn wanted(&self) -> matedit::Wanted {
        if self.only.is_empty() {
            return matedit::Wanted::ALL;
        }
        matedit::Wanted {
            env: self.only.contains(&GradKind::Env),
            normals: self.only.contains(&GradKind::Normals),
            ctrl: self.only.contains(&GradKind::Ctrl),
        }
    }
}

#[derive(Args)]
struct SynthArgs {
    /// The spec: a JSON file naming the sources, the count, the sizes and the seed (see docs/synth.md).
    spec: PathBuf,
    /// Output folder (created if missing).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Write only shard I of N: the chunks c with c mod N = I (for array jobs).
    #[arg(long, value_name = "I/N", default_value = "0/1")]
    shard: matedit::synth::Shard,
    /// Backend: cpu (the fast f32 SIMD path), gpu, reference or auto. The chunks' bits depend on it (and on the CPU path's instruction set, see MATEDIT_SIMD), not on the split or the thread count.
    #[arg(long, value_name = "cpu|gpu|reference|auto", default_value = "cpu")]
    device: Device,
    /// Worker threads of the CPU paths [default: RAYON_NUM_THREADS, else one per core].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    threads: Option<u16>,
    /// Render nothing: check every chunk against its record and rewrite the manifest; fails if any chunk is missing.
    #[arg(long, conflicts_with = "shard")]
    verify: bool,
}

fn parse_tolerance(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not a positive number"))
    }
}

fn parse_fov(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() && v > 0.0 && v < 180.0 {
        Ok(v)
    } else {
        Err(format!("{v} degrees is outside (0, 180)"))
    }
}

/// A failure and the exit code it gets.
struct Failure {
    error: Error,
    code: u8,
}

impl From<Error> for Failure {
    fn from(error: Error) -> Self {
        let code = if error.is_input_error() { 2 } else { 1 };
        Failure { error, code }
    }
}

/// A runtime failure (exit code 1) whatever the error's kind, e.g. a write that failed
/// after the inputs were accepted.
fn runtime(error: Error) -> Failure {
    Failure { error, code: 1 }
}

impl SceneArgs {
    fn accuracy(&self) -> Accuracy {
        match (self.tolerance, self.method) {
            (Some(t), _) => Accuracy::Tolerance(t),
            (None, Some(m)) => Accuracy::Method(m),
            (None, None) => Accuracy::Exact,
        }
    }

    fn options(&self) -> SceneOptions {
        SceneOptions {
            normals: match (&self.normals, self.sphere) {
                (Some(p), _) => Some(NormalsSource::File(p.clone())),
                (None, Some(n)) => Some(NormalsSource::Sphere(n as usize)),
                (None, None) => None,
            },
            env: self.env.clone(),
            env_size: self.env_size,
            convention: self.convention,
            material: match (&self.material, &self.preset) {
                (Some(p), _) => Some(MaterialSource::File(p.clone())),
                (None, Some(n)) => Some(MaterialSource::Preset(n.clone())),
                (None, None) => None,
            },
            fov: self.fov,
        }
    }

    /// The plan: one scene from the options, or the manifest's scenes.
    fn plan(&self, output: Option<&Path>, upstream: Option<&Path>) -> Result<Plan, Failure> {
        let opts = self.options();
        match &self.batch {
            Some(manifest) => {
                let m = io::manifest::read(manifest, output)?;
                Ok(Plan::from_manifest(&opts, &m, upstream))
            }
            None => {
                let output = output.ok_or_else(|| Error::Invalid("no output given (-o)".into()))?;
                Ok(Plan::single(
                    &opts,
                    output.to_path_buf(),
                    upstream.map(Path::to_path_buf),
                ))
            }
        }
    }
}

/// Runs `f`, showing a spinner on stderr if it takes more than a second and stderr is a
/// terminal.
fn with_progress<T>(label: &'static str, f: impl FnOnce() -> T) -> T {
    if !std::io::stderr().is_terminal() {
        return f();
    }
    let (done, wait) = std::sync::mpsc::channel::<()>();
    let spinner = std::thread::spawn(move || {
        if let Err(std::sync::mpsc::RecvTimeoutError::Timeout) =
            wait.recv_timeout(Duration::from_secs(1))
        {
            let bar = indicatif::ProgressBar::new_spinner().with_message(label);
            if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {msg} {elapsed}")
            {
                bar.set_style(style);
            }
            bar.enable_steady_tick(Duration::from_millis(100));
            let _ = wait.recv();
            bar.finish_and_clear();
        }
    });
    let out = f();
    drop(done);
    let _ = spinner.join();
    out
}

fn renderer(scene: &SceneArgs) -> Result<Renderer, Failure> {
    if let Some(n) = scene.threads {
        // only fails if the pool was already built, which nothing here does first
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(n))
            .build_global();
    }
    let r = Renderer::new(scene.device)?;
    eprintln!("matedit: device: {}", r.describe());
    Ok(r)
}

fn render(args: &RenderArgs) -> Result<(), Failure> {
    let plan = args.scene.plan(args.output.as_deref(), None)?;
    for s in &plan.scenes {
        io::check_output(&s.output, &[Format::Exr, Format::Npy, Format::Png])?;
    }
    let loaded = plan.load()?;
    for n in &loaded.notes {
        eprintln!("matedit: {n}");
    }
    let accuracy = args.scene.accuracy();
    check_method(&accuracy, &loaded.batch)?;
    let renderer = renderer(&args.scene)?;
    let start = Instant::now();
    let (images, choices) = with_progress("rendering", || {
        renderer.render_with(&loaded.batch, &accuracy)
    })?;
    if args.scene.timings {
        print_timings(&renderer, start.elapsed());
    }
    report(&accuracy, &choices);
    let preview = args.preview.preview();
    let mut staged = Vec::with_capacity(images.len());
    for (s, image) in plan.scenes.iter().zip(&images) {
        let bytes = io::encode_image(&s.output, image, &preview).map_err(runtime)?;
        staged.push(io::stage(&s.output, &bytes).map_err(runtime)?);
    }
    for (p, image) in io::commit_all(staged).map_err(runtime)?.iter().zip(&images) {
        eprintln!(
            "matedit: wrote {} ({}x{})",
            p.display(),
            image.width,
            image.height
        );
    }
    Ok(())
}

/// `--timings`: per pass, the GPU time and pairs per second of the last call on the device,
/// or the host time where there are no GPU timestamps.
fn print_timings(renderer: &Renderer, host: Duration) {
    let timings = renderer.last_timings();
    if timings.is_empty() {
        eprintln!(
            "matedit: timings: {:.6} s on the host (per-pass times are GPU timestamps: --device gpu on an adapter with timestamp queries)",
            host.as_secs_f64()
        );
        return;
    }
    eprintln!("matedit: timings (GPU timestamps, last call on the device):");
    for t in &timings {
        let rate = t
            .pairs_per_second()
            .map_or("-".to_string(), |r| format!("{:.1} M pairs/s", r * 1e-6));
        eprintln!(
            "matedit:   {:<16} {:>11.6} s  {:>18}  ({} compute passes)",
            t.pass, t.seconds, rate, t.compute_passes
        );
    }
    let total: f64 = timings.iter().map(|t| t.seconds).sum();
    eprintln!(
        "matedit:   {:<16} {:>11.6} s  (host: {:.6} s)",
        "all passes",
        total,
        host.as_secs_f64()
    );
}

/// A method named on the command line must suit every scene (tables: orthographic).
fn check_method(accuracy: &Accuracy, batch: &matedit::Batch) -> Result<(), Failure> {
    if let Accuracy::Method(m) = accuracy {
        for s in batch.scenes() {
            m.validate(s)?;
        }
    }
    Ok(())
}

/// The level of detail used, on stderr.
fn report(accuracy: &Accuracy, choices: &[Option<lod::Choice>]) {
    if let Accuracy::Method(m) = accuracy {
        eprintln!("matedit: level of detail: method {m}");
    }
    for (b, c) in choices.iter().enumerate() {
        if let Some(c) = c {
            if choices.len() > 1 {
                eprintln!("matedit: scene {b}: level of detail: {c}");
            } else {
                eprintln!("matedit: level of detail: {c}");
            }
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

fn grad(args: &GradArgs) -> Result<(), Failure> {
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
    let renderer = renderer(&args.scene)?;
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
    batch: &matedit::Batch,
    grads: &[matedit::Gradients],
    wanted: matedit::Wanted,
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

fn fit_brdf(args: &FitArgs) -> Result<(), Failure> {
    use matedit::fit::job::{self, Bundle, Source};
    let (source, label) = match (&args.nbrdf, &args.merl) {
        (Some(path), _) => (
            Source::Nbrdf {
                path: path.clone(),
                name: args.name.clone(),
            },
            path.display().to_string(),
        ),
        (None, Some(path)) => (Source::Merl(path.clone()), path.display().to_string()),
        (None, None) => unreachable!("clap requires --nbrdf or --merl"),
    };
    // Outputs are checked before minutes of fitting.
    if let Some(b) = &args.bundle {
        io::check_parent(b)?;
    }
    let brdfs = job::load(&source)?;
    let to_file = args.output.as_ref().filter(|o| {
        o.extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("json"))
    });
    if let (Some(o), true) = (to_file, brdfs.len() > 1) {
        return Err(Error::Invalid(format!(
            "-o {}: {label} holds {} materials; give a folder for one NAME.json each, or pick one with --name",
            o.display(),
            brdfs.len()
        ))
        .into());
    }
    if let Some(o) = to_file {
        io::check_parent(o)?;
    }
    let options = matedit::fit::Options {
        lobes: args.lobes,
        tolerance: args.tolerance,
        ..Default::default()
    };
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(brdfs.len() as u64);
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "fitting {bar:30} {pos}/{len} {elapsed} (eta {eta})",
        ) {
            bar.set_style(style);
        }
        bar
    });
    let start = Instant::now();
    let fits = job::fit_all(&brdfs, &options, &|| {
        if let Some(b) = &bar {
            b.inc(1);
        }
    })?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    for f in &fits {
        eprintln!("matedit: {}: {}", f.best().material.name, job::describe(f));
    }
    eprintln!(
        "matedit: fitted {} material{} in {:.1} s on {} thread{}",
        fits.len(),
        if fits.len() == 1 { "" } else { "s" },
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        if rayon::current_num_threads() == 1 {
            ""
        } else {
            "s"
        }
    );
    let mut staged = Vec::new();
    if let Some(o) = to_file {
        let f = &fits[0];
        let bytes =
            io::json::encode_material(&f.best().material, Some(&job::description(f, &label)));
        staged.push(io::stage(o, &bytes).map_err(runtime)?);
    }
    if let Some(b) = &args.bundle {
        staged.push(io::stage(b, &Bundle::new(&label, &fits).encode()).map_err(runtime)?);
    }
    let mut written = io::commit_all(staged).map_err(runtime)?;
    if let (Some(dir), None) = (&args.output, to_file) {
        written.extend(job::write_folder(dir, &fits, &label).map_err(runtime)?);
    }
    if written.len() <= 3 {
        for p in &written {
            eprintln!("matedit: wrote {}", p.display());
        }
    } else {
        eprintln!("matedit: wrote {} files", written.len());
    }
    Ok(())
}

fn threads(n: Option<u16>) {
    if let Some(n) = n {
        // only fails if the pool was already built, which nothing here does first
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(n))
            .build_global();
    }
}

fn fit_image(args: &FitImageArgs) -> Result<(), Failure> {
    use matedit::edit::{self, Light};
    // checked before minutes of fitting: the folder (created at the end, with its
    // parents) must not be a file, nor be under one
    if let Some(blocker) = args.output.ancestors().find(|p| p.exists() && !p.is_dir()) {
        return Err(Error::file(
            &args.output,
            format!("{} is a file, not a folder", blocker.display()),
        )
        .into());
    }
    let target = io::load_image(&args.image)?;
    let normals = match (&args.normals, args.sphere) {
        (Some(p), _) => io::load_normals(p)?,
        (None, Some(n)) => {
            if target.width != target.height || (n != 0 && n as usize != target.width) {
                return Err(Error::file(
                    &args.image,
                    format!(
                        "size {}x{} is not the {}sphere's",
                        target.width,
                        target.height,
                        if n == 0 {
                            String::new()
                        } else {
                            format!("{n}x{n} ")
                        }
                    ),
                )
                .into());
            }
            matedit::NormalMap::sphere(target.width)
        }
        (None, None) => unreachable!("clap requires --normals or --sphere"),
    };
    if (normals.width, normals.height) != (target.width, target.height) {
        return Err(Error::file(
            &args.image,
            format!(
                "size {}x{} differs from the normals' {}x{}",
                target.width, target.height, normals.width, normals.height
            ),
        )
        .into());
    }
    let mask = match &args.mask {
        None => None,
        Some(p) => {
            let (w, h, m) = io::load_mask(p)?;
            if (w, h) != (target.width, target.height) {
                return Err(Error::file(
                    p,
                    format!(
                        "size {w}x{h} differs from the image's {}x{}",
                        target.width, target.height
                    ),
                )
                .into());
            }
            Some(m)
        }
    };
    let inputs = edit::Inputs::new(normals, target, mask).map_err(|e| match e {
        Error::Invalid(m) => Error::file(&args.image, m),
        other => other,
    })?;
    let convention = args.convention.unwrap_or_default();
    let (light, light_name) = match &args.env {
        Some(p) => {
            let loaded = io::load_env(p, convention)?;
            let env = io::resample::fit(loaded.env, args.env_size.unwrap_or_default(), p)?;
            (Light::Fixed(env), p.display().to_string())
        }
        None => {
            let (height, width) = match args.fit_env {
                Some(EnvSize::Size { height, width }) => (height, width),
                Some(EnvSize::Full) => {
                    return Err(Error::Invalid("--fit-env takes HxW, not 'full'".into()).into());
                }
                None => (16, 32),
            };
            (
                Light::Fit { height, width },
                format!("fitted {height}x{width}"),
            )
        }
    };
    let camera = match args.fov {
        Some(fov_y_deg) => matedit::Camera::Perspective { fov_y_deg },
        None => matedit::Camera::Orthographic,
    };
    let init = matedit::presets::lookup(&args.init).expect("clap checks preset names");
    let options = edit::Options {
        convention,
        camera,
        steps: args.steps as usize,
        work_size: args.work_size as usize,
        ..edit::Options::new(init, light)
    };
    threads(args.threads);
    let renderer = Renderer::new(args.device)?;
    eprintln!("matedit: device: {}", renderer.describe());
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(u64::from(args.steps));
        if let Ok(style) =
            indicatif::ProgressStyle::with_template("fitting {bar:30} {pos}/{len} {elapsed} {msg}")
        {
            bar.set_style(style);
        }
        bar
    });
    let fitted = edit::fit(&renderer, &inputs, &options, &mut |step, loss| {
        if let Some(b) = &bar {
            b.set_position(step as u64 + 1);
            b.set_message(format!("loss {loss:.3e}"));
        }
    })?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    let batch = matedit::Batch::single(matedit::Scene {
        normals: inputs.normals.clone(),
        env: fitted.env.clone(),
        material: fitted.material.clone(),
        camera,
    })?;
    let render = renderer.render(&batch)?.remove(0);
    let psnr = edit::psnr(&render, &inputs.target, &inputs.mask);
    let masked = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
        v.iter()
            .zip(&inputs.mask)
            .map(|(p, &m)| if m { *p } else { [0.0; 3] })
            .collect()
    };
    let normals = matedit::NormalMap {
        normals: masked(&inputs.normals.normals),
        ..inputs.normals.clone()
    };
    let target = matedit::Image {
        pixels: masked(&inputs.target.pixels),
        ..inputs.target.clone()
    };
    let report = edit::dir::Report {
        psnr,
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
    edit::dir::write(
        &args.output,
        &edit::dir::Output {
            material: &fitted.material,
            env: &fitted.env,
            normals: &normals,
            target: &target,
            render: &render,
            losses: &fitted.losses,
            report: &report,
        },
    )
    .map_err(runtime)?;
    eprintln!(
        "matedit: fitted in {:.1} s ({} steps at {}x{}), PSNR {:.2} dB; wrote {}",
        fitted.seconds,
        fitted.steps,
        fitted.work_size.0,
        fitted.work_size.1,
        psnr,
        args.output.display()
    );
    Ok(())
}

fn transfer(args: &TransferArgs) -> Result<(), Failure> {
    use matedit::edit::dir;
    io::check_output(&args.output, &[Format::Exr, Format::Npy, Format::Png])?;
    let a = dir::read(&args.shape_light)?;
    let material = if args.material.is_dir() {
        dir::read(&args.material)?.material
    } else {
        io::load_material(&args.material)?
    };
    let renderer = Renderer::new(args.device)?;
    let image = dir::transfer(&renderer, &a, &material)?;
    let bytes = io::encode_image(&args.output, &image, &Preview::default())?;
    io::write_atomic(&args.output, &bytes).map_err(runtime)?;
    eprintln!("matedit: wrote {}", args.output.display());
    Ok(())
}

fn grid(args: &GridArgs) -> Result<(), Failure> {
    use matedit::edit::dir;
    io::check_output(&args.output, &[Format::Png])?;
    let fits = args
        .fits
        .iter()
        .map(|p| dir::read(p))
        .collect::<Result<Vec<_>, _>>()?;
    let renderer = Renderer::new(args.device)?;
    let preview = args.preview.preview();
    let (w, h, rgb) = with_progress("rendering the grid", || {
        dir::grid(&renderer, &fits, args.cell as usize, &preview)
    })?;
    let bytes = io::png::encode_rgb8(w, h, &rgb)?;
    io::write_atomic(&args.output, &bytes).map_err(runtime)?;
    eprintln!(
        "matedit: wrote {} ({}x{} cells)",
        args.output.display(),
        fits.len(),
        fits.len()
    );
    Ok(())
}

fn synth(args: &SynthArgs) -> Result<(), Failure> {
    use matedit::synth;
    let spec = synth::Spec::load(&args.spec)?;
    threads(args.threads);
    let engine = synth::Engine::new(args.device)?;
    if args.verify {
        let v = synth::verify(&spec, &args.output, &engine.label)?;
        eprintln!(
            "matedit: synth: {} of {} chunks present and verified; wrote {}",
            v.chunks_present,
            v.chunks_total,
            args.output.join("manifest.json").display()
        );
        if !v.missing.is_empty() {
            let names: Vec<String> = v
                .missing
                .iter()
                .take(8)
                .map(|&c| synth::chunk_file(&spec, c))
                .collect();
            return Err(runtime(Error::file(
                &args.output,
                format!(
                    "{} chunk{} missing or not matching {} record: {}{}; run the shards again",
                    v.missing.len(),
                    if v.missing.len() == 1 { "" } else { "s" },
                    if v.missing.len() == 1 { "its" } else { "their" },
                    names.join(", "),
                    if v.missing.len() > 8 { ", ..." } else { "" }
                ),
            )));
        }
        return Ok(());
    }
    let shard = args.shard;
    synth::check(&spec, &args.output, shard, &engine.label)?;
    eprintln!("matedit: device: {}", engine.renderer.describe());
    let mine = shard.chunks(spec.chunks()).count() as u64 * spec.chunk_size;
    let bar = std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(mine);
        if let Ok(style) = indicatif::ProgressStyle::with_template(
            "{prefix} {bar:30} {pos}/{len} samples {elapsed} (eta {eta})",
        ) {
            bar.set_style(style);
        }
        bar.set_prefix(format!("shard {shard}"));
        bar
    });
    let progress = |n: u64| {
        if let Some(b) = &bar {
            b.inc(n);
        }
    };
    let s = synth::run(&spec, &args.output, shard, &engine, &progress).map_err(runtime)?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    eprintln!(
        "matedit: synth: shard {}: {} samples in {:.2} s ({:.1} samples/s), {} chunk{} written, {} skipped; {} of {} chunks present in {}",
        s.shard,
        s.samples,
        s.seconds,
        s.samples_per_second(),
        s.chunks_written,
        if s.chunks_written == 1 { "" } else { "s" },
        s.chunks_skipped,
        s.chunks_present,
        s.chunks_total,
        args.output.display()
    );
    Ok(())
}

fn presets(name: Option<&str>) -> Result<(), Failure> {
    match name {
        None => {
            let width = matedit::presets::names()
                .iter()
                .map(|n| n.len())
                .max()
                .unwrap_or(0);
            // A closed pipe (`matedit presets | head`) ends the list quietly.
            let mut out = std::io::stdout().lock();
            for p in matedit::presets::all() {
                if writeln!(out, "{:<width$}  {}", p.name, p.description).is_err() {
                    break;
                }
            }
        }
        Some(name) => {
            let Some(p) = matedit::presets::all().iter().find(|p| p.name == name) else {
                return Err(Error::Invalid(format!(
                    "unknown preset '{name}'; the presets are {}",
                    matedit::presets::names().join(", ")
                ))
                .into());
            };
            let bytes = io::json::encode_material(&p.material(), Some(&p.description));
            print!("{}", String::from_utf8_lossy(&bytes));
        }
    }
    Ok(())
}

fn run(cli: Cli) -> Result<(), Failure> {
    match cli.command {
        Command::Render(args) => render(&args),
        Command::Grad(args) => grad(&args),
        Command::Info { file } => {
            print!("{}", io::info::describe(&file)?);
            Ok(())
        }
        Command::FitBrdf(args) => fit_brdf(&args),
        Command::Fit(args) => fit_image(&args),
        Command::Transfer(args) => transfer(&args),
        Command::Grid(args) => grid(&args),
        Command::Synth(args) => synth(&args),
        Command::Presets { name } => presets(name.as_deref()),
    }
}

fn main() -> ExitCode {
    if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
        // Without it the Vulkan loader prints "error: XDG_RUNTIME_DIR is invalid" lines
        // that look like matedit's own errors; a headless run has no use for the variable.
        // SAFETY: no other thread exists yet.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", std::env::temp_dir()) };
    }
    if std::env::var_os("RUST_BACKTRACE").is_none() {
        // A bug is still a bug, but the user gets one line, not a backtrace dump.
        std::panic::set_hook(Box::new(|info| {
            let msg = info.to_string().replace('\n', " ");
            eprintln!("error: internal error (please report it): {msg}");
        }));
    }
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("error: {}", f.error);
            ExitCode::from(f.code)
        }
    }
}
