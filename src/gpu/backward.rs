//! Host side of shaders/backward_texel.wgsl, reduce_ctrl.wgsl and backward_normal.wgsl.

use super::buffers::{ParamsTable, bind, bind_scenes, output, reduce_slices, storage, tiled};
use super::forward::{bases, batch_params, encode_per_pixel, scatter_pixels};
use super::layout::{Params, Pixel, Texel};
use super::plan::SHARE_BYTES;
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::material::N_PARAMS;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Wanted};

/// Readback slots of one scene's gradients.
/// The GPU records of a scene's texels.
fn texel_records(prep: &Prepared) -> Vec<Texel> {
    prep.texels
        .iter()
        .map(|t| Texel::new(t, &prep.active_lobes))
        .collect()
}

/// Encodes the per-texel gather over the pixels of each scene with a non-zero upstream
/// gradient, the sums over slices, and the reduction of the shares into dLoss/dctrl: the
/// whole batch in one dispatch of each where the planner allows, else scene by scene.
/// Returns per scene the readback slots of d_env (one per texel range) and of d_ctrl.
fn encode_texel(
    r: &GpuRenderer,
    preps: &[Prepared],
    pixels: &[Vec<Pixel>],
    sub: &mut Submission<'_>,
) -> Vec<(Vec<usize>, usize)> {
    let device = &r.ctx.device;
    let active: Vec<Vec<Pixel>> = pixels
        .iter()
        .map(|px| {
            px.iter()
                .filter(|p| p.g[..3].iter().any(|&v| v != 0.0))
                .copied()
                .collect()
        })
        .collect();
    let nt: Vec<usize> = preps.iter().map(|p| p.texels.len()).collect();
    let na: Vec<usize> = active.iter().map(Vec::len).collect();
    let Some(shape) = r.planner.batch(Pass::BackwardTexel, &nt, &na) else {
        return preps
            .iter()
            .zip(&active)
            .map(|(prep, a)| encode_texel_scene(r, prep, a, sub))
            .collect();
    };
    let b = preps.len();
    let texel_base = bases(&nt);
    let total = shape.outer;
    let scenes = batch_params(preps, &shape, &na, &nt, &na);
    let mut table = ParamsTable::default();
    let offset = table.push_scenes(&scenes);
    // a batch's maps have one size: the shares of scene z start at z * nt
    let reduce_offset = table.push(Params {
        n_texels: nt[0] as u32,
        first: 1,
        ..scenes[0]
    });
    let params = table.upload(device, "params");
    let records: Vec<Texel> = preps.iter().flat_map(texel_records).collect();
    let tex = storage(device, "texels", &records);
    let pix = storage(device, "pixels", &active.concat());
    let slices = shape.slices as u64;
    let d_env = output(device, "d_env", total as u64 * 16 * slices);
    let d_share = output(device, "d_share", total as u64 * SHARE_BYTES * slices);
    let d_ctrl = output(device, "d_ctrl", b as u64 * SHARE_BYTES);
    let bg = bind_scenes(
        r,
        Pass::BackwardTexel,
        &params,
        b,
        &[&pix, &tex, &d_env, &d_share],
    );
    let [x, y, _] = shape.groups(nt.iter().copied().max().unwrap_or(0));
    let pairs = nt.iter().zip(&na).map(|(&t, &a)| (t * a) as u64).sum();
    sub.compute(
        Pass::BackwardTexel,
        pairs,
        &[(&bg, offset, [x, y, b as u32])],
    );
    let (env, share) = if shape.slices > 1 {
        (
            reduce_slices(r, sub, scenes[0], &d_env, total, shape.slices),
            reduce_slices(
                r,
                sub,
                scenes[0],
                &d_share,
                total * N_PARAMS / 4,
                shape.slices,
            ),
        )
    } else {
        (d_env, d_share)
    };
    let reduce_bg = bind(r, Pass::ReduceCtrl, &params, &[&share, &d_ctrl]);
    sub.compute(
        Pass::ReduceCtrl,
        0,
        &[(&reduce_bg, reduce_offset, [N_PARAMS as u32, 1, b as u32])],
    );
    (0..b)
        .map(|z| {
            let (at, bytes) = (texel_base[z] as u64 * 16, nt[z] as u64 * 16);
            let env_slot = sub.readback.copy_at(device, &mut sub.enc, &env, at, bytes);
            let at = z as u64 * SHARE_BYTES;
            let ctrl_slot = sub
                .readback
                .copy_at(device, &mut sub.enc, &d_ctrl, at, SHARE_BYTES);
            (vec![env_slot], ctrl_slot)
        })
        .collect()
}

/// [`encode_texel`] for one scene, texel range by texel range.
fn encode_texel_scene(
    r: &GpuRenderer,
    prep: &Prepared,
    active: &[Pixel],
    sub: &mut Submission<'_>,
) -> (Vec<usize>, usize) {
    let device = &r.ctx.device;
    let texels = texel_records(prep);
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
                    slice_stride: nt as u32,
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

/// Gradients per prepared scene for upstream images, in one submission: the per-texel
/// passes (dLoss/dL, dLoss/dctrl) and the per-pixel pass (dLoss/dn) as far as `wanted`
/// asks for them; what it leaves out is zeros.
pub(super) fn backward(
    r: &GpuRenderer,
    preps: &[Prepared],
    upstream: &[Image],
    wanted: Wanted,
) -> Result<Vec<Gradients>> {
    let zeros = |prep: &Prepared| {
        Gradients::zeros(prep.env_height * prep.env_width, prep.width * prep.height)
    };
    if !wanted.any() {
        return Ok(preps.iter().map(zeros).collect());
    }
    let mut sub = Submission::new(r, "backward");
    let pixels: Vec<Vec<Pixel>> = preps
        .iter()
        .zip(upstream)
        .map(|(prep, g)| {
            prep.pixels
                .iter()
                .map(|p| Pixel::new(p, g.pixels[p.index]))
                .collect()
        })
        .collect();
    let texel = (wanted.env || wanted.ctrl).then(|| encode_texel(r, preps, &pixels, &mut sub));
    let normal = wanted
        .normals
        .then(|| encode_per_pixel(r, Pass::BackwardNormal, preps, &pixels, &mut sub));
    let (data, run) = sub.finish()?;
    r.record(run);
    Ok(preps
        .iter()
        .enumerate()
        .map(|(b, prep)| {
            let mut g = zeros(prep);
            if let Some(texel) = &texel {
                let (d_env, d_ctrl) = &texel[b];
                let vals = d_env.iter().flat_map(|&i| data[i].chunks_exact(4));
                for (t, v) in prep.texels.iter().zip(vals) {
                    g.d_env[t.index] = [v[0], v[1], v[2]];
                }
                g.d_ctrl.copy_from_slice(&data[*d_ctrl][..N_PARAMS]);
            }
            if let Some(normal) = &normal {
                g.d_normals = scatter_pixels(prep, &data, &normal[b]);
            }
            g
        })
        .collect())
}
