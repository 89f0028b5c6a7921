//! The dispatch plan. Each gather pass (forward, backward_normal: one invocation per pixel
//! looping over texels; backward_texel: one per texel looping over pixels) is split into
//! ranges (so that every binding stays within the device's limits), slices (the
//! dispatch's y dimension: independent partial sums over consecutive parts of the
//! looped-over records, added afterwards by reduce_slices in slice order) and workgroups.
//! Pure: computed from the problem's sizes and the device's limits, so that the shape a
//! large GPU gets can be shown, and checked, on any machine.

use std::ops::Range;

use super::layout::{PIXEL_CHUNK, Pixel, TEXEL_CHUNK, Texel, WG};
use super::pipelines::{Pass, Tiles};
use crate::material::N_PARAMS;

/// Invocations a large GPU keeps resident, the amount of independent work the automatic
/// slice count aims for: an H100 SXM's 132 SMs x 2048 resident threads per SM.
pub const LARGE_GPU_RESIDENT: u64 = 132 * 2048;

/// Bytes of one texel's shares of dLoss/dctrl.
pub const SHARE_BYTES: u64 = (N_PARAMS * 4) as u64;

/// Bytes of one vec4 result (a pixel's colour or dLoss/dn, a texel's dLoss/dL).
const VEC4_BYTES: u64 = 16;

/// Most records one invocation loops over through workgroup tiles on a software adapter
/// (256 tiles). Lavapipe (Mesa 22.3) sums such loops wrongly past about 300 tiles: a
/// 4 x 4 sphere under a 112 x 224 map (25,088 lit texels in one range) came out 2.4e-3
/// off the reference, 128 x 256 (32,768) 2.5e-2 and 512 x 1024 0.89, while the same
/// inputs in ranges of 16,384 or 20,480 records, or in short slices, are within 5e-6.
pub const SOFTWARE_TILED_RECORDS: usize = 16384;

/// What a plan depends on: the device's limits and kind, and the overrides.
#[derive(Clone, Debug)]
pub struct Planner {
    /// Bytes of one storage binding (the device's limit, or a smaller cap).
    pub max_binding: u64,
    /// Bytes of one buffer.
    pub max_buffer: u64,
    /// Workgroups per dispatch dimension.
    pub max_groups: u32,
    /// A software adapter (lavapipe): its invocations are SIMD lanes on a few CPU cores,
    /// which the pixels (or texels) alone keep busy, so the automatic slice count is 1.
    pub software: bool,
    /// Slices asked for instead of the automatic count (still capped by the limits).
    pub slices: Option<u32>,
    /// Where the gather passes read their looped-over records: with [`Tiles::Uniform`] an
    /// inner range is one uniform chunk.
    pub tiles: Tiles,
}

/// One dispatch of the plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Dispatch {
    /// The pass.
    pub pass: Pass,
    /// Workgroups in x, y (slices for the gather passes) and z.
    pub workgroups: [u32; 3],
}

impl Dispatch {
    /// Invocations: workgroups times [`WG`].
    pub fn invocations(&self) -> u64 {
        self.workgroups.iter().map(|&g| g as u64).product::<u64>() * WG as u64
    }
}

/// The layout of one gather pass: `outer` records (one invocation each) against `inner`
/// records (looped over).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GatherShape {
    /// Records with one invocation each.
    pub outer: usize,
    /// Records looped over.
    pub inner: usize,
    /// Most outer records per dispatch (one binding).
    pub outer_range: usize,
    /// Most inner records per dispatch (one binding); later ranges add to the first's sums.
    pub inner_range: usize,
    /// Slices of an inner range: the dispatch's y dimension.
    pub slices: u32,
    /// Inner records per slice (the last may have fewer).
    pub slice_len: u32,
}

/// Bytes of an outer record in, of its largest partial result out, of an inner record,
/// and inner records per uniform chunk, of gather pass `pass`.
fn record_bytes(pass: Pass) -> (u64, u64, u64, usize) {
    let (texel, pixel) = (size_of::<Texel>() as u64, size_of::<Pixel>() as u64);
    match pass {
        Pass::BackwardTexel => (texel, SHARE_BYTES, pixel, PIXEL_CHUNK),
        _ => (pixel, VEC4_BYTES, texel, TEXEL_CHUNK),
    }
}

fn ranges(n: usize, per: usize) -> Vec<Range<usize>> {
    (0..n.div_ceil(per))
        .map(|k| k * per..n.min((k + 1) * per))
        .collect()
}

impl GatherShape {
    /// The outer ranges, in order (none for no records).
    pub fn outer_ranges(&self) -> Vec<Range<usize>> {
        ranges(self.outer, self.outer_range)
    }

