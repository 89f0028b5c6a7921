//! The in-process paths' timings through `matedit::Renderer`, with the GPU time of each
//! pass where the adapter has timestamp queries.

use std::time::Instant;

use matedit::gpu::PassTiming;
use matedit::{Batch, Gradients, Image, Renderer};
use serde_json::{Value, json};

/// What [`time_renderer`] measured: forward and forward + backward seconds per run, the
/// last image and gradients, and the per-pass GPU times of the last forward and the last
/// backward call (empty off the GPU or without timestamp queries).
pub struct Timed {
    pub fwd: Vec<f64>,
    pub fb: Vec<f64>,
    pub image: Image,
    pub grads: Gradients,
    pub fwd_passes: Vec<PassTiming>,
    pub bwd_passes: Vec<PassTiming>,
    /// Per run, the call's wall time minus its passes' GPU time (empty without timings).
    pub fwd_host: Vec<f64>,
    pub fb_host: Vec<f64>,
}

/// The GPU seconds of the last call's passes; `None` without timestamp queries.
pub fn gpu_seconds(r: &Renderer) -> Option<f64> {
    let t = r.last_timings();
    (!t.is_empty()).then(|| t.iter().map(|p| p.seconds).sum())
}

/// The in-process paths render for at least this long before they are timed.
pub const WARM_UP_S: f64 = 0.5;

/// fwd and fb timings of one renderer: warm-up (if asked), then `reps` runs of each.
pub fn time_renderer(
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
pub fn pass_timings(call: &str, timings: &[PassTiming]) -> Value {
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
