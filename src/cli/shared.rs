//! What several commands share: the scene options of `render` and `grad`, the PNG preview
//! options, the failure type and its exit codes, the backend and its threads, progress on
//! stderr and the reports of timings and levels of detail.

use std::io::IsTerminal;
use std::path::{Path, PathBuf};
use std::time::Duration;

use matedit::io::source::{MaterialSource, NormalsSource};
use matedit::io::{self, EnvSize, Preview, Tonemap};
use matedit::{Accuracy, Batch, Convention, Device, Error, Renderer, continuous_light, lod};

use super::job::{Plan, SceneOptions};

/// A failure and the exit code it gets.
pub struct Failure {
    /// What went wrong, printed as one line.
    pub error: Error,
    /// The exit code: 2 for bad usage or input, 1 for a runtime failure.
    pub code: u8,
}

impl From<Error> for Failure {
    fn from(error: Error) -> Self {
        let code = if error.is_input_error() { 2 } else { 1 };
        Failure { error, code }
    }
}

/// A runtime failure (exit code 1) whatever the error's kind, e.g. a write that failed
/// after the inputs were accepted.
pub fn runtime(error: Error) -> Failure {
    Failure { error, code: 1 }
}

/// The scene options of `render` and `grad`, their device and their levels of detail.
#[derive(clap::Args)]
pub struct SceneArgs {
    /// Normal map: .exr (channels R, G, B = n.x, n.y, n.z), .npy (H x W x 3) or .png (8-bit, n = 2v/255 - 1).
    #[arg(long, value_name = "FILE", conflicts_with = "sphere")]
    pub normals: Option<PathBuf>,
    /// A unit sphere filling an N x N image [default: 256 when no --normals].
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=8192))]
    pub sphere: Option<u32>,
    /// Lat-long HDR environment map, .exr or .npy, row 0 = top [default: a built-in procedural sky with a sun].
    #[arg(long, value_name = "FILE")]
    pub env: Option<PathBuf>,
    /// Environment size HxW; a larger map is downsampled by a whole factor per axis (solid-angle weighted); 'full' keeps the file's size [default: 64x128].
    #[arg(long, value_name = "HxW|full")]
    pub env_size: Option<EnvSize>,
    /// Texel convention: 'equirect' (physical solid angles) or 'paper' (the supplemental's equations) [default: equirect].
    #[arg(long, value_name = "NAME")]
    pub convention: Option<Convention>,
    /// Material JSON file: {"name": ..., "ctrl": [108 numbers]}.
    #[arg(long, value_name = "FILE", conflicts_with = "preset")]
    pub material: Option<PathBuf>,
    /// A built-in material (see `matedit presets`) [default: red-specular-plastic].
    #[arg(long, value_name = "NAME", value_parser = clap::builder::PossibleValuesParser::new(matedit::presets::names()))]
    pub preset: Option<String>,
    /// Perspective camera with this vertical field of view in degrees [default: orthographic].
    #[arg(long, value_name = "DEG", value_parser = parse_fov)]
    pub fov: Option<f64>,
    /// Backend: auto (a hardware GPU if any, else cpu), gpu (any wgpu adapter, lavapipe included), cpu (the fast f32 SIMD path) or reference (the f64 reference).
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    pub device: Device,
    /// Worker threads of the CPU paths [default: RAYON_NUM_THREADS, else one per core]. Results do not depend on it.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u16).range(1..))]
    pub threads: Option<u16>,
    /// Approximate: the cheapest level of detail whose estimated relative error (max |I - I_exact| over max I_exact; with `grad`, each gradient's too) is within REL, chosen per scene and printed on stderr [default: exact].
    #[arg(long, value_name = "REL", value_parser = parse_tolerance, conflicts_with = "method")]
    pub tolerance: Option<f64>,
    /// A level of detail by name: 'exact', or parts joined by '+': envF (the map in F x F blocks), keepK (its K brightest texels kept), tableR (an R x R table of normals), cullB (lights culled within B of the largest value); tables and culling need an orthographic camera. E.g. table128+keep16.
    #[arg(long, value_name = "METHOD")]
    pub method: Option<lod::Method>,
    /// The continuous light: texels near each pixel's specular peak split into sub-texel lights whose radiance comes from the same light at 4x the rows and columns (the built-in sky generated finer, or the map's file where it is that large; else constant over the texel), as finely as an estimate on sampled pixels says keeps the relative error within REL ('off': the layer's point lights) [default: off; `render` of the built-in sky: --supersample 1].
    #[arg(long, value_name = "REL|off", value_parser = parse_light_tolerance, conflicts_with = "supersample")]
    pub light_tolerance: Option<LightTolerance>,
    /// The continuous light at a fixed level Q (1 to 64): texels near each pixel's specular peak split so that about Q sub-texels span the lobe's width; 0 is the layer.
    #[arg(long, value_name = "Q", value_parser = clap::value_parser!(u32).range(0..=64))]
    pub supersample: Option<u32>,
    /// A JSON manifest listing several scenes, rendered in one batch (see docs/FORMATS.md). Options above are defaults for what it leaves out.
    #[arg(long, value_name = "MANIFEST")]
    pub batch: Option<PathBuf>,
    /// Print on stderr the time of each pass of the last call on the device (GPU timestamps: seconds and pixel-texel pairs per second) where the adapter has timestamp queries; on other devices the call's host time.
    #[arg(long)]
    pub timings: bool,
}

