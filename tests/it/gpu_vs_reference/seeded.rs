//! Forward and backward on seeded random scenes (the shared test scenes, presets, inputs
//! split over the binding limit) against the reference, and the backward pass's
//! determinism.

use super::{compare, compare_on, output_bits, sphere_scene};
use crate::common::{Rng, gpu, random_scene, scenes};
use matedit::{Batch, Camera, Convention};

#[test]
fn forward_backward_64x128_env_equirect() {
    compare("64x128 equirect", &scenes::equirect_64x128());
}

#[test]
fn forward_backward_non_square_paper() {
    compare("13x7 paper", &scenes::non_square_paper());
}

#[test]
fn forward_backward_batch_of_3() {
    compare("batch of 3", &scenes::batch_of_3());
}

#[test]
fn forward_backward_perspective_both_conventions() {
    for (conv, batch) in scenes::perspective() {
        compare(&format!("perspective {conv:?}"), &batch);
    }
}

#[test]
fn forward_splits_more_pixels_than_one_chunk_of_texels() {
    // more lit texels than one uniform chunk (252) or one tile (64) and a sphere: the sums
    // over chunks or tiles must agree
    let s = sphere_scene(16, 32);
    compare("sphere 20 env 32x64", &Batch::single(s).unwrap());
}

#[test]
fn backward_is_deterministic() {
    let Some(g) = gpu("backward_is_deterministic") else {
        return;
    };
    let mut rng = Rng::new(17);
    let s = random_scene(
        &mut rng,
        16,
        16,
        32,
        64,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let batch = Batch::single(s).unwrap();
    assert!(
        output_bits(&g, &batch) == output_bits(&g, &batch),
        "two GPU runs differ"
    );
}

#[test]
fn inputs_over_the_binding_limit_are_split() {
    let Some(g) = gpu("inputs_over_the_binding_limit_are_split") else {
        return;
    };
    // 64 pixels x 48 bytes and 64 texels x 432 bytes per range: a 20x20 sphere (~300
    // pixels) and a 16x32 map (512 texels) need 5 pixel ranges and 8 texel ranges
    let g = g.with_binding_cap(64 * 48);
    compare_on(
        &g,
        "split ranges",
        &Batch::single(sphere_scene(18, 16)).unwrap(),
    );
}

#[test]
fn forward_backward_presets_with_constant_and_zero_lobes() {
    // the built-in presets have diffuse (constant) lobes and unused (scale 0) lobes
    let mut rng = Rng::new(19);
    for (conv, camera) in [
        (Convention::Equirect, Camera::Orthographic),
        (Convention::Paper, Camera::Perspective { fov_y_deg: 50.0 }),
    ] {
        let scenes = ["plastic-red", "matte-white", "gold"]
            .iter()
            .map(|name| {
                let mut s = random_scene(&mut rng, 10, 9, 16, 32, conv, camera);
                s.material = matedit::presets::lookup(name).expect("preset");
                s
            })
            .collect();
        compare(&format!("presets {camera:?}"), &Batch::new(scenes).unwrap());
    }
}
