//! The layer's discrete sum against the same light at 4x and 16x the texels, next to the
//! continuous light (`supersample`) and the levels of detail, timed; a log-log chart of
//! error against time, and a before/after crop of the default render.
//!
//! ```sh
//! cargo xtask discretisation                 # writes docs/continuous_light/
//! cargo xtask discretisation -- --out DIR --sphere 128 --hdri forest
//! ```
//!
//! The finer lights: the built-in sky generated at 128 x 256 and 256 x 512; an HDRI of
//! ../shared/data/envmaps (when present) downsampled from the full-resolution file to
//! each size. Errors: max |I - I_ref| / max I_ref on an orthographic sphere. One run each.

use std::path::{Path, PathBuf};
use std::time::Instant;

use matedit::continuous_light::{self, Integration};
use matedit::io::png::{Preview, encode_preview};
use matedit::io::resample::downsample;
use matedit::{
    Accuracy, Batch, Camera, Convention, Device, EnvMap, Image, NormalMap, Renderer, Scene,
    builtin_sky, io, lod, presets,
};
use plotters::prelude::*;

const MATERIALS: [(&str, &str); 3] = [
    ("diffuse", "clay"),
    ("glossy", "red-specular-plastic"),
    ("sharp", "chrome-ish"),
];

type Run<'a> = Box<dyn Fn(&Renderer, &Batch) -> Image + 'a>;

fn main() {
    if let Err(e) = run() {
        eprintln!("discretisation: {e}");
        std::process::exit(1);
    }
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let out = PathBuf::from(arg(&args, "--out").unwrap_or_else(|| "docs/continuous_light".into()));
    let size: usize =
        arg(&args, "--sphere").map_or(Ok(128), |s| s.parse().map_err(|_| "--sphere N"))?;
    let hdri = arg(&args, "--hdri").unwrap_or_else(|| "forest".into());
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let renderer = Renderer::new(Device::Cpu).map_err(|e| e.to_string())?;
    eprintln!("device: {}", renderer.describe());

    // each light at 1x, 4x and 16x the texels
    let sky = |h, w| builtin_sky::procedural_env(h, w, Convention::Equirect);
    let mut lights = vec![(
        "sky".to_string(),
        [sky(64, 128), sky(128, 256), sky(256, 512)],
    )];
    let path = Path::new("../shared/data/envmaps").join(format!("{hdri}.exr"));
    if path.exists() {
        let full = io::load_env(&path, Convention::Equirect)
            .map_err(|e| e.to_string())?
            .env;
        let at = |h, w| downsample(&full, h, w);
        lights.push((hdri.clone(), [at(64, 128)?, at(128, 256)?, at(256, 512)?]));
    } else {
        eprintln!("{} not found: the built-in sky alone", path.display());
    }

    let mut rows = Vec::new();
    println!("| light | material | method | seconds | error vs 4x | error vs 16x |");
    println!("| --- | --- | --- | ---: | ---: | ---: |");
    for (light, maps) in &lights {
        for (kind, preset) in MATERIALS {
            let material = presets::lookup(preset).ok_or(preset)?;
            let batch_of = |env: &EnvMap| {
                Batch::single(Scene {
                    normals: NormalMap::sphere(size),
                    env: env.clone(),
                    material: material.clone(),
                    camera: Camera::Orthographic,
                })
                .map_err(|e| e.to_string())
            };
            let exact: Run = Box::new(|r, b| r.render(b).expect("renders").remove(0));
            let (ref4, t4) = timed(&renderer, &batch_of(&maps[1])?, &exact);
            let (ref16, _) = timed(&renderer, &batch_of(&maps[2])?, &exact);
            let base = batch_of(&maps[0])?;
            // the sub-texels' radiance from the 16x map (as the CLI does), or constant
            let detail = [Some(maps[2].clone())];
            let light_run = |l: Integration| -> Run {
                let detail = detail.clone();
                Box::new(move |r, b| {
                    continuous_light::render(r, b, &Accuracy::Exact, l, &detail)
                        .expect("renders")
                        .0
                        .remove(0)
                })
            };
            let constant_run = |l: Integration| -> Run {
                Box::new(move |r, b| {
                    continuous_light::render(r, b, &Accuracy::Exact, l, &[])
                        .expect("renders")
                        .0
                        .remove(0)
                })
            };
            let lod_run = |a: Accuracy| -> Run {
                Box::new(move |r, b| r.render_with(b, &a).expect("renders").0.remove(0))
            };
            let method = |m: &str| m.parse::<lod::Method>().expect("a method");
            let mut candidates: Vec<(&str, String, Run)> = vec![
                (
                    "discrete",
                    "discrete (the layer)".into(),
                    light_run(Integration::Discrete),
                ),
                (
                    "light",
                    "--supersample 1".into(),
                    light_run(Integration::Level(1)),
                ),
                (
                    "light",
                    "--supersample 2".into(),
                    light_run(Integration::Level(2)),
                ),
                (
                    "light",
                    "--supersample 4".into(),
                    light_run(Integration::Level(4)),
                ),
                (
                    "constant",
                    "--supersample 2, radiance constant per texel".into(),
                    constant_run(Integration::Level(2)),
                ),
                (
                    "light",
                    "--light-tolerance 1e-2".into(),
                    light_run(Integration::Tolerance(1e-2)),
                ),
                (
                    "light",
                    "--light-tolerance 1e-3".into(),
                    light_run(Integration::Tolerance(1e-3)),
                ),
            ];
            for m in ["env2", "table64+keep16", "table128+keep16"] {
                candidates.push((
                    "lod",
                    format!("--method {m}"),
                    lod_run(Accuracy::Method(method(m))),
                ));
            }
            candidates.push((
                "lod",
                "--tolerance 1e-3".into(),
                lod_run(Accuracy::Tolerance(1e-3)),
            ));
            let mut record = |family: &str, name: &str, secs: f64, image: &Image| {
                let (e4, e16) = (relative(image, &ref4), relative(image, &ref16));
                println!(
                    "| {light} | {kind} ({preset}) | {name} | {secs:.3} | {e4:.2e} | {e16:.2e} |"
                );
                rows.push((kind, family.to_string(), secs, e16));
            };
            for (family, name, run) in &candidates {
                let (image, secs) = timed(&renderer, &base, run);
                record(family, name, secs, &image);
            }
            record("finer", "the map at 4x (128 x 256)", t4, &ref4);
        }
    }
    let chart = out.join("discretisation.png");
    plot(&rows, &chart, size)?;
    eprintln!("wrote {}", chart.display());
    default_crop(&renderer, &out.join("default_rings.png"))
}

