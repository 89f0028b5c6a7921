//! Forward and backward on seeded random scenes against the reference: the shared test
//! scenes, a sphere with more lit texels than one chunk, the presets, lobes mixed and
//! shared across channels, normals not of unit length and facing away.

use super::{compare, sphere_scene};
use crate::common::{Rng, random_material, random_scene, scenes};
use matedit::{Batch, Camera, Convention, Material, NormalMap};

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

/// Normals facing away from the camera: texels above their horizon whose half vector is
/// not (x = max(0, h.n) = 0, log2 x standing in as a large negative number), under nine
/// lobes with exponents to 80, whose x^m1 must come out 0 there, not NaN.
#[test]
fn normals_facing_away_have_lit_texels_with_x_zero() {
    let mut rng = Rng::new(23);
    let mut s = random_scene(
        &mut rng,
        12,
        10,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let n = s.normals.normals.iter().map(|v| [v[0], v[1], -v[2].abs()]);
    s.normals = NormalMap::new(12, 10, n.collect()).unwrap();
    s.material = random_material(&mut rng, (0.02, 1.2), (2.0, 80.0));
    compare("normals facing away", &Batch::single(s).unwrap());
}

#[test]
fn forward_backward_presets_with_constant_and_zero_lobes() {
    // the built-in presets have diffuse (constant) lobes, unused (scale 0) lobes and
    // exponents shared across channels
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 40.0 },
    ] {
        let mut rng = Rng::new(16);
        let scenes = matedit::presets::names()
            .iter()
            .map(|name| {
                let mut s = random_scene(&mut rng, 8, 8, 16, 32, Convention::Equirect, camera);
                s.material = matedit::presets::lookup(name).expect("preset");
                s
            })
            .collect();
        compare(&format!("presets {camera:?}"), &Batch::new(scenes).unwrap());
    }
    // three of them in both conventions
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
        compare(
            &format!("presets {conv:?} {camera:?}"),
            &Batch::new(scenes).unwrap(),
        );
    }
}

#[test]
fn forward_backward_mixed_lobes_and_shared_terms() {
    // lobe 0: constant in channel 0, active elsewhere; lobe 1: the same curves in all
    // channels (one shared evaluation); lobe 2: scale 0 in channel 1 only
    let mut rng = Rng::new(17);
    let mut ctrl = random_material(&mut rng, (0.05, 1.5), (1.0, 40.0)).ctrl;
    use matedit::material::idx;
    for j in 0..6 {
        ctrl[idx(0, 0, 1, j)] = 0.0;
        for k in 1..3 {
            ctrl[idx(k, 1, 0, j)] = ctrl[idx(0, 1, 0, j)];
            ctrl[idx(k, 1, 1, j)] = ctrl[idx(0, 1, 1, j)];
        }
        ctrl[idx(1, 2, 0, j)] = 0.0;
    }
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 70.0 },
    ] {
        let mut s = random_scene(&mut rng, 9, 7, 16, 32, Convention::Equirect, camera);
        s.material = Material::new("mixed", &ctrl).unwrap();
        compare(
            &format!("mixed lobes {camera:?}"),
            &Batch::single(s).unwrap(),
        );
    }
}

#[test]
fn forward_backward_non_unit_normals_and_background() {
    let mut rng = Rng::new(18);
    let mut s = random_scene(
        &mut rng,
        11,
        9,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let mut n = s.normals.normals.clone();
    for (i, v) in n.iter_mut().enumerate() {
        // |n| > 1 lets x exceed 1 (up to the 1 + 1e-5 that NormalMap accepts)
        let scale = [0.5f32, 1.0, 1.000_009][i % 3];
        *v = v.map(|c| c * scale);
    }
    s.normals = NormalMap::new(11, 9, n).unwrap();
    compare("non-unit normals", &Batch::single(s).unwrap());
}
