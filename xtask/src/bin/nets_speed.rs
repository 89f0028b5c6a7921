//! How long `Nets::predict` takes on a 256 x 256 image: the figure in docs/nets.md.
//!
//! `cargo xtask nets_speed -- WEIGHTS [SIZE] [REPS]`: WEIGHTS from
//! `matedit.nets.save` (python/examples/nets/parity_data.py --default-weights PATH writes a
//! random default `NetsConfig()`); a SIZE x SIZE (default 256) image of a lit sphere; the
//! median of REPS (default 5) calls after a warm-up, with a given mask and without (two
//! passes of the normals net), on rayon's threads (RAYON_NUM_THREADS, else one per core).

use std::time::Instant;

use matedit::nets::Nets;
use matedit::{Image, NormalMap};

/// The median of `reps` timed calls of `f`, after one untimed.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    let mut seconds = Vec::with_capacity(reps);
    for _ in 0..reps {
        let t = Instant::now();
        f();
        seconds.push(t.elapsed().as_secs_f64());
    }
    seconds.sort_by(f64::total_cmp);
    seconds[reps / 2]
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let weights = args
        .next()
        .ok_or("usage: nets_speed WEIGHTS [SIZE] [REPS]")?;
    let size: usize = args.next().map_or(Ok(256), |s| s.parse())?;
    let reps: usize = args.next().map_or(Ok(5), |s| s.parse())?;
    let nets = Nets::load(weights.as_ref())?;
    let sphere = NormalMap::sphere(size);
    let light = [0.3f32, 0.5, 0.8];
    let image = Image {
        width: size,
        height: size,
        pixels: sphere
            .normals
            .iter()
            .map(|n| {
                let d = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]).max(0.0);
                [d, 0.8 * d, 0.6 * d]
            })
            .collect(),
    };
    let mask: Vec<bool> = sphere.normals.iter().map(|n| n[2] > 0.0).collect();
    let cfg = nets.config();
    println!(
        "config width {} levels {} env {}x{}; image {size}x{size}; threads {}",
        cfg.width,
        cfg.levels,
        cfg.env_height,
        cfg.env_width,
        rayon::current_num_threads()
    );
    let with = time(reps, || {
        nets.predict(&image, Some(&mask)).expect("predicts");
    });
    let without = time(reps, || {
        nets.predict(&image, None).expect("predicts");
    });
    println!(
        "predict with a mask: {:.1} ms (median of {reps})",
        with * 1e3
    );
    println!(
        "predict without:     {:.1} ms (median of {reps})",
        without * 1e3
    );
    Ok(())
}
