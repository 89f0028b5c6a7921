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

mod common;

use std::path::{Path, PathBuf};
use std::time::Instant;

use common::{BUMPY_SEED, flat3, list, median, num, rel_errors, target_dir, upstream_for, write};
use matedit::cpu::FastCpu;
use matedit::lod::{self, Choice, Method};
use matedit::prepare::Prepared;
use matedit::{Backend, Camera, EnvMap, Gradients, Image, Material, NormalMap, Scene};
use plotters::coord::Shift;
use plotters::coord::combinators::LogCoord;
use plotters::prelude::*;
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
/// Where the charts draw errors of 0 (the exact layer against itself): log axes have no 0.
const FLOOR: f64 = 1e-7;
/// The outputs errors are measured on; `fb` records have all four.
const OUTPUTS: [&str; 4] = ["image", "d_env", "d_normals", "d_ctrl"];

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

// ---------------------------------------------------------------------------------------
// inputs

fn normals_of(scene: &str) -> NormalMap {
    match scene {
        "sphere128" => NormalMap::sphere(128),
        "sphere256" => NormalMap::sphere(256),
        "sphere512" => NormalMap::sphere(512),
        _ => NormalMap::bumpy(512, 512, BUMPY_SEED),
    }
}

/// A preset by name, or `random-SEED`: [`Material::random`], nine lobes with nothing to
/// share.
fn material(name: &str) -> Option<Material> {
    match name.strip_prefix("random-").map(str::parse::<u64>) {
        Some(Ok(seed)) => Some(Material::random(seed)),
        _ => matedit::presets::lookup(name),
    }
}

