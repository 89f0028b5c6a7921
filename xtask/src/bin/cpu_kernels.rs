//! The fast CPU path's kernels on one scene, without the rest of a call: the lobe-plan
//! kernels against the kernels for materials with nothing to share (`matedit::cpu::dense`),
//! alternated, and the largest difference between their results.
//!
//! `cargo xtask cpu_kernels -- [--scene sphereN|bumpyWxH] [--material
//! random-SEED[:L]|PRESET] [--env HxW] [--reps N] [--kernels plan,dense] [--pass fwd,bwd]`
//! (defaults: sphere256, random-1, the built-in sky at 64 x 128, 5 reps, both kernels, both
//! passes). Times are medians of the prepared scene's forward (`fwd`) and backward (`bwd`)
//! calls of `FastCpu`, after a warm-up, in M pixel-texel pairs per second. With `--reps 1`
//! and one kernel and pass it is also what valgrind counts instructions on. `--math exp2|
//! exp2m1|ln1m` instead evaluates that function of `matedit::cpu::math` on 2^20 values
//! `--reps` times (valgrind's count per value, from two rep counts, is its cost in a lane).

use std::time::Instant;

use matedit::cpu::FastCpu;
use matedit::prepare::Prepared;
use matedit::{Camera, Convention, Material, NormalMap, Scene};

fn arg(args: &[String], name: &str, default: &str) -> String {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
        .unwrap_or_else(|| default.to_string())
}

fn size(v: &str) -> Option<(usize, usize)> {
    let (a, b) = v.split_once('x')?;
    Some((a.parse().ok()?, b.parse().ok()?))
}

fn normals(name: &str) -> Option<NormalMap> {
    if let Some(n) = name.strip_prefix("sphere") {
        return Some(NormalMap::sphere(n.parse().ok()?));
    }
    let (w, h) = size(name.strip_prefix("bumpy")?)?;
    Some(NormalMap::bumpy(w, h, 1))
}

