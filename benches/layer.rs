//! The layer's speed and accuracy on every path, beside the peer implementations, in one run.
//!
//! `cargo bench --bench layer -- [OPTIONS]` (`--help` lists them). For each scene (128 x 128
//! and 256 x 256 spheres, a 256 x 256 bumpy sphere) against a 64 x 128 env map (the first
//! `.exr` in ../shared/data/envmaps, downsampled; the built-in sky without it), and each
//! material (a glossy and a diffuse preset), orthographic, `equirect`:
//!
//! - the f64 reference's image and gradients are computed once (the ground truth, cached
//!   for the whole scene and material); that computation is also the `reference` path's
//!   timing unless `--ref-reps N` asks for N timed runs through `Device::Reference`;
//! - each in-process path (`cpu`, `gpu`, `reference`) is timed through
//!   `matedit::Renderer`: `fwd` = one render call, `fb` = one render call plus one
//!   backward call; median of `--reps` runs after a warm-up (at least 0.5 s of calls);
//! - the release command line (`matedit render` and `matedit grad --device cpu` as
//!   separate processes on the same inputs written as NPY/JSON) is timed whole, as a
//!   user sees it: `cli-cpu` `fwd` = render process, `fb` = render + grad processes;
//! - the peers (../shared/peers/time_peers.py, Dr.Jit and Numba, 2 threads each) are run
//!   on the same files, when Python can import them; their outputs are checked too.
//!
//! Every record gives the median seconds, M pairs/s (foreground pixels x texels with
//! d_omega > 0, per second) and the error against the f64 reference: max abs error over
//! the reference's max abs value, for the image and each gradient (d_env, d_normals,
//! d_ctrl). The upstream gradient is a fixed pseudo-random image in [-1, 1]. Peers also
//! get ratios: peer seconds / matedit seconds (> 1: matedit is faster), against the
//! in-process `cpu` path and against the whole command-line processes.
//!
//! dI/dn jumps where a texel crosses a pixel's horizon (n . w = 0): a texel within f32
//! rounding of it is counted on one side by f32 code and on the other by the f64
//! reference, so a few pixels can show d_normals errors near 1e-4 in every f32
//! implementation alike (bumpy256 with clay does: one sky texel at n . w = -4e-10).
//!
//! The `gpu` path also prints, per scene, the GPU time of each pass of its last forward
//! and its last backward call (timestamp queries, where the adapter has them; in
//! layer.json as `pass_timings`), and the host's share of a call: the call's wall time
//! minus its passes' GPU time, median over the timed runs (`host_overhead_s`; for `fb`,
//! the forward and the backward call together).
//!
//! Before the runs, an occupancy table (`--occupancy` prints it alone and exits): for each
//! scene and pass, the dispatches, workgroups and invocations per dispatch, before
//! (the shape of commit fa34885: one dispatch per uniform chunk, one slice, which is also
//! what a software adapter gets now) and after (the plan on a large GPU, src/gpu/plan.rs),
//! against a large GPU's resident invocations: an H100 SXM's 132 SMs x 2048 = 270,336.
//!
//! Output: a table on stdout; target/bench/layer.json and layer.csv.

mod common;

use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;

use common::{
    BUMPY_SEED, Files, flat3, list, median, num, read_npy, rel_err, run_peers, target_dir,
    upstream_for, write, write_inputs,
};
use matedit::gpu::layout::WG;
use matedit::gpu::plan::LARGE_GPU_RESIDENT;
use matedit::gpu::{Dispatch, Pass, PassTiming, Planner, Tiles};
use matedit::io::npy;
use matedit::prepare::Prepared;
use matedit::reference::{self, GradientsF64};
use matedit::{Batch, Camera, Device, EnvMap, Gradients, Image, NormalMap, Renderer, Scene};
use serde_json::{Value, json};

const USAGE: &str = "\
cargo bench --bench layer -- [OPTIONS]
  --scenes LIST      of sphere128, sphere256, bumpy256, bumpy320x240, sphere1024
                     [sphere128,sphere256,bumpy256]
  --materials LIST   preset names or random-SEED (nine lobes, each its own scale and
                     exponent curve, exponents 0.3-80) [plastic-red,clay,random-1]
  --paths LIST       of cpu, gpu, reference [cpu,reference]; the reference's results are
                     computed once per scene and material whatever this says
  --reps N           timed runs per path and pass, after a warm-up [5]
  --ref-reps N       0: time the reference by its one ground-truth run (f64 functions, cold);
                     N > 0: N timed runs through Device::Reference as well [0]
  --cli-reps N       timed runs of each command-line process, after a warm-up; 0 skips [--reps]
  --peers LIST       of drjit, numba, torch, or none [drjit,numba]
  --peer-reps N      timed runs per peer (time_peers.py --reps) [--reps]
  --threads N        rayon threads here and --threads of the command line [2, as the peers]
  --env FILE         an .exr or .npy env map instead of the first in ../shared/data/envmaps
  --env-size HxW     the size the map is resampled to [64x128]
  --out DIR          where layer.json and layer.csv go [target/bench]
  --occupancy        print the occupancy table (dispatch shapes against a large GPU) and exit
  --keep             keep the files given to the command line and the peers, and what they
                     wrote, in DIR/inputs/SCENE-MATERIAL (else a temporary folder), with the
                     reference's image, d_env and d_normals as float32 reference_*.npy";