/// The materials of `names` (checked), each printed with its description.
fn materials(names: &[String]) -> Vec<Material> {
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
fn hard_sun((h, w): (usize, usize)) -> (EnvMap, String) {
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
const SUN_TEXEL: f32 = 20.0;

/// An env map of the run: its name, the map and what was measured of it.
struct Env {
    name: String,
    env: EnvMap,
    info: Value,
}

/// How peaked a map's lighting is: (brightest texel / median texel, by luminance; the
/// share of the map's energy, luminance x solid angle, in its 16 most energetic texels:
/// what `keep16` keeps).
fn contrast(env: &EnvMap) -> (f64, f64) {
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
fn lighting(ratio: f64) -> &'static str {
    if ratio < 500.0 {
        "soft"
    } else if ratio < 5000.0 {
        "mixed"
    } else {
        "hard"
    }
}

fn load_envs(names: &[String]) -> Vec<Env> {
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

// ---------------------------------------------------------------------------------------
// errors

/// Per output: {"max": max |x - x_exact| / max |x_exact|, "mean": mean |x - x_exact| /
/// max |x_exact|}, for the image and, with `grads`, (d_env, d_normals, d_ctrl), every
/// output as flat f64 values.
fn errors(exact: &[Vec<f64>; 4], image: &[f64], grads: Option<[&[f64]; 3]>) -> Value {
    let mut e = serde_json::Map::new();
    let got = std::iter::once(image).chain(grads.into_iter().flatten());
    for ((name, want), got) in OUTPUTS.iter().zip(exact).zip(got) {
        if got.len() == want.len() {
            let (max, mean) = rel_errors(got.iter().copied(), want.iter().copied());
            e.insert(name.to_string(), json!({"max": max, "mean": mean}));
        } else {
            e.insert(
                format!("{name}_shape_mismatch"),
                json!([got.len(), want.len()]),
            );
        }
    }
    Value::Object(e)
}

/// The outputs of a render and backward as flat f64 values, as [`errors`] takes them.
fn flat(image: &Image, grads: &Gradients) -> [Vec<f64>; 4] {
    [
        flat3(&image.pixels).collect(),
        flat3(&grads.d_env).collect(),
        flat3(&grads.d_normals).collect(),
        grads.d_ctrl.iter().map(|&v| f64::from(v)).collect(),
    ]
}

fn errors_of(exact: &[Vec<f64>; 4], image: &Image, grads: Option<&Gradients>) -> Value {
    let img: Vec<f64> = flat3(&image.pixels).collect();
    match grads.map(|g| flat(image, g)) {
        None => errors(exact, &img, None),
        Some([_, e, n, c]) => errors(exact, &img, Some([&e, &n, &c])),
    }
}

/// The largest of a record's max errors (infinite where an output could not be compared).
fn worst(errors: &Value) -> f64 {
    match errors.as_object() {
        Some(o) if !o.keys().any(|k| k.ends_with("_shape_mismatch")) => o
            .values()
            .filter_map(|v| v["max"].as_f64())
            .fold(0.0, f64::max),
        _ => f64::INFINITY,
    }
}

// ---------------------------------------------------------------------------------------
// timing

/// A run taking longer than this (seconds) is timed `Reps::long` times.
const LONG_S: f64 = 1.0;

/// How many timed runs: `n`, or `long` where the first took over [`LONG_S`].
#[derive(Clone, Copy)]
struct Reps {
    n: usize,
    long: usize,
}

/// Timed runs of `f` (see [`Reps`]), after a warm-up run if `warm_up`: the seconds and the
/// last result.
fn timed<T>(
    reps: Reps,
    warm_up: bool,
    mut f: impl FnMut() -> matedit::Result<T>,
) -> matedit::Result<(Vec<f64>, T)> {
    let mut last = if warm_up { Some(f()?) } else { None };
    let mut times: Vec<f64> = Vec::with_capacity(reps.n);
    let wanted = |t: &[f64]| match t.first() {
        Some(&first) if first > LONG_S => reps.long,
        _ => reps.n,
    };
    while times.len() < wanted(&times).max(1) {
        let s = Instant::now();
        last = Some(f()?);
        times.push(s.elapsed().as_secs_f64());
    }
    Ok((times, last.expect("at least one run")))
}

/// One measurement: a method (or a tolerance's choice, or a peer) on one scene, one pass.
struct Rec {
    scene: String,
    env: String,
    material: String,
    /// The method's name (the chosen one for a tolerance; `peer-NAME` for a peer).
    method: String,
    pass: &'static str,
    times: Vec<f64>,
    reps: usize,
    errors: Value,
    /// For a tolerance's run: the tolerance and the choice.
    chosen: Option<(f64, Choice)>,
    extra: serde_json::Map<String, Value>,
}

impl Rec {
    fn json(&self) -> Value {
        let mut v = json!({
            "scene": self.scene, "env": self.env, "material": self.material,
            "method": self.method, "family": family(&self.method), "pass": self.pass,
            "median_s": median(&self.times), "reps": self.reps, "times_s": self.times,
            "errors": self.errors, "err_max": worst(&self.errors),
            "chosen_by_tol": self.chosen.is_some(),
        });
        if let (Some((tol, c)), Value::Object(o)) = (&self.chosen, &mut v) {
            let e = &c.estimate;
            o.insert("tol".into(), json!(tol));
            o.insert(
                "estimate".into(),
                json!({
                    "image": e.image, "d_env": e.d_env, "d_normals": e.d_normals,
                    "d_ctrl": e.d_ctrl, "max": e.max(), "pixels": e.pixels,
                }),
            );
            o.insert("predicted_cost".into(), json!(c.cost));
            o.insert("estimate_wrong".into(), json!(worst(&self.errors) > *tol));
        }
        if let Value::Object(o) = &mut v {
            o.extend(self.extra.clone());
        }
        v
    }
}

/// The chart's grouping of a method: exact, env (blocks), env+keep, table, table+env
/// (a table over blocks, kept texels or both), cull (culling alone), or peer.
fn family(method: &str) -> &'static str {
    if method.starts_with("peer-") {
        return "peer";
    }
    let Ok(m) = method.parse::<Method>() else {
        return "other";
    };
    match (m.table, m.env_factor > 1 || m.keep > 0) {
        _ if m.is_exact() => "exact",
        // culling alone (beside a table or blocks, those name the family)
        (None, false) => "cull",
        (None, true) if m.keep > 0 => "env+keep",
        (None, true) => "env",
        (Some(_), false) => "table",
        (Some(_), true) => "table+env",
    }
}

/// Everything measured on one scene (normals, env, material).
struct Case<'a> {
    name: String,
    env: &'a str,
    scene: Scene,
    upstream: Image,
}

impl Case<'_> {
    fn rec(&self, method: String, pass: &'static str, times: Vec<f64>, errors: Value) -> Rec {
        Rec {
            scene: self.name.clone(),
            env: self.env.to_string(),
            material: self.scene.material.name.clone(),
            method,
            pass,
            reps: times.len(),
            times,
            errors,
            chosen: None,
            extra: serde_json::Map::new(),
        }
    }
}

/// A pass pair's timings: `fwd` (after a warm-up if `warm_up`), then `fb`, whose render
/// the `fwd` runs have warmed (the median drops a slower first backward): seconds and last
/// results.
type Pair<A, B> = (Vec<f64>, A, Vec<f64>, B);

fn fwd_fb<A, B>(
    reps: Reps,
    warm_up: bool,
    fwd: impl FnMut() -> matedit::Result<A>,
    fb: impl FnMut() -> matedit::Result<B>,
) -> matedit::Result<Pair<A, B>> {
    let (tf, a) = timed(reps, warm_up, fwd)?;
    let (tb, b) = timed(reps, false, fb)?;
    Ok((tf, a, tb, b))
}

