//! Host side of shaders/forward.wgsl, and the encoding it shares with backward_normal.

use super::buffers::{ParamsTable, bind, bind_scenes, output, reduce_slices, storage, tiled};
use super::layout::{Params, Pixel, Texel};
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::prepare::Prepared;
use crate::scene::Image;

/// The lit texels of a scene as GPU records.
fn lit_texels(prep: &Prepared) -> Vec<Texel> {
    prep.lit
        .iter()
        .map(|&i| Texel::new(&prep.texels[i], &prep.active_lobes))
        .collect()
}

/// Per scene, the start of each scene's records when `counts` records are concatenated.
pub(super) fn bases(counts: &[usize]) -> Vec<usize> {
    counts
        .iter()
        .scan(0, |acc, &n| {
            let b = *acc;
            *acc += n;
            Some(b)
        })
        .collect()
}

/// Per scene of a batched dispatch of `shape`, its [`Params`]: `np[z]` pixels and `nt[z]`
/// texels at their starts in the concatenated buffers, its slices of `inner[z]` records
/// (the looped-over ones) as long as they would be were it alone.
pub(super) fn batch_params(
    preps: &[Prepared],
    shape: &super::Shape,
    np: &[usize],
    nt: &[usize],
    inner: &[usize],
) -> Vec<Params> {
    let (pixel_base, texel_base) = (bases(np), bases(nt));
    preps
        .iter()
        .enumerate()
        .map(|(z, prep)| Params {
            n_pixels: np[z] as u32,
            n_texels: nt[z] as u32,
            first: 1,
            slice_len: shape.slice_len_of(inner[z]),
            n_slices: shape.slices,
            pixel_base: pixel_base[z] as u32,
            texel_base: texel_base[z] as u32,
            slice_stride: shape.outer as u32,
            ..Params::for_scene(prep)
        })
        .collect()
}

/// Encodes a per-pixel pass (forward or backward_normal) over `pixels[b]` of each scene
/// `preps[b]` against its lit texels: the whole batch in one dispatch where the planner
/// allows ([`super::Planner::batch`]), else scene by scene in the planner's ranges and
/// slices; the slices then added by reduce_slices. Returns, per scene, the readback slot
/// of each pixel range, in order.
pub(super) fn encode_per_pixel(
    r: &GpuRenderer,
    pass: Pass,
    preps: &[Prepared],
    pixels: &[Vec<Pixel>],
    sub: &mut Submission<'_>,
) -> Vec<Vec<usize>> {
    let lit: Vec<Vec<Texel>> = preps.iter().map(lit_texels).collect();
    let np: Vec<usize> = pixels.iter().map(Vec::len).collect();
    let nl: Vec<usize> = lit.iter().map(Vec::len).collect();
    let Some(shape) = r.planner.batch(pass, &np, &nl) else {
        return preps
            .iter()
            .zip(pixels)
            .zip(&lit)
            .map(|((prep, px), lit)| encode_scene(r, pass, prep, px, lit, sub))
            .collect();
    };
    let device = &r.ctx.device;
    let pixel_base = bases(&np);
    let total = shape.outer;
    let scenes = batch_params(preps, &shape, &np, &nl, &nl);
    let mut table = ParamsTable::default();
    let offset = table.push_scenes(&scenes);
    let params = table.upload(device, "params");
    let tex = storage(device, "lit texels", &lit.concat());
    let pix = storage(device, "pixels", &pixels.concat());
    let parts = output(
        device,
        pass.name(),
        (total * 16) as u64 * shape.slices as u64,
    );
    let bg = bind_scenes(r, pass, &params, preps.len(), &[&tex, &pix, &parts]);
    let max_np = np.iter().copied().max().unwrap_or(0);
    let [x, y, _] = shape.groups(max_np);
    let pairs = np.iter().zip(&nl).map(|(&p, &l)| (p * l) as u64).sum();
    sub.compute(pass, pairs, &[(&bg, offset, [x, y, preps.len() as u32])]);
    let out = if shape.slices > 1 {
        reduce_slices(r, sub, scenes[0], &parts, total, shape.slices)
    } else {
        parts
    };
    (0..preps.len())
        .map(|b| {
            let (at, bytes) = (pixel_base[b] as u64 * 16, np[b] as u64 * 16);
            vec![sub.readback.copy_at(device, &mut sub.enc, &out, at, bytes)]
        })
        .collect()
}

/// [`encode_per_pixel`] for one scene, range by range.
fn encode_scene(
    r: &GpuRenderer,
    pass: Pass,
    prep: &Prepared,
    pixels: &[Pixel],
    lit: &[Texel],
    sub: &mut Submission<'_>,
) -> Vec<usize> {
    let device = &r.ctx.device;
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
                    slice_stride: n as u32,
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
    let pixels: Vec<Vec<Pixel>> = preps
        .iter()
        .map(|prep| {
            prep.pixels
                .iter()
                .map(|p| Pixel::new(p, [0.0; 3]))
                .collect()
        })
        .collect();
    let slots = encode_per_pixel(r, Pass::Forward, preps, &pixels, &mut sub);
    let (data, run) = sub.finish()?;
    r.record(run);
    Ok(preps
        .iter()
        .zip(slots)
        .map(|(prep, s)| prep.image(scatter_pixels(prep, &data, &s)))
        .collect())
}