const SCENES: [&str; 3] = ["sphere128", "sphere256", "bumpy256"];
/// The scenes `--scenes` takes: the default ones and a large one for the GPU path.
const KNOWN: [&str; 5] = [
    "sphere128",
    "sphere256",
    "bumpy256",
    "bumpy320x240",
    "sphere1024",
];

struct Opts {
    scenes: Vec<String>,
    materials: Vec<String>,
    paths: Vec<String>,
    reps: usize,
    ref_reps: usize,
    cli_reps: usize,
    peers: Vec<String>,
    peer_reps: usize,
    threads: usize,
    env: Option<PathBuf>,
    env_size: (usize, usize),
    out: PathBuf,
    keep: bool,
    occupancy: bool,
}

fn parse_args() -> Result<Opts, String> {
    let mut o = Opts {
        scenes: SCENES.iter().map(|s| s.to_string()).collect(),
        materials: list("plastic-red,clay,random-1"),
        paths: list("cpu,reference"),
        reps: 5,
        ref_reps: 0,
        cli_reps: usize::MAX,
        peers: list("drjit,numba"),
        peer_reps: usize::MAX,
        threads: 2,
        env: None,
        env_size: common::ENV_SIZE,
        out: target_dir().join("bench"),
        keep: false,
        occupancy: false,
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--bench" => {} // cargo's
            "--help" | "-h" => {
                println!("{USAGE}");
                std::process::exit(0);
            }
            "--scenes" => o.scenes = list(&args.next().unwrap_or_default()),
            "--materials" => o.materials = list(&args.next().unwrap_or_default()),
            "--paths" => o.paths = list(&args.next().unwrap_or_default()),
            "--peers" => o.peers = list(&args.next().unwrap_or_default()),
            "--reps" => o.reps = num(args.next(), "--reps")?.max(1),
            "--ref-reps" => o.ref_reps = num(args.next(), "--ref-reps")?,
            "--cli-reps" => o.cli_reps = num(args.next(), "--cli-reps")?,
            "--peer-reps" => o.peer_reps = num(args.next(), "--peer-reps")?.max(1),
            "--threads" => o.threads = num(args.next(), "--threads")?.max(1),
            "--env" => o.env = args.next().map(PathBuf::from),
            "--env-size" => {
                let v = args.next().unwrap_or_default();
                o.env_size = v
                    .split_once('x')
                    .and_then(|(h, w)| Some((h.parse().ok()?, w.parse().ok()?)))
                    .filter(|&(h, w)| h > 0 && w > 0)
                    .ok_or(format!("--env-size '{v}': expected HxW, e.g. 16x32"))?;
            }
            "--out" => o.out = PathBuf::from(args.next().unwrap_or_default()),
            "--keep" => o.keep = true,
            "--occupancy" => o.occupancy = true,
            _ => return Err(format!("unknown argument '{a}'")),
        }
    }
    if o.cli_reps == usize::MAX {
        o.cli_reps = o.reps;
    }
    if o.peer_reps == usize::MAX {
        o.peer_reps = o.reps;
    }
    o.peers.retain(|p| p != "none");
    common::check_names(&o.scenes, &KNOWN, &o.materials)?;
    for p in &o.paths {
        if !["cpu", "gpu", "reference"].contains(&p.as_str()) {
            return Err(format!(
                "unknown path '{p}': expected cpu, gpu or reference"
            ));
        }
    }
    Ok(o)
}

// ---------------------------------------------------------------------------------------
// machine and inputs

/// The env map: a real HDR map resampled to `--env-size` (64 x 128), else the built-in sky.
fn load_env(opts: &Opts) -> (EnvMap, String) {
    let path = opts
        .env
        .clone()
        .or_else(|| common::envmap_files().into_iter().next());
    let Some(path) = path else {
        println!("env: no ../shared/data/envmaps/*.exr; using the built-in sky");
        return common::builtin_sky(opts.env_size);
    };
    match common::load_env_file(&path, opts.env_size) {
        Ok(l) => (l.env, l.desc),
        Err(e) => {
            println!("env: {e}; using the built-in sky");
            common::builtin_sky(opts.env_size)
        }
    }
}

fn normals_of(scene: &str) -> NormalMap {
    match scene {
        "sphere128" => NormalMap::sphere(128),
        "sphere256" => NormalMap::sphere(256),
        "sphere1024" => NormalMap::sphere(1024),
        "bumpy320x240" => NormalMap::bumpy(320, 240, BUMPY_SEED),
        _ => NormalMap::bumpy(256, 256, BUMPY_SEED),
    }
}

// ---------------------------------------------------------------------------------------
// errors against the reference

/// The reference's results for one scene and material.
struct Truth {
    image: Vec<[f64; 3]>,
    grads: GradientsF64,
    fwd_s: f64,
    bwd_s: f64,
}

