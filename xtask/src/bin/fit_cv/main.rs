//! Cross-validation of the MERL fitter: how well fits render on materials and under a light
//! that no choice of the fitter was tuned on.
//!
//! ```text
//! cargo xtask fit_cv -- [--merl ../shared/data/merl_nbrdf]
//!     [--envmaps ../shared/data/envmaps] [--set held-out|tuning|all] [--limit N]
//!     [--maps studio,...]
//!     [--methods current,joint,new,oracle] [--tolerance REL (new only)] [--sphere 64] [--env-size 64x128]
//!     [--cache DIR] [--oracle-steps N]
//! ```
//!
//! The split is fixed: the materials of the NBRDF file sorted by name, every third one
//! (indices 2, 5, 8, ...: 30 of 90) held out, the other 60 the tuning set; the HDRI
//! `forest` is held out from every choice (`--set tuning` renders `studio` and `sunset`
//! only).
//! `--limit N` takes the first N of the chosen set; `--set all` takes all 90 (for what
//! refitting the presets would change, not for choices) and `--maps` some of the maps. Each material is fitted by each
//! method, rendered on a sphere under each HDRI with the fast CPU path and compared with
//! the sphere rendered with the measured BRDF (`matedit::brdf::render::render_measured`):
//! PSNR over the sphere's pixels with the measured image's largest value as the peak, as
//! `xtask/src/bin/merl_report.rs` measures.
//!
//! Methods: `current` is `matedit::fit_brdf::fit` without the joint refinement, `joint` the
//! plain joint least-squares fit of the 108 control points (`matedit::fit_brdf::joint::plain`),
//! `new` the fitter's defaults. `oracle` is not a fitter: `new`'s fit moved by Adam through
//! the layer towards the measured images under every map, the held-out one included (see
//! [`oracle`]); what it reaches shows how far the DSBRDF itself can go from the fit's
//! start. `--cache DIR` keeps the measured renders (NPY) between runs.

#[path = "../../common/maps.rs"]
mod maps;
mod oracle;

use std::path::{Path, PathBuf};
use std::time::Instant;

use matedit::brdf::nbrdf::{self, Nbrdf};
use matedit::brdf::render::render_measured;
use matedit::fit_brdf::samples::Grid;
use matedit::fit_brdf::{BrdfFitOptions, fit, joint};
use matedit::{Batch, Camera, Device, EnvMap, Image, Material, NormalMap, Renderer, Scene};
use rayon::prelude::*;

/// The HDRI no choice is tuned on.
const HELD_OUT_MAP: &str = "forest";
/// Every HELD_OUT_EVERY-th material (sorted by name, from index HELD_OUT_EVERY - 1) is held
/// out.
const HELD_OUT_EVERY: usize = 3;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Method {
    Current,
    Joint,
    New,
    Oracle,
}

impl Method {
    fn parse(v: &str) -> Result<Self, String> {
        match v {
            "current" => Ok(Method::Current),
            "joint" => Ok(Method::Joint),
            "new" => Ok(Method::New),
            "oracle" => Ok(Method::Oracle),
            _ => Err(format!(
                "--methods: '{v}' is not current, joint, new or oracle"
            )),
        }
    }

    fn label(self) -> &'static str {
        match self {
            Method::Current => "current",
            Method::Joint => "plain joint",
            Method::New => "new",
            Method::Oracle => "oracle",
        }
    }
}

