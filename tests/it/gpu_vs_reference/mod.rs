//! What is the GPU path's own against the f64 CPU reference (lavapipe in CI), a module per
//! idea: the determinism of the backward pass and inputs split over the binding limit
//! (`seeded`), the edges of the shaders' lobe branches (`branches`) and the gather passes
//! split into slices (`slices`). What every backend must do is in `backends`. Here: the
//! comparison of one configured renderer with the reference, and the helpers the modules
//! share.
//!
//! Tolerance: max abs error <= 1e-4 of the largest value of each output (why: backends).

mod branches;
mod seeded;
mod slices;

use crate::common::{Truth, upstream_for};
use matedit::prepare::Prepared;
use matedit::{Backend, Batch, Wanted};

pub(super) const TOL: f64 = 1e-4;

/// Forward and backward of `batch` on `g` against the CPU reference.
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