/// Errors of an image and (optionally) gradients, each as f64 slices.
struct Got<'a> {
    image: &'a [f64],
    grads: Option<(&'a [f64], &'a [f64], &'a [f64])>,
}

fn errors(t: &Truth, got: Got) -> Value {
    let mut e = serde_json::Map::new();
    if got.image.len() == t.image.len() * 3 {
        e.insert(
            "image".into(),
            json!(rel_err(got.image.iter().copied(), flat3(&t.image))),
        );
    } else {
        e.insert("image_shape_mismatch".into(), json!(got.image.len()));
    }
    if let Some((d_env, d_n, d_ctrl)) = got.grads {
        let g = &t.grads;
        let pairs: [(&str, &[f64], Vec<f64>); 3] = [
            ("d_env", d_env, flat3(&g.d_env).collect()),
            ("d_normals", d_n, flat3(&g.d_normals).collect()),
            ("d_ctrl", d_ctrl, g.d_ctrl.to_vec()),
        ];
        for (name, got, want) in pairs {
            if got.len() == want.len() {
                e.insert(
                    name.into(),
                    json!(rel_err(got.iter().copied(), want.into_iter())),
                );
            } else {
                e.insert(format!("{name}_shape_mismatch"), json!(got.len()));
            }
        }
    }
    Value::Object(e)
}

fn f64s(v: &[[f32; 3]]) -> Vec<f64> {
    flat3(v).collect()
}

fn errors_f32(t: &Truth, image: &Image, grads: Option<&Gradients>) -> Value {
    let img = f64s(&image.pixels);
    match grads {
        None => errors(
            t,
            Got {
                image: &img,
                grads: None,
            },
        ),
        Some(g) => {
            let (e, n) = (f64s(&g.d_env), f64s(&g.d_normals));
            let c: Vec<f64> = g.d_ctrl.iter().map(|&v| v as f64).collect();
            errors(
                t,
                Got {
                    image: &img,
                    grads: Some((&e, &n, &c)),
                },
            )
        }
    }
}

// ---------------------------------------------------------------------------------------
// timing

struct Rec {
    path: String,
    scene: String,
    material: String,
    pass: &'static str,
    times: Vec<f64>,
    /// Timed runs behind the median (peers report the median alone).
    reps: usize,
    pairs: f64,
    errors: Value,
    extra: serde_json::Map<String, Value>,
    /// GPU time per pass of the last call (in-process `gpu` path only).
    timings: Vec<PassTiming>,
}

impl Rec {
    fn median(&self) -> f64 {
        median(&self.times)
    }
    fn json(&self) -> Value {
        let m = self.median();
        let mut v = json!({
            "path": self.path, "scene": self.scene, "material": self.material,
            "pass": self.pass, "median_s": m, "reps": self.reps,
            "mpairs_per_s": self.pairs / m / 1e6, "errors": self.errors,
        });
        if let Value::Object(o) = &mut v {
            o.extend(self.extra.clone());
        }
        v
    }
}

/// fwd and fb timings of one renderer: warm-up (if asked), then `reps` runs of each.
/// What [`time_renderer`] measured: forward and forward + backward seconds per run, the
/// last image and gradients, and the per-pass GPU times of the last forward and the last
/// backward call (empty off the GPU or without timestamp queries).
struct Timed {
    fwd: Vec<f64>,
    fb: Vec<f64>,
    image: Image,
    grads: Gradients,
    fwd_passes: Vec<PassTiming>,
    bwd_passes: Vec<PassTiming>,
    /// Per run, the call's wall time minus its passes' GPU time (empty without timings).
    fwd_host: Vec<f64>,
    fb_host: Vec<f64>,
}

/// The GPU seconds of the last call's passes; `None` without timestamp queries.
fn gpu_seconds(r: &Renderer) -> Option<f64> {
    let t = r.last_timings();
    (!t.is_empty()).then(|| t.iter().map(|p| p.seconds).sum())
}

/// The in-process paths render for at least this long before they are timed.
const WARM_UP_S: f64 = 0.5;

fn time_renderer(
    r: &Renderer,
    batch: &Batch,
    upstream: &[Image],
    reps: usize,
    warm_up: bool,
) -> Result<Timed, matedit::Error> {
    if warm_up {
        // a GPU idles at a low clock and takes a while to raise it: on an H100, after a
        // single warm-up call, the timed forward calls' GPU time had a median of 37 ms
        // against 6.5 ms in the last of them (sphere256), so warm up for a while
        let s = Instant::now();
        while s.elapsed().as_secs_f64() < WARM_UP_S {
            r.render(batch)?;
        }
    }
    let mut fwd = Vec::new();
    let mut fwd_host = Vec::new();
    let mut image = None;
    for _ in 0..reps {
        let s = Instant::now();
        let out = r.render(batch)?;
        let call = s.elapsed().as_secs_f64();
        fwd.push(call);
        fwd_host.extend(gpu_seconds(r).map(|g| call - g));
        image = out.into_iter().next();
    }
    let fwd_passes = r.last_timings();
    if warm_up {
        r.render(batch)?;
        r.backward(batch, upstream)?;
    }
    let mut fb = Vec::new();
    let mut fb_host = Vec::new();
    let mut grads = None;
    for _ in 0..reps {
        let s = Instant::now();
        let out = r.render(batch)?;
        let forward_gpu = gpu_seconds(r);
        let g = r.backward(batch, upstream)?;
        let call = s.elapsed().as_secs_f64();
        fb.push(call);
        if let (Some(f), Some(b)) = (forward_gpu, gpu_seconds(r)) {
            fb_host.push(call - f - b);
        }
        image = out.into_iter().next();
        grads = g.into_iter().next();
    }
    Ok(Timed {
        fwd,
        fb,
        image: image.expect("reps >= 1"),
        grads: grads.expect("reps >= 1"),
        fwd_passes,
        bwd_passes: r.last_timings(),
        fwd_host,
        fb_host,
    })
}

