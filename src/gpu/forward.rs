//! Host side of shaders/forward.wgsl, and the encoding it shares with backward_normal.

use rayon::prelude::*;

use super::buffers::{MIN_BYTES, ParamsTable, Slot};
use super::layout::{CHUNK_BYTES, DispatchParams, Pixel, Texel};
use super::pipelines::Tiles;
use super::pixels::{PixelSource, Selection};
use super::submission::Submission;
use super::{GpuRenderer, Pass};
use crate::error::Result;
use crate::prepare::Prepared;
use crate::scene::Image;

/// One scene of a call: its prepared lights, material and camera, and where its pixels
/// come from.
pub struct Input<'a> {
    /// The scene's lights, material and camera (its pixel list is used only by
    /// [`PixelSource::Listed`]).
    pub prep: &'a Prepared,
    /// Its pixels.
    pub source: PixelSource<'a>,
}

/// Which of a scene's texels a pass reads: the lit ones (the per-pixel passes) or all
/// (backward_texel, whose dLoss/dL covers every texel).
#[derive(Clone, Copy)]
pub(super) enum Texels {
    Lit,
    All,
}

impl Texels {
    /// How many of `prep`'s texels.
    pub(super) fn count(self, prep: &Prepared) -> usize {
        match self {
            Texels::Lit => prep.lit.len(),
            Texels::All => prep.texels.len(),
        }
    }

    /// `prep`'s `k`-th such texel as a GPU record.
    fn record(self, prep: &Prepared, k: usize) -> Texel {
        let i = match self {
            Texels::Lit => prep.lit[k],
            Texels::All => k,
        };
        Texel::new(&prep.texels[i], &prep.active_lobes)
    }
}

/// Texel records per task of [`upload_texels`].
const TEXEL_BLOCK: usize = 1024;

/// A buffer for `usage` of `bytes` (at least the records') holding the records of `which`
/// texels of each of `preps`, one scene after another, computed on all cores straight
/// into the staging buffer (the continuous light's corrections hand the GPU hundreds of
/// scenes of thousands of lights each, 256 bytes a record; docs/gpu.md).
pub(super) fn upload_texels(
    sub: &mut Submission<'_>,
    label: &'static str,
    usage: wgpu::BufferUsages,
    bytes: u64,
    preps: &[&Prepared],
    which: Texels,
) -> Result<wgpu::Buffer> {
    const BYTES: usize = size_of::<Texel>();
    sub.upload_with(label, usage, bytes, |out| {
        // one slot a record (a sized array: what crosses threads), in blocks of records
        let n: usize = preps.iter().map(|p| which.count(p)).sum();
        let mut slots = out
            .into_slice(..n * BYTES)
            .into_chunks::<BYTES>()
            .0
            .into_iter();
        let mut blocks = Vec::new();
        for &prep in preps {
            let count = which.count(prep);
            for first in (0..count).step_by(TEXEL_BLOCK) {
                let len = TEXEL_BLOCK.min(count - first);
                let block: Vec<wgpu::WriteOnly<'_, [u8; BYTES]>> =
                    slots.by_ref().take(len).collect();
                blocks.push((prep, first, block));
            }
        }
        blocks.into_par_iter().for_each(|(prep, first, block)| {
            for (k, slot) in block.into_iter().enumerate() {
                slot.write(bytemuck::cast(which.record(prep, first + k)));
            }
        });
    })
}

