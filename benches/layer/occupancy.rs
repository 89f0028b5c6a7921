//! The occupancy table: the dispatch shapes of every pass against a large GPU.

use matedit::gpu::layout::WG;
use matedit::gpu::plan::LARGE_GPU_RESIDENT;
use matedit::gpu::{Dispatch, Pass, Planner, Tiles};
use matedit::prepare::Prepared;
use matedit::{Camera, EnvMap, Scene};

use crate::common::upstream_for;
use crate::inputs::normals_of;

/// The occupancy table: for each scene, call and pass, the dispatches and the largest's
/// workgroups and invocations, before (fa34885: a dispatch per uniform chunk, one slice;
/// also what a software adapter gets now) and after (the plan on a large GPU), against a
/// large GPU's resident invocations.
pub fn occupancy(scenes: &[String], env: &EnvMap, material: &matedit::Material) {
    let after = Planner::large_gpu();
    let mut before = Planner::large_gpu().with_slices(1);
    before.tiles = Tiles::Uniform;
    println!(
        "\noccupancy against a large GPU (assumed: an H100 SXM, 132 SMs x 2048 resident \
         invocations = {LARGE_GPU_RESIDENT}; workgroups of {WG} invocations)"
    );
    println!(
        "{:<10} {:<4} {:<15} {:<6} {:>10} {:>15} {:>12} {:>9}",
        "scene", "call", "pass", "shape", "dispatches", "workgroups", "invocations", "resident"
    );
    for name in scenes {
        let normals = normals_of(name);
        let up = upstream_for(normals.width, normals.height);
        let scene = Scene {
            normals,
            env: env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        };
        let prep = Prepared::new(&scene);
        let (np, nl, nt) = (prep.pixels.len(), prep.lit.len(), prep.texels.len());
        let active = prep
            .pixels
            .iter()
            .filter(|p| up.pixels[p.index].iter().any(|&v| v != 0.0))
            .count();
        for (call, plan) in [
            ("fwd", (&before.forward(np, nl), &after.forward(np, nl))),
            (
                "bwd",
                (
                    &before.backward(np, nl, nt, active),
                    &after.backward(np, nl, nt, active),
                ),
            ),
        ] {
            let mut passes: Vec<Pass> = Vec::new();
            for d in plan.0.iter().chain(plan.1) {
                if !passes.contains(&d.pass) {
                    passes.push(d.pass);
                }
            }
            for pass in passes {
                for (shape, ds) in [("before", plan.0), ("after", plan.1)] {
                    let ds: Vec<&Dispatch> = ds.iter().filter(|d| d.pass == pass).collect();
                    let Some(big) = ds.iter().max_by_key(|d| d.invocations()) else {
                        continue;
                    };
                    let [x, y, z] = big.workgroups;
                    println!(
                        "{:<10} {:<4} {:<15} {:<6} {:>10} {:>15} {:>12} {:>8.1}%",
                        name,
                        call,
                        pass.name(),
                        shape,
                        ds.len(),
                        format!("{x} x {y} x {z}"),
                        big.invocations(),
                        100.0 * big.invocations() as f64 / LARGE_GPU_RESIDENT as f64
                    );
                }
            }
        }
    }
}
