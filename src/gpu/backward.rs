//! Host side of shaders/backward_texel.wgsl, reduce_ctrl.wgsl and backward_normal.wgsl.

use super::buffers::{ParamsTable, bind, output, reduce_slices, storage, tiled};
use super::forward::{encode_per_pixel, scatter_pixels};
use super::layout::{Params, Pixel, Texel};
use super::plan::SHARE_BYTES;
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::material::N_PARAMS;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image};

/// Readback slots of one scene's gradients.
struct Slots {
    d_env: Vec<usize>,
    d_ctrl: usize,
    d_normals: Vec<usize>,
}

/// Encodes the per-texel gather over the pixels with a non-zero upstream gradient (in the
/// planner's ranges and slices), the sums over slices, and the reduction of the shares into
/// dLoss/dctrl, texel range by texel range.
fn encode_texel(
    r: &GpuRenderer,
    prep: &Prepared,
    pixels: &[Pixel],
    sub: &mut Submission<'_>,
) -> (Vec<usize>, usize) {
    let device = &r.ctx.device;
    let active: Vec<Pixel> = pixels
        .iter()
        .filter(|p| p.g[..3].iter().any(|&v| v != 0.0))
        .copied()
        .collect();
    let texels: Vec<Texel> = prep
        .texels
        .iter()
        .map(|t| Texel::new(t, &prep.active_lobes))
        .collect();
    let shape = r
        .planner
        .gather(Pass::BackwardTexel, texels.len(), active.len());
    let inner = shape.inner_ranges();
    let pix: Vec<wgpu::Buffer> = inner
        .iter()
        .map(|q| tiled(r, "pixels", &active[q.clone()]))
        .collect();
    let d_ctrl = output(device, "d_ctrl", SHARE_BYTES);
    let base = Params::for_scene(prep);
    let mut d_env_slots = Vec::new();
    for (ri, o) in shape.outer_ranges().into_iter().enumerate() {
        let part = &texels[o];
        let nt = part.len();
        let mut table = ParamsTable::default();
        let offsets: Vec<u32> = inner
            .iter()
            .enumerate()
            .map(|(k, q)| {
                table.push(Params {
                    n_pixels: q.len() as u32,
                    n_texels: nt as u32,
                    first: (k == 0) as u32,
                    slice_len: shape.slice_len,
                    n_slices: shape.slices,
                    ..base
                })
            })
            .collect();
        let reduce_offset = table.push(Params {
            n_pixels: 0,
            n_texels: nt as u32,
            first: (ri == 0) as u32,
            ..base
        });
        let params = table.upload(device, "params");
        let tex = storage(device, "texels", part);
        let env_bytes = nt as u64 * 16;
        let slices = shape.slices as u64;
        let d_env = output(device, "d_env", env_bytes * slices);
        let d_share = output(device, "d_share", nt as u64 * SHARE_BYTES * slices);
        let groups: Vec<wgpu::BindGroup> = pix
            .iter()
            .map(|p| {
                bind(
                    r,
                    Pass::BackwardTexel,
                    &params,
                    &[p, &tex, &d_env, &d_share],
                )
            })
            .collect();
        let dispatches: Vec<_> = groups
            .iter()
            .zip(&offsets)
            .map(|(bg, &off)| (bg, off, shape.groups(nt)))
            .collect();
        sub.compute(
            Pass::BackwardTexel,
            nt as u64 * active.len() as u64,
            &dispatches,
        );
        let (env, share) = if shape.slices > 1 {
            (
                reduce_slices(r, sub, base, &d_env, nt, shape.slices),
                reduce_slices(r, sub, base, &d_share, nt * N_PARAMS / 4, shape.slices),
            )
        } else {
            (d_env, d_share)
        };
        let reduce_bg = bind(r, Pass::ReduceCtrl, &params, &[&share, &d_ctrl]);
        sub.compute(
            Pass::ReduceCtrl,
            0,
            &[(&reduce_bg, reduce_offset, [N_PARAMS as u32, 1, 1])],
        );
        d_env_slots.push(sub.readback.copy(device, &mut sub.enc, &env, env_bytes));
    }
    let ctrl_slot = sub
        .readback
        .copy(device, &mut sub.enc, &d_ctrl, SHARE_BYTES);
    (d_env_slots, ctrl_slot)
}

/// Gradients per prepared scene for upstream images, in one submission.
pub(super) fn backward(
    r: &GpuRenderer,
    preps: &[Prepared],
    upstream: &[Image],
) -> Result<Vec<Gradients>> {
    let mut sub = Submission::new(r, "backward");
    let slots: Vec<Slots> = preps
        .iter()
        .zip(upstream)
        .map(|(prep, g)| {
            let pixels: Vec<Pixel> = prep
                .pixels
                .iter()
                .map(|p| Pixel::new(p, g.pixels[p.index]))
                .collect();
            let (d_env, d_ctrl) = encode_texel(r, prep, &pixels, &mut sub);
            let d_normals = encode_per_pixel(r, Pass::BackwardNormal, prep, &pixels, &mut sub);
            Slots {
                d_env,
                d_ctrl,
                d_normals,
            }
        })
        .collect();
    let (data, run) = sub.finish()?;
    r.record(run);
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
