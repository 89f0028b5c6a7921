//! What the benches share: the machine's description, medians, the inputs (env maps, the
//! upstream gradient), errors, and the files and processes of the peers
//! (../shared/peers/time_peers.py).
//!
//! Each bench is its own crate (benches/NAME/main.rs) and uses part of this module
//! (`#[path = "../common/mod.rs"] mod common;`), so items one of them leaves unused are
//! expected.

#![allow(dead_code, reason = "each bench uses a part of the shared code")]

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use matedit::io::npy;
use matedit::{Convention, EnvMap, Image, Scene};
use serde_json::{Value, json};

/// Every env map is downsampled to this (rows, columns).
pub const ENV_SIZE: (usize, usize) = (64, 128);
/// Seed of `NormalMap::bumpy` scenes.
pub const BUMPY_SEED: u64 = 1;
/// Seed of the upstream gradient.
pub const UPSTREAM_SEED: u64 = 0x5eed;

/// A comma-separated list, blanks dropped.
pub fn list(s: &str) -> Vec<String> {
    s.split(',')
        .map(str::trim)
        .filter(|v| !v.is_empty())
        .map(str::to_string)
        .collect()
}

/// The number after an option.
pub fn num(v: Option<String>, name: &str) -> Result<usize, String> {
    v.as_deref()
        .and_then(|s| s.parse().ok())
        .ok_or_else(|| format!("{name} needs a number"))
}

/// Checks the scene and material names given on the command line.
pub fn check_names(scenes: &[String], known: &[&str], materials: &[String]) -> Result<(), String> {
    for s in scenes {
        if !known.contains(&s.as_str()) {
            return Err(format!("unknown scene '{s}': expected one of {known:?}"));
        }
    }
    for m in materials {
        if material(m).is_none() {
            return Err(format!(
                "unknown material '{m}': expected random-SEED or one of {:?}",
                matedit::presets::names()
            ));
        }
    }
    Ok(())
}

/// The presets of `names` (checked by [`check_names`]), each printed with its description.
pub fn materials(names: &[String]) -> Vec<matedit::Material> {
    for m in matedit::presets::all() {
        if names.iter().any(|n| n == m.name) {
            println!("material {}: {}", m.name, m.description);
        }
    }
    names
        .iter()
        .map(|m| material(m).expect("checked"))
        .collect()
}

/// A preset by name, or `random-SEED`: [`matedit::Material::random`], nine lobes with
/// nothing to share.
pub fn material(name: &str) -> Option<matedit::Material> {
    match name.strip_prefix("random-").map(str::parse::<u64>) {
        Some(Ok(seed)) => Some(matedit::Material::random(seed)),
        _ => matedit::presets::lookup(name),
    }
}

/// target/ of this build: the command-line binary lives in target/PROFILE/.
pub fn target_dir() -> PathBuf {
    let bin = Path::new(env!("CARGO_BIN_EXE_matedit"));
    bin.parent()
        .and_then(Path::parent)
        .map(Path::to_path_buf)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("target"))
}

/// ../shared beside the checkout: env maps and peers.
pub fn shared_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared")
}

/// The median (NaN for no values).
pub fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

/// splitmix64 stream, uniform in [-1, 1).
pub fn signed_uniform(seed: u64) -> impl FnMut() -> f32 {
    let mut rng = matedit::splitmix::SplitMix(seed);
    move || ((rng.next_u64() >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
}

// ---------------------------------------------------------------------------------------
// machine and inputs

/// CPU model, hardware threads and the SIMD levels the fast path can use.
pub fn machine() -> Value {
    let info = std::fs::read_to_string("/proc/cpuinfo").unwrap_or_default();
    let field = |name: &str| {
        info.lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_once(':'))
            .map(|(_, v)| v.trim().to_string())
    };
    let model = field("model name").unwrap_or_else(|| "unknown".into());
    let flags = field("flags").unwrap_or_default();
    let simd: Vec<&str> = ["avx512f", "avx2", "fma"]
        .into_iter()
        .filter(|f| flags.split_whitespace().any(|x| x == *f))
        .collect();
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    json!({"cpu": model, "hardware_threads": cores, "simd": simd.join(" ")})
}

/// Sets rayon's global pool to `threads` and prints the machine's line: its [`machine`]
/// description. `threads_where` ends the line (where those threads run).
pub fn set_up(threads: usize, threads_where: &str) -> Value {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .expect("rayon's global pool is set once");
    let mach = machine();
    println!(
        "machine: {} ({} hardware threads; {}); {threads} rayon threads{threads_where}",
        mach["cpu"].as_str().unwrap_or(""),
        mach["hardware_threads"],
        mach["simd"].as_str().unwrap_or(""),
    );
    mach
}

/// The `.exr` maps of ../shared/data/envmaps, by name (none without the folder).
pub fn envmap_files() -> Vec<PathBuf> {
    let Ok(dir) = std::fs::read_dir(shared_dir().join("data/envmaps")) else {
        return Vec::new();
    };
    let mut maps: Vec<PathBuf> = dir
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x.eq_ignore_ascii_case("exr")))
        .collect();
    maps.sort();
    maps
}