/// The GPU time of each pass, printed under the path's rows; as JSON for layer.json.
fn pass_timings(call: &str, timings: &[PassTiming]) -> Value {
    if timings.is_empty() {
        return Value::Null;
    }
    println!("  {call}: GPU timestamps per pass");
    for t in timings {
        let rate = t
            .pairs_per_second()
            .map_or("-".to_string(), |r| format!("{:.1}", r / 1e6));
        println!(
            "    {:<16} {:>10.6} s {:>9} Mpairs/s  {} compute passes",
            t.pass, t.seconds, rate, t.compute_passes
        );
    }
    json!(
        timings
            .iter()
            .map(
                |t| json!({"pass": t.pass, "seconds": t.seconds, "pairs": t.pairs,
                "compute_passes": t.compute_passes})
            )
            .collect::<Vec<_>>()
    )
}

/// The occupancy table: for each scene, call and pass, the dispatches and the largest's
/// workgroups and invocations, before (fa34885: a dispatch per uniform chunk, one slice;
/// also what a software adapter gets now) and after (the plan on a large GPU), against a
/// large GPU's resident invocations.
fn occupancy(scenes: &[String], env: &EnvMap, material: &matedit::Material) {
    let after = Planner::large_gpu();
    let mut before = Planner::large_gpu().with_slices(1);
    before.tiles = Tiles::Uniform;
    println!(
        "\noccupancy against a large GPU (assumed: an H100 SXM, 132 SMs x 2048 resident \
         invocations = {LARGE_GPU_RESIDENT}; workgroups of {WG} invocations)"
    );
    println!(
        "{:<10} {:<4} {:<15} {:<6} {:>10} {:>15} {:>12} {:>9}",
        "scene", "call", "pass", "shape", "dispatches", "workgroups", "invocations", "resident"
    );
    for name in scenes {
        let normals = normals_of(name);
        let up = upstream_for(normals.width, normals.height);
        let scene = Scene {
            normals,
            env: env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        };
        let prep = Prepared::new(&scene);
        let (np, nl, nt) = (prep.pixels.len(), prep.lit.len(), prep.texels.len());
        let active = prep
            .pixels
            .iter()
            .filter(|p| up.pixels[p.index].iter().any(|&v| v != 0.0))
            .count();
        for (call, plan) in [
            ("fwd", (&before.forward(np, nl), &after.forward(np, nl))),
            (
                "bwd",
                (
                    &before.backward(np, nl, nt, active),
                    &after.backward(np, nl, nt, active),
                ),
            ),
        ] {
            let mut passes: Vec<Pass> = Vec::new();
            for d in plan.0.iter().chain(plan.1) {
                if !passes.contains(&d.pass) {
                    passes.push(d.pass);
                }
            }
            for pass in passes {
                for (shape, ds) in [("before", plan.0), ("after", plan.1)] {
                    let ds: Vec<&Dispatch> = ds.iter().filter(|d| d.pass == pass).collect();
                    let Some(big) = ds.iter().max_by_key(|d| d.invocations()) else {
                        continue;
                    };
                    let [x, y, z] = big.workgroups;
                    println!(
                        "{:<10} {:<4} {:<15} {:<6} {:>10} {:>15} {:>12} {:>8.1}%",
                        name,
                        call,
                        pass.name(),
                        shape,
                        ds.len(),
                        format!("{x} x {y} x {z}"),
                        big.invocations(),
                        100.0 * big.invocations() as f64 / LARGE_GPU_RESIDENT as f64
                    );
                }
            }
        }
    }
}

// ---------------------------------------------------------------------------------------
// command line and peers: files

/// Runs a command to completion; its wall seconds, or its stderr's tail on failure.
fn run_timed(cmd: &mut Command) -> Result<f64, String> {
    let s = Instant::now();
    let out = cmd.output().map_err(|e| format!("cannot start: {e}"))?;
    let t = s.elapsed().as_secs_f64();
    if out.status.success() {
        Ok(t)
    } else {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: String = err.lines().rev().take(3).collect::<Vec<_>>().join(" | ");
        Err(format!("{}: {tail}", out.status))
    }
}