/// A preset, `random-SEED`, or `random-SEED:L`: its first L lobes per channel only (the
/// others' scales 0; the image leaves them out).
fn material(name: &str) -> Option<Material> {
    let Some(rest) = name.strip_prefix("random-") else {
        return matedit::presets::lookup(name);
    };
    let (seed, lobes) = rest.split_once(':').unwrap_or((rest, "3"));
    let (seed, lobes): (u64, usize) = (seed.parse().ok()?, lobes.parse().ok()?);
    let mut ctrl = Material::random(seed).ctrl;
    for k in 0..3 {
        for s in lobes..3 {
            for j in 0..6 {
                ctrl[matedit::material::idx(k, s, 0, j)] = 0.0;
            }
        }
    }
    Material::new(name, &ctrl).ok()
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn max_diff(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let scale = a
        .iter()
        .flatten()
        .fold(0.0f64, |m, v| m.max(v.abs() as f64));
    let d = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs() as f64));
    d / scale.max(1e-30)
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scene_name = arg(&args, "--scene", "sphere256");
    let mat_name = arg(&args, "--material", "random-1");
    let (hl, wl) = size(&arg(&args, "--env", "64x128")).ok_or("--env: expected HxW")?;
    let reps: usize = arg(&args, "--reps", "5")
        .parse()
        .map_err(|_| "--reps: expected a number")?;
    let kernels = arg(&args, "--kernels", "plan,dense");
    let passes = arg(&args, "--pass", "fwd,bwd");
    if let Some(f) = args.iter().position(|a| a == "--math") {
        return math(args.get(f + 1).map_or("", String::as_str), reps);
    }
    let scene = Scene {
        normals: normals(&scene_name).ok_or(format!("unknown scene '{scene_name}'"))?,
        env: matedit::builtin_sky::procedural_env(hl, wl, Convention::Equirect),
        material: material(&mat_name).ok_or(format!("unknown material '{mat_name}'"))?,
        camera: Camera::Orthographic,
    };
    let prep = Prepared::new(&scene);
    let plan = matedit::cpu::table::LobePlan::new(&prep.ctrl, |_, _| true);
    let groups = plan.groups.iter().filter(|g| g.exp_col.is_some()).count();
    let lobes: usize = plan.groups.iter().map(|g| g.lobes.len()).sum();
    let channels: u32 = plan
        .groups
        .iter()
        .flat_map(|g| g.lobes.iter().map(|l| l.channels.count_ones()))
        .sum();
    println!(
        "backward plan: {groups} exponent groups, {lobes} lobes for {channels} (channel, lobe)s"
    );
    let g: Vec<[f32; 3]> = (0..prep.width * prep.height)
        .map(|i| [1.0, 0.5 + (i % 7) as f32 * 0.1, -0.25])
        .collect();
    let pairs = (prep.pixels.len() * prep.lit.len()) as f64;
    let best = FastCpu::new().map_err(|e| e.to_string())?;
    let cpus: Vec<(&str, FastCpu)> = kernels
        .split(',')
        .map(|k| match k {
            "plan" => Ok(("plan", best.plan_kernels_only())),
            "dense" => Ok(("dense", best)),
            _ => Err(format!("unknown kernels '{k}': expected plan or dense")),
        })
        .collect::<Result<_, _>>()?;
    println!(
        "{scene_name}, {mat_name}, sky {hl} x {wl}, {:?}, {} threads: {:.1} M pairs",
        best.level(),
        rayon::current_num_threads(),
        pairs / 1e6
    );
    for pass in passes.split(',') {
        let mut times = vec![Vec::new(); cpus.len()];
        for rep in 0..reps + 1 {
            // per kernel, its outputs (the image; or dLoss/dL and dLoss/dn)
            let mut outs: Vec<Vec<Vec<[f32; 3]>>> = Vec::new();
            for (i, (_, cpu)) in cpus.iter().enumerate() {
                let t = Instant::now();
                outs.push(match pass {
                    "fwd" => vec![cpu.forward(&prep)],
                    "bwd" => {
                        let gr = cpu.backward(&prep, &g, matedit::Wanted::ALL);
                        vec![gr.d_env, gr.d_normals]
                    }
                    _ => return Err(format!("unknown pass '{pass}': expected fwd or bwd")),
                });
                if rep > 0 {
                    times[i].push(t.elapsed().as_secs_f64());
                }
            }
            if rep == 0 && outs.len() == 2 {
                for (x, y) in outs[0].iter().zip(&outs[1]) {
                    println!(
                        "  {pass}: largest difference / largest value {:.1e}",
                        max_diff(x, y)
                    );
                }
            }
        }
        for ((name, _), t) in cpus.iter().zip(times) {
            if !t.is_empty() {
                let m = median(t);
                println!(
                    "  {pass} {name:>6}: {m:.4} s  {:8.1} M pairs/s",
                    pairs / m / 1e6
                );
            }
        }
    }
    Ok(())
}

/// `--math`: one function of the kernels' math over 2^20 values in (0, 1), `reps` times.
fn math(name: &str, reps: usize) -> Result<(), String> {
    use matedit::cpu::math::{MathFn, eval};
    let f = match name {
        "exp2" => MathFn::Exp2,
        "exp2m1" => MathFn::Exp2m1,
        "ln1m" => MathFn::Ln1m,
        _ => return Err(format!("--math '{name}': expected exp2, exp2m1 or ln1m")),
    };
    let cpu = FastCpu::new().map_err(|e| e.to_string())?;
    // arguments as the kernels see them: exponents of x^m1 in (-8, 0), lobe arguments
    // in (0, 2), and 1 - x in (0, 1)
    let xs: Vec<f32> = (0..1 << 20)
        .map(|i| {
            let t = (i as f32 + 0.5) / (1 << 20) as f32;
            match f {
                MathFn::Exp2 => -8.0 * t,
                MathFn::Exp2m1 => 2.0 * t,
                _ => t,
            }
        })
        .collect();
    let mut sum = 0.0f64;
    for _ in 0..reps {
        sum += eval(&cpu, f, &xs).iter().map(|&v| v as f64).sum::<f64>();
    }
    println!("{name} over {} values x {reps}: sum {sum:.6e}", xs.len());
    Ok(())
}