/// The built-in procedural sky at `(h, w)` (the benchmarks' default: [`ENV_SIZE`]), and its
/// description.
pub fn builtin_sky((h, w): (usize, usize)) -> (EnvMap, String) {
    (
        matedit::builtin_sky::procedural_env(h, w, Convention::Equirect),
        format!("built-in procedural sky, {h}x{w}"),
    )
}

/// An env map file, as loaded and resampled to the size asked for.
pub struct LoadedEnv {
    /// At the file's size (negative values clamped).
    pub full: EnvMap,
    /// Downsampled.
    pub env: EnvMap,
    /// File name, sizes and clamped values.
    pub desc: String,
}

/// Loads an `.exr` or `.npy` env map (`equirect`) and resamples it to `(h, w)` (the
/// benchmarks' default: [`ENV_SIZE`]).
pub fn load_env_file(path: &Path, (h, w): (usize, usize)) -> matedit::Result<LoadedEnv> {
    let l = matedit::io::load_env(path, Convention::Equirect)?;
    let (fh, fw) = (l.env.height, l.env.width);
    let full = l.env.clone();
    let env = matedit::io::resample::fit(
        l.env,
        matedit::io::EnvSize::Size {
            height: h,
            width: w,
        },
        path,
    )?;
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    Ok(LoadedEnv {
        full,
        env,
        desc: format!(
            "{name} ({fh}x{fw}, {} negative values clamped), downsampled to {h}x{w}",
            l.clamped
        ),
    })
}

/// A fixed pseudo-random upstream gradient dLoss/dImage in [-1, 1).
pub fn upstream_for(w: usize, h: usize) -> Image {
    let mut next = signed_uniform(UPSTREAM_SEED);
    Image {
        width: w,
        height: h,
        pixels: (0..w * h).map(|_| [next(), next(), next()]).collect(),
    }
}

// ---------------------------------------------------------------------------------------
// errors

/// (max |got - want|, mean |got - want|), each over max |want| (0 / 0 = 0); a non-finite
/// `got` makes both infinite.
pub fn rel_errors(got: impl Iterator<Item = f64>, want: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut err, mut sum, mut scale, mut n) = (0.0f64, 0.0f64, 0.0f64, 0usize);
    for (g, w) in got.zip(want) {
        let d = (g - w).abs();
        err = err.max(d);
        sum += d;
        n += 1;
        scale = scale.max(w.abs());
        if !g.is_finite() {
            err = f64::INFINITY;
            sum = f64::INFINITY;
        }
    }
    if err == 0.0 {
        (0.0, 0.0)
    } else {
        (err / scale, sum / n as f64 / scale)
    }
}

/// max |got - want| / max |want| (0 / 0 = 0).
pub fn rel_err(got: impl Iterator<Item = f64>, want: impl Iterator<Item = f64>) -> f64 {
    rel_errors(got, want).0
}

/// The values of RGB triples, in order.
pub fn flat3<T: Copy + Into<f64>>(v: &[[T; 3]]) -> impl Iterator<Item = f64> + '_ {
    v.iter().flatten().map(|&x| x.into())
}

// ---------------------------------------------------------------------------------------
// files

