//! How far the levels of detail's estimates (`lod::Chooser::estimate`: the samples the
//! choice judges a method on) fall below the errors they stand for (the method against the
//! exact layer on every pixel and texel), per output: what the safety factors
//! (`lod::SAFETY`, `lod::SAFETY_SUMS`) must cover.
//!
//! ```sh
//! cargo xtask lod_estimates -- [--size 512] [--envs studio,forest]
//!     [--materials plastic-red,random-1,clay] [--methods table128+keep16,...]
//! ```
//!
//! Scenes: the orthographic sphere and the bumpy surface (seed 1) at `--size`; maps from
//! ../shared/data/envmaps at 64 x 128 (the built-in sky where a name is `sky`); the
//! upstream gradient a fixed pseudo-random image in [-1, 1). Prints each case's measured
//! error over its estimate for the image, dLoss/dL, dLoss/dn and dLoss/dctrl, and per
//! output the median and the largest ratio.

use std::path::Path;

use matedit::cpu::FastCpu;
use matedit::lod::{self, Chooser, Method};
use matedit::{Camera, Convention, EnvMap, Image, NormalMap, Scene, builtin_sky, io};

fn arg(args: &[String], name: &str, default: &str) -> String {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .cloned()
        .unwrap_or_else(|| default.to_string())
}

fn env(name: &str) -> Result<EnvMap, String> {
    if name == "sky" {
        return Ok(builtin_sky::procedural_env(64, 128, Convention::Equirect));
    }
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("../shared/data/envmaps/{name}.exr"));
    let l = io::load_env(&path, Convention::Equirect).map_err(|e| e.to_string())?;
    let size = io::EnvSize::Size {
        height: 64,
        width: 128,
    };
    io::resample::fit(l.env, size, &path).map_err(|e| e.to_string())
}

/// max |a - b| over max |b|.
fn rel(a: &[f32], b: &[f32]) -> f64 {
    let diff = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max(f64::from(x - y).abs()));
    let scale = b.iter().fold(0.0f64, |m, y| m.max(f64::from(*y).abs()));
    if diff == 0.0 { 0.0 } else { diff / scale }
}

fn flat(v: &[[f32; 3]]) -> Vec<f32> {
    v.iter().flatten().copied().collect()
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = arg(&args, "--size", "512")
        .parse()
        .map_err(|e| format!("--size: {e}"))?;
    let envs = arg(&args, "--envs", "studio,forest");
    let materials = arg(&args, "--materials", "plastic-red,random-1,clay");
    let methods = arg(
        &args,
        "--methods",
        "table128+keep16,table192+keep16,table256+keep16,table192+keep64",
    );
    let cpu = FastCpu::new().map_err(|e| e.to_string())?;
    let mut rng = matedit::splitmix::SplitMix(0x5eed);
    let mut next = move || ((rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0;
    let up = Image {
        width: size,
        height: size,
        pixels: (0..size * size).map(|_| [next(), next(), next()]).collect(),
    };
    let names = ["image", "d_env", "d_normals", "d_ctrl"];
    let mut ratios: Vec<Vec<f64>> = vec![Vec::new(); 4];
    println!(
        "scene      env     material     method            measured / estimated: image  d_env  d_normals  d_ctrl"
    );
    for (sn, normals) in [
        ("sphere", NormalMap::sphere(size)),
        ("bumpy", NormalMap::bumpy(size, size, 1)),
    ] {
        for en in envs.split(',') {
            let env = env(en)?;
            for mn in materials.split(',') {
                let material = match mn.strip_prefix("random-") {
                    Some(k) => matedit::Material::random(k.parse().map_err(|_| format!("{mn}?"))?),
                    None => matedit::presets::lookup(mn).ok_or(format!("no preset {mn}"))?,
                };
                let scene = Scene {
                    normals: normals.clone(),
                    env: env.clone(),
                    material,
                    camera: Camera::Orthographic,
                };
                let exact_image =
                    lod::render(&cpu, &scene, &Method::EXACT).map_err(|e| e.to_string())?;
                let exact =
                    lod::backward(&cpu, &scene, &up, &Method::EXACT).map_err(|e| e.to_string())?;
                for m in methods.split(',') {
                    let method: Method = m.parse()?;
                    let e = Chooser::default()
                        .estimate(&cpu, &scene, &method, Some(&up))
                        .map_err(|e| e.to_string())?;
                    let image = lod::render(&cpu, &scene, &method).map_err(|e| e.to_string())?;
                    let g = lod::backward(&cpu, &scene, &up, &method).map_err(|e| e.to_string())?;
                    let measured = [
                        rel(&flat(&image.pixels), &flat(&exact_image.pixels)),
                        rel(&flat(&g.d_env), &flat(&exact.d_env)),
                        rel(&flat(&g.d_normals), &flat(&exact.d_normals)),
                        rel(&g.d_ctrl, &exact.d_ctrl),
                    ];
                    let estimated = [
                        e.image,
                        e.d_env.unwrap_or(0.0),
                        e.d_normals.unwrap_or(0.0),
                        e.d_ctrl.unwrap_or(0.0),
                    ];
                    let mut line = format!("{sn:10} {en:7} {mn:12} {m:17}");
                    for k in 0..4 {
                        let r = measured[k] / estimated[k];
                        line += &format!(" {:>6.2}", r);
                        if r.is_finite() {
                            ratios[k].push(r);
                        }
                    }
                    println!("{line}");
                }
            }
        }
    }
    for (k, name) in names.iter().enumerate() {
        let v = &mut ratios[k];
        v.sort_by(f64::total_cmp);
        if let Some(max) = v.last() {
            println!(
                "{name:10} measured / estimated over {} cases: median {:.2}, largest {:.2}",
                v.len(),
                v[v.len() / 2],
                max
            );
        }
    }
    Ok(())
}
