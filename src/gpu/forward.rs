//! Host side of shaders/forward.wgsl, and the encoding it shares with backward_normal.

use super::buffers::{ParamsTable, bind, output, reduce_slices, storage, tiled};
use super::layout::{Params, Pixel, Texel};
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::prepare::Prepared;
use crate::scene::Image;

/// Encodes a per-pixel pass (forward or backward_normal) over `pixels` against the lit
/// texels, in the planner's ranges and slices, the slices then added by reduce_slices;
/// returns the readback slot of each pixel range, in order.
pub(super) fn encode_per_pixel(
    r: &GpuRenderer,
    pass: Pass,
    prep: &Prepared,
    pixels: &[Pixel],
    sub: &mut Submission<'_>,
) -> Vec<usize> {
    let device = &r.ctx.device;
    let lit: Vec<Texel> = prep
        .lit
        .iter()
        .map(|&i| Texel::new(&prep.texels[i], &prep.active_lobes))
        .collect();
    let shape = r.planner.gather(pass, pixels.len(), lit.len());
    let inner = shape.inner_ranges();
    let texels: Vec<wgpu::Buffer> = inner
        .iter()
        .map(|t| tiled(r, "lit texels", &lit[t.clone()]))
        .collect();
    let base = Params::for_scene(prep);
    let mut slots = Vec::new();
    for o in shape.outer_ranges() {
        let part = &pixels[o];
        let n = part.len();
        let mut table = ParamsTable::default();
        let offsets: Vec<u32> = inner
            .iter()
            .enumerate()
            .map(|(k, t)| {
                table.push(Params {
                    n_pixels: n as u32,
                    n_texels: t.len() as u32,
                    first: (k == 0) as u32,
                    slice_len: shape.slice_len,
                    n_slices: shape.slices,
                    ..base
                })
            })
            .collect();
        let params = table.upload(device, "params");
        let pix = storage(device, "pixels", part);
        let out_bytes = n as u64 * 16;
        let parts = output(device, pass.name(), out_bytes * shape.slices as u64);
        let groups: Vec<wgpu::BindGroup> = texels
            .iter()
            .map(|tex| bind(r, pass, &params, &[tex, &pix, &parts]))
            .collect();
        let dispatches: Vec<_> = groups
            .iter()
            .zip(&offsets)
            .map(|(bg, &off)| (bg, off, shape.groups(n)))
            .collect();
        sub.compute(pass, n as u64 * lit.len() as u64, &dispatches);
        let out = if shape.slices > 1 {
            reduce_slices(r, sub, base, &parts, n, shape.slices)
        } else {
            parts
        };
        slots.push(sub.readback.copy(device, &mut sub.enc, &out, out_bytes));
    }
    slots
}

/// Scatters per-pixel vec4 results (in `prep.pixels` order, read back into `data` at
/// `slots`) into a full row-major image.
pub(super) fn scatter_pixels(prep: &Prepared, data: &[Vec<f32>], slots: &[usize]) -> Vec<[f32; 3]> {
    let mut img = vec![[0.0f32; 3]; prep.width * prep.height];
    let vals = slots.iter().flat_map(|&i| data[i].chunks_exact(4));
    for (px, v) in prep.pixels.iter().zip(vals) {
        img[px.index] = [v[0], v[1], v[2]];
    }
    img
}

/// One image per prepared scene, in one submission.
pub(super) fn forward(r: &GpuRenderer, preps: &[Prepared]) -> Result<Vec<Image>> {
    let mut sub = Submission::new(r, "forward");
    let slots: Vec<Vec<usize>> = preps
        .iter()
        .map(|prep| {
            let pixels: Vec<Pixel> = prep
                .pixels
                .iter()
                .map(|p| Pixel::new(p, [0.0; 3]))
                .collect();
            encode_per_pixel(r, Pass::Forward, prep, &pixels, &mut sub)
        })
        .collect();
    let (data, run) = sub.finish()?;
    r.record(run);
    Ok(preps
        .iter()
        .zip(slots)
        .map(|(prep, s)| prep.image(scatter_pixels(prep, &data, &s)))
        .collect())
}