    /// The inner ranges, in order; one empty range for no records, so that the sums are
    /// still written (as zeros).
    pub fn inner_ranges(&self) -> Vec<Range<usize>> {
        let mut r = ranges(self.inner, self.inner_range);
        if r.is_empty() {
            r.push(0..0);
        }
        r
    }

    /// Records per slice of a scene of `n` inner records in a batched dispatch: the length
    /// it would get alone with [`GatherShape::slices`] asked for.
    pub fn slice_len_of(&self, n: usize) -> u32 {
        n.div_ceil(self.slices as usize) as u32
    }

    /// Workgroups of the gather over `n` outer records.
    pub fn groups(&self, n: usize) -> [u32; 3] {
        [n.div_ceil(WG) as u32, self.slices, 1]
    }
}

impl Planner {
    /// The plan for a device with `limits`.
    pub fn for_limits(limits: &wgpu::Limits, software: bool) -> Self {
        Planner {
            max_binding: limits.max_storage_buffer_binding_size,
            max_buffer: limits.max_buffer_size,
            max_groups: limits.max_compute_workgroups_per_dimension,
            software,
            slices: None,
            tiles: if software {
                Tiles::Uniform
            } else {
                Tiles::Workgroup
            },
        }
    }

    /// The large GPU the occupancy report assumes: an H100 SXM under Vulkan (storage
    /// bindings up to 4 GiB - 1, buffers up to 80 GB, 65535 workgroups per dimension), with
    /// [`LARGE_GPU_RESIDENT`] resident invocations.
    pub fn large_gpu() -> Self {
        Planner {
            max_binding: u32::MAX as u64,
            max_buffer: 80 << 30,
            max_groups: 65535,
            software: false,
            slices: None,
            tiles: Tiles::Workgroup,
        }
    }

    /// This device's limits planned as on a large GPU: slices for [`LARGE_GPU_RESIDENT`]
    /// invocations and workgroup tiles (so batches go in one dispatch), even on a
    /// software adapter.
    pub fn as_large_gpu(mut self) -> Self {
        self.software = false;
        self.tiles = Tiles::Workgroup;
        self
    }

    /// The same plan with `n` slices asked for (see [`GpuRenderer::with_slices`]).
    ///
    /// [`GpuRenderer::with_slices`]: super::GpuRenderer::with_slices
    pub fn with_slices(mut self, n: u32) -> Self {
        self.slices = Some(n.max(1));
        self
    }

    /// Most records of `bytes` bytes one binding (and one dispatch) may hold, in whole
    /// workgroups, at least one workgroup's worth.
    pub fn max_records(&self, bytes: u64) -> usize {
        let by_binding = self.max_binding.min(self.max_buffer) / bytes;
        let by_dispatch = self.max_groups as u64 * WG as u64;
        let n = by_binding.min(by_dispatch) as usize;
        // whole workgroups, so that range offsets stay aligned
        (n / WG * WG).max(WG)
    }

    /// Slices for `scenes` x `outer` invocations per slice over `inner` records: enough
    /// for [`LARGE_GPU_RESIDENT`] invocations in all, at least a tile of records each; 1 on
    /// a software adapter.
    fn auto_slices(&self, scenes: usize, outer: usize, inner: usize) -> usize {
        if self.software {
            return 1;
        }
        let per_slice = (scenes * outer.div_ceil(WG) * WG).max(WG) as u64;
        let want = LARGE_GPU_RESIDENT.div_ceil(per_slice) as usize;
        want.min(inner.div_ceil(WG)).max(1)
    }

    /// The shape of gather pass `pass` over `outer` and `inner` records.
    pub fn gather(&self, pass: Pass, outer: usize, inner: usize) -> GatherShape {
        let (outer_in, out, inner_in, chunk) = record_bytes(pass);
        let inner_range = match self.tiles {
            Tiles::Workgroup if self.software => {
                self.max_records(inner_in).min(SOFTWARE_TILED_RECORDS)
            }
            Tiles::Workgroup => self.max_records(inner_in),
            Tiles::Uniform => chunk,
        };
        let n_in = inner.min(inner_range);
        let s = self.slices_for(pass, 1, outer, n_in);
        let slice_len = n_in.div_ceil(s);
        // slices that would be empty are not dispatched
        let slices = if slice_len == 0 {
            1
        } else {
            n_in.div_ceil(slice_len)
        };
        let outer_range = self
            .max_records(outer_in)
            .min(self.max_records(out * slices as u64));
        GatherShape {
            outer,
            inner,
            outer_range,
            inner_range,
            slices: slices as u32,
            slice_len: slice_len as u32,
        }
    }

    /// Slices asked for (or the automatic count), within the caps: the partial sums of one
    /// workgroup of outer records fit in one binding.
    fn slices_for(&self, pass: Pass, scenes: usize, outer: usize, inner: usize) -> usize {
        let out = record_bytes(pass).1;
        let want = self
            .slices
            .map_or_else(|| self.auto_slices(scenes, outer, inner), |s| s as usize);
        let cap = (self.max_records(out) / WG).min(self.max_groups as usize);
        want.clamp(1, cap.max(1))
    }