/// The exact run first (the errors' reference), then every other method and every
/// tolerance: their records, and the exact outputs.
fn measure(
    cpu: &FastCpu,
    case: &Case,
    opts: &Opts,
    notes: &mut Vec<String>,
) -> Option<(Vec<Rec>, [Vec<f64>; 4])> {
    let (scene, up) = (&case.scene, &case.upstream);
    let big = scene.normals.width * scene.normals.height >= 512 * 512;
    let reps = Reps {
        n: opts.reps,
        long: opts.big_reps.min(opts.reps),
    };
    // the exact and the tolerance runs of the 512 scenes are long: all of them
    let big_reps = if big {
        Reps {
            n: reps.long,
            ..reps
        }
    } else {
        reps
    };
    let run = |m: &Method, reps: Reps| {
        fwd_fb(
            reps,
            true,
            || lod::render(cpu, scene, m),
            || {
                let img = lod::render(cpu, scene, m)?;
                Ok((img, lod::backward(cpu, scene, up, m)?))
            },
        )
    };
    let (tf, tb, exact) = match run(&Method::EXACT, big_reps) {
        Ok((tf, _, tb, (img, g))) => (tf, tb, flat(&img, &g)),
        Err(e) => {
            let n = format!("{}: exact failed: {e}", case_name(case));
            println!("{n}");
            notes.push(n);
            return None;
        }
    };
    let zero = errors(&exact, &exact[0], Some([&exact[1], &exact[2], &exact[3]]));
    let mut recs = vec![
        case.rec("exact".into(), "fwd", tf, json!({"image": zero["image"]})),
        case.rec("exact".into(), "fb", tb, zero),
    ];
    print_pair(&recs[0], &recs[1]);
    for m in opts.methods.iter().filter(|m| !m.is_exact()) {
        let pair = run(m, reps).map(|(tf, img, tb, (img_b, g))| {
            (
                case.rec(m.to_string(), "fwd", tf, errors_of(&exact, &img, None)),
                case.rec(m.to_string(), "fb", tb, errors_of(&exact, &img_b, Some(&g))),
            )
        });
        push_pair(pair, &mut recs, notes, || {
            format!("{} {m}", case_name(case))
        });
    }
    for &tol in &opts.tols {
        // no warm-up: the methods before have run every kernel the choice and its plan use
        let pair = fwd_fb(
            big_reps,
            false,
            || lod::render_within(cpu, scene, tol),
            || {
                let (g, c) = lod::backward_within(cpu, scene, up, tol)?;
                Ok((lod::render(cpu, scene, &c.method)?, g, c))
            },
        )
        .and_then(|(tf, (img, cf), tb, (img_b, g, cb))| {
            let mut a = case.rec(
                cf.method.to_string(),
                "fwd",
                tf,
                errors_of(&exact, &img, None),
            );
            let mut b = case.rec(
                cb.method.to_string(),
                "fb",
                tb,
                errors_of(&exact, &img_b, Some(&g)),
            );
            // the choice alone, once: how much of the time it is
            for (r, c, up) in [(&mut a, cf, None), (&mut b, cb, Some(up))] {
                let s = Instant::now();
                lod::choose(cpu, scene, tol, up)?;
                r.extra
                    .insert("choose_s".into(), json!(s.elapsed().as_secs_f64()));
                r.chosen = Some((tol, c));
            }
            Ok((a, b))
        });
        push_pair(pair, &mut recs, notes, || {
            format!("{} tolerance {tol:e}", case_name(case))
        });
    }
    Some((recs, exact))
}

fn case_name(case: &Case) -> String {
    format!("{} {} {}", case.name, case.env, case.scene.material.name)
}

/// Prints and keeps a fwd and fb pair, or notes its failure.
fn push_pair(
    run: matedit::Result<(Rec, Rec)>,
    recs: &mut Vec<Rec>,
    notes: &mut Vec<String>,
    what: impl FnOnce() -> String,
) {
    match run {
        Ok((a, b)) => {
            print_pair(&a, &b);
            recs.push(a);
            recs.push(b);
        }
        Err(e) => {
            let n = format!("{}: failed: {e}", what());
            println!("{n}");
            notes.push(n);
        }
    }
}