/// The records as CSV: a header of `cols`, then a row a record, each cell the value
/// `field` finds for the column (empty for null, strings unquoted).
pub fn csv<'r>(
    records: &'r [Value],
    cols: &[&str],
    field: impl Fn(&'r Value, &str) -> &'r Value,
) -> String {
    let mut out = cols.join(",") + "\n";
    for r in records {
        let cell = |c: &str| -> String {
            match field(r, c) {
                Value::Null => String::new(),
                Value::String(s) => s.clone(),
                other => other.to_string(),
            }
        };
        out += &cols.iter().map(|c| cell(c)).collect::<Vec<_>>().join(",");
        out.push('\n');
    }
    out
}

/// Writes a file; a failure ends the bench.
pub fn write(path: &Path, bytes: &[u8]) {
    std::fs::write(path, bytes).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

/// Reads an `.npy` file.
pub fn read_npy(path: &Path) -> Result<npy::NpyArray, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    npy::parse(&bytes).map_err(|e| format!("{}: {e}", path.display()))
}

/// The arrays of an uncompressed `.npz` (a zip of `.npy` files, as `numpy.savez` writes),
/// found through the zip's central directory.
pub fn read_npz(path: &Path) -> Result<BTreeMap<String, npy::NpyArray>, String> {
    let b = std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?;
    let bad = |m: &str| format!("{}: {m}", path.display());
    let u16_at = |o: usize| {
        b.get(o..o + 2)
            .map(|x| u16::from_le_bytes([x[0], x[1]]) as usize)
            .ok_or_else(|| bad("truncated zip"))
    };
    let u32_at = |o: usize| {
        b.get(o..o + 4)
            .map(|x| u32::from_le_bytes([x[0], x[1], x[2], x[3]]) as usize)
            .ok_or_else(|| bad("truncated zip"))
    };
    let eocd = (0..=b.len().saturating_sub(22))
        .rev()
        .find(|&o| b[o..].starts_with(b"PK\x05\x06"))
        .ok_or_else(|| bad("no zip end record"))?;
    let entries = u16_at(eocd + 10)?;
    let mut cd = u32_at(eocd + 16)?;
    if entries == 0xffff || cd == 0xffff_ffff {
        return Err(bad("zip64 archives are not read here"));
    }
    let mut out = BTreeMap::new();
    for _ in 0..entries {
        if !b.get(cd..).is_some_and(|x| x.starts_with(b"PK\x01\x02")) {
            return Err(bad("bad zip central directory"));
        }
        let method = u16_at(cd + 10)?;
        let (name_len, extra_len, comment_len) =
            (u16_at(cd + 28)?, u16_at(cd + 30)?, u16_at(cd + 32)?);
        let local = u32_at(cd + 42)?;
        let name = b
            .get(cd + 46..cd + 46 + name_len)
            .map(|n| String::from_utf8_lossy(n).into_owned())
            .ok_or_else(|| bad("truncated zip"))?;
        if method != 0 || local == 0xffff_ffff {
            return Err(bad(&format!(
                "{name}: compressed or zip64 entries are not read here"
            )));
        }
        if !b.get(local..).is_some_and(|x| x.starts_with(b"PK\x03\x04")) {
            return Err(bad("bad zip local header"));
        }
        let data = local + 30 + u16_at(local + 26)? + u16_at(local + 28)?;
        // the .npy header says how much data follows; the rest of the zip is ignored
        let arr = npy::parse(b.get(data..).unwrap_or_default()).map_err(|e| bad(&e))?;
        out.insert(name.trim_end_matches(".npy").to_string(), arr);
        cd += 46 + name_len + extra_len + comment_len;
    }
    Ok(out)
}

/// The input files of one scene, as the command line and the peers read them.
pub struct Files {
    /// The temporary folder, removed when dropped (None with --keep).
    _temp: Option<tempfile::TempDir>,
    pub dir: PathBuf,
    pub normals: PathBuf,
    pub env: PathBuf,
    pub material: PathBuf,
    pub upstream: PathBuf,
}

