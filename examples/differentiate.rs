//! Differentiate a scene: the gradient of an image loss with respect to the light, the
//! normals and the material, from one backward pass, checked against finite differences.
//!
//! ```text
//! cargo run --release --example differentiate
//! ```
//!
//! The loss is the squared difference between the render and a target made of another
//! material; its gradient dLoss/dImage = 2 (image - target) is what `backward` takes.

use matedit::{
    Batch, Camera, Convention, Device, Image, Material, NormalMap, Renderer, Scene, builtin_sky,
    presets,
};

fn scene(material: Material) -> Scene {
    Scene {
        normals: NormalMap::sphere(64),
        env: builtin_sky::procedural_env(16, 32, Convention::default()),
        material,
        camera: Camera::Orthographic,
    }
}

fn loss(renderer: &Renderer, material: &Material, target: &Image) -> matedit::Result<f64> {
    let image = renderer
        .render(&Batch::single(scene(material.clone()))?)?
        .remove(0);
    Ok(image
        .pixels
        .iter()
        .zip(&target.pixels)
        .flat_map(|(p, t)| (0..3).map(move |k| f64::from(p[k] - t[k]).powi(2)))
        .sum())
}

fn main() -> matedit::Result<()> {
    // the f64 reference, so that finite differences are exact enough to compare with
    let renderer = Renderer::new(Device::Reference)?;
    let gold = presets::lookup("gold-metallic-paint").expect("a shipped preset");
    let plastic = presets::lookup(presets::DEFAULT).expect("a shipped preset");

    let target = renderer.render(&Batch::single(scene(gold))?)?.remove(0);
    let batch = Batch::single(scene(plastic.clone()))?;
    let image = renderer.render(&batch)?.remove(0);

    // dLoss/dImage for the squared error, then one backward pass for all three gradients
    let upstream = Image {
        width: image.width,
        height: image.height,
        pixels: (image.pixels.iter().zip(&target.pixels))
            .map(|(p, t)| std::array::from_fn(|k| 2.0 * (p[k] - t[k])))
            .collect(),
    };
    let grads = renderer.backward(&batch, &[upstream])?.remove(0);
    let norm = |v: &[[f32; 3]]| {
        v.iter()
            .flatten()
            .map(|x| f64::from(*x).powi(2))
            .sum::<f64>()
            .sqrt()
    };
    println!("loss {:.4}", loss(&renderer, &plastic, &target)?);
    println!(
        "|dLoss/dL| {:.4e} over {} texels",
        norm(&grads.d_env),
        grads.d_env.len()
    );
    println!(
        "|dLoss/dn| {:.4e} over {} pixels",
        norm(&grads.d_normals),
        grads.d_normals.len()
    );

    // the material's largest gradient entry against a central difference
    let (i, g) = (grads.d_ctrl.iter().enumerate())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .expect("108 entries");
    let h = 1e-4 * plastic.ctrl[i].abs().max(1e-2);
    let moved = |d: f64| {
        let mut m = plastic.clone();
        m.ctrl[i] += d;
        loss(&renderer, &m, &target)
    };
    let fd = (moved(h)? - moved(-h)?) / (2.0 * h);
    println!(
        "dLoss/d{}: backward {g:.6e}, finite difference {fd:.6e}",
        matedit::material::describe_index(i)
    );
    Ok(())
}