impl SceneArgs {
    /// `--tolerance` or `--method`, else exact.
    pub fn accuracy(&self) -> Accuracy {
        match (self.tolerance, self.method) {
            (Some(t), _) => Accuracy::Tolerance(t),
            (None, Some(m)) => Accuracy::Method(m),
            (None, None) => Accuracy::Exact,
        }
    }

    /// `--light-tolerance` or `--supersample`, else `default`.
    pub fn light(&self, default: continuous_light::Integration) -> continuous_light::Integration {
        match (self.light_tolerance, self.supersample) {
            (Some(LightTolerance(Some(t))), _) => continuous_light::Integration::Tolerance(t),
            (Some(LightTolerance(None)), _) => continuous_light::Integration::Discrete,
            (None, Some(q)) => continuous_light::Integration::Level(q),
            (None, None) => default,
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
    pub fn plan(&self, output: Option<&Path>, upstream: Option<&Path>) -> Result<Plan, Failure> {
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

/// How a PNG output shows linear values.
#[derive(clap::Args)]
pub struct PreviewArgs {
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
    /// The options as the library takes them.
    pub fn preview(&self) -> Preview {
        Preview {
            exposure: self.exposure,
            tonemap: self.tonemap,
        }
    }
}

/// `--tolerance`: a positive number.
pub fn parse_tolerance(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(format!("{v} is not a positive number"))
    }
}

/// The finer maps the continuous light takes its sub-texels from (none for the layer).
pub fn light_details(
    plan: &Plan,
    batch: &Batch,
    light: continuous_light::Integration,
) -> Result<Vec<Option<matedit::EnvMap>>, Failure> {
    match light {
        continuous_light::Integration::Discrete | continuous_light::Integration::Level(0) => {
            Ok(Vec::new())
        }
        _ => Ok(plan.details(batch, matedit::builtin_sky::LIGHT_DETAIL)?),
    }
}

/// A fixed level of the continuous light, on stderr.
pub fn report_light_level(
    light: continuous_light::Integration,
    details: &[Option<matedit::EnvMap>],
) {
    if let continuous_light::Integration::Level(q @ 1..) = light {
        let from = match details.first().and_then(Option::as_ref) {
            Some(d) => format!("sub-texels from the light at {}x{}", d.height, d.width),
            None => "radiance constant over each texel".into(),
        };
        eprintln!("matedit: continuous light: level {q} ({from})");
    }
}

/// `--light-tolerance`: a relative error, or `None` for 'off'.
#[derive(Clone, Copy, Debug)]
pub struct LightTolerance(pub Option<f64>);

/// `--light-tolerance`: a positive number, or 'off'.
pub fn parse_light_tolerance(s: &str) -> Result<LightTolerance, String> {
    if s == "off" {
        return Ok(LightTolerance(None));
    }
    parse_tolerance(s).map(|t| LightTolerance(Some(t)))
}

/// `--fov`: degrees in (0, 180).
pub fn parse_fov(s: &str) -> Result<f64, String> {
    let v: f64 = s.parse().map_err(|_| format!("'{s}' is not a number"))?;
    if v.is_finite() && v > 0.0 && v < 180.0 {
        Ok(v)
    } else {
        Err(format!("{v} degrees is outside (0, 180)"))
    }
}

/// Runs `f`, showing a spinner on stderr if it takes more than a second and stderr is a
/// terminal.
pub fn with_progress<T>(label: &'static str, f: impl FnOnce() -> T) -> T {
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

/// The renderer on `device`, the CPU paths on `threads` threads; its device on stderr.
pub fn renderer(device: Device, threads: Option<u16>) -> Result<Renderer, Failure> {
    self::threads(threads);
    let r = Renderer::new(device)?;
    eprintln!("matedit: device: {}", r.describe());
    Ok(r)
}

/// `--threads`: the size of rayon's global pool, which the CPU paths run on.
pub fn threads(n: Option<u16>) {
    if let Some(n) = n {
        // only fails if the pool was already built, which nothing here does first
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(usize::from(n))
            .build_global();
    }
}

/// A bar of `len` steps on stderr drawn with `template`, if stderr is a terminal.
pub fn progress_bar(len: u64, template: &str) -> Option<indicatif::ProgressBar> {
    std::io::stderr().is_terminal().then(|| {
        let bar = indicatif::ProgressBar::new(len);
        if let Ok(style) = indicatif::ProgressStyle::with_template(template) {
            bar.set_style(style);
        }
        bar
    })
}

/// `--timings`: per pass, the GPU time and pairs per second of the last call on the device,
/// or the host time where there are no GPU timestamps.
pub fn print_timings(renderer: &Renderer, host: Duration) {
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
pub fn check_method(accuracy: &Accuracy, batch: &Batch) -> Result<(), Failure> {
    if let Accuracy::Method(m) = accuracy {
        for s in batch.scenes() {
            m.validate(s)?;
        }
    }
    Ok(())
}

/// The light each scene got with a tolerance, on stderr.
pub fn report_light(choices: &[Option<continuous_light::LevelChoice>]) {
    report_each("continuous light", choices);
}

/// Each scene's choice, named `what`, on stderr.
fn report_each<T: std::fmt::Display>(what: &str, choices: &[Option<T>]) {
    for (b, c) in choices.iter().enumerate() {
        if let Some(c) = c {
            if choices.len() > 1 {
                eprintln!("matedit: scene {b}: {what}: {c}");
            } else {
                eprintln!("matedit: {what}: {c}");
            }
        }
    }
}

/// The level of detail used, on stderr.
pub fn report(accuracy: &Accuracy, choices: &[Option<lod::Choice>]) {
    if let Accuracy::Method(m) = accuracy {
        eprintln!("matedit: level of detail: method {m}");
    }
    report_each("level of detail", choices);
}

/// `--box`, `--point` and `--not` of `edit` and `grid`: where the object is.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct PointingArgs {
    /// A box around the object, in pixels: columns X0 to X1, rows Y0 to Y1, X1 and Y1
    /// exclusive (the cut keeps nothing outside it).
    #[arg(long = "box", value_name = "X0,Y0,X1,Y1", allow_hyphen_values = true)]
    pub bounds: Option<String>,
    /// A pixel (column, row) on the object; repeatable.
    #[arg(long = "point", value_name = "X,Y", allow_hyphen_values = true)]
    pub points: Vec<String>,
    /// A pixel (column, row) not on the object; repeatable.
    #[arg(long = "not", value_name = "X,Y", allow_hyphen_values = true)]
    pub nots: Vec<String>,
}

impl PointingArgs {
    /// Whether none is given.
    pub fn is_empty(&self) -> bool {
        self.bounds.is_none() && self.points.is_empty() && self.nots.is_empty()
    }

    /// The pointing at photo number `number` (1-based, `None`: values carry no `N:`
    /// prefix) of a `width` x `height` photo, checked; `None` if none is given for it.
    pub fn pointing(
        &self,
        number: Option<usize>,
        width: usize,
        height: usize,
    ) -> Result<Option<matedit::edit::photo::Pointing>, Failure> {
        use matedit::edit::photo::Pointing;
        use matedit::segment::Rect;
        let mut p = Pointing::default();
        let take = |flag: &str, value: &str, n: usize| -> Result<Option<Vec<usize>>, Failure> {
            let bad =
                |what: &str| Failure::from(Error::Invalid(format!("--{flag} {value}: {what}")));
            let rest = match number {
                None => value,
                Some(k) => {
                    let Some((i, rest)) = value.split_once(':') else {
                        return Err(bad("give the photo's number first (1:X,Y for the first)"));
                    };
                    if i.trim().parse::<usize>().ok() != Some(k) {
                        return Ok(None);
                    }
                    rest
                }
            };
            let v: Vec<usize> = rest
                .split(',')
                .map(|s| s.trim().parse::<usize>())
                .collect::<Result<_, _>>()
                .map_err(|_| bad(&format!("{n} whole numbers of pixels expected")))?;
            if v.len() != n {
                return Err(bad(&format!("{n} whole numbers of pixels expected")));
            }
            Ok(Some(v))
        };
        if let Some(b) = &self.bounds
            && let Some(v) = take("box", b, 4)?
        {
            p.bounds = Some(Rect {
                x0: v[0],
                y0: v[1],
                x1: v[2],
                y1: v[3],
            });
        }
        for (values, flag, into) in [
            (&self.points, "point", &mut p.object),
            (&self.nots, "not", &mut p.background),
        ] {
            for s in values {
                if let Some(v) = take(flag, s, 2)? {
                    into.push([v[0], v[1]]);
                }
            }
        }
        if p.is_empty() {
            return Ok(None);
        }
        p.check(width, height)
            .map_err(|e| Failure::from(Error::Invalid(format!("--{e}"))))?;
        Ok(Some(p))
    }
}

/// A pointing as report.json shows it.
pub fn pointing_json(p: Option<&matedit::edit::photo::Pointing>) -> serde_json::Value {
    match p {
        None => serde_json::Value::Null,
        Some(p) => serde_json::json!({
            "box": p.bounds.map(|b| [b.x0, b.y0, b.x1, b.y1]),
            "points": p.object,
            "not": p.background,
        }),
    }
}
