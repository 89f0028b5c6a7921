//! Host time per call of the GPU path: the wall time of a warm in-process call minus the
//! GPU time of its passes (timestamps), for the forward and the backward, and where the
//! host time goes (preparing the scene, the passes' records, the submission and readback).
//!
//! `cargo xtask gpu_overhead -- [N ...] [--env HxW]`: N x N spheres
//! (default 256 and 1024) under the built-in sky at 16 x 32 (small, so that a software
//! adapter's passes stay short: the host's work grows with the pixels), a nine-lobe
//! random material, orthographic; median of 5 calls after a warm-up.

use std::time::Instant;

use matedit::gpu::GpuRenderer;
use matedit::{Backend, Batch, Camera, Convention, Image, Material, NormalMap, Scene, Wanted};

fn material() -> Material {
    // nine lobe-channels with scales and exponents spread over the range a fit gives
    let mut ctrl = [0.0; 108];
    let mut s = matedit::splitmix::SplitMix(7);
    for k in 0..3 {
        for l in 0..3 {
            for j in 0..6 {
                ctrl[matedit::material::idx(k, l, 0, j)] = 0.05 + 1.5 * s.uniform();
                ctrl[matedit::material::idx(k, l, 1, j)] = 1.0 + 80.0 * s.uniform();
            }
        }
    }
    Material::new("random", &ctrl).expect("a valid material")
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() -> matedit::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (mut hl, mut wl) = (16, 32);
    if let Some(k) = args.iter().position(|a| a == "--env")
        && let Some((h, w)) = args.get(k + 1).and_then(|v| v.split_once('x'))
    {
        (hl, wl) = (h.parse().unwrap_or(hl), w.parse().unwrap_or(wl));
    }
    let sizes: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let sizes = if sizes.is_empty() {
        vec![256, 1024]
    } else {
        sizes
    };
    let g = GpuRenderer::new()?;
    println!("{}; env {hl} x {wl}", g.describe());
    println!(
        "{:>6} {:>9} {:>11} {:>11} {:>11} {:>11} {:>11} {:>11}",
        "N", "call", "fwd call", "fwd GPU", "fwd host", "bwd call", "bwd GPU", "bwd host"
    );
    for n in sizes {
        let scene = Scene {
            normals: NormalMap::sphere(n),
            env: matedit::builtin_sky::procedural_env(hl, wl, Convention::Equirect),
            material: material(),
            camera: Camera::Orthographic,
        };
        let batch = Batch::single(scene)?;
        let up = vec![Image {
            width: n,
            height: n,
            pixels: vec![[1.0, 0.5, -0.25]; n * n],
        }];
        let time = |f: &dyn Fn() -> matedit::Result<()>| {
            f()?; // warm-up
            let mut call = Vec::new();
            let mut gpu = Vec::new();
            for _ in 0..5 {
                let t = Instant::now();
                f()?;
                call.push(t.elapsed().as_secs_f64());
                gpu.push(g.last_timings().iter().map(|t| t.seconds).sum::<f64>());
            }
            let host: Vec<f64> = call.iter().zip(&gpu).map(|(c, g)| c - g).collect();
            Ok::<_, matedit::Error>((median(call), median(gpu), median(host)))
        };
        let f = time(&|| g.render((&batch).into()).map(drop))?;
        let b = time(&|| g.backward((&batch).into(), &up, Wanted::ALL).map(drop))?;
        println!(
            "{n:>6} {:>9} {:>9.2}ms {:>9.2}ms {:>9.2}ms {:>9.2}ms {:>9.2}ms {:>9.2}ms",
            "warm",
            f.0 * 1e3,
            f.1 * 1e3,
            f.2 * 1e3,
            b.0 * 1e3,
            b.1 * 1e3,
            b.2 * 1e3
        );
    }
    Ok(())
}