/// The peers on one scene: their records, errors against `exact`.
fn measure_peers(
    case: &Case,
    peers: &[String],
    reps: usize,
    exact: &[Vec<f64>; 4],
    notes: &mut Vec<String>,
) -> Vec<Rec> {
    let files = common::write_inputs(&case.scene, &case.upstream, None);
    let res = match common::run_peers(&files, peers, reps) {
        Ok(r) => r,
        Err(e) => {
            let n = format!("peers {}: {e}", case_name(case));
            println!("{n}");
            notes.push(n);
            return Vec::new();
        }
    };
    let mut recs = Vec::new();
    for peer in peers {
        let r = &res[peer.as_str()];
        if let Some(err) = r.get("error") {
            let n = format!(
                "peer {peer} {}: failed: {}",
                case_name(case),
                err.as_str().unwrap_or("").replace('\n', " | ")
            );
            println!("{n}");
            notes.push(n);
            continue;
        }
        let (e_fwd, e_fb) = match common::read_peer_image(&files, peer) {
            Err(e) => (json!({"unread": e}), json!({"unread": e})),
            Ok(img) => {
                let fwd = errors(exact, &img, None);
                let fb = match common::read_peer_grads(&files, peer) {
                    Ok([e, n, c]) => errors(exact, &img, Some([&e, &n, &c])),
                    Err(common::Unread::File(e) | common::Unread::Arrays(e)) => {
                        json!({"unread": e})
                    }
                };
                (fwd, fb)
            }
        };
        let (Some(tf), Some(tb)) = (r["fwd"].as_f64(), r["fb"].as_f64()) else {
            continue;
        };
        let mut a = case.rec(format!("peer-{peer}"), "fwd", vec![tf], e_fwd);
        let mut b = case.rec(format!("peer-{peer}"), "fb", vec![tb], e_fb);
        a.reps = reps;
        b.reps = reps;
        print_pair(&a, &b);
        recs.push(a);
        recs.push(b);
    }
    recs
}

// ---------------------------------------------------------------------------------------
// report

fn sci(v: Option<f64>) -> String {
    match v {
        Some(x) if x.is_finite() => format!("{x:.1e}"),
        Some(_) => "inf".into(),
        None => "-".into(),
    }
}

fn err_of(r: &Rec, output: &str, stat: &str) -> Option<f64> {
    r.errors[output][stat].as_f64()
}

fn header() {
    println!(
        "{:<30} {:>8} {:>3} {:>8} {:>8} | {:>8} {:>3} {:>8} {:>8} {:>8} {:>8} | {:>6} {:>8} {:>8}",
        "method",
        "fwd s",
        "n",
        "img max",
        "img mean",
        "fb s",
        "n",
        "img max",
        "d_env",
        "d_normal",
        "d_ctrl",
        "tol",
        "estimate",
        "wrong"
    );
}

/// One row: a method's fwd and fb records.
fn print_pair(a: &Rec, b: &Rec) {
    let tol = a.chosen.as_ref().map(|(t, _)| *t);
    let method = match (&a.chosen, &b.chosen) {
        (Some(_), Some((_, cb))) if cb.method.to_string() != a.method => {
            format!("{} / {}", a.method, cb.method)
        }
        _ => a.method.clone(),
    };
    let est = match (&a.chosen, &b.chosen) {
        (Some((_, ca)), Some((_, cb))) => {
            format!(
                "{}/{}",
                sci(Some(ca.estimate.max())),
                sci(Some(cb.estimate.max()))
            )
        }
        _ => "-".into(),
    };
    let wrong = match tol {
        Some(t) => {
            let w = |r: &Rec| if worst(&r.errors) > t { "WRONG" } else { "ok" };
            format!("{}/{}", w(a), w(b))
        }
        None => "-".into(),
    };
    println!(
        "{:<30} {:>8.4} {:>3} {:>8} {:>8} | {:>8.4} {:>3} {:>8} {:>8} {:>8} {:>8} | {:>6} {:>8} {:>8}",
        method,
        median(&a.times),
        a.reps,
        sci(err_of(a, "image", "max")),
        sci(err_of(a, "image", "mean")),
        median(&b.times),
        b.reps,
        sci(err_of(b, "image", "max")),
        sci(err_of(b, "d_env", "max")),
        sci(err_of(b, "d_normals", "max")),
        sci(err_of(b, "d_ctrl", "max")),
        tol.map_or("-".into(), |t| format!("{t:.0e}")),
        est,
        wrong
    );
}

