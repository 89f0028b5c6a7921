//! The lod bench's inputs: scenes, materials and env maps, with how peaked each map's
//! lighting is.

use std::path::PathBuf;

use matedit::{EnvMap, Material, NormalMap};
use serde_json::{Value, json};

use crate::common::{self, BUMPY_SEED, median};

/// The normals of a scene of `--scenes`.
pub fn normals_of(scene: &str) -> NormalMap {
    match scene {
        "sphere128" => NormalMap::sphere(128),
        "sphere256" => NormalMap::sphere(256),
        "sphere512" => NormalMap::sphere(512),
        _ => NormalMap::bumpy(512, 512, BUMPY_SEED),
    }
}

/// A preset by name, or `random-SEED`: [`Material::random`], nine lobes with nothing to
/// share.
pub fn material(name: &str) -> Option<Material> {
    match name.strip_prefix("random-").map(str::parse::<u64>) {
        Some(Ok(seed)) => Some(Material::random(seed)),
        _ => matedit::presets::lookup(name),
    }
}

/// The materials of `names` (checked), each printed with its description.
pub fn materials(names: &[String]) -> Vec<Material> {
    for n in names {
        let desc = match matedit::presets::all()
            .iter()
            .find(|p| p.name == n.as_str())
        {
            Some(p) => p.description.as_str(),
            None => "nine lobes, each its own scale (0.02-1.2) and exponent (0.3-80) curve",
        };
        println!("material {n}: {desc}");
    }
    names.iter().filter_map(|n| material(n)).collect()
}

/// The built-in sky with its sun (the texels above [`SUN_TEXEL`]) ten times brighter: a
/// hard sun, most of the energy in a few texels.
pub fn hard_sun((h, w): (usize, usize)) -> (EnvMap, String) {
    let mut env = matedit::builtin_sky::procedural_env(h, w, matedit::Convention::Equirect);
    for t in &mut env.texels {
        if t.iter().any(|&v| v > SUN_TEXEL) {
            *t = t.map(|v| v * 10.0);
        }
    }
    (env, format!("built-in sky, its sun 10x, {h}x{w}"))
}

/// Radiance above which a texel of the built-in sky is the sun's (the sky and its glow
/// stay under 3).
pub const SUN_TEXEL: f32 = 20.0;

/// An env map of the run: its name, the map and what was measured of it.
pub struct Env {
    pub name: String,
    pub env: EnvMap,
    pub info: Value,
}

/// How peaked a map's lighting is: (brightest texel / median texel, by luminance; the
/// share of the map's energy, luminance x solid angle, in its 16 most energetic texels:
/// what `keep16` keeps).
pub fn contrast(env: &EnvMap) -> (f64, f64) {
    let lum = |t: &[f32; 3]| {
        0.2126 * f64::from(t[0]) + 0.7152 * f64::from(t[1]) + 0.0722 * f64::from(t[2])
    };
    let l: Vec<f64> = env.texels.iter().map(lum).collect();
    let max = l.iter().copied().fold(0.0, f64::max);
    let mut energy: Vec<f64> = l
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (r, c) = (i / env.width, i % env.width);
            v * env.convention.texel(r, c, env.height, env.width).1
        })
        .collect();
    energy.sort_by(|a, b| b.total_cmp(a));
    let total: f64 = energy.iter().sum();
    let top: f64 = energy.iter().take(16).sum();
    (
        max / median(&l).max(f64::MIN_POSITIVE),
        top / total.max(f64::MIN_POSITIVE),
    )
}

/// Soft, mixed or hard lighting, by the brightest / median texel at the bench's 64 x 128.
pub fn lighting(ratio: f64) -> &'static str {
    if ratio < 500.0 {
        "soft"
    } else if ratio < 5000.0 {
        "mixed"
    } else {
        "hard"
    }
}

/// The env maps of `--envs` (every map of ../shared/data/envmaps without it, else the
/// built-in sky), each printed with how peaked its lighting is; a map that cannot be
/// read is skipped.
pub fn load_envs(names: &[String]) -> Vec<Env> {
    let files = common::envmap_files();
    let mut wanted: Vec<Option<PathBuf>> = if names.is_empty() {
        files.iter().cloned().map(Some).collect()
    } else {
        names
            .iter()
            .map(|n| {
                (n != "sky" && n != "sun").then(|| {
                    files
                        .iter()
                        .find(|f| f.file_stem().is_some_and(|s| s == n.as_str()))
                        .cloned()
                        .unwrap_or_else(|| PathBuf::from(n))
                })
            })
            .collect()
    };
    if wanted.is_empty() {
        println!("env: no ../shared/data/envmaps/*.exr; using the built-in sky");
        wanted.push(None);
    }
    let mut envs = Vec::new();
    let mut builtin = names.iter().filter(|n| *n == "sky" || *n == "sun");
    for w in wanted {
        let (name, env, full, desc) = match w {
            None if builtin.next().is_some_and(|n| n == "sun") => {
                let (env, desc) = hard_sun(common::ENV_SIZE);
                ("sun".to_string(), env, None, desc)
            }
            None => {
                let (env, desc) = common::builtin_sky(common::ENV_SIZE);
                ("sky".to_string(), env, None, desc)
            }
            Some(path) => match common::load_env_file(&path, common::ENV_SIZE) {
                Ok(l) => {
                    let name = path.file_stem().unwrap_or_default().to_string_lossy();
                    (name.into_owned(), l.env, Some(l.full), l.desc)
                }
                Err(e) => {
                    println!("env {}: skipped: {e}", path.display());
                    continue;
                }
            },
        };
        let (ratio, top16) = contrast(&env);
        let full_ratio = full.as_ref().map(|f| contrast(f).0);
        println!(
            "env {name}: {desc}; brightest / median texel {ratio:.0} at 64x128{}, {:.0}% of the \
             energy in the 16 brightest texels: {} lighting",
            full_ratio.map_or(String::new(), |c| format!(" ({c:.0} at full size)")),
            100.0 * top16,
            lighting(ratio)
        );
        let info = json!({
            "name": name, "desc": desc, "brightest_over_median": ratio,
            "brightest_over_median_full_size": full_ratio, "top16_energy_share": top16,
            "lighting": lighting(ratio),
        });
        envs.push(Env { name, env, info });
    }
    envs
}
