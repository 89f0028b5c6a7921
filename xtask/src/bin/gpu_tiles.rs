//! GPU time per pass of both ways of reading the looped-over records (workgroup-memory
//! tiles, uniform chunks) and of a few slice counts, on this machine's adapter: what
//! docs/gpu.md's choice for software adapters rests on.
//!
//! `cargo xtask gpu_tiles -- [N]`: an N x N sphere (default 128) under the
//! built-in sky at 64 x 128, `plastic-red`, orthographic; forward and backward, median of
//! 3 calls after a warm-up, from GPU timestamps.

use matedit::gpu::{GpuRenderer, PassTiming, Tiles};
use matedit::{Backend, Batch, Camera, Convention, Image, NormalMap, Scene, Wanted};

fn main() -> matedit::Result<()> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(128);
    let scene = Scene {
        normals: NormalMap::sphere(n),
        env: matedit::builtin_sky::procedural_env(64, 128, Convention::Equirect),
        material: matedit::presets::lookup("plastic-red").expect("a preset"),
        camera: Camera::Orthographic,
    };
    let batch = Batch::single(scene)?;
    let (w, h) = batch.image_size();
    let up = vec![Image {
        width: w,
        height: h,
        pixels: vec![[1.0, 0.5, -0.25]; w * h],
    }];
    for tiles in [Tiles::Uniform, Tiles::Workgroup] {
        for slices in [1, 4] {
            let g = GpuRenderer::new()?.with_tiles(tiles)?.with_slices(slices);
            let med = |run: &dyn Fn() -> matedit::Result<Vec<PassTiming>>| {
                run()?; // warm-up
                let mut calls = Vec::new();
                for _ in 0..3 {
                    calls.push(run()?);
                }
                calls.sort_by(|a, b| total(a).total_cmp(&total(b)));
                Ok::<_, matedit::Error>(calls.swap_remove(1))
            };
            let fwd = med(&|| {
                g.render((&batch).into())?;
                Ok(g.last_timings())
            })?;
            let bwd = med(&|| {
                g.backward((&batch).into(), &up, Wanted::ALL)?;
                Ok(g.last_timings())
            })?;
            println!("{tiles:?}, {slices} slice(s), {n} x {n}, {}", g.describe());
            for t in fwd.iter().chain(&bwd) {
                let rate = t
                    .pairs_per_second()
                    .map_or("-".into(), |r| format!("{:.1} M pairs/s", r / 1e6));
                println!("  {:<16} {:>10.4} s  {rate}", t.pass, t.seconds);
            }
        }
    }
    Ok(())
}

/// Seconds over every pass of a call.
fn total(t: &[PassTiming]) -> f64 {
    t.iter().map(|p| p.seconds).sum()
}
