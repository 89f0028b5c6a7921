//! Edit a photo: the built-in networks find the object, its shape, light and material; the
//! object is then rendered in another material and put back into the photo.
//!
//! ```text
//! cargo run --release --example edit_photo -- PHOTO.jpg [PRESET] [OUT.png]
//! cargo run --release --example edit_photo               # on a photo it renders itself
//! ```
//!
//! `matedit edit` is this with masks, `--like` another photo, reports and previews.

use std::path::PathBuf;

use matedit::edit::photo::{self, PhotoOptions};
use matedit::io::{self, Preview};
use matedit::nets::Nets;
use matedit::shapes::{self, Rotation, Shape, View};
use matedit::{Accuracy, Batch, Camera, Convention, Device, Image, Renderer, Scene};
use matedit::{builtin_sky, presets};

/// A stand-in photo: a turned torus of red plastic under the built-in sky, on grey.
fn rendered_photo(renderer: &Renderer) -> matedit::Result<Image> {
    let torus: Shape = "torus".parse().map_err(matedit::Error::Invalid)?;
    let view = View {
        width: 192,
        height: 192,
        camera: Camera::Orthographic,
        rotation: Rotation {
            yaw: 30.0,
            pitch: 20.0,
            roll: 0.0,
        },
        flat: false,
        margin: 0.15,
    };
    let (normals, mask) = shapes::render_normals(&torus.mesh(0), &view)?;
    let scene = Scene {
        normals,
        env: builtin_sky::procedural_env(32, 64, Convention::default()),
        material: presets::lookup(presets::DEFAULT).expect("a shipped preset"),
        camera: Camera::Orthographic,
    };
    let mut image = renderer.render(&Batch::single(scene)?)?.remove(0);
    for (p, &on) in image.pixels.iter_mut().zip(&mask) {
        if !on {
            *p = [0.18; 3];
        }
    }
    Ok(image)
}

fn main() -> matedit::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let preset = args.get(1).map_or("gold-metallic-paint", String::as_str);
    let out = PathBuf::from(args.get(2).map_or("edit.png", String::as_str));
    let renderer = Renderer::new(Device::Auto)?;

    // linear RGB, as the layer renders; a PNG or JPEG is decoded from sRGB
    let photo = match args.first() {
        Some(path) => io::load_image(path.as_ref())?,
        None => rendered_photo(&renderer)?,
    };
    let material = presets::lookup(preset).ok_or_else(|| {
        matedit::Error::Invalid(format!("{preset}: no such preset (see `matedit presets`)"))
    })?;

    // the object's mask, normals, light and material: predicted by the nets, then refined
    // through the layer so that the object's own material renders the photo
    let nets = Nets::builtin()?;
    let d = photo::decompose(
        &renderer,
        &nets,
        &photo,
        None,
        &PhotoOptions::default(),
        &mut |stage| {
            eprintln!("{stage:?}");
        },
    )?;
    println!(
        "object: {} of {} pixels; its own material gives it back at {:.1} dB",
        d.mask.iter().filter(|&&m| m).count(),
        d.mask.len(),
        d.psnr_refined
    );

    // the object in the new material under the refined light, over the untouched photo
    let edit = d.edit(&renderer, &photo, &material, None, Accuracy::Exact)?;
    let png = io::encode_image(&out, &edit, &Preview::default())?;
    io::write_atomic(&out, &png)?;
    println!("{}: the object made of {preset}", out.display());
    Ok(())
}
