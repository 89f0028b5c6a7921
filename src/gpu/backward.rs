//! Host side of shaders/backward_texel.wgsl, reduce_ctrl.wgsl and backward_normal.wgsl.

use super::buffers::{
    ParamsTable, Readback, dispatch_chunks, output, storage, uniform_chunks, whole, window,
};
use super::forward::{encode_per_pixel, scatter_pixels};
use super::layout::{CHUNK_BYTES, PIXEL_CHUNK, Params, Pixel, Texel, WG};
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::material::N_PARAMS;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image};

/// Bytes of one texel's shares of dLoss/dctrl.
const SHARE_BYTES: u64 = (N_PARAMS * 4) as u64;

/// Readback slots of one scene's gradients.
struct Slots {
    d_env: Vec<usize>,
    d_ctrl: usize,
    d_normals: Vec<usize>,
}

/// Encodes the per-texel gather over the pixels with a non-zero upstream gradient, and the
/// reduction of the shares into dLoss/dctrl, texel range by texel range.
fn encode_texel(
    r: &GpuRenderer,
    prep: &Prepared,
    pixels: &[Pixel],
    enc: &mut wgpu::CommandEncoder,
    readback: &mut Readback,
) -> (Vec<usize>, usize) {
    let device = &r.ctx.device;
    let gather = r.pipeline(Pass::BackwardTexel);
    let reduce = r.pipeline(Pass::ReduceCtrl);
    let active: Vec<Pixel> = pixels
        .iter()
        .filter(|p| p.g[..3].iter().any(|&v| v != 0.0))
        .copied()
        .collect();
    let (pix, chunk_sizes) = uniform_chunks(device, "pixel chunks", &active, PIXEL_CHUNK);
    let d_ctrl = output(device, "d_ctrl", SHARE_BYTES);
    let texels: Vec<Texel> = prep
        .texels
        .iter()
        .map(|t| Texel::new(t, &prep.active_lobes))
        .collect();
    let range = r.max_records(SHARE_BYTES);
    let base = Params::for_scene(prep);
    let mut d_env_slots = Vec::new();
    for (ri, part) in texels.chunks(range).enumerate() {
        let nt = part.len() as u32;
        let mut table = ParamsTable::default();
        let offsets = table.push_chunks(base, &chunk_sizes, |np| (np, nt));
        let reduce_offset = table.push(Params {
            n_pixels: 0,
            n_texels: nt,
            first: (ri == 0) as u32,
            ..base
        });
        let params = table.upload(device, "params");
        let tex = storage(device, "texels", part);
        let env_bytes = part.len() as u64 * 16;
        let d_env = output(device, "d_env", env_bytes);
        let d_share = output(device, "d_share", part.len() as u64 * SHARE_BYTES);
        let bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("backward_texel"),
            layout: &gather.layout,
            entries: &[
                window(0, &params, size_of::<Params>() as u64),
                window(1, &pix, CHUNK_BYTES),
                whole(2, &tex),
                whole(3, &d_env),
                whole(4, &d_share),
            ],
        });
        let reduce_bg = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("reduce_ctrl"),
            layout: &reduce.layout,
            entries: &[
                window(0, &params, size_of::<Params>() as u64),
                whole(1, &d_share),
                whole(2, &d_ctrl),
            ],
        });
        {
            let mut cp = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("backward_texel"),
                timestamp_writes: None,
            });
            cp.set_pipeline(&gather.pipeline);
            dispatch_chunks(&mut cp, &bg, &offsets, nt.div_ceil(WG as u32));
            cp.set_pipeline(&reduce.pipeline);
            cp.set_bind_group(0, &reduce_bg, &[reduce_offset]);
            cp.dispatch_workgroups(N_PARAMS as u32, 1, 1);
        }
        d_env_slots.push(readback.copy(device, enc, &d_env, env_bytes));
    }
    let ctrl_slot = readback.copy(device, enc, &d_ctrl, SHARE_BYTES);
    (d_env_slots, ctrl_slot)
}

/// Gradients per prepared scene for upstream images, in one submission.
pub(super) fn backward(
    r: &GpuRenderer,
    preps: &[Prepared],
    upstream: &[Image],
) -> Result<Vec<Gradients>> {
    let device = &r.ctx.device;
    let mut enc = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
        label: Some("backward"),
    });
    let mut readback = Readback::default();
    let slots: Vec<Slots> = preps
        .iter()
        .zip(upstream)
        .map(|(prep, g)| {
            let pixels: Vec<Pixel> = prep
                .pixels
                .iter()
                .map(|p| Pixel::new(p, g.pixels[p.index]))
                .collect();
            let (d_env, d_ctrl) = encode_texel(r, prep, &pixels, &mut enc, &mut readback);
            let d_normals = encode_per_pixel(
                r,
                Pass::BackwardNormal,
                prep,
                &pixels,
                &mut enc,
                &mut readback,
            );
            Slots {
                d_env,
                d_ctrl,
                d_normals,
            }
        })
        .collect();
    r.ctx.queue.submit([enc.finish()]);
    let data = readback.finish(device)?;
    Ok(preps
        .iter()
        .zip(slots)
        .map(|(prep, s)| {
            let mut d_env = vec![[0.0f32; 3]; prep.env_height * prep.env_width];
            let vals = s.d_env.iter().flat_map(|&i| data[i].chunks_exact(4));
            for (t, v) in prep.texels.iter().zip(vals) {
                d_env[t.index] = [v[0], v[1], v[2]];
            }
            let mut d_ctrl = [0.0f32; N_PARAMS];
            d_ctrl.copy_from_slice(&data[s.d_ctrl][..N_PARAMS]);
            Gradients {
                d_env,
                d_normals: scatter_pixels(prep, &data, &s.d_normals),
                d_ctrl,
            }
        })
        .collect())
}
