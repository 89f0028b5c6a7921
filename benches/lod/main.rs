//! Levels of detail: the speed and the accuracy of every `matedit::lod` method, with charts.
//!
//! `cargo bench --bench lod -- [OPTIONS]` (`--help` lists them). For each scene (spheres of
//! 128, 256 and 512 pixels a side and a 512 x 512 bumpy surface, orthographic, `equirect`),
//! each env map (every `.exr` of ../shared/data/envmaps downsampled to 64 x 128; the
//! built-in sky without them) and each material (a diffuse, a glossy and a sharply specular
//! preset), on the fast CPU path (`FastCpu`):
//!
//! - every method of `--methods` (`lod::render`, and `lod::render` + `lod::backward`), and
//!   for every tolerance of `--tols` the method `lod::render_within` (`fwd`) and
//!   `lod::backward_within` + `lod::render` of its choice (`fb`) pick, the choice timed
//!   with it; median of `--reps` runs (`--big-reps` for the exact and the tolerance runs
//!   of the 512 scenes and for any run over a second: the defaults' budget is about 15
//!   minutes on 2 cores), the `fwd` runs after a warm-up and the `fb` runs after those;
//!   the tolerance runs come after every method has warmed the kernels;
//! - errors against the exact layer on the same path (`Method::EXACT`), per output: max
//!   |x - x_exact| / max |x_exact| and mean |x - x_exact| / max |x_exact|; the exact path's
//!   own error against the f64 reference is measured once, on the 128 sphere;
//! - the peers (../shared/peers/time_peers.py: Dr.Jit and Numba, 2 threads each) on the 512
//!   scenes, when Python can import them, with their errors against the same exact result.
//!
//! The upstream gradient is a fixed pseudo-random image in [-1, 1]. Output: a table on
//! stdout, then a check of the tolerance runs (measured error above the tolerance: the
//! estimate was wrong; slower than the exact layer); target/bench/lod.json and lod.csv,
//! and the charts lod_fwd.{png,svg} and lod_fb.{png,svg} (log-log: time against the
//! largest error).

#[path = "../common/mod.rs"]
mod common;

mod charts;
mod errors;
mod inputs;
mod measure;
mod record;
mod report;

use std::path::PathBuf;
use std::time::Instant;

use common::{list, num, target_dir, upstream_for};
use errors::reference_check;
use inputs::{load_envs, material, materials, normals_of};
use matedit::cpu::FastCpu;
use matedit::lod::Method;
use matedit::prepare::Prepared;
use matedit::{Backend, Camera, Scene};
use measure::{measure, measure_peers};
use record::{Case, Rec};
use report::{finish, header, print_checks, write_outputs};
use serde_json::{Value, json};

