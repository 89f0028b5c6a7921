//! Render a scene: a sphere of a measured material under the built-in sky, written as a PNG.
//!
//! ```text
//! cargo run --release --example render -- [PRESET] [OUT.png]
//! cargo run --release --example render -- gold-metallic-paint gold.png
//! ```
//!
//! `matedit presets` lists the 90 measured materials a scene can be made of.

use std::path::PathBuf;

use matedit::io::{self, Preview};
use matedit::{
    Batch, Camera, Convention, Device, NormalMap, Renderer, Scene, builtin_sky, presets,
};

fn main() -> matedit::Result<()> {
    let mut args = std::env::args().skip(1);
    let preset = args.next().unwrap_or_else(|| presets::DEFAULT.to_string());
    let out = PathBuf::from(args.next().unwrap_or_else(|| "render.png".into()));

    let material = presets::lookup(&preset).ok_or_else(|| {
        matedit::Error::Invalid(format!("{preset}: no such preset (see `matedit presets`)"))
    })?;
    let scene = Scene {
        // a 256 x 256 orthographic view of the unit sphere (pixels off it are background)
        normals: NormalMap::sphere(256),
        // the procedural sky with its sun, as a 64 x 128 lat-long map
        env: builtin_sky::procedural_env(64, 128, Convention::default()),
        material,
        camera: Camera::Orthographic,
    };

    // a hardware GPU if there is one, else the fast CPU path
    let renderer = Renderer::new(Device::Auto)?;
    let image = renderer.render(&Batch::single(scene)?)?.remove(0);

    // linear radiance to an 8-bit sRGB PNG, written whole or not at all
    let png = io::encode_image(&out, &image, &Preview::default())?;
    io::write_atomic(&out, &png)?;
    println!("{}: {preset} on {}", out.display(), renderer.describe());
    Ok(())
}
