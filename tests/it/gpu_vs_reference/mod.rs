//! The GPU path against the f64 CPU reference (lavapipe in CI), a module per idea: seeded
//! random scenes and the determinism of the backward pass (`seeded`), analytic values on
//! both backends (`analytic`), sharp lobes (`sharp`), the edges of the shaders' lobe
//! branches (`branches`) and the gather passes split into slices (`slices`). Here: the
//! comparison with the reference and the helpers the modules share.
//!
//! Tolerance: max abs error <= 1e-4 of the largest value of each output. The f32 error
//! floor is about 1e-5 of the largest value (x^m1 with m1 up to 60 multiplies the ~6e-8
//! error of x by up to 60, and sums over 8192 texels add ~1e-6), so 1e-4 leaves 10x room
//! while still catching any wrong term. Sharp lobes (m1 up to 1e4) stay within it only
//! because x and ln x keep their digits near x = 1 (`lobe_x`; docs/CONVENTIONS.md).

mod analytic;
mod branches;
mod seeded;
mod sharp;
mod slices;

use crate::common::{Rng, Truth, gpu, random_scene, upstream_for};
use matedit::prepare::Prepared;
use matedit::{Backend, Batch, Camera, Convention, NormalMap, Scene, Wanted};

pub(super) const TOL: f64 = 1e-4;

/// Forward and backward of `batch` on the GPU against the CPU reference.
pub(super) fn compare(test: &str, batch: &Batch) {
    let Some(g) = gpu(test) else { return };
    compare_on(&g, test, batch);
}

pub(super) fn compare_on(g: &matedit::gpu::GpuRenderer, test: &str, batch: &Batch) {
    let images = g.render(batch.into()).expect("gpu render");
    let up = upstream_for(batch, 99);
    let grads = g
        .backward(batch.into(), &up, Wanted::ALL)
        .expect("gpu backward");
    for (b, scene) in batch.scenes().iter().enumerate() {
        let truth = Truth::new(&Prepared::new(scene), &up[b].pixels);
        let what = format!("{test} scene {b}");
        truth.check(&what, &images[b].pixels, &grads[b], TOL, TOL);
    }
}

/// A random orthographic scene (seed `seed`, an `hl` x `2 hl` equirect map) seen on a
/// 20 x 20 sphere.
pub(super) fn sphere_scene(seed: u64, hl: usize) -> Scene {
    let mut rng = Rng::new(seed);
    let mut s = random_scene(
        &mut rng,
        4,
        4,
        hl,
        2 * hl,
        Convention::Equirect,
        Camera::Orthographic,
    );
    s.normals = NormalMap::sphere(20);
    s
}

/// Every output of a forward and a backward call, as bits.
pub(super) fn output_bits(g: &matedit::gpu::GpuRenderer, batch: &Batch) -> Vec<u32> {
    let up = upstream_for(batch, 5);
    let images = g.render(batch.into()).unwrap();
    let grads = g.backward(batch.into(), &up, Wanted::ALL).unwrap();
    images
        .iter()
        .flat_map(|i| i.pixels.iter().flatten())
        .chain(grads.iter().flat_map(|v| {
            v.d_env
                .iter()
                .flatten()
                .chain(v.d_normals.iter().flatten())
                .chain(v.d_ctrl.iter())
        }))
        .map(|x| x.to_bits())
        .collect()
}