fn timed(renderer: &Renderer, batch: &Batch, run: &Run) -> (Image, f64) {
    let start = Instant::now();
    let image = run(renderer, batch);
    (image, start.elapsed().as_secs_f64())
}

/// max |a - b| / max b.
fn relative(a: &Image, b: &Image) -> f64 {
    let max = f64::from(b.max_value());
    let diff = a
        .pixels
        .iter()
        .flatten()
        .zip(b.pixels.iter().flatten())
        .fold(0.0f64, |m, (&x, &y)| m.max(f64::from((x - y).abs())));
    diff / max
}

/// The families of runs, as the table's rows name them.
const FAMILIES: [&str; 5] = ["discrete", "light", "constant", "lod", "finer"];

fn describe(family: &str) -> &'static str {
    match family {
        "discrete" => "the layer",
        "light" => "continuous light",
        "constant" => "constant radiance",
        "lod" => "levels of detail",
        _ => "the map at 4x",
    }
}

/// A family's marker, centred on (0, 0) in pixels.
fn marker<DB: DrawingBackend>(
    family: &str,
    colour: RGBColor,
) -> DynElement<'static, DB, (i32, i32)> {
    let style = colour.stroke_width(2);
    match family {
        "discrete" => Circle::new((0, 0), 7, style).into_dyn(),
        "light" => TriangleMarker::new((0, 0), 7, style).into_dyn(),
        "constant" => Rectangle::new([(-5, -5), (5, 5)], style).into_dyn(),
        "lod" => Cross::new((0, 0), 6, style).into_dyn(),
        _ => Rectangle::new([(-5, -5), (5, 5)], colour.filled()).into_dyn(),
    }
}

