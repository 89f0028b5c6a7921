//! The GPU's own on seeded random scenes: the backward pass's determinism, and inputs split
//! over the binding limit against the reference (what every backend must do: backends).

use super::{compare_on, output_bits};
use crate::backends::sphere_scene;
use crate::common::{Rng, gpu, random_scene};
use matedit::{Batch, Camera, Convention};

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
