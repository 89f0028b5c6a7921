//! Fit a material to an image: a sphere of gold under a known light, recovered by Adam
//! through the layer from a red plastic start.
//!
//! ```text
//! cargo run --release --example fit_material
//! ```
//!
//! `matedit fit` does the same from image files, and can fit the light too
//! (`edit::Light::Fit`).

use matedit::edit::{self, Inputs, Light, Options};
use matedit::{
    Batch, Camera, Convention, Device, NormalMap, Renderer, Scene, builtin_sky, presets,
};

fn main() -> matedit::Result<()> {
    let renderer = Renderer::new(Device::Auto)?;
    let env = builtin_sky::procedural_env(16, 32, Convention::default());
    let normals = NormalMap::sphere(64);

    // the image to fit: what a photo of the sphere would be, rendered here
    let truth = presets::lookup("gold-metallic-paint").expect("a shipped preset");
    let scene = Scene {
        normals: normals.clone(),
        env: env.clone(),
        material: truth,
        camera: Camera::Orthographic,
    };
    let target = renderer.render(&Batch::single(scene)?)?.remove(0);

    // the object is where the normals are; the light is known
    let inputs = Inputs::new(normals.clone(), target.clone(), None)?;
    let start = presets::lookup(presets::DEFAULT).expect("a shipped preset");
    let mut options = Options::new(start, Light::Fixed(env.clone()));
    options.steps = 300;
    let fitted = edit::fit(&renderer, &inputs, &options, &mut |step, loss| {
        if step % 50 == 0 {
            println!("step {step:4}: loss {loss:.5}");
        }
    })?;

    let first = fitted.losses.first().copied().unwrap_or(f64::NAN);
    let last = fitted.losses.last().copied().unwrap_or(f64::NAN);
    println!(
        "{} steps in {:.2} s on {}: loss {first:.5} -> {last:.5}",
        fitted.steps,
        fitted.seconds,
        renderer.describe()
    );

    // the fitted material rendered again, against the image, over the sphere's pixels
    let scene = Scene {
        normals,
        env,
        material: fitted.material,
        camera: Camera::Orthographic,
    };
    let image = renderer.render(&Batch::single(scene)?)?.remove(0);
    println!(
        "PSNR over the sphere: {:.1} dB",
        edit::psnr(&image, &target, &inputs.mask)
    );
    Ok(())
}