/// Error against the 16x light over time, log-log: a colour per material, a marker per
/// family.
fn plot(rows: &[(&str, String, f64, f64)], path: &Path, size: usize) -> Result<(), String> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::HACK_REGULAR,
    )
    .map_err(|_| "the embedded font cannot be read")?;
    let e = |e: DrawingAreaErrorKind<_>| e.to_string();
    let (w, h) = (1000u32, 640u32);
    let mut buf = vec![0u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(e)?;
        let (x0, x1) = bounds(rows.iter().map(|r| r.2));
        let (y0, y1) = bounds(rows.iter().map(|r| r.3.max(1e-7)));
        let mut chart = ChartBuilder::on(&root)
            .caption(
                format!(
                    "matedit: error against the light at 16x the texels ({size} x {size} sphere)"
                ),
                ("sans-serif", 20),
            )
            .margin(14)
            .x_label_area_size(46)
            .y_label_area_size(74)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(e)?;
        chart
            .configure_mesh()
            .x_desc("time (s)")
            .y_desc("max |I - I_16x| / max I_16x")
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .label_style(("sans-serif", 14))
            .draw()
            .map_err(e)?;
        let colours = [("diffuse", BLUE), ("glossy", RED), ("sharp", BLACK)];
        for (kind, colour) in colours {
            for family in FAMILIES {
                let pts: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| r.0 == kind && r.1 == family)
                    .map(|r| (r.2, r.3.max(1e-7)))
                    .collect();
                if pts.is_empty() {
                    continue;
                }
                chart
                    .draw_series(
                        pts.into_iter()
                            .map(|p| EmptyElement::at(p) + marker(family, colour)),
                    )
                    .map_err(e)?
                    .label(format!("{kind}: {}", describe(family)))
                    .legend(move |c| EmptyElement::at(c) + marker(family, colour));
            }
        }
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.9))
            .border_style(BLACK)
            .label_font(("sans-serif", 12))
            .draw()
            .map_err(e)?;
        root.present().map_err(e)?;
    }
    let png =
        matedit::io::png::encode_rgb8(w as usize, h as usize, &buf).map_err(|e| e.to_string())?;
    std::fs::write(path, png).map_err(|e| format!("{}: {e}", path.display()))
}

fn bounds(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = v.fold((f64::MAX, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
    (lo / 2.0, hi * 2.0)
}

/// The default scene (`matedit render -o x.png`) with the discrete light and with the
/// default light tolerance: the left rim, magnified 3x, side by side.
fn default_crop(renderer: &Renderer, path: &Path) -> Result<(), String> {
    let batch = Batch::single(Scene {
        normals: NormalMap::sphere(256),
        env: builtin_sky::procedural_env(64, 128, Convention::Equirect),
        material: presets::lookup(presets::DEFAULT).ok_or("default preset")?,
        camera: Camera::Orthographic,
    })
    .map_err(|e| e.to_string())?;
    let mut crops = Vec::new();
    let f = builtin_sky::LIGHT_DETAIL;
    let detail = [Some(builtin_sky::procedural_env(
        64 * f,
        128 * f,
        Convention::Equirect,
    ))];
    for light in [
        Integration::Discrete,
        Integration::Level(builtin_sky::LIGHT_LEVEL),
    ] {
        let start = Instant::now();
        let (mut images, _) =
            continuous_light::render(renderer, &batch, &Accuracy::Exact, light, &detail)
                .map_err(|e| e.to_string())?;
        eprintln!(
            "default scene, {light:?}: {:.2} s",
            start.elapsed().as_secs_f64()
        );
        crops.push(images.remove(0));
    }
    let (x0, y0, w, h, zoom) = (0, 64, 96, 128, 3);
    let mut pixels = Vec::new();
    for y in 0..h * zoom {
        for crop in &crops {
            for x in 0..w * zoom {
                pixels.push(crop.pixels[(y0 + y / zoom) * 256 + x0 + x / zoom]);
            }
        }
    }
    let side = Image {
        width: 2 * w * zoom,
        height: h * zoom,
        pixels,
    };
    let png = encode_preview(&side, &Preview::default()).map_err(|e| e.to_string())?;
    std::fs::write(path, png).map_err(|e| format!("{}: {e}", path.display()))?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