/// Speed-ups against the exact run of the same scene and pass, and the checks of the
/// tolerance runs: (records, estimate wrong, slower than exact).
fn finish(records: Vec<Value>) -> (Vec<Value>, Vec<Value>, Vec<Value>) {
    let key = |r: &Value| {
        ["scene", "env", "material", "pass"].map(|k| r[k].as_str().unwrap_or("").to_string())
    };
    let exact: Vec<([String; 4], f64)> = records
        .iter()
        .filter(|r| r["method"] == "exact" && r["chosen_by_tol"] == false)
        .map(|r| (key(r), r["median_s"].as_f64().unwrap_or(f64::NAN)))
        .collect();
    let (mut wrong, mut slower) = (Vec::new(), Vec::new());
    let records: Vec<Value> = records
        .into_iter()
        .map(|mut r| {
            let k = key(&r);
            let t = r["median_s"].as_f64().unwrap_or(f64::NAN);
            if let Some((_, te)) = exact.iter().find(|(e, _)| *e == k) {
                r["speedup_vs_exact"] = json!(te / t);
                if r["chosen_by_tol"] == true {
                    r["slower_than_exact"] = json!(t > *te);
                }
            }
            let summary = || {
                json!({
                    "scene": r["scene"], "env": r["env"], "material": r["material"],
                    "pass": r["pass"], "tol": r["tol"], "method": r["method"],
                    "estimate": r["estimate"]["max"], "measured": r["err_max"],
                    "median_s": r["median_s"], "speedup_vs_exact": r["speedup_vs_exact"],
                })
            };
            if r["estimate_wrong"] == true {
                wrong.push(summary());
            }
            if r["slower_than_exact"] == true {
                slower.push(summary());
            }
            r
        })
        .collect();
    (records, wrong, slower)
}

fn print_checks(wrong: &[Value], slower: &[Value], tol_rows: usize) {
    let row = |v: &Value| {
        format!(
            "  {} {} {} {} tol {}: {} estimated {} measured {} ({:.4} s, {:.2}x exact's speed)",
            v["scene"].as_str().unwrap_or(""),
            v["env"].as_str().unwrap_or(""),
            v["material"].as_str().unwrap_or(""),
            v["pass"].as_str().unwrap_or(""),
            sci(v["tol"].as_f64()),
            v["method"].as_str().unwrap_or(""),
            sci(v["estimate"].as_f64()),
            sci(v["measured"].as_f64()),
            v["median_s"].as_f64().unwrap_or(f64::NAN),
            v["speedup_vs_exact"].as_f64().unwrap_or(f64::NAN),
        )
    };
    println!(
        "\ncheck: {} of {tol_rows} tolerance runs measured an error above the tolerance \
         (estimate wrong){}",
        wrong.len(),
        if wrong.is_empty() { "" } else { ":" }
    );
    for v in wrong {
        println!("{}", row(v));
    }
    println!(
        "check: {} of {tol_rows} tolerance runs were slower than the exact layer{}",
        slower.len(),
        if slower.is_empty() { "" } else { ":" }
    );
    for v in slower {
        println!("{}", row(v));
    }
}

fn csv(records: &[Value]) -> String {
    let mut cols: Vec<String> = [
        "scene",
        "env",
        "material",
        "method",
        "family",
        "pass",
        "median_s",
        "reps",
        "speedup_vs_exact",
        "err_max",
    ]
    .map(String::from)
    .to_vec();
    for o in OUTPUTS {
        cols.push(format!("err_{o}_max"));
        cols.push(format!("err_{o}_mean"));
    }
    cols.extend(
        [
            "chosen_by_tol",
            "tol",
            "est_max",
            "est_image",
            "est_d_env",
            "est_d_normals",
            "est_d_ctrl",
            "predicted_cost",
            "choose_s",
            "estimate_wrong",
            "slower_than_exact",
        ]
        .map(String::from),
    );
    let cols: Vec<&str> = cols.iter().map(String::as_str).collect();
    common::csv(records, &cols, |r, c| {
        if let Some(k) = c.strip_prefix("est_") {
            &r["estimate"][k]
        } else if let Some(k) = c.strip_prefix("err_").filter(|k| *k != "max") {
            let (o, stat) = k.rsplit_once('_').unwrap_or((k, "max"));
            &r["errors"][o][stat]
        } else {
            &r[c]
        }
    })
}

// ---------------------------------------------------------------------------------------
// charts

/// Chart size in pixels (the SVG's too).
const CHART: (u32, u32) = (1280, 860);

/// Colour and legend name of each family, in legend order.
const FAMILIES: [(&str, RGBColor); 7] = [
    ("exact", RGBColor(0, 0, 0)),
    ("env", RGBColor(31, 119, 180)),
    ("env+keep", RGBColor(23, 190, 207)),
    ("table", RGBColor(44, 160, 44)),
    ("table+env", RGBColor(255, 127, 14)),
    ("cull", RGBColor(200, 160, 0)),
    ("peer", RGBColor(148, 103, 189)),
];
/// Tolerance lines and the marks of their choices, in `--tols` order.
const TOL_COLOURS: [RGBColor; 4] = [
    RGBColor(214, 39, 40),
    RGBColor(227, 119, 194),
    RGBColor(140, 86, 75),
    RGBColor(188, 189, 34),
];

