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

#[path = "../common/mod.rs"]
mod common;

mod case;
mod cli;
mod errors;
mod inputs;
mod occupancy;
mod peers;
mod report;
mod timing;

use std::path::PathBuf;
use std::time::Instant;

use case::{Gathered, Setup, run_case};
use cli::cli_mtime;
use common::{list, num, target_dir, upstream_for, write};
use inputs::{load_env, normals_of};
use matedit::{Camera, Device, Renderer, Scene};
use occupancy::occupancy;
use report::{Rec, csv, print_ratios};
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

    let cli_built = cli_mtime();
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
    let setup = Setup {
        opts: &opts,
        env: &env,
        renderers: &renderers,
        cli_devices: &cli_devices,
        peers: &peers,
    };
    let mut out = Gathered {
        records: Vec::new(),
        ratios: Vec::new(),
        notes: Vec::new(),
        cli_built,
    };
    for scene_name in &opts.scenes {
        let normals = normals_of(scene_name);
        let upstream = upstream_for(normals.width, normals.height);
        let g64: Vec<[f64; 3]> = upstream.pixels.iter().map(|p| p.map(f64::from)).collect();
        for material in &materials {
            let scene = Scene {
                normals: normals.clone(),
                env: env.clone(),
                material: material.clone(),
                camera: Camera::Orthographic,
            };
            run_case(&setup, scene_name, scene, &upstream, &g64, &mut out);
        }
    }
    let Gathered {
        records,
        ratios,
        notes,
        ..
    } = out;

    // peers against matedit
    print_ratios(&ratios);

    println!(
        "\nerrors: max abs error / max abs value of the f64 reference's output. d_normals jumps \
         where a texel crosses a pixel's horizon; a texel within f32 rounding of it can put a \
         few pixels near 1e-4 in every f32 implementation alike."
    );
    let records: Vec<Value> = records.iter().map(Rec::json).collect();
    let report = json!({
        "machine": mach,
        "threads": setup.opts.threads,
        "describe": describe,
        "env": env_desc,
        "materials": setup.opts.materials,
        "camera": "orthographic",
        "convention": "equirect",
        "reps": setup.opts.reps, "ref_reps": setup.opts.ref_reps, "cli_reps": setup.opts.cli_reps,
        "peer_reps": setup.opts.peer_reps,
        "pairs": "foreground pixels x texels with d_omega > 0",
        "errors": "max abs error / max abs value of the f64 reference's output",
        "records": records,
        "peer_ratios": ratios,
        "notes": notes,
        "seconds_total": started.elapsed().as_secs_f64(),
    });
    if let Err(e) = std::fs::create_dir_all(&setup.opts.out) {
        eprintln!("cannot create {}: {e}", setup.opts.out.display());
        return;
    }
    let (jp, cp) = (
        setup.opts.out.join("layer.json"),
        setup.opts.out.join("layer.csv"),
    );
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
