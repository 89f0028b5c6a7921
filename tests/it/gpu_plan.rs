//! The GPU dispatch plan (src/gpu/plan.rs) without a GPU: the shape a large GPU gets, the
//! shape a software adapter gets, and the caps.

use matedit::gpu::layout::{TEXEL_CHUNK, WG};
use matedit::gpu::plan::LARGE_GPU_RESIDENT;
use matedit::gpu::{Pass, Planner, Tiles};

/// A 128 x 128 sphere (12892 foreground pixels) against a 64 x 128 map, every texel lit.
const PIXELS: usize = 12892;
const TEXELS: usize = 8192;

fn invocations(d: &[matedit::gpu::Dispatch], pass: Pass) -> Vec<u64> {
    d.iter()
        .filter(|d| d.pass == pass)
        .map(|d| d.invocations())
        .collect()
}

#[test]
fn a_large_gpu_gets_a_resident_load_in_every_gather() {
    let p = Planner::large_gpu();
    let fwd = p.forward(PIXELS, TEXELS);
    let bwd = p.backward(PIXELS, TEXELS, TEXELS, PIXELS);
    for (d, pass) in [
        (&fwd, Pass::Forward),
        (&bwd, Pass::BackwardTexel),
        (&bwd, Pass::BackwardNormal),
    ] {
        let inv = invocations(d, pass);
        assert_eq!(inv.len(), 1, "{pass:?}: one dispatch: {d:?}");
        assert!(inv[0] >= LARGE_GPU_RESIDENT, "{pass:?}: {inv:?}");
    }
    // the slices are summed afterwards: once per per-pixel pass, twice in the backward
    // texel pass (d_env and the shares)
    assert_eq!(invocations(&fwd, Pass::ReduceSlices).len(), 1);
    assert_eq!(invocations(&bwd, Pass::ReduceSlices).len(), 3);
}

#[test]
fn a_software_adapter_gets_one_slice_and_uniform_chunks() {
    let p = Planner::for_limits(&wgpu::Limits::default(), true);
    assert_eq!(p.tiles, Tiles::Uniform);
    let fwd = p.forward(PIXELS, TEXELS);
    assert_eq!(fwd.len(), TEXELS.div_ceil(TEXEL_CHUNK));
    assert!(
        fwd.iter()
            .all(|d| d.workgroups == [PIXELS.div_ceil(WG) as u32, 1, 1])
    );
}

#[test]
fn slices_stay_within_the_caps() {
    let mut p = Planner::large_gpu().with_slices(50);
    // 64 pixels' partial sums of 16 bytes per binding: at most 3 slices of a workgroup
    p.max_binding = 64 * 48;
    let s = p.gather(Pass::Forward, PIXELS, TEXELS);
    assert_eq!(s.slices, 3);
    assert_eq!(s.outer_range, WG);
    // the shares (432 bytes) of one workgroup of texels do not fit twice: 1 slice
    assert_eq!(p.gather(Pass::BackwardTexel, TEXELS, PIXELS).slices, 1);
    // workgroups per dimension bound the slices and the ranges
    let mut p = Planner::large_gpu().with_slices(50);
    p.max_groups = 4;
    let s = p.gather(Pass::Forward, PIXELS, TEXELS);
    assert_eq!((s.slices, s.outer_range), (4, 4 * WG));
    assert_eq!(p.reduce_groups(5 * WG * 4), [4, 5, 1]);
}

#[test]
fn slices_never_come_out_empty() {
    // forced slices: as many as asked, where the records allow
    let p = Planner::large_gpu();
    for inner in [0, 1, 39, 40, 41, 100, 130] {
        let s = p.clone().with_slices(40).gather(Pass::Forward, 64, inner);
        assert!(s.slices >= 1 && s.slices <= 40, "{inner}: {s:?}");
        assert!(
            (s.slices as usize - 1) * (s.slice_len as usize) < inner.max(1),
            "{inner}: an empty slice: {s:?}"
        );
    }
}