    /// The shape of gather pass `pass` over a batch in one dispatch, the scenes in z:
    /// `outer[z]` and `inner[z]` records of scene z, concatenated. `None` where the batch
    /// goes scene by scene: one scene, uniform chunks (a software adapter), or records or
    /// partial sums over one binding. Scene z's slices are as long as they would be were it
    /// alone ([`GatherShape::slice_len_of`]); a scene with fewer leaves its last slices empty
    /// (zeros, which its sum over slices adds exactly).
    pub fn batch(&self, pass: Pass, outer: &[usize], inner: &[usize]) -> Option<GatherShape> {
        let b = outer.len();
        if b < 2 || self.tiles == Tiles::Uniform || b > self.max_groups as usize {
            return None;
        }
        let (outer_in, out, inner_in, _) = record_bytes(pass);
        let max_out = outer.iter().copied().max().unwrap_or(0);
        let max_in = inner.iter().copied().max().unwrap_or(0);
        if self.software && max_in > SOFTWARE_TILED_RECORDS {
            return None;
        }
        let total_out: usize = outer.iter().sum();
        let total_in: usize = inner.iter().sum();
        let asked = self.slices_for(pass, b, max_out, max_in) as u32;
        let limit = self.max_binding.min(self.max_buffer);
        let fits = total_out as u64 * outer_in <= limit
            && total_out as u64 * out * asked as u64 <= limit
            && total_in as u64 * inner_in <= limit
            && max_out.div_ceil(WG) <= self.max_groups as usize;
        let shape = GatherShape {
            outer: total_out,
            inner: total_in,
            outer_range: total_out,
            inner_range: total_in,
            slices: asked,
            slice_len: max_in.div_ceil(asked as usize) as u32,
        };
        fits.then_some(shape)
    }

    /// Workgroups for `elements` invocations: x up to the limit, then y.
    pub fn reduce_groups(&self, elements: usize) -> [u32; 3] {
        let g = elements.div_ceil(WG) as u64;
        let max = self.max_groups as u64;
        if g <= max {
            [g as u32, 1, 1]
        } else {
            [max as u32, g.div_ceil(max) as u32, 1]
        }
    }

    /// The dispatches of a per-pixel pass (forward or backward_normal) over `pixels`
    /// foreground pixels and `lit` lit texels.
    pub fn per_pixel(&self, pass: Pass, pixels: usize, lit: usize) -> Vec<Dispatch> {
        let shape = self.gather(pass, pixels, lit);
        let mut out = Vec::new();
        for o in shape.outer_ranges() {
            for _ in shape.inner_ranges() {
                out.push(Dispatch {
                    pass,
                    workgroups: shape.groups(o.len()),
                });
            }
            if shape.slices > 1 {
                out.push(self.reduce(o.len()));
            }
        }
        out
    }

    /// The dispatches of backward_texel and its reductions over `texels` texels and
    /// `active` pixels with a non-zero upstream gradient.
    pub fn texel(&self, texels: usize, active: usize) -> Vec<Dispatch> {
        let shape = self.gather(Pass::BackwardTexel, texels, active);
        let mut out = Vec::new();
        for o in shape.outer_ranges() {
            for _ in shape.inner_ranges() {
                out.push(Dispatch {
                    pass: Pass::BackwardTexel,
                    workgroups: shape.groups(o.len()),
                });
            }
            if shape.slices > 1 {
                out.push(self.reduce(o.len()));
                out.push(self.reduce(o.len() * N_PARAMS / 4));
            }
            out.push(Dispatch {
                pass: Pass::ReduceCtrl,
                workgroups: [N_PARAMS as u32, 1, 1],
            });
        }
        out
    }

    /// The dispatch of reduce_slices over `elements` vec4 elements.
    pub fn reduce(&self, elements: usize) -> Dispatch {
        Dispatch {
            pass: Pass::ReduceSlices,
            workgroups: self.reduce_groups(elements),
        }
    }

    /// Every dispatch of a forward call on one scene.
    pub fn forward(&self, pixels: usize, lit: usize) -> Vec<Dispatch> {
        self.per_pixel(Pass::Forward, pixels, lit)
    }

    /// Every dispatch of a backward call on one scene: `pixels` foreground pixels, `lit`
    /// lit texels, `texels` texels, `active` pixels with a non-zero upstream gradient.
    pub fn backward(
        &self,
        pixels: usize,
        lit: usize,
        texels: usize,
        active: usize,
    ) -> Vec<Dispatch> {
        let mut out = self.texel(texels, active);
        out.extend(self.per_pixel(Pass::BackwardNormal, pixels, lit));
        out
    }
}
