//! Where the continuous light's time goes: for the default scene (an N x N sphere under
//! the built-in sky at 64 x 128 with its 4x detail, the default material), the layer's
//! image, the corrections' grouping (`Corrections::new`) and their evaluation
//! (`add_forward`) on each backend named (`gpu`: the best adapter), median of 3 after a
//! warm-up. docs/gpu.md has its figures on an H200.
//!
//! `cargo xtask corrections_speed -- [N ...] [--device cpu,gpu]`

use std::time::Instant;

use matedit::continuous_light::Corrections;
use matedit::prepare::Prepared;
use matedit::{Backend, Camera, Convention, NormalMap, Scene, builtin_sky};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time(f: &mut dyn FnMut() -> matedit::Result<()>) -> matedit::Result<f64> {
    f()?;
    let mut t = Vec::new();
    for _ in 0..3 {
        let s = Instant::now();
        f()?;
        t.push(s.elapsed().as_secs_f64());
    }
    Ok(median(t))
}

fn main() -> matedit::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut devices = vec!["cpu".to_string()];
    if let Some(k) = args.iter().position(|a| a == "--device")
        && let Some(v) = args.get(k + 1)
    {
        devices = v.split(',').map(String::from).collect();
    }
    let sizes: Vec<usize> = args.iter().filter_map(|a| a.parse().ok()).collect();
    let sizes = if sizes.is_empty() { vec![256] } else { sizes };
    let env = builtin_sky::procedural_env(64, 128, Convention::Equirect);
    let f = builtin_sky::LIGHT_DETAIL;
    let mut detail = None;
    let sky = time(&mut || {
        detail = Some(builtin_sky::procedural_env(
            64 * f,
            128 * f,
            Convention::Equirect,
        ));
        Ok(())
    })?;
    let detail = detail.expect("made");
    println!("the sky at {} x {}: {sky:.4} s", 64 * f, 128 * f);
    for d in &devices {
        let backend: Box<dyn Backend> = match d.as_str() {
            "gpu" => Box::new(matedit::gpu::GpuRenderer::new()?),
            _ => Box::new(matedit::cpu::FastCpu::new()?),
        };
        println!("{}", backend.describe());
        for &n in &sizes {
            let scene = Scene {
                normals: NormalMap::sphere(n),
                env: env.clone(),
                material: matedit::presets::lookup(matedit::presets::DEFAULT).expect("a preset"),
                camera: Camera::Orthographic,
            };
            let prep = Prepared::new(&scene);
            let layer = time(&mut || backend.render((&prep).into()).map(drop))?;
            let mut c = None;
            let group = time(&mut || {
                c = Some(Corrections::new(
                    &prep,
                    &env,
                    Some(&detail),
                    builtin_sky::LIGHT_LEVEL,
                ));
                Ok(())
            })?;
            let c = c.expect("built");
            let mut image = backend.render((&prep).into())?.remove(0);
            let add = time(&mut || c.add_forward(backend.as_ref(), &mut image))?;
            println!(
                "N {n}: layer {layer:.4} s, grouping {group:.4} s, corrections {add:.4} s ({}; {} pairs)",
                c.describe(),
                c.pairs()
            );
        }
    }
    Ok(())
}
