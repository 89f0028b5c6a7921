//! The photos of the edit tests: a procedural shape under the built-in sky on a grey
//! background, rendered by the layer, with its mask and its true normals.

use std::path::{Path, PathBuf};

use matedit::io::{self, Preview};
use matedit::shapes::{self, Rotation, Shape, View};
use matedit::{Batch, Camera, Convention, Device, Renderer, Scene};

/// A PNG photo of `shape` (its seed, turned) made of `preset` under the built-in sky,
/// `size` pixels square, on a grey background; and its mask as a PNG.
pub(crate) fn photo(
    dir: &Path,
    name: &str,
    shape: &str,
    preset: &str,
    size: usize,
) -> (PathBuf, PathBuf) {
    wide_photo(dir, name, shape, preset, (size, size))
}

/// [`photo`], `width` x `height` pixels.
pub(crate) fn wide_photo(
    dir: &Path,
    name: &str,
    shape: &str,
    preset: &str,
    size: (usize, usize),
) -> (PathBuf, PathBuf) {
    photo_on(dir, name, shape, preset, size, 0.18)
}

/// [`wide_photo`] on a background of linear grey `background`.
pub(crate) fn photo_on(
    dir: &Path,
    name: &str,
    shape: &str,
    preset: &str,
    (width, height): (usize, usize),
    background: f32,
) -> (PathBuf, PathBuf) {
    let (normals, mask) = true_normals(shape, (width, height));
    let scene = Scene {
        normals,
        env: matedit::builtin_sky::procedural_env(16, 32, Convention::Equirect),
        material: matedit::presets::lookup(preset).unwrap(),
        camera: Camera::Orthographic,
    };
    let mut img = Renderer::new(Device::Cpu)
        .unwrap()
        .render(&Batch::single(scene).unwrap())
        .unwrap()
        .remove(0);
    for (p, &m) in img.pixels.iter_mut().zip(&mask) {
        if !m {
            *p = [background; 3];
        }
    }
    let (p, mpath) = (
        dir.join(format!("{name}.png")),
        dir.join(format!("{name}_mask.png")),
    );
    std::fs::write(
        &p,
        io::png::encode_preview(&img, &Preview::default()).unwrap(),
    )
    .unwrap();
    std::fs::write(&mpath, io::png::encode_mask(width, height, &mask).unwrap()).unwrap();
    (p, mpath)
}

/// The normals and mask of the photos' `shape` (its seed, turned) at `width` x `height`.
pub(crate) fn true_normals(
    shape: &str,
    (width, height): (usize, usize),
) -> (matedit::NormalMap, Vec<bool>) {
    let spec: Shape = shape.parse().unwrap();
    let view = View {
        width,
        height,
        camera: Camera::Orthographic,
        rotation: Rotation {
            yaw: 30.0,
            pitch: 20.0,
            roll: 0.0,
        },
        flat: false,
        margin: 0.15,
    };
    shapes::render_normals(&spec.mesh(0), &view).unwrap()
}

/// [`photo`]'s red blob, 96 pixels square, loaded back: the photo (linear) and its mask.
pub(crate) fn red_blob(dir: &Path) -> (matedit::Image, Vec<bool>) {
    let (a, a_mask) = photo(dir, "a", "blobby:seed=3", "plastic-red", 96);
    let (_, _, mask) = io::load_mask(&a_mask).unwrap();
    (io::load_image(&a).unwrap(), mask)
}