/// A point of a chart.
struct Point {
    x: f64,
    y: f64,
    family: &'static str,
    /// Peers: which.
    label: String,
    /// The tolerance that chose it.
    tol: Option<f64>,
}

/// The points of one pass: x = median seconds, y = the largest error (fwd: the image's;
/// fb: the largest of the image's and the gradients'), at least [`FLOOR`].
fn points(records: &[Value], pass: &str) -> Vec<Point> {
    records
        .iter()
        .filter(|r| r["pass"] == pass)
        .filter_map(|r| {
            let x = r["median_s"].as_f64()?;
            let y = if pass == "fwd" {
                r["errors"]["image"]["max"].as_f64()?
            } else {
                r["err_max"].as_f64()?
            };
            let method = r["method"].as_str().unwrap_or("");
            let family = FAMILIES
                .iter()
                .map(|f| f.0)
                .find(|f| *f == r["family"].as_str().unwrap_or(""))?;
            (x > 0.0 && x.is_finite() && y.is_finite()).then(|| Point {
                x,
                y: y.max(FLOOR),
                family,
                label: method.trim_start_matches("peer-").to_string(),
                tol: r["tol"].as_f64(),
            })
        })
        .collect()
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>;

/// Runs `$body` with `$s` bound to a closure that makes the marker of `$family` at (0, 0)
/// (pixel offsets), `$h` pixels from its centre to its edge, in colour `$c`: each family's
/// marker is its own type.
macro_rules! with_marker {
    ($family:expr, $h:expr, $c:expr, $s:ident => $body:expr) => {{
        let (h, c): (i32, RGBColor) = ($h, $c);
        match $family {
            "exact" => {
                let $s = || Cross::new((0, 0), h + 1, c.stroke_width(2));
                $body
            }
            "env" => {
                let $s = || Circle::new((0, 0), h, c.filled());
                $body
            }
            "env+keep" => {
                let $s = || TriangleMarker::new((0, 0), h + 1, c.filled());
                $body
            }
            "table" => {
                let $s = || Rectangle::new([(-h, -h), (h, h)], c.filled());
                $body
            }
            "table+env" => {
                let $s = || {
                    Polygon::new(
                        vec![(0, -h - 1), (h + 1, 0), (0, h + 1), (-h - 1, 0)],
                        c.filled(),
                    )
                };
                $body
            }
            "cull" => {
                let $s = || TriangleMarker::new((0, 0), h + 2, c.stroke_width(2));
                $body
            }
            // a tolerance's choice: a ring
            "ring" => {
                let $s = || Circle::new((0, 0), h, c.stroke_width(2));
                $body
            }
            // peers: a hollow square
            _ => {
                let $s = || Rectangle::new([(-h, -h), (h, h)], c.stroke_width(2));
                $body
            }
        }
    }};
}

/// A legend entry: marker (family, half size, colour) and text.
type Entry = ((&'static str, i32, RGBColor), String);

/// Draws one pass's chart on `root`: the plot, a legend beside it, a note below.
fn draw_chart<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    pass: &str,
    pts: &[Point],
    tols: &[f64],
    note: &str,
) -> Result<(), String>
where
    DB::ErrorType: 'static,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    root.fill(&WHITE).map_err(e)?;
    let (main, foot) = root.split_vertically(CHART.1 - 30);
    let (plot, side) = main.split_horizontally(CHART.0 - 340);
    let (mut x0, mut x1) = pts.iter().fold((f64::INFINITY, 0.0f64), |(a, b), p| {
        (a.min(p.x), b.max(p.x))
    });
    if !(x0.is_finite() && x1 > 0.0) {
        (x0, x1) = (1e-3, 1.0);
    }
    let (x0, x1) = (x0 / 1.6, x1 * 1.6);
    let y1 = pts
        .iter()
        .map(|p| p.y)
        .chain(tols.iter().copied())
        .fold(1e-2, f64::max);
    let (y0, y1) = (FLOOR / 3.0, y1 * 3.0);
    let (what, y_desc) = if pass == "fwd" {
        ("forward (lod::render)", "max |I - I_exact| / max |I_exact|")
    } else {
        (
            "forward + backward (lod::render + lod::backward)",
            "largest max relative error: image, d_env, d_normals, d_ctrl",
        )
    };
    let mut chart = ChartBuilder::on(&plot)
        .caption(format!("matedit lod: {what}"), ("sans-serif", 22))
        .margin(14)
        .x_label_area_size(46)
        .y_label_area_size(74)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(e)?;
    chart
        .configure_mesh()
        .x_desc("median time (s)")
        .y_desc(y_desc)
        .x_label_formatter(&|v| format!("{v:.0e}"))
        .y_label_formatter(&|v| format!("{v:.0e}"))
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(236, 236, 236))
        .draw()
        .map_err(e)?;
    let entries = draw_points(&mut chart, pts, tols, (x0, x1)).map_err(e)?;
    for (k, ((family, h, c), text)) in entries.iter().enumerate() {
        let (x, y) = (16, 60 + 24 * k as i32);
        if *h > 0 {
            with_marker!(*family, *h, *c, m => side.draw(&(EmptyElement::at((x, y)) + m())))
                .map_err(e)?;
        }
        side.draw(&Text::new(
            text.as_str(),
            (x + 16, y - 7),
            ("sans-serif", 14),
        ))
        .map_err(e)?;
    }
    foot.draw(&Text::new(
        note,
        (20, 6),
        ("sans-serif", 13).into_font().color(&RGBColor(80, 80, 80)),
    ))
    .map_err(e)?;
    root.present().map_err(e)
}

