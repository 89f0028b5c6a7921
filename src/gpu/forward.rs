//! Host side of shaders/forward.wgsl.

use super::buffers::{
    ParamsTable, Readback, dispatch_chunks, output, storage, uniform_chunks, whole, window,
};
use super::layout::{CHUNK_BYTES, Params, Pixel, TEXEL_CHUNK, Texel, WG};
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::prepare::Prepared;
use crate::scene::Image;

/// The lit texels of a scene in uniform chunks: the buffer and the chunk sizes.
pub(super) fn lit_chunks(r: &GpuRenderer, prep: &Prepared) -> (wgpu::Buffer, Vec<u32>) {
    let lit: Vec<Texel> = prep
        .lit
        .iter()
        .map(|&i| Texel::new(&prep.texels[i], &prep.active_lobes))
        .collect();
    uniform_chunks(&r.ctx.device, "lit texels", &lit, TEXEL_CHUNK)
}

/// Encodes a per-pixel pass (forward or backward_normal) over `pixels` against the lit
/// texel chunks; returns the readback slot of each pixel range, in order.
pub(super) fn encode_per_pixel(
    r: &GpuRenderer,
    pass: Pass,
    prep: &Prepared,
    pixels: &[Pixel],
    enc: &mut wgpu::CommandEncoder,
    readback: &mut Readback,
) -> Vec<usize> {
    let device = &r.ctx.device;
    let pipe = r.pipeline(pass);
    let (texels, chunk_sizes) = lit_chunks(r, prep);
    let range = r.max_records(size_of::<Pixel>() as u64);
    let mut slots = Vec::new();
    for part in pixels.chunks(range.max(1)) {
        let n = part.len() as u32;
        let mut table = ParamsTable::default();
        let offsets = table.push_chunks(Params::for_scene(prep), &chunk_sizes, |nt| (n, nt));
        let params = table.upload(device, "params");
        let pix = storage(device, "pixels", part);
        let out_bytes = part.len() as u64 * 16;
        let out = output(device, pass.name(), out_bytes);
        let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(pass.name()),
            layout: &pipe.layout,
            entries: &[
                window(0, &params, size_of::<Params>() as u64),
                window(1, &texels, CHUNK_BYTES),
                whole(2, &pix),
                whole(3, &out),
            ],
        });
        {
            let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some(pass.name()),
                timestamp_writes: None,
            });
            cp.set_pipeline(&pipe.pipeline);
            dispatch_chunks(&mut cp, &bg, &offsets, n.div_ceil(WG as u32));
        }
        slots.push(readback.copy(device, enc, &out, out_bytes));
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
    let device = &r.ctx.device;
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("forward"),
    });
    let mut readback = Readback::default();
    let slots: Vec<Vec<usize>> = preps
        .iter()
        .map(|prep| {
            let pixels: Vec<Pixel> = prep
                .pixels
                .iter()
                .map(|p| Pixel::new(p, [0.0; 3]))
                .collect();
            encode_per_pixel(r, Pass::Forward, prep, &pixels, &mut enc, &mut readback)
        })
        .collect();
    r.ctx.queue.submit([enc.finish()]);
    let data = readback.finish(device)?;
    Ok(preps
        .iter()
        .zip(slots)
        .map(|(prep, s)| prep.image(scatter_pixels(prep, &data, &s)))
        .collect())
}
