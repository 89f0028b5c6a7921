//! Forward and backward timings of each backend on the same scene: a sphere against an
//! env map, orthographic, with a random HDR-ish map and a glossy material.
//!
//! `cargo bench --bench layer -- [SIZE] [HLxWL] [REPS]` (defaults: 128 64x128 3). Prints one
//! line per backend and pass: median wall seconds and Mpairs/s (pairs = foreground pixels x
//! texels), and the GPU's max error against the CPU reference relative to each output's
//! largest value.

use std::time::Instant;

use matedit::prepare::Prepared;
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Image, Material, NormalMap, Scene, reference,
};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// This process's user + system CPU seconds (Linux; 0 elsewhere): less sensitive than
/// wall time to other load on a small machine.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else {
        return 0.0;
    };
    // fields after the command name (which is in parentheses): utime is the 12th, stime the 13th
    let rest = stat.rsplit_once(')').map_or("", |(_, r)| r);
    let f: Vec<&str> = rest.split_whitespace().collect();
    let field = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (field(11) + field(12)) / 100.0
}

fn time<T>(reps: usize, mut f: impl FnMut() -> T) -> (f64, T) {
    let mut out = f(); // warm-up
    let mut t = Vec::new();
    let c0 = cpu_seconds();
    for _ in 0..reps {
        let s = Instant::now();
        out = f();
        t.push(s.elapsed().as_secs_f64());
    }
    eprintln!(
        "  (cpu-s per run {:.2}, wall {:.2})",
        (cpu_seconds() - c0) / reps as f64,
        median(t.clone())
    );
    (median(t), out)
}

fn rel_err(got: &[[f32; 3]], want: &[[f64; 3]]) -> f64 {
    let scale = want.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    let err = got
        .iter()
        .flatten()
        .zip(want.iter().flatten())
        .fold(0.0f64, |a, (&g, &w)| a.max((g as f64 - w).abs()));
    err / scale
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with('-'))
        .collect();
    let size: usize = args.first().and_then(|s| s.parse().ok()).unwrap_or(128);
    let (hl, wl) = args
        .get(1)
        .and_then(|s| s.split_once('x'))
        .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
        .unwrap_or((64, 128));
    let reps: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(3);
    // a 4th argument `gpu` skips the CPU reference (and the error columns)
    let gpu_only = args.get(3).is_some_and(|s| s == "gpu");

    // deterministic HDR-ish map: smooth sky with a bright patch, lower half dimmer
    let texels = (0..hl * wl)
        .map(|i| {
            let (r, c) = (i / wl, i % wl);
            let v = 0.3 + 0.7 * ((r * 7 + c * 3) % 11) as f32 / 10.0;
            let sun = if r < hl / 4 && c % (wl / 4) < 2 {
                50.0
            } else {
                0.0
            };
            let k = if r > hl / 2 { 0.3 } else { 1.0 };
            [k * v + sun, k * v * 0.9 + sun, k * v * 0.8 + sun]
        })
        .collect();
    let scene = Scene {
        normals: NormalMap::sphere(size),
        env: EnvMap::new(hl, wl, Convention::Equirect, texels).unwrap(),
        material: Material::constant("bench", [(0.3, 0.0), (1.2, 30.0), (2.0, 300.0)]).unwrap(),
        camera: Camera::Orthographic,
    };
    let batch = Batch::single(scene.clone()).unwrap();
    let prep = Prepared::new(&scene);
    let pairs = (prep.pixels.len() * prep.lit.len()) as f64 / 1e6;
    let upstream = vec![Image {
        width: size,
        height: size,
        pixels: vec![[1.0, 0.5, 0.25]; size * size],
    }];
    println!(
        "scene: sphere {size}x{size} ({} fg px), env {hl}x{wl} ({} lit texels), {pairs:.1} Mpairs; median of {reps}",
        prep.pixels.len(),
        prep.lit.len()
    );

    let c = reference::Reference;
    let g64: Vec<[f64; 3]> = upstream[0]
        .pixels
        .iter()
        .map(|p| p.map(f64::from))
        .collect();
    let (cf, cimg, cb, cgrad) = if gpu_only {
        (
            f64::NAN,
            Vec::new(),
            f64::NAN,
            reference::backward(
                &Prepared::new(&Scene {
                    normals: NormalMap::sphere(1),
                    ..scene.clone()
                }),
                &[[0.0; 3]],
            ),
        )
    } else {
        let (cf, cimg) = time(reps, || reference::forward(&prep));
        let (cb, cgrad) = time(reps, || reference::backward(&prep, &g64));
        println!(
            "{:<60} forward {cf:8.3} s {:8.1} Mpairs/s | backward {cb:8.3} s",
            c.describe(),
            pairs / cf
        );
        (cf, cimg, cb, cgrad)
    };

    match matedit::gpu::GpuRenderer::new() {
        Err(e) => println!("gpu: not run: {e}"),
        Ok(g) => {
            let (gf, gimg) = time(reps, || g.render(&batch).unwrap());
            let (gb, ggrad) = time(reps, || g.backward(&batch, &upstream).unwrap());
            println!(
                "{:<60} forward {gf:8.3} s {:8.1} Mpairs/s | backward {gb:8.3} s | vs cpu: fwd {:.2}x bwd {:.2}x",
                g.describe(),
                pairs / gf,
                cf / gf,
                cb / gb
            );
            if gpu_only {
                return;
            }
            let dctrl_scale = cgrad.d_ctrl.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            let dctrl_err = ggrad[0]
                .d_ctrl
                .iter()
                .zip(&cgrad.d_ctrl)
                .fold(0.0f64, |a, (&x, &y)| a.max((x as f64 - y).abs()));
            println!(
                "gpu max error / max value: image {:.2e}, dL {:.2e}, dn {:.2e}, dctrl {:.2e}",
                rel_err(&gimg[0].pixels, &cimg),
                rel_err(&ggrad[0].d_env, &cgrad.d_env),
                rel_err(&ggrad[0].d_normals, &cgrad.d_normals),
                dctrl_err / dctrl_scale
            );
        }
    }
}