/// The points and the tolerance lines: the legend's entries.
fn draw_points<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    pts: &[Point],
    tols: &[f64],
    (x0, x1): (f64, f64),
) -> Result<Vec<Entry>, DrawingAreaErrorKind<DB::ErrorType>>
where
    DB::ErrorType: 'static,
{
    let mut entries: Vec<Entry> = Vec::new();
    for (i, &t) in tols.iter().enumerate() {
        let c = TOL_COLOURS[i % TOL_COLOURS.len()];
        chart.draw_series(DashedLineSeries::new(
            [(x0, t), (x1, t)],
            8,
            5,
            c.stroke_width(1),
        ))?;
        chart.draw_series(std::iter::once(Text::new(
            format!("tol {t:.0e}"),
            (x0 * 1.08, t * 1.3),
            ("sans-serif", 13).into_font().color(&c),
        )))?;
    }
    let mut draw = |family: &'static str, xy: Vec<(f64, f64)>, h: i32, c: RGBColor| {
        with_marker!(family, h, c, m => chart.draw_series(
            xy.iter().map(|&p| EmptyElement::at(p) + m())
        ).map(|_| ()))
    };
    for &(family, c) in &FAMILIES {
        let of: Vec<&Point> = pts
            .iter()
            .filter(|p| p.family == family && p.tol.is_none())
            .collect();
        // peers: one colour each
        let mut names: Vec<&str> = of.iter().map(|p| p.label.as_str()).collect();
        names.sort();
        names.dedup();
        // a family only a tolerance chose still gets its legend entry
        if names.is_empty() && pts.iter().any(|p| p.family == family) {
            entries.push(((family, 3, c), family.to_string()));
        }
        for (k, name) in names.iter().enumerate() {
            let xy: Vec<(f64, f64)> = of
                .iter()
                .filter(|p| family != "peer" || p.label == *name)
                .map(|p| (p.x, p.y))
                .collect();
            let (text, c, h) = match family {
                "peer" => (
                    format!("peer {name} (error vs our exact)"),
                    if k == 0 { c } else { RGBColor(127, 127, 127) },
                    5,
                ),
                "exact" => (format!("exact (error 0: drawn at {FLOOR:.0e})"), c, 4),
                _ => (family.to_string(), c, 3),
            };
            draw(family, xy, h, c)?;
            entries.push(((family, h, c), text));
            if family != "peer" {
                break;
            }
        }
    }
    // the tolerance runs: their choice's marker inside a ring of the tolerance's colour
    for (i, &t) in tols.iter().enumerate() {
        let c = TOL_COLOURS[i % TOL_COLOURS.len()];
        let of: Vec<&Point> = pts.iter().filter(|p| p.tol == Some(t)).collect();
        if of.is_empty() {
            continue;
        }
        draw("ring", of.iter().map(|p| (p.x, p.y)).collect(), 9, c)?;
        for &(family, _) in &FAMILIES {
            let xy: Vec<(f64, f64)> = of
                .iter()
                .filter(|p| p.family == family)
                .map(|p| (p.x, p.y))
                .collect();
            draw(family, xy, 3, c)?;
        }
        entries.push((("ring", 7, c), format!("chosen for tol {t:.0e}")));
    }
    if entries.iter().any(|((f, ..), _)| *f == "ring") {
        entries.push((("none", 0, WHITE), "(its time includes the choice)".into()));
    }
    Ok(entries)
}