const USAGE: &str = "\
cargo bench --bench lod -- [OPTIONS]
  --scenes LIST     of sphere128, sphere256, sphere512, bumpy512 [all]
  --envs LIST       env maps: names of ../shared/data/envmaps/*.exr (forest), .exr/.npy
                    paths, sky (the built-in sky) or sun (the built-in sky, its sun ten
                    times brighter: a hard sun) [every map there, else sky]
  --materials LIST  preset names or random-SEED (Material::random: nine lobes, each its
                    own scale and exponent curve) [clay,plastic-red,chrome-ish]
  --methods LIST    lod methods (exact, envF, keepK, tableR joined by '+'; exact is always
                    run: it is what the errors are measured against) [exact,env2,env4,env8,
                    env4+keep16,table32,table64,table128,table256,table128+env2+keep16,
                    table64+env4+keep16]
  --tols LIST       tolerances for lod::render_within / backward_within; none: no such runs
                    [1e-2,1e-3,1e-4]
  --reps N          timed runs per method and pass [5]: fwd after a warm-up, then fb
  --big-reps N      timed runs of the exact and the tolerance runs on the 512 scenes,
                    and of any run whose first timed run took over 1 s [2]
  --peers LIST      of drjit, numba, torch, or none; run on the 512 scenes [drjit,numba]
  --peer-reps N     timed runs per peer (time_peers.py --reps, after its warm-up) [1]
  --peer-envs N     the peers run with the first N env maps [1]
  --peer-materials LIST
                    and these materials (all: every one) [plastic-red]; the peers' time
                    depends on neither: they evaluate every lobe of every pair
  --no-ref-check    skip the exact path's error against the f64 reference (128 sphere)
  --threads N       rayon threads [2, as the peers]
  --out DIR         where lod.json, lod.csv and the charts go [target/bench]
  --chart DIR       the same as --out DIR
  --replot FILE     draw the charts and write the csv of a lod.json again, run nothing";

const SCENES: [&str; 4] = ["sphere128", "sphere256", "sphere512", "bumpy512"];
const METHODS: &str = "exact,env2,env4,env8,env4+keep16,table32,table64,table128,table256,\
                       table128+env2+keep16,table64+env4+keep16";

struct Opts {
    scenes: Vec<String>,
    envs: Vec<String>,
    materials: Vec<String>,
    methods: Vec<Method>,
    tols: Vec<f64>,
    reps: usize,
    big_reps: usize,
    peers: Vec<String>,
    peer_reps: usize,
    peer_envs: usize,
    peer_materials: Vec<String>,
    ref_check: bool,
    threads: usize,
    out: PathBuf,
    replot: Option<PathBuf>,
}

fn parse_args() -> Result<Opts, String> {
    let mut o = Opts {
        scenes: SCENES.iter().map(|s| s.to_string()).collect(),
        envs: Vec::new(),
        materials: list("clay,plastic-red,chrome-ish"),
        methods: Vec::new(),
        tols: vec![1e-2, 1e-3, 1e-4],
        reps: 5,
        big_reps: 2,
        peers: list("drjit,numba"),
        peer_reps: 1,
        peer_envs: 1,
        peer_materials: list("plastic-red"),
        ref_check: true,
        threads: 2,
        out: target_dir().join("bench"),
        replot: None,
    };
    let mut methods = list(METHODS);
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().unwrap_or_default();
        match a.as_str() {
            "--bench" => {} // cargo's
            "--help" | "-h" => {
                println!("{USAGE}");
                std::process::exit(0);
            }
            "--scenes" => o.scenes = list(&value()),
            "--envs" => o.envs = list(&value()),
            "--materials" => o.materials = list(&value()),
            "--methods" => methods = list(&value()),
            "--tols" => {
                o.tols = list(&value())
                    .iter()
                    .filter(|t| *t != "none")
                    .map(|t| match t.parse::<f64>() {
                        Ok(v) if v > 0.0 && v.is_finite() => Ok(v),
                        _ => Err(format!("--tols: '{t}' is not a positive number")),
                    })
                    .collect::<Result<_, _>>()?
            }
            "--peers" => o.peers = list(&value()),
            "--reps" => o.reps = num(Some(value()), "--reps")?.max(1),
            "--big-reps" => o.big_reps = num(Some(value()), "--big-reps")?.max(1),
            "--peer-reps" => o.peer_reps = num(Some(value()), "--peer-reps")?.max(1),
            "--peer-envs" => o.peer_envs = num(Some(value()), "--peer-envs")?,
            "--peer-materials" => o.peer_materials = list(&value()),
            "--no-ref-check" => o.ref_check = false,
            "--threads" => o.threads = num(Some(value()), "--threads")?.max(1),
            "--out" | "--chart" => o.out = PathBuf::from(value()),
            "--replot" => o.replot = Some(PathBuf::from(value())),
            _ => return Err(format!("unknown argument '{a}'")),
        }
    }
    o.peers.retain(|p| p != "none");
    common::check_names(&o.scenes, &SCENES, &[])?;
    if let Some(m) = o.materials.iter().find(|m| material(m).is_none()) {
        return Err(format!(
            "unknown material '{m}': expected random-SEED or one of {:?}",
            matedit::presets::names()
        ));
    }
    // the exact layer first: every error is measured against it
    o.methods.push(Method::EXACT);
    for m in &methods {
        let m: Method = m.parse()?;
        if !o.methods.contains(&m) {
            o.methods.push(m);
        }
    }
    Ok(o)
}

fn main() {
    let opts = parse_args().unwrap_or_else(|e| {
        eprintln!("lod bench: {e}\n\n{USAGE}");
        std::process::exit(2)
    });
    if let Some(file) = &opts.replot {
        let report: Value = std::fs::read(file)
            .map_err(|e| e.to_string())
            .and_then(|b| serde_json::from_slice(&b).map_err(|e| e.to_string()))
            .unwrap_or_else(|e| {
                eprintln!("lod bench: {}: {e}", file.display());
                std::process::exit(2);
            });
        write_outputs(&report, &opts.out, false);
        return;
    }
    let started = Instant::now();
    let mach = common::set_up(opts.threads, "");
    let cpu = match FastCpu::new() {
        Ok(c) => c,
        Err(e) => {
            eprintln!("lod bench: the fast CPU path: {e}");
            std::process::exit(1);
        }
    };
    println!("backend: {}", cpu.describe());
    let envs = load_envs(&opts.envs);
    let materials = materials(&opts.materials);
    let peers = common::runnable_peers(&opts.peers, opts.peer_reps);
    let mut notes = Vec::new();
    let ref_check = match envs.first() {
        Some(env) if opts.ref_check => reference_check(&cpu, env, &materials),
        _ => Vec::new(),
    };
    println!(
        "\nerrors: max (and mean) |x - x_exact| / max |x_exact| against Method::EXACT on this \
         path; times: median seconds; n: timed runs; fb errors are the image's and the \
         gradients'; tolerance rows: method (fwd / fb choice), estimated errors fwd/fb, WRONG \
         where the measured error is above the tolerance"
    );

    let mut records: Vec<Rec> = Vec::new();
    for scene_name in &opts.scenes {
        let normals = normals_of(scene_name);
        let (w, h) = (normals.width, normals.height);
        let upstream = upstream_for(w, h);
        for (ei, env) in envs.iter().enumerate() {
            for material in &materials {
                let case = Case {
                    name: scene_name.clone(),
                    env: &env.name,
                    scene: Scene {
                        normals: normals.clone(),
                        env: env.env.clone(),
                        material: material.clone(),
                        camera: Camera::Orthographic,
                    },
                    upstream: upstream.clone(),
                };
                let prep = Prepared::new(&case.scene);
                println!(
                    "\n== {scene_name} ({w}x{h}, {} foreground px) x {} lit texels; {}; {} ({})",
                    prep.pixels.len(),
                    prep.lit.len(),
                    material.name,
                    env.name,
                    env.info["lighting"].as_str().unwrap_or("")
                );
                drop(prep);
                header();
                let Some((recs, exact)) = measure(&cpu, &case, &opts, &mut notes) else {
                    continue;
                };
                records.extend(recs);
                let peer_material = opts
                    .peer_materials
                    .iter()
                    .any(|m| *m == material.name || m == "all");
                if !peers.is_empty() && w >= 512 && ei < opts.peer_envs && peer_material {
                    records.extend(measure_peers(
                        &case,
                        &peers,
                        opts.peer_reps,
                        &exact,
                        &mut notes,
                    ));
                }
            }
        }
    }

    let (records, wrong, slower) = finish(records.iter().map(Rec::json).collect());
    let tol_rows = records
        .iter()
        .filter(|r| r["chosen_by_tol"] == true)
        .count();
    print_checks(&wrong, &slower, tol_rows);
    let report = json!({
        "machine": mach,
        "threads": opts.threads,
        "backend": cpu.describe(),
        "envs": envs.iter().map(|e| e.info.clone()).collect::<Vec<_>>(),
        "materials": opts.materials,
        "scenes": opts.scenes,
        "camera": "orthographic",
        "convention": "equirect",
        "methods": opts.methods.iter().map(Method::to_string).collect::<Vec<_>>(),
        "tols": opts.tols,
        "reps": opts.reps, "big_reps": opts.big_reps, "peer_reps": opts.peer_reps,
        "errors": "per output, max |x - x_exact| / max |x_exact| (max) and mean |x - x_exact| / \
                   max |x_exact| (mean), against Method::EXACT on the same fast CPU path; err_max: \
                   the largest max over the outputs of the record",
        "exact_vs_reference": ref_check,
        "exact_vs_reference_note": "the exact fast path's own max error against the f64 \
                                    reference, sphere128 with the first env map",
        "check": {"estimate_wrong": wrong, "slower_than_exact": slower, "tolerance_runs": tol_rows},
        "records": records,
        "notes": notes,
        "seconds_total": started.elapsed().as_secs_f64(),
    });
    write_outputs(&report, &opts.out, true);
    println!("({:.0} s in all)", started.elapsed().as_secs_f64());
}