/// Writes a scene and an upstream gradient as NPY/JSON files, in `keep` (else a temporary
/// folder).
pub fn write_inputs(scene: &Scene, upstream: &Image, keep: Option<PathBuf>) -> Files {
    let (temp, dir) = match keep {
        Some(d) => {
            std::fs::create_dir_all(&d).unwrap_or_else(|e| panic!("{}: {e}", d.display()));
            (None, d)
        }
        None => {
            let t = tempfile::Builder::new()
                .prefix("matedit-bench-")
                .tempdir()
                .expect("temp folder");
            let d = t.path().to_path_buf();
            (Some(t), d)
        }
    };
    let p = |n: &str| dir.join(n);
    let (normals, env, material, up) = (
        p("normals.npy"),
        p("env.npy"),
        p("ctrl.json"),
        p("upstream.npy"),
    );
    let n = &scene.normals;
    write(&normals, &npy::encode_rgb(n.width, n.height, &n.normals));
    let e = &scene.env;
    write(&env, &npy::encode_rgb(e.width, e.height, &e.texels));
    // {"name", "ctrl": [108]}: the command line's material file and the peers' CTRL
    write(
        &material,
        &matedit::io::json::encode_material(&scene.material, None),
    );
    write(
        &up,
        &npy::encode_rgb(upstream.width, upstream.height, &upstream.pixels),
    );
    Files {
        _temp: temp,
        dir,
        normals,
        env,
        material,
        upstream: up,
    }
}

// ---------------------------------------------------------------------------------------
// peers

/// Whether python3 can import `module`.
pub fn python_has(module: &str) -> bool {
    Command::new("python3")
        .args(["-c", &format!("import {module}")])
        .output()
        .is_ok_and(|o| o.status.success())
}

/// The peers of `requested` that can run here (time_peers.py exists and python3 imports
/// them), saying on stdout which are skipped and why.
pub fn runnable_peers(requested: &[String], reps: usize) -> Vec<String> {
    let peers_script = shared_dir().join("peers/time_peers.py");
    if requested.is_empty() {
        println!("peers: none asked");
        return Vec::new();
    }
    if !peers_script.is_file() {
        println!("peers: skipped: no {}", peers_script.display());
        return Vec::new();
    }
    let (have, missing): (Vec<String>, Vec<String>) =
        requested.iter().cloned().partition(|p| python_has(p));
    if !missing.is_empty() {
        println!("peers: skipped {missing:?}: python3 cannot import them");
    }
    if !have.is_empty() {
        println!(
            "peers: {have:?} through {} (2 threads each, median of {reps})",
            peers_script.display(),
        );
    }
    have
}

/// time_peers.py on the input files: its JSON line.
pub fn run_peers(f: &Files, peers: &[String], reps: usize) -> Result<Value, String> {
    let script = shared_dir().join("peers/time_peers.py");
    let out = Command::new("python3")
        .arg(&script)
        .args([&f.normals, &f.env, &f.material, &f.upstream])
        .args(["--peers", &peers.join(","), "--reps", &reps.to_string()])
        .output()
        .map_err(|e| format!("cannot run python3: {e}"))?;
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout
        .lines()
        .rev()
        .find(|l| l.trim_start().starts_with('{'));
    match line {
        Some(l) if out.status.success() => {
            serde_json::from_str(l).map_err(|e| format!("time_peers.py printed {l:?}: {e}"))
        }
        _ => Err(format!(
            "time_peers.py failed ({}): {}",
            out.status,
            String::from_utf8_lossy(&out.stderr)
                .lines()
                .last()
                .unwrap_or("")
        )),
    }
}

/// A peer's forward image, left beside the normals by time_peers.py.
pub fn read_peer_image(f: &Files, peer: &str) -> Result<Vec<f64>, String> {
    read_npy(&f.dir.join(format!("peer_{peer}.npy"))).map(|a| a.data)
}

/// Why a peer's gradients could not be read.
pub enum Unread {
    /// The file: its error.
    File(String),
    /// The file lacks d_env, d_normals or d_ctrl: the arrays it has.
    Arrays(String),
}

/// A peer's (d_env, d_normals, d_ctrl), left beside the normals by time_peers.py.
pub fn read_peer_grads(f: &Files, peer: &str) -> Result<[Vec<f64>; 3], Unread> {
    let g = read_npz(&f.dir.join(format!("peer_{peer}_grads.npz"))).map_err(Unread::File)?;
    match (g.get("d_env"), g.get("d_normals"), g.get("d_ctrl")) {
        (Some(e), Some(n), Some(c)) => Ok([e.data.clone(), n.data.clone(), c.data.clone()]),
        _ => Err(Unread::Arrays(format!(
            "{:?}",
            g.keys().collect::<Vec<_>>()
        ))),
    }
}