/// Registers the font the charts' text is drawn with: Hack (MIT / Bitstream Vera
/// license), as epaint_default_fonts ships it, so that no system font is needed.
fn register_font() -> Result<(), String> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::HACK_REGULAR,
    )
    .map_err(|_| "the embedded font cannot be read".to_string())
}

/// lod_fwd.{png,svg} and lod_fb.{png,svg} in `dir`, from the records: their paths.
fn charts(records: &[Value], tols: &[f64], dir: &Path) -> Result<Vec<PathBuf>, String> {
    let mut written = Vec::new();
    for pass in ["fwd", "fb"] {
        let pts = points(records, pass);
        let caption = format!(
            "{} points: each method on each scene (normals x env map x material), fast CPU path; \
             errors against the exact layer on the same path",
            pts.len()
        );
        let svg = dir.join(format!("lod_{pass}.svg"));
        {
            let root = SVGBackend::new(&svg, CHART).into_drawing_area();
            draw_chart(&root, pass, &pts, tols, &caption)?;
        }
        let png = dir.join(format!("lod_{pass}.png"));
        let (w, h) = (CHART.0 as usize, CHART.1 as usize);
        let mut buf = vec![0u8; w * h * 3];
        {
            let root = BitMapBackend::with_buffer(&mut buf, CHART).into_drawing_area();
            draw_chart(&root, pass, &pts, tols, &caption)?;
        }
        let bytes = matedit::io::png::encode_rgb8(w, h, &buf).map_err(|e| e.to_string())?;
        write(&png, &bytes);
        written.push(png);
        written.push(svg);
    }
    Ok(written)
}

// ---------------------------------------------------------------------------------------

/// The exact fast path against the f64 reference on the 128 sphere, per material, with
/// the first env map: max errors per output.
fn reference_check(cpu: &FastCpu, env: &Env, materials: &[Material]) -> Vec<Value> {
    let normals = NormalMap::sphere(128);
    let upstream = upstream_for(128, 128);
    let g64: Vec<[f64; 3]> = upstream.pixels.iter().map(|p| p.map(f64::from)).collect();
    let mut out = Vec::new();
    for material in materials {
        let scene = Scene {
            normals: normals.clone(),
            env: env.env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        };
        let prep = Prepared::new(&scene);
        let image = matedit::reference::forward(&prep);
        let g = matedit::reference::backward(&prep, &g64);
        let truth = [
            flat3(&image).collect(),
            flat3(&g.d_env).collect(),
            flat3(&g.d_normals).collect(),
            g.d_ctrl.to_vec(),
        ];
        let got = lod::render(cpu, &scene, &Method::EXACT).and_then(|img| {
            let g = lod::backward(cpu, &scene, &upstream, &Method::EXACT)?;
            Ok(errors_of(&truth, &img, Some(&g)))
        });
        let errs = got.unwrap_or_else(|e| json!({"failed": e.to_string()}));
        println!(
            "exact fast path vs f64 reference, sphere128 {} {}: max error image {} d_env {} \
             d_normals {} d_ctrl {}",
            env.name,
            material.name,
            sci(errs["image"]["max"].as_f64()),
            sci(errs["d_env"]["max"].as_f64()),
            sci(errs["d_normals"]["max"].as_f64()),
            sci(errs["d_ctrl"]["max"].as_f64()),
        );
        out.push(json!({
            "scene": "sphere128", "env": env.name, "material": material.name, "errors": errs,
        }));
    }
    out
}

/// lod.csv and the charts in `dir`, and lod.json unless the report was read from it.
fn write_outputs(report: &Value, dir: &Path, json_too: bool) {
    if let Err(e) = std::fs::create_dir_all(dir) {
        eprintln!("cannot create {}: {e}", dir.display());
        return;
    }
    let records = report["records"].as_array().cloned().unwrap_or_default();
    let tols: Vec<f64> = report["tols"]
        .as_array()
        .map(|t| t.iter().filter_map(Value::as_f64).collect())
        .unwrap_or_default();
    println!();
    if json_too {
        let jp = dir.join("lod.json");
        let text = serde_json::to_string_pretty(report).unwrap_or_default() + "\n";
        write(&jp, text.as_bytes());
        println!("wrote {}", jp.display());
    }
    let cp = dir.join("lod.csv");
    write(&cp, csv(&records).as_bytes());
    println!("wrote {}", cp.display());
    match register_font().and_then(|()| charts(&records, &tols, dir)) {
        Ok(paths) => {
            for p in paths {
                println!("wrote {}", p.display());
            }
        }
        Err(e) => println!("charts: {e}"),
    }
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