/// [`upload_texels`] into a storage buffer of just the records.
pub(super) fn storage_texels(
    sub: &mut Submission<'_>,
    label: &'static str,
    preps: &[&Prepared],
    which: Texels,
) -> Result<wgpu::Buffer> {
    let n: usize = preps.iter().map(|p| which.count(p)).sum();
    let bytes = ((n * size_of::<Texel>()) as u64).max(MIN_BYTES);
    upload_texels(sub, label, wgpu::BufferUsages::STORAGE, bytes, preps, which)
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

/// Per scene of a batched dispatch of `shape`, its [`DispatchParams`]: `np[z]` pixels and `nt[z]`
/// texels at their starts in the concatenated buffers, its slices of `inner[z]` records
/// (the looped-over ones) as long as they would be were it alone.
pub(super) fn batch_params(
    inputs: &[Input<'_>],
    shape: &super::GatherShape,
    np: &[usize],
    nt: &[usize],
    inner: &[usize],
) -> Vec<DispatchParams> {
    let (pixel_base, texel_base) = (bases(np), bases(nt));
    inputs
        .iter()
        .enumerate()
        .map(|(z, input)| DispatchParams {
            n_pixels: np[z] as u32,
            n_texels: nt[z] as u32,
            first: 1,
            slice_len: shape.slice_len_of(inner[z]),
            n_slices: shape.slices,
            pixel_base: pixel_base[z] as u32,
            texel_base: texel_base[z] as u32,
            slice_stride: shape.outer as u32,
            ..DispatchParams::for_scene(input.prep)
        })
        .collect()
}

/// Where a binding lies in its buffer: offset and size.
pub(super) type Window = (u64, Option<u64>);

/// The binding of records `range` of `T` in a buffer that holds them from its start
/// (range starts are whole workgroups, so the offset is aligned): (offset, size).
pub(super) fn range_of<T>(range: &std::ops::Range<usize>) -> Window {
    let size = size_of::<T>() as u64;
    let bytes = (range.len() as u64 * size).max(MIN_BYTES);
    (range.start as u64 * size, Some(bytes))
}

/// The looped-over records of one scene, all its inner ranges in one buffer as the gather
/// passes read them: storage ([`Tiles::Workgroup`]), or one uniform chunk per range
/// ([`Tiles::Uniform`]: a chunk's records fill [`CHUNK_BYTES`] exactly, so the chunks are
/// the records in order, the last padded). Returns the buffer and each range's binding.
pub(super) fn tiled<T>(
    r: &GpuRenderer,
    sub: &mut Submission<'_>,
    n: usize,
    ranges: &[std::ops::Range<usize>],
    upload: impl FnOnce(&mut Submission<'_>, wgpu::BufferUsages, u64) -> Result<wgpu::Buffer>,
) -> Result<(wgpu::Buffer, Vec<Window>)> {
    let bytes = (n * size_of::<T>()) as u64;
    Ok(match r.planner.tiles {
        Tiles::Workgroup => {
            let b = upload(sub, wgpu::BufferUsages::STORAGE, bytes)?;
            (b, ranges.iter().map(range_of::<T>).collect())
        }
        Tiles::Uniform => {
            let total = ranges.len() as u64 * CHUNK_BYTES;
            let b = upload(sub, wgpu::BufferUsages::UNIFORM, total)?;
            let chunks = (0..ranges.len() as u64)
                .map(|k| (k * CHUNK_BYTES, Some(CHUNK_BYTES)))
                .collect();
            (b, chunks)
        }
    })
}

/// Encodes a per-pixel pass (forward or backward_normal) over the pixels `sels[b]` of
/// each scene `inputs[b]` against its lit texels: the whole batch in one dispatch where the
/// planner allows ([`super::Planner::batch`]), else scene by scene in the planner's
/// ranges and slices; the slices then added by reduce_slices. Returns, per scene, the
/// first and last readback slots of its results (one vec4 per selected pixel, in order).
pub(super) fn encode_per_pixel(
    r: &GpuRenderer,
    pass: Pass,
    inputs: &[Input<'_>],
    sels: &[Selection<'_>],
    sub: &mut Submission<'_>,
) -> Result<Vec<(Slot, Slot)>> {
    let np: Vec<usize> = sels.iter().map(Selection::len).collect();
    let nl: Vec<usize> = inputs.iter().map(|i| Texels::Lit.count(i.prep)).collect();
    let Some(shape) = r.planner.batch(pass, &np, &nl) else {
        return inputs
            .iter()
            .zip(sels)
            .map(|(input, sel)| encode_scene(r, pass, input.prep, sel, sub))
            .collect();
    };
    let pixel_base = bases(&np);
    let total = shape.outer;
    let scenes = batch_params(inputs, &shape, &np, &nl, &nl);
    let mut table = ParamsTable::default();
    let offset = table.push_scenes(&scenes);
    let params = sub.params(&table);
    let preps: Vec<&Prepared> = inputs.iter().map(|i| i.prep).collect();
    let tex = storage_texels(sub, "lit texels", &preps, Texels::Lit)?;
    let bytes = (total * size_of::<Pixel>()) as u64;
    let pix = sub.upload_pixels("pixels", wgpu::BufferUsages::STORAGE, sels, bytes)?;
    let parts = sub.output(pass.name(), (total * 16) as u64 * shape.slices as u64);
    let bg = sub.bind(
        pass,
        &params,
        inputs.len(),
        &[(&tex, 0, None), (&pix, 0, None), (&parts, 0, None)],
    );
    let max_np = np.iter().copied().max().unwrap_or(0);
    let [x, y, _] = shape.groups(max_np);
    let pairs = np.iter().zip(&nl).map(|(&p, &l)| (p * l) as u64).sum();
    sub.compute(pass, pairs, &[(&bg, offset, [x, y, inputs.len() as u32])]);
    let out = if shape.slices > 1 {
        sub.reduce_slices(scenes[0], &parts, total, shape.slices)
    } else {
        parts
    };
    Ok((0..inputs.len())
        .map(|b| {
            let s = sub.read(&out, pixel_base[b] as u64 * 16, np[b] as u64 * 16);
            (s, s)
        })
        .collect())
}

/// [`encode_per_pixel`] for one scene, range by range.
fn encode_scene(
    r: &GpuRenderer,
    pass: Pass,
    prep: &Prepared,
    sel: &Selection<'_>,
    sub: &mut Submission<'_>,
) -> Result<(Slot, Slot)> {
    let n_pixels = sel.len();
    let n_lit = Texels::Lit.count(prep);
    let shape = r.planner.gather(pass, n_pixels, n_lit);
    let inner = shape.inner_ranges();
    let (texels, tex_at) = tiled::<Texel>(r, sub, n_lit, &inner, |sub, usage, bytes| {
        upload_texels(sub, "lit texels", usage, bytes, &[prep], Texels::Lit)
    })?;
    let bytes = (n_pixels * size_of::<Pixel>()) as u64;
    let pix = sub.upload_pixels(
        "pixels",
        wgpu::BufferUsages::STORAGE,
        std::slice::from_ref(sel),
        bytes,
    )?;
    let base = DispatchParams::for_scene(prep);
    let mut slots = Vec::new();
    for o in shape.outer_ranges() {
        let n = o.len();
        let mut table = ParamsTable::default();
        let offsets: Vec<u32> = inner
            .iter()
            .enumerate()
            .map(|(k, t)| {
                table.push(DispatchParams {
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
        let params = sub.params(&table);
        let out_bytes = n as u64 * 16;
        let parts = sub.output(pass.name(), out_bytes * shape.slices as u64);
        let (pix_at, pix_size) = range_of::<Pixel>(&o);
        let groups: Vec<wgpu::BindGroup> = tex_at
            .iter()
            .map(|&(at, size)| {
                sub.bind(
                    pass,
                    &params,
                    1,
                    &[
                        (&texels, at, size),
                        (&pix, pix_at, pix_size),
                        (&parts, 0, None),
                    ],
                )
            })
            .collect();
        let dispatches: Vec<_> = groups
            .iter()
            .zip(&offsets)
            .map(|(bg, &off)| (bg, off, shape.groups(n)))
            .collect();
        sub.compute(pass, (n * n_lit) as u64, &dispatches);
        let out = if shape.slices > 1 {
            sub.reduce_slices(base, &parts, n, shape.slices)
        } else {
            parts
        };
        slots.push(sub.read(&out, 0, out_bytes));
    }
    Ok(match (slots.first(), slots.last()) {
        (Some(&a), Some(&b)) => (a, b),
        // no pixels: an empty slot
        _ => {
            let s = sub.read(&pix, 0, 0);
            (s, s)
        }
    })
}

/// One image per scene, in one submission.
pub(super) fn forward(r: &GpuRenderer, inputs: &[Input<'_>]) -> Result<Vec<Image>> {
    let sels: Vec<Selection<'_>> = inputs
        .iter()
        .map(|i| Selection::new(i.source, None, false))
        .collect();
    let mut sub = Submission::new(r, "forward")?;
    let slots = encode_per_pixel(r, Pass::Forward, inputs, &sels, &mut sub)?;
    let (out, run) = sub.finish()?;
    let images = inputs
        .iter()
        .zip(&sels)
        .zip(slots)
        .map(|((input, sel), (first, last))| {
            let p = input.prep;
            p.image(sel.scatter(out.span(first, last), p.width, p.height))
        })
        .collect();
    drop(out);
    r.record(run);
    Ok(images)
}
