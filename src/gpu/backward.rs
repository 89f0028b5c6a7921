//! Host side of shaders/backward_texel.wgsl, reduce_ctrl.wgsl and backward_normal.wgsl.

use super::buffers::{ParamsTable, Slot};
use super::forward::{
    Input, Texels, bases, batch_params, encode_per_pixel, range_of, storage_texels, tiled,
};
use super::layout::{DispatchParams, Pixel, Texel};
use super::pixels::Selection;
use super::plan::SHARE_BYTES;
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::material::N_PARAMS;
use crate::prepare::Prepared;
use crate::scene::{Gradients, Image, Wanted};

/// Readback slots of one scene's dLoss/dL (first and last) and dLoss/dctrl.
type TexelSlots = (Slot, Slot, Slot);

/// Encodes the per-texel gather over the pixels `active[b]` of each scene (those with a
/// non-zero upstream gradient), the sums over slices, and the reduction of the shares
/// into dLoss/dctrl: the whole batch in one dispatch of each where the planner allows,
/// else scene by scene.
fn encode_texel(
    r: &GpuRenderer,
    inputs: &[Input<'_>],
    active: &[Selection<'_>],
    sub: &mut Submission<'_>,
) -> Result<Vec<TexelSlots>> {
    let nt: Vec<usize> = inputs.iter().map(|i| i.prep.texels.len()).collect();
    let na: Vec<usize> = active.iter().map(Selection::len).collect();
    let Some(shape) = r.planner.batch(Pass::BackwardTexel, &nt, &na) else {
        return inputs
            .iter()
            .zip(active)
            .map(|(input, a)| encode_texel_scene(r, input.prep, a, sub))
            .collect();
    };
    let b = inputs.len();
    let texel_base = bases(&nt);
    let total = shape.outer;
    let scenes = batch_params(inputs, &shape, &na, &nt, &na);
    let mut table = ParamsTable::default();
    // also reduce_ctrl's: the shares of scene z are its n_texels from its texel_base
    let offset = table.push_scenes(&scenes);
    let params = sub.params(&table);
    let preps: Vec<&Prepared> = inputs.iter().map(|i| i.prep).collect();
    let tex = storage_texels(sub, "texels", &preps, Texels::All)?;
    let n_active: usize = na.iter().sum();
    let bytes = (n_active * size_of::<Pixel>()) as u64;
    let pix = sub.upload_pixels("pixels", wgpu::BufferUsages::STORAGE, active, bytes)?;
    let slices = shape.slices as u64;
    let d_env = sub.output("d_env", total as u64 * 16 * slices);
    let d_share = sub.output("d_share", total as u64 * SHARE_BYTES * slices);
    let d_ctrl = sub.output("d_ctrl", b as u64 * SHARE_BYTES);
    let bg = sub.bind(
        Pass::BackwardTexel,
        &params,
        b,
        &[
            (&pix, 0, None),
            (&tex, 0, None),
            (&d_env, 0, None),
            (&d_share, 0, None),
        ],
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
            sub.reduce_slices(scenes[0], &d_env, total, shape.slices),
            sub.reduce_slices(scenes[0], &d_share, total * N_PARAMS / 4, shape.slices),
        )
    } else {
        (d_env, d_share)
    };
    let reduce_bg = sub.bind(
        Pass::ReduceCtrl,
        &params,
        b,
        &[(&share, 0, None), (&d_ctrl, 0, None)],
    );
    sub.compute(
        Pass::ReduceCtrl,
        0,
        &[(&reduce_bg, offset, [N_PARAMS as u32, 1, b as u32])],
    );
    let env_slots: Vec<Slot> = (0..b)
        .map(|z| sub.read(&env, texel_base[z] as u64 * 16, nt[z] as u64 * 16))
        .collect();
    Ok(env_slots
        .into_iter()
        .enumerate()
        .map(|(z, e)| (e, e, sub.read(&d_ctrl, z as u64 * SHARE_BYTES, SHARE_BYTES)))
        .collect())
}

/// [`encode_texel`] for one scene, texel range by texel range.
fn encode_texel_scene(
    r: &GpuRenderer,
    prep: &Prepared,
    active: &Selection<'_>,
    sub: &mut Submission<'_>,
) -> Result<TexelSlots> {
    let n_texels = prep.texels.len();
    let n_active = active.len();
    let shape = r.planner.gather(Pass::BackwardTexel, n_texels, n_active);
    let inner = shape.inner_ranges();
    let (pix, pix_at) = tiled::<Pixel>(r, sub, n_active, &inner, |sub, usage, bytes| {
        sub.upload_pixels("pixels", usage, std::slice::from_ref(active), bytes)
    })?;
    let tex = storage_texels(sub, "texels", &[prep], Texels::All)?;
    // with no texels no range reduces into it
    let d_ctrl = sub.zeroed("d_ctrl", SHARE_BYTES);
    let base = DispatchParams::for_scene(prep);
    let mut env_slots = Vec::new();
    for (ri, o) in shape.outer_ranges().into_iter().enumerate() {
        let nt = o.len();
        let mut table = ParamsTable::default();
        let offsets: Vec<u32> = inner
            .iter()
            .enumerate()
            .map(|(k, q)| {
                table.push(DispatchParams {
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
        let reduce_offset = table.push(DispatchParams {
            n_pixels: 0,
            n_texels: nt as u32,
            first: (ri == 0) as u32,
            ..base
        });
        let params = sub.params(&table);
        let (tex_at, tex_size) = range_of::<Texel>(&o);
        let env_bytes = nt as u64 * 16;
        let slices = shape.slices as u64;
        let d_env = sub.output("d_env", env_bytes * slices);
        let d_share = sub.output("d_share", nt as u64 * SHARE_BYTES * slices);
        let groups: Vec<wgpu::BindGroup> = pix_at
            .iter()
            .map(|&(at, size)| {
                sub.bind(
                    Pass::BackwardTexel,
                    &params,
                    1,
                    &[
                        (&pix, at, size),
                        (&tex, tex_at, tex_size),
                        (&d_env, 0, None),
                        (&d_share, 0, None),
                    ],
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
            nt as u64 * n_active as u64,
            &dispatches,
        );
        let (env, share) = if shape.slices > 1 {
            (
                sub.reduce_slices(base, &d_env, nt, shape.slices),
                sub.reduce_slices(base, &d_share, nt * N_PARAMS / 4, shape.slices),
            )
        } else {
            (d_env, d_share)
        };
        let reduce_bg = sub.bind(
            Pass::ReduceCtrl,
            &params,
            1,
            &[(&share, 0, None), (&d_ctrl, 0, None)],
        );
        sub.compute(
            Pass::ReduceCtrl,
            0,
            &[(&reduce_bg, reduce_offset, [N_PARAMS as u32, 1, 1])],
        );
        env_slots.push(sub.read(&env, 0, env_bytes));
    }
    let ctrl_slot = sub.read(&d_ctrl, 0, SHARE_BYTES);
    Ok(match (env_slots.first(), env_slots.last()) {
        (Some(&a), Some(&b)) => (a, b, ctrl_slot),
        // no texels: an empty slot
        _ => {
            let s = sub.read(&d_ctrl, 0, 0);
            (s, s, ctrl_slot)
        }
    })
}

/// Gradients per scene for upstream images, in one submission: the per-texel passes
/// (dLoss/dL, dLoss/dctrl) and the per-pixel pass (dLoss/dn) as far as `wanted` asks for
/// them; what it leaves out is zeros.
pub(super) fn backward(
    r: &GpuRenderer,
    inputs: &[Input<'_>],
    upstream: &[Image],
    wanted: Wanted,
) -> Result<Vec<Gradients>> {
    let zeros = |prep: &Prepared| {
        Gradients::zeros(prep.env_height * prep.env_width, prep.width * prep.height)
    };
    if !wanted.any() {
        return Ok(inputs.iter().map(|i| zeros(i.prep)).collect());
    }
    let texel_pass = wanted.env || wanted.ctrl;
    let select = |active_only: bool| -> Vec<Selection<'_>> {
        inputs
            .iter()
            .zip(upstream)
            .map(|(i, u)| Selection::new(i.source, Some(u), active_only))
            .collect()
    };
    let active = if texel_pass { select(true) } else { Vec::new() };
    let all = if wanted.normals {
        select(false)
    } else {
        Vec::new()
    };
    let mut sub = Submission::new(r, "backward")?;
    let texel = if texel_pass {
        Some(encode_texel(r, inputs, &active, &mut sub)?)
    } else {
        None
    };
    let normal = if wanted.normals {
        Some(encode_per_pixel(
            r,
            Pass::BackwardNormal,
            inputs,
            &all,
            &mut sub,
        )?)
    } else {
        None
    };
    let (out, run) = sub.finish()?;
    let grads = inputs
        .iter()
        .enumerate()
        .map(|(b, input)| {
            let prep = input.prep;
            let mut g = zeros(prep);
            if let Some(texel) = &texel {
                let (first, last, d_ctrl) = texel[b];
                let vals = out.span(first, last).chunks_exact(4);
                for (t, v) in prep.texels.iter().zip(vals) {
                    g.d_env[t.index] = [v[0], v[1], v[2]];
                }
                g.d_ctrl.copy_from_slice(&out.get(d_ctrl)[..N_PARAMS]);
            }
            if let Some(normal) = &normal {
                let (first, last) = normal[b];
                g.d_normals = all[b].scatter(out.span(first, last), prep.width, prep.height);
            }
            g
        })
        .collect();
    drop(out);
    r.record(run);
    Ok(grads)
}
