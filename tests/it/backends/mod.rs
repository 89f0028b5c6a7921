//! Every backend against the f64 reference, each comparison written once: the fast f32
//! CPU path at every SIMD level this machine has, and the GPU path where an adapter is
//! found (lavapipe in CI). The reference is computed once per scene and every backend is
//! checked against it. A module per idea: seeded random scenes (`seeded`), sharp lobes
//! (`sharp`), analytic values (`analytic`). What belongs to one backend stays with it:
//! threads and SIMD kernels in `cpu_vs_reference`, shader branches, slices and dispatches
//! in `gpu_vs_reference`.
//!
//! Tolerances, each of an output's largest value. CPU: image 1e-5, gradients 1e-4 (its
//! image sums run in f32 over groups of 256 texels and then in f64, so the image's error is
//! a few f32 roundings of the largest terms; gradients add the f32 rounding of x^m1 ln x
//! and m1 x^(m1 - 1) near x = 0). GPU: 1e-4 for both (its f32 error floor is about 1e-5:
//! x^m1 with m1 up to 60 multiplies the ~6e-8 error of x by up to 60, and sums over 8192
//! texels add ~1e-6; 1e-4 leaves 10x room while still catching any wrong term).

mod analytic;
mod seeded;
mod sharp;

use crate::common::{Rng, Truth, gpus, random_scene, upstream_for};
use matedit::cpu::{FastCpu, SimdLevel};
use matedit::prepare::Prepared;
use matedit::{Backend, Batch, Camera, Convention, NormalMap, Scene, Wanted};

/// A backend under test and the tolerances it is held to.
pub(crate) struct Under {
    pub name: String,
    pub backend: Box<dyn Backend>,
    pub image_tol: f64,
    pub grad_tol: f64,
}

/// Every backend there is here: each CPU level, widest first (scalar is always there),
/// then the GPU under each plan it runs ([`gpus`]: on lavapipe its own and a large GPU's;
/// skipped, with a line on stderr, without an adapter unless MATEDIT_REQUIRE_GPU=1). The
/// reference is computed once for all of them.
pub(crate) fn backends(test: &str) -> Vec<Under> {
    let mut out: Vec<Under> = SimdLevel::ALL
        .into_iter()
        .filter_map(FastCpu::with_level)
        .map(|c| Under {
            name: format!("cpu {}", c.level().name()),
            backend: Box::new(c),
            image_tol: 1e-5,
            grad_tol: 1e-4,
        })
        .collect();
    assert!(out.iter().any(|u| u.name == "cpu scalar"));
    for (name, g) in gpus(test) {
        out.push(Under {
            name: name.into(),
            backend: Box::new(g),
            image_tol: 1e-4,
            grad_tol: 1e-4,
        });
    }
    let names: Vec<&str> = out.iter().map(|u| u.name.as_str()).collect();
    eprintln!("{test}: backends {names:?}");
    out
}

/// Forward and backward of every scene of `batch` on every backend against the reference,
/// at each backend's tolerances.
pub(crate) fn compare(test: &str, batch: &Batch) {
    compare_with(test, batch, |u| (u.image_tol, u.grad_tol));
}

/// The same at the tolerances `tol` gives each backend.
pub(crate) fn compare_with(test: &str, batch: &Batch, tol: impl Fn(&Under) -> (f64, f64)) {
    let up = upstream_for(batch, 99);
    let truths: Vec<Truth> = batch
        .scenes()
        .iter()
        .zip(&up)
        .map(|(scene, u)| Truth::new(&Prepared::new(scene), &u.pixels))
        .collect();
    for under in backends(test) {
        let images = under.backend.render(batch.into()).expect("render");
        let grads = under
            .backend
            .backward(batch.into(), &up, Wanted::ALL)
            .expect("backward");
        let (image_tol, grad_tol) = tol(&under);
        for (b, truth) in truths.iter().enumerate() {
            let what = format!("{test} scene {b} {}", under.name);
            truth.check(&what, &images[b].pixels, &grads[b], image_tol, grad_tol);
        }
    }
}

/// A random orthographic scene (seed `seed`, an `hl` x `2 hl` equirect map) seen on a
/// 20 x 20 sphere.
pub(crate) fn sphere_scene(seed: u64, hl: usize) -> Scene {
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