/// `matedit render` and `matedit grad` as whole processes: (render s, grad s) per rep, and
/// the errors of what they wrote.
fn time_cli(
    f: &Files,
    device: &str,
    threads: usize,
    reps: usize,
    truth: &Truth,
) -> Result<(Vec<f64>, Vec<f64>, Value, Value), String> {
    let bin = env!("CARGO_BIN_EXE_matedit");
    let image = f.dir.join(format!("cli_{device}.npy"));
    let grads = f.dir.join(format!("cli_{device}_grads"));
    let common = |sub: &str| {
        let mut c = Command::new(bin);
        c.arg(sub)
            .arg("--normals")
            .arg(&f.normals)
            .arg("--env")
            .arg(&f.env)
            .arg("--material")
            .arg(&f.material)
            .args(["--device", device, "--threads", &threads.to_string()]);
        c
    };
    let mut render = common("render");
    render.arg("-o").arg(&image);
    let mut grad = common("grad");
    grad.arg("--upstream")
        .arg(&f.upstream)
        .arg("-o")
        .arg(&grads);
    // warm-up: page cache, and a check that both work
    run_timed(&mut render).map_err(|e| format!("matedit render: {e}"))?;
    run_timed(&mut grad).map_err(|e| format!("matedit grad: {e}"))?;
    let (mut tr, mut tg) = (Vec::new(), Vec::new());
    for _ in 0..reps {
        tr.push(run_timed(&mut render)?);
        tg.push(run_timed(&mut grad)?);
    }
    // what the processes wrote, against the reference
    let img = read_npy(&image)?;
    let d_env = read_npy(&grads.join("d_env.npy"))?;
    let d_n = read_npy(&grads.join("d_normals.npy"))?;
    let ctrl_file = grads.join("d_material.json");
    let ctrl: Value = serde_json::from_slice(&std::fs::read(&ctrl_file).unwrap_or_default())
        .map_err(|e| format!("{}: {e}", ctrl_file.display()))?;
    let d_ctrl: Vec<f64> = ctrl["ctrl"]
        .as_array()
        .map(|a| a.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    let e_fwd = errors(
        truth,
        Got {
            image: &img.data,
            grads: None,
        },
    );
    let e_fb = errors(
        truth,
        Got {
            image: &img.data,
            grads: Some((&d_env.data, &d_n.data, &d_ctrl)),
        },
    );
    Ok((tr, tg, e_fwd, e_fb))
}

/// The command-line binary's modification time, to notice a rebuild during the run (other
/// builds in the same target folder overwrite it).
fn cli_mtime() -> Option<std::time::SystemTime> {
    std::fs::metadata(env!("CARGO_BIN_EXE_matedit"))
        .and_then(|m| m.modified())
        .ok()
}

/// A peer's image and gradients (left beside the normals by time_peers.py) against the
/// reference: (fwd errors, fb errors).
fn peer_errors(f: &Files, peer: &str, truth: &Truth) -> (Value, Value) {
    let img = match common::read_peer_image(f, peer) {
        Ok(img) => img,
        Err(e) => return (json!({"unread": e}), json!({"unread": e})),
    };
    let fwd = errors(
        truth,
        Got {
            image: &img,
            grads: None,
        },
    );
    let fb = match common::read_peer_grads(f, peer) {
        Ok([e, n, c]) => errors(
            truth,
            Got {
                image: &img,
                grads: Some((&e, &n, &c)),
            },
        ),
        Err(common::Unread::Arrays(keys)) => json!({"unread": format!("arrays {keys}")}),
        Err(common::Unread::File(e)) => {
            let mut v = fwd.clone();
            v["grads_unread"] = json!(e);
            v
        }
    };
    (fwd, fb)
}

// ---------------------------------------------------------------------------------------
// report

fn fmt_err(e: &Value, key: &str) -> String {
    match e.get(key).and_then(Value::as_f64) {
        Some(v) => format!("{v:.1e}"),
        None => "-".into(),
    }
}

fn print_row(r: &Rec) {
    let m = r.median();
    println!(
        "{:<12} {:<10} {:<12} {:<4} {:>9.4} {:>3} {:>9.1} {:>8} {:>8} {:>8} {:>8}",
        r.path,
        r.scene,
        r.material,
        r.pass,
        m,
        r.reps,
        r.pairs / m / 1e6,
        fmt_err(&r.errors, "image"),
        fmt_err(&r.errors, "d_env"),
        fmt_err(&r.errors, "d_normals"),
        fmt_err(&r.errors, "d_ctrl"),
    );
}

fn header() {
    println!(
        "{:<12} {:<10} {:<12} {:<4} {:>9} {:>3} {:>9} {:>8} {:>8} {:>8} {:>8}",
        "path",
        "scene",
        "material",
        "pass",
        "median s",
        "n",
        "Mpairs/s",
        "err img",
        "d_env",
        "d_normal",
        "d_ctrl"
    );
}

fn csv(records: &[Value]) -> String {
    let cols = [
        "path",
        "scene",
        "material",
        "pass",
        "median_s",
        "reps",
        "mpairs_per_s",
        "err_image",
        "err_d_env",
        "err_d_normals",
        "err_d_ctrl",
        "ratio_vs_cpu",
        "ratio_vs_cli",
    ];
    common::csv(records, &cols, |r, c| match c.strip_prefix("err_") {
        Some(k) => &r["errors"][k],
        None => &r[c],
    })
}

fn main() {
    let opts = match parse_args() {
        Ok(o) => o,
        Err(e) => {
            eprintln!("layer bench: {e}\n\n{USAGE}");
            std::process::exit(2);
        }
    };
    let started = Instant::now();
    let mach = common::set_up(opts.threads, " here and in the command line");

    // the renderers of the in-process paths
    let mut renderers: Vec<(String, Renderer)> = Vec::new();
    let mut describe = serde_json::Map::new();
    for p in &opts.paths {
        let device = match p.as_str() {
            "cpu" => Device::Cpu,
            "gpu" => Device::Gpu,
            _ => Device::Reference,
        };
        match Renderer::new(device) {
            Ok(r) => {
                println!("path {p}: {}", r.describe());
                describe.insert(p.clone(), json!(r.describe()));
                renderers.push((p.clone(), r));
            }
            Err(e) => {
                println!("path {p}: skipped: {e}");
                describe.insert(p.clone(), json!(format!("skipped: {e}")));
            }
        }
    }
    let (env, env_desc) = load_env(&opts);
    println!("env: {env_desc}; equirect, orthographic camera");
    let materials = common::materials(&opts.materials);
    occupancy(&opts.scenes, &env, &materials[0]);
    if opts.occupancy {
        return;
    }

    // the command line and the peers
    let cli_devices: Vec<&str> = if opts.cli_reps == 0 {
        Vec::new()
    } else {
        renderers
            .iter()
            .map(|(p, _)| p.as_str())
            .filter(|p| *p != "reference")
            .collect()
    };
    let peers = common::runnable_peers(&opts.peers, opts.peer_reps);

    let mut cli_built = cli_mtime();
    if !cli_devices.is_empty() {
        let bench_built = std::env::current_exe()
            .and_then(std::fs::metadata)
            .and_then(|m| m.modified())
            .ok();
        if let (Some(c), Some(b)) = (cli_built, bench_built)
            && let Ok(d) = c.duration_since(b)
            && d.as_secs() > 60
        {
            println!(
                "warning: {} was built {} s after this bench: it may hold other code",
                env!("CARGO_BIN_EXE_matedit"),
                d.as_secs()
            );
        }
        println!("command line: {}", env!("CARGO_BIN_EXE_matedit"));
    }
    let mut records: Vec<Rec> = Vec::new();
    let mut ratios: Vec<Value> = Vec::new();
    let mut notes: Vec<String> = Vec::new();
    for scene_name in &opts.scenes {
        let normals = normals_of(scene_name);
        let (w, h) = (normals.width, normals.height);
        let upstream = upstream_for(w, h);
        let g64: Vec<[f64; 3]> = upstream.pixels.iter().map(|p| p.map(f64::from)).collect();
        for material in &materials {
            let scene = Scene {
                normals: normals.clone(),
                env: env.clone(),
                material: material.clone(),
                camera: Camera::Orthographic,
            };
            let batch = Batch::single(scene.clone()).expect("valid scene");
            let ups = vec![upstream.clone()];

            // ground truth, once
            let s = Instant::now();
            let prep = Prepared::new(&scene);
            let image = reference::forward(&prep);
            let fwd_s = s.elapsed().as_secs_f64();
            let s = Instant::now();
            let grads = reference::backward(&prep, &g64);
            let bwd_s = s.elapsed().as_secs_f64();
            let truth = Truth {
                image,
                grads,
                fwd_s,
                bwd_s,
            };
            let pairs = (prep.pixels.len() * prep.texels.len()) as f64;
            println!(
                "\n== {scene_name} ({w}x{h}, {} foreground px) x {} texels = {:.1} M pairs; {}; \
                 reference computed in {:.2} s fwd + {:.2} s bwd",
                prep.pixels.len(),
                prep.texels.len(),
                pairs / 1e6,
                material.name,
                truth.fwd_s,
                truth.bwd_s
            );
            header();
            let rec = |path: &str, pass: &'static str, times: Vec<f64>, errors: Value| Rec {
                path: path.to_string(),
                scene: scene_name.clone(),
                material: material.name.clone(),
                pass,
                reps: times.len(),
                times,
                pairs,
                errors,
                extra: serde_json::Map::new(),
                timings: Vec::new(),
            };

            // in-process paths
            let mut cpu_s: Option<(f64, f64)> = None;
            for (path, r) in &renderers {
                let timed = if path == "reference" && opts.ref_reps == 0 {
                    let img = Image {
                        width: w,
                        height: h,
                        pixels: truth.image.iter().map(|p| p.map(|v| v as f32)).collect(),
                    };
                    let e_fwd = errors_f32(&truth, &img, None);
                    let e_fb = {
                        let g = &truth.grads;
                        let f32s = |v: &[[f64; 3]]| -> Vec<f64> {
                            v.iter().flatten().map(|&x| x as f32 as f64).collect()
                        };
                        let (e, n) = (f32s(&g.d_env), f32s(&g.d_normals));
                        let c: Vec<f64> = g.d_ctrl.iter().map(|&x| x as f32 as f64).collect();
                        let img = f64s(&img.pixels);
                        errors(
                            &truth,
                            Got {
                                image: &img,
                                grads: Some((&e, &n, &c)),
                            },
                        )
                    };
                    let mut a = rec(path, "fwd", vec![truth.fwd_s], e_fwd);
                    let mut b = rec(path, "fb", vec![truth.fwd_s + truth.bwd_s], e_fb);
                    let how = json!(
                        "the ground-truth run: f64 functions, once, cold; errors: its f32 rounding"
                    );
                    a.extra.insert("timing".into(), how.clone());
                    b.extra.insert("timing".into(), how);
                    Ok((a, b))
                } else {
                    let reps = if path == "reference" {
                        opts.ref_reps
                    } else {
                        opts.reps
                    };
                    time_renderer(r, &batch, &ups, reps, path != "reference").map(|t| {
                        let mut a = rec(path, "fwd", t.fwd, errors_f32(&truth, &t.image, None));
                        let mut b = rec(
                            path,
                            "fb",
                            t.fb,
                            errors_f32(&truth, &t.image, Some(&t.grads)),
                        );
                        a.timings = t.fwd_passes;
                        b.timings = t.bwd_passes;
                        for (r, host) in [(&mut a, t.fwd_host), (&mut b, t.fb_host)] {
                            if !host.is_empty() {
                                r.extra
                                    .insert("host_overhead_s".into(), json!(median(&host)));
                            }
                        }
                        (a, b)
                    })
                };
                match timed {
                    Ok((mut a, mut b)) => {
                        if path == "cpu" {
                            cpu_s = Some((a.median(), b.median()));
                        }
                        print_row(&a);
                        print_row(&b);
                        for (r, call) in [
                            (&mut a, "last forward call"),
                            (&mut b, "last backward call"),
                        ] {
                            let t = pass_timings(call, &r.timings);
                            if !t.is_null() {
                                r.extra.insert("pass_timings".into(), t);
                            }
                            if let Some(h) = r.extra.get("host_overhead_s").and_then(Value::as_f64)
                            {
                                println!(
                                    "    {} host overhead (call - GPU passes, median): {:.2} ms",
                                    r.pass,
                                    h * 1e3
                                );
                            }
                        }
                        records.push(a);
                        records.push(b);
                    }
                    Err(e) => {
                        let n = format!("{path} {scene_name} {}: failed: {e}", material.name);
                        println!("{n}");
                        notes.push(n);
                    }
                }
            }

            // whole processes and peers share the input files
            let keep = opts.keep.then(|| {
                opts.out
                    .join(format!("inputs/{scene_name}-{}", material.name))
            });
            let files = write_inputs(&scene, &upstream, keep);
            if opts.keep {
                let f32s = |v: &[[f64; 3]]| -> Vec<[f32; 3]> {
                    v.iter().map(|p| p.map(|x| x as f32)).collect()
                };
                let g = &truth.grads;
                let (hl, wl) = (env.height, env.width);
                for (name, wd, ht, v) in [
                    ("reference_image.npy", w, h, &truth.image),
                    ("reference_d_env.npy", wl, hl, &g.d_env),
                    ("reference_d_normals.npy", w, h, &g.d_normals),
                ] {
                    write(&files.dir.join(name), &npy::encode_rgb(wd, ht, &f32s(v)));
                }
            }
            let mut cli_s: Option<(f64, f64)> = None;
            for device in &cli_devices {
                if cli_mtime() != cli_built {
                    let n = format!(
                        "warning: {} was rebuilt during this run; command-line timings from here on \
                         may be of other code",
                        env!("CARGO_BIN_EXE_matedit")
                    );
                    println!("{n}");
                    notes.push(n);
                    cli_built = cli_mtime();
                }
                match time_cli(&files, device, opts.threads, opts.cli_reps, &truth) {
                    Ok((tr, tg, e_fwd, e_fb)) => {
                        let fb: Vec<f64> = tr.iter().zip(&tg).map(|(a, b)| a + b).collect();
                        let path = format!("cli-{device}");
                        let a = rec(&path, "fwd", tr.clone(), e_fwd);
                        let mut b = rec(&path, "fb", fb, e_fb);
                        b.extra
                            .insert("grad_process_median_s".into(), json!(median(&tg)));
                        if *device == "cpu" {
                            cli_s = Some((a.median(), b.median()));
                        }
                        print_row(&a);
                        print_row(&b);
                        records.push(a);
                        records.push(b);
                    }
                    Err(e) => {
                        let n = format!("cli {device} {scene_name} {}: {e}", material.name);
                        println!("{n}");
                        notes.push(n);
                    }
                }
            }
            if !peers.is_empty() {
                match run_peers(&files, &peers, opts.peer_reps) {
                    Err(e) => {
                        let n = format!("peers {scene_name} {}: {e}", material.name);
                        println!("{n}");
                        notes.push(n);
                    }
                    Ok(res) => {
                        for peer in &peers {
                            let r = &res[peer.as_str()];
                            if let Some(err) = r.get("error") {
                                let n = format!(
                                    "peer {peer} {scene_name} {}: failed: {}",
                                    material.name,
                                    err.as_str().unwrap_or("").replace('\n', " | ")
                                );
                                println!("{n}");
                                notes.push(n);
                                continue;
                            }
                            let (e_fwd, e_fb) = peer_errors(&files, peer, &truth);
                            let path = format!("peer-{peer}");
                            let mut ratio = json!({
                                "peer": peer, "scene": scene_name, "material": material.name,
                            });
                            for (pass, errs, idx) in [("fwd", e_fwd, 0), ("fb", e_fb, 1)] {
                                let Some(t) = r[pass].as_f64() else { continue };
                                let mut x = rec(&path, pass, vec![t], errs);
                                x.reps = opts.peer_reps;
                                let pick = |v: (f64, f64)| if idx == 0 { v.0 } else { v.1 };
                                let vs_cpu = cpu_s.map(|c| t / pick(c));
                                let vs_cli = cli_s.map(|c| t / pick(c));
                                x.extra.insert("ratio_vs_cpu".into(), json!(vs_cpu));
                                x.extra.insert("ratio_vs_cli".into(), json!(vs_cli));
                                ratio[pass] = json!({
                                    "peer_s": t, "cpu_s": cpu_s.map(pick), "cli_s": cli_s.map(pick),
                                    "ratio_vs_cpu": vs_cpu, "ratio_vs_cli": vs_cli,
                                });
                                print_row(&x);
                                records.push(x);
                            }
                            ratios.push(ratio);
                        }
                    }
                }
            }
        }
    }

    // peers against matedit
    if !ratios.is_empty() {
        println!(
            "\nratios peer s / matedit s (> 1: matedit is faster); cpu = in-process Device::Cpu, \
             cli = whole `matedit render` (+ `grad`) processes"
        );
        println!(
            "{:<8} {:<10} {:<12} {:>9} {:>9} {:>9} {:>9} | {:>9} {:>9} {:>9} {:>9}",
            "peer",
            "scene",
            "material",
            "fwd s",
            "cpu s",
            "vs cpu",
            "vs cli",
            "fb s",
            "cpu s",
            "vs cpu",
            "vs cli"
        );
        let f = |v: &Value, d: usize| match v.as_f64() {
            Some(x) => format!("{x:.d$}"),
            None => "-".into(),
        };
        for r in &ratios {
            println!(
                "{:<8} {:<10} {:<12} {:>9} {:>9} {:>9} {:>9} | {:>9} {:>9} {:>9} {:>9}",
                r["peer"].as_str().unwrap_or(""),
                r["scene"].as_str().unwrap_or(""),
                r["material"].as_str().unwrap_or(""),
                f(&r["fwd"]["peer_s"], 4),
                f(&r["fwd"]["cpu_s"], 4),
                f(&r["fwd"]["ratio_vs_cpu"], 3),
                f(&r["fwd"]["ratio_vs_cli"], 3),
                f(&r["fb"]["peer_s"], 4),
                f(&r["fb"]["cpu_s"], 4),
                f(&r["fb"]["ratio_vs_cpu"], 3),
                f(&r["fb"]["ratio_vs_cli"], 3),
            );
        }
    }

    println!(
        "\nerrors: max abs error / max abs value of the f64 reference's output. d_normals jumps \
         where a texel crosses a pixel's horizon; a texel within f32 rounding of it can put a \
         few pixels near 1e-4 in every f32 implementation alike."
    );
    let records: Vec<Value> = records.iter().map(Rec::json).collect();
    let report = json!({
        "machine": mach,
        "threads": opts.threads,
        "describe": describe,
        "env": env_desc,
        "materials": opts.materials,
        "camera": "orthographic",
        "convention": "equirect",
        "reps": opts.reps, "ref_reps": opts.ref_reps, "cli_reps": opts.cli_reps,
        "peer_reps": opts.peer_reps,
        "pairs": "foreground pixels x texels with d_omega > 0",
        "errors": "max abs error / max abs value of the f64 reference's output",
        "records": records,
        "peer_ratios": ratios,
        "notes": notes,
        "seconds_total": started.elapsed().as_secs_f64(),
    });
    if let Err(e) = std::fs::create_dir_all(&opts.out) {
        eprintln!("cannot create {}: {e}", opts.out.display());
        return;
    }
    let (jp, cp) = (opts.out.join("layer.json"), opts.out.join("layer.csv"));
    write(
        &jp,
        (serde_json::to_string_pretty(&report).unwrap_or_default() + "\n").as_bytes(),
    );
    write(&cp, csv(&records).as_bytes());
    println!(
        "\nwrote {} and {} ({:.0} s in all)",
        jp.display(),
        cp.display(),
        started.elapsed().as_secs_f64()
    );
}
