//! One scene and material through every path: the f64 reference once, the in-process
//! paths, the command line and the peers.

use std::time::{Instant, SystemTime};

use matedit::io::npy;
use matedit::prepare::Prepared;
use matedit::reference;
use matedit::{Batch, EnvMap, Image, Material, Renderer, Scene};
use serde_json::{Value, json};

use crate::Opts;
use crate::cli::run_cli;
use crate::common::{median, write, write_inputs};
use crate::errors::{Got, Truth, errors, errors_f32, f64s};
use crate::peers::run_peers_of;
use crate::report::{Rec, header, print_row};
use crate::timing::{pass_timings, time_renderer};

/// What every scene and material adds to: the records, the peers' ratios, the notes, and
/// the command line's modification time as last seen (to notice a rebuild).
pub struct Gathered {
    pub records: Vec<Rec>,
    pub ratios: Vec<Value>,
    pub notes: Vec<String>,
    pub cli_built: Option<SystemTime>,
}

/// What every scene and material is run with: the options, the env map, the in-process
/// paths' renderers, the command line's devices and the runnable peers.
pub struct Setup<'a> {
    pub opts: &'a Opts,
    pub env: &'a EnvMap,
    pub renderers: &'a [(String, Renderer)],
    pub cli_devices: &'a [&'a str],
    pub peers: &'a [String],
}

/// One scene and material: their names and the scene's pairs (foreground pixels x
/// texels with d_omega > 0), which every record of it carries.
pub struct Case<'a> {
    pub scene_name: &'a str,
    pub material: &'a Material,
    pub pairs: f64,
}

impl Case<'_> {
    /// A record of this scene and material.
    pub fn rec(&self, path: &str, pass: &'static str, times: Vec<f64>, errors: Value) -> Rec {
        Rec {
            path: path.to_string(),
            scene: self.scene_name.to_string(),
            material: self.material.name.clone(),
            pass,
            reps: times.len(),
            times,
            pairs: self.pairs,
            errors,
            extra: serde_json::Map::new(),
            timings: Vec::new(),
        }
    }
}

/// `scene` (named `scene_name`) through every path, against the reference's results;
/// `upstream` and `g64` (the same in f64) are the upstream gradient.
pub fn run_case(
    setup: &Setup,
    scene_name: &str,
    scene: Scene,
    upstream: &Image,
    g64: &[[f64; 3]],
    out: &mut Gathered,
) {
    let material = &scene.material;
    let (w, h) = (scene.normals.width, scene.normals.height);
    let batch = Batch::single(scene.clone()).expect("valid scene");
    let ups = vec![upstream.clone()];

    // ground truth, once
    let s = Instant::now();
    let prep = Prepared::new(&scene);
    let image = reference::forward(&prep);
    let fwd_s = s.elapsed().as_secs_f64();
    let s = Instant::now();
    let grads = reference::backward(&prep, g64);
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
    let case = Case {
        scene_name,
        material,
        pairs,
    };
    let cpu_s = in_process(setup, &case, &truth, &batch, &ups, (w, h), out);

    // whole processes and peers share the input files
    let keep = setup.opts.keep.then(|| {
        setup
            .opts
            .out
            .join(format!("inputs/{scene_name}-{}", material.name))
    });
    let files = write_inputs(&scene, upstream, keep);
    if setup.opts.keep {
        let f32s =
            |v: &[[f64; 3]]| -> Vec<[f32; 3]> { v.iter().map(|p| p.map(|x| x as f32)).collect() };
        let g = &truth.grads;
        let (hl, wl) = (setup.env.height, setup.env.width);
        for (name, wd, ht, v) in [
            ("reference_image.npy", w, h, &truth.image),
            ("reference_d_env.npy", wl, hl, &g.d_env),
            ("reference_d_normals.npy", w, h, &g.d_normals),
        ] {
            write(&files.dir.join(name), &npy::encode_rgb(wd, ht, &f32s(v)));
        }
    }
    let cli_s = run_cli(setup, &case, &files, &truth, out);
    run_peers_of(setup, &case, &files, &truth, (cpu_s, cli_s), out);
}

/// The in-process paths on one scene and material (`w` x `h` pixels), their records kept
/// in `out`: the `cpu` path's (fwd, fb) median seconds.
fn in_process(
    setup: &Setup,
    case: &Case,
    truth: &Truth,
    batch: &Batch,
    ups: &[Image],
    (w, h): (usize, usize),
    out: &mut Gathered,
) -> Option<(f64, f64)> {
    let (scene_name, material) = (case.scene_name, case.material);
    // in-process paths
    let mut cpu_s: Option<(f64, f64)> = None;
    for (path, r) in setup.renderers {
        let timed = if path == "reference" && setup.opts.ref_reps == 0 {
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
            let mut a = case.rec(path, "fwd", vec![truth.fwd_s], e_fwd);
            let mut b = case.rec(path, "fb", vec![truth.fwd_s + truth.bwd_s], e_fb);
            let how =
                json!("the ground-truth run: f64 functions, once, cold; errors: its f32 rounding");
            a.extra.insert("timing".into(), how.clone());
            b.extra.insert("timing".into(), how);
            Ok((a, b))
        } else {
            let reps = if path == "reference" {
                setup.opts.ref_reps
            } else {
                setup.opts.reps
            };
            time_renderer(r, &batch, &ups, reps, path != "reference").map(|t| {
                let mut a = case.rec(path, "fwd", t.fwd, errors_f32(&truth, &t.image, None));
                let mut b = case.rec(
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
                    if let Some(h) = r.extra.get("host_overhead_s").and_then(Value::as_f64) {
                        println!(
                            "    {} host overhead (call - GPU passes, median): {:.2} ms",
                            r.pass,
                            h * 1e3
                        );
                    }
                }
                out.records.push(a);
                out.records.push(b);
            }
            Err(e) => {
                let n = format!("{path} {scene_name} {}: failed: {e}", material.name);
                println!("{n}");
                out.notes.push(n);
            }
        }
    }
    cpu_s
}