struct Args {
    merl: PathBuf,
    envmaps: PathBuf,
    held_out: bool,
    all: bool,
    only_maps: Option<Vec<String>>,
    limit: Option<usize>,
    methods: Vec<Method>,
    tolerance: f64,
    sphere: usize,
    env_size: (usize, usize),
    cache: Option<PathBuf>,
    oracle_steps: usize,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        merl: "../shared/data/merl_nbrdf".into(),
        envmaps: "../shared/data/envmaps".into(),
        held_out: true,
        all: false,
        only_maps: None,
        limit: None,
        methods: vec![Method::Current, Method::Joint, Method::New],
        tolerance: BrdfFitOptions::default().tolerance,
        sphere: 64,
        env_size: (64, 128),
        cache: None,
        oracle_steps: oracle::ORACLE_STEPS,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--merl" => a.merl = value()?.into(),
            "--envmaps" => a.envmaps = value()?.into(),
            "--set" => {
                a.held_out = match value()?.as_str() {
                    "held-out" => true,
                    "tuning" => false,
                    "all" => {
                        a.all = true;
                        false
                    }
                    v => return Err(format!("--set: '{v}' is not held-out, tuning or all")),
                }
            }
            "--maps" => a.only_maps = Some(value()?.split(',').map(String::from).collect()),
            "--limit" => a.limit = Some(value()?.parse().map_err(|e| format!("--limit: {e}"))?),
            "--methods" => {
                a.methods = value()?
                    .split(',')
                    .map(Method::parse)
                    .collect::<Result<_, _>>()?
            }
            "--tolerance" => {
                a.tolerance = value()?.parse().map_err(|e| format!("--tolerance: {e}"))?
            }
            "--sphere" => a.sphere = value()?.parse().map_err(|e| format!("--sphere: {e}"))?,
            "--env-size" => a.env_size = maps::env_size(&value()?)?,
            "--cache" => a.cache = Some(value()?.into()),
            "--oracle-steps" => {
                a.oracle_steps = value()?
                    .parse()
                    .map_err(|e| format!("--oracle-steps: {e}"))?
            }
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok(a)
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

/// The held-out or tuning materials, in name order.
fn split(mut nets: Vec<Nbrdf>, held_out: bool) -> Vec<Nbrdf> {
    nets.sort_by(|a, b| a.name.cmp(&b.name));
    nets.into_iter()
        .enumerate()
        .filter(|(i, _)| (i % HELD_OUT_EVERY == HELD_OUT_EVERY - 1) == held_out)
        .map(|(_, n)| n)
        .collect()
}

/// `net` rendered under `env`, from `cache` when it holds the render.
fn measured(
    net: &Nbrdf,
    map: &str,
    env: &EnvMap,
    normals: &NormalMap,
    cache: Option<&Path>,
) -> Result<Image, String> {
    let file = cache.map(|c| {
        c.join(format!(
            "{}_{map}_{}x{}_{}.npy",
            net.name, env.height, env.width, normals.width
        ))
    });
    if let Some(f) = file.as_ref().filter(|f| f.exists()) {
        return matedit::io::load_image(f).map_err(|e| e.to_string());
    }
    let img =
        render_measured(net, normals, env, Camera::Orthographic).map_err(|e| e.to_string())?;
    if let Some(f) = &file {
        std::fs::create_dir_all(f.parent().expect("a folder"))
            .map_err(|e| format!("{}: {e}", f.display()))?;
        let bytes = matedit::io::npy::encode_rgb(img.width, img.height, &img.pixels);
        matedit::io::write_atomic(f, &bytes).map_err(|e| e.to_string())?;
    }
    Ok(img)
}

/// PSNR over the sphere's pixels, the measured image's largest value as the peak.
fn psnr(fitted: &Image, measured: &Image, mask: &[bool]) -> f64 {
    let (mut se, mut n, mut peak) = (0.0, 0usize, 0.0f64);
    for ((a, b), _) in fitted
        .pixels
        .iter()
        .zip(&measured.pixels)
        .zip(mask)
        .filter(|(_, m)| **m)
    {
        for k in 0..3 {
            let (a, b) = (f64::from(a[k]), f64::from(b[k]));
            se += (a - b) * (a - b);
            peak = peak.max(b);
            n += 1;
        }
    }
    10.0 * (peak * peak / (se / n.max(1) as f64).max(1e-300)).log10()
}

/// `material` on the sphere `normals` under each of `maps`, one scene each.
pub fn under_maps(
    material: &Material,
    maps: &[(String, EnvMap)],
    normals: &NormalMap,
) -> Result<Batch, String> {
    let scenes = maps
        .iter()
        .map(|(_, env)| Scene {
            normals: normals.clone(),
            env: env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        })
        .collect();
    Batch::new(scenes).map_err(|e| e.to_string())
}

/// Median, worst and mean.
fn stats(v: &[f64]) -> (f64, f64, f64) {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    let n = s.len();
    let median = if n % 2 == 1 {
        s[n / 2]
    } else {
        0.5 * (s[n / 2 - 1] + s[n / 2])
    };
    (median, s[0], s.iter().sum::<f64>() / n as f64)
}

fn fit_one(method: Method, net: &Nbrdf, tolerance: f64) -> Result<(Material, usize), String> {
    let options = match method {
        // the fitter as it was: no joint refinement, 5% slack for fewer lobes
        Method::Current => BrdfFitOptions {
            joint: false,
            tolerance: 0.05,
            ..BrdfFitOptions::default()
        },
        _ => BrdfFitOptions {
            tolerance,
            ..BrdfFitOptions::default()
        },
    };
    match method {
        Method::Joint => joint::plain(net, &net.name, Grid::default())
            .map(|m| (m, 3))
            .map_err(|e| e.to_string()),
        Method::Current | Method::New | Method::Oracle => fit(net, &net.name, &options)
            .map(|f| (f.best().material.clone(), f.best().lobes))
            .map_err(|e| e.to_string()),
    }
}

fn run() -> Result<(), String> {
    let a = args()?;
    let file = if a.merl.is_dir() {
        a.merl.join("merl_nbrdf.json")
    } else {
        a.merl.clone()
    };
    let nets = nbrdf::read(&file).map_err(|e| e.to_string())?;
    let mut nets = if a.all { nets } else { split(nets, a.held_out) };
    if let Some(n) = a.limit {
        nets.truncate(n);
    }
    if nets.is_empty() {
        return Err("no materials to fit".into());
    }
    let mut maps = maps::load_maps(&a.envmaps, a.env_size)?;
    if !maps.iter().any(|(n, _)| n == HELD_OUT_MAP) {
        return Err(format!(
            "{}: no {HELD_OUT_MAP}.exr, the held-out map",
            a.envmaps.display()
        ));
    }
    if !a.held_out && !a.all {
        // Tuning never looks at the held-out map.
        maps.retain(|(name, _)| name != HELD_OUT_MAP);
    }
    if let Some(only) = &a.only_maps {
        maps.retain(|(name, _)| only.contains(name));
        if maps.is_empty() {
            return Err(format!("--maps: none of {} found", only.join(", ")));
        }
    }
    let normals = NormalMap::sphere(a.sphere);
    let mask: Vec<bool> = normals.normals.iter().map(|n| n[2] > 0.0).collect();
    let renderer = Renderer::new(Device::Cpu).map_err(|e| e.to_string())?;
    let set = match (a.all, a.held_out) {
        (true, _) => "all",
        (false, true) => "held-out",
        (false, false) => "tuning",
    };
    eprintln!(
        "{} {set} materials, maps {} (held out: {HELD_OUT_MAP}), {} threads",
        nets.len(),
        maps.iter()
            .map(|m| m.0.as_str())
            .collect::<Vec<_>>()
            .join(", "),
        rayon::current_num_threads()
    );
    let start = Instant::now();
    let references: Vec<Vec<Image>> = nets
        .iter()
        .map(|n| {
            maps.iter()
                .map(|(name, env)| measured(n, name, env, &normals, a.cache.as_deref()))
                .collect()
        })
        .collect::<Result<_, String>>()?;
    eprintln!("measured renders: {:.1} s", start.elapsed().as_secs_f64());

    println!(
        "| method | {HELD_OUT_MAP} (held out): median / worst / mean PSNR | other maps: median / worst / mean | fit time per material |"
    );
    println!("|---|---|---|---|");
    for &method in &a.methods {
        let start = Instant::now();
        let fits: Vec<(Material, usize, f64)> = nets
            .par_iter()
            .map(|n| {
                let t = Instant::now();
                let (m, lobes) = fit_one(method, n, a.tolerance)?;
                Ok((m, lobes, t.elapsed().as_secs_f64()))
            })
            .collect::<Result<_, String>>()?;
        let fits = if method == Method::Oracle {
            let refine = |((m, lobes, t), refs): (&(Material, usize, f64), &Vec<Image>)| {
                let start = Instant::now();
                let m = oracle::oracle(m, &maps, &normals, &mask, refs, a.oracle_steps)?;
                Ok((m, *lobes, t + start.elapsed().as_secs_f64()))
            };
            fits.par_iter()
                .zip(&references)
                .map(refine)
                .collect::<Result<_, String>>()?
        } else {
            fits
        };
        let wall = start.elapsed().as_secs_f64();
        let (mut held, mut others) = (Vec::new(), Vec::new());
        for ((net, (material, lobes, _)), refs) in nets.iter().zip(&fits).zip(&references) {
            let images = renderer
                .render(&under_maps(material, &maps, &normals)?)
                .map_err(|e| e.to_string())?;
            let mut line = format!("{:10} {:28} {lobes} lobes", method.label(), net.name);
            for ((name, _), (img, reference)) in maps.iter().zip(images.iter().zip(refs)) {
                let p = psnr(img, reference, &mask);
                line += &format!("  {name} {p:.1}");
                if name == HELD_OUT_MAP {
                    held.push(p)
                } else {
                    others.push(p)
                }
            }
            eprintln!("{line}");
        }
        let seconds: Vec<f64> = fits.iter().map(|f| f.2).collect();
        let summary = |v: &[f64]| {
            if v.is_empty() {
                "-".to_string()
            } else {
                let (m, w, a) = stats(v);
                format!("{m:.1} / {w:.1} / {a:.1} dB")
            }
        };
        println!(
            "| {} | {} | {} | {:.1} s ({:.0} s wall for {} on {} threads) |",
            method.label(),
            summary(&held),
            summary(&others),
            stats(&seconds).2,
            wall,
            nets.len(),
            rayon::current_num_threads()
        );
    }
    Ok(())
}
