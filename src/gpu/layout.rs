//! The structs shared with the shaders, byte for byte. Kept in sync with the structs of
//! shaders/common.wgsl; tests/it/shaders/ compares every member offset and size with naga's.

use bytemuck::{Pod, Zeroable};

use crate::material::{N_PARAMS, idx};
use crate::prepare::{PixelRec, TexelRec};

/// What the shaders get for coefficient `t` (0: scale, 1: exponent) of value `v`: the
/// lobes are computed in base 2 (exp(m0 x^m1) - 1 = 2^(m0 log2(e) x^m1) - 1), so every
/// scale is stored times log2(e) and the pair loops have no multiplication by it.
fn for_shader(t: usize, v: f64) -> f32 {
    if t == 0 {
        (v * std::f64::consts::LOG2_E) as f32
    } else {
        v as f32
    }
}

/// What the channels of a lobe with scales `m0` and exponents `m1` (R, G, B) share, as
/// `SHARES_EXPONENT` and `SHARES_LOBE` in common.wgsl: 2 for both curves, 1 for the
/// exponent, else 0. Then the pixel passes compute x^m1, or the whole lobe, once.
fn shared(m0: &[f32; 4], m1: &[f32; 4]) -> f32 {
    let same = |v: &[f32; 4]| v[0] == v[1] && v[1] == v[2];
    match (same(m1), same(m0)) {
        (true, true) => 2.0,
        (true, false) => 1.0,
        _ => 0.0,
    }
}

/// `lobe_x`'s pad in common.wgsl for a texel with orthographic half vector `h`: 1 where the
/// half vector is undefined (w_i = -w_p, h = 0), so that x = 0 there.
fn half_vector_pad(h: [f64; 3]) -> f32 {
    if h == [0.0; 3] { 1.0 } else { 0.0 }
}

/// Threads per workgroup (`WG` in common.wgsl), and records per workgroup-memory tile.
pub const WG: usize = 64;
// a tile of texels fills WebGPU's minimum of 16 KiB of workgroup memory exactly
const _: () = assert!(WG * size_of::<Texel>() <= 16384);
/// Texels per uniform chunk on a software adapter (`CHUNK` in forward.wgsl and
/// backward_normal.wgsl).
pub const TEXEL_CHUNK: usize = 252;
/// Pixels per uniform chunk on a software adapter (`CHUNK` in backward_texel.wgsl).
pub const PIXEL_CHUNK: usize = 1344;
/// Bytes of one uniform chunk of texels or of pixels: under 64 KiB, a multiple of 256.
pub const CHUNK_BYTES: u64 = (TEXEL_CHUNK * size_of::<Texel>()) as u64;
const _: () = assert!(CHUNK_BYTES == (PIXEL_CHUNK * size_of::<Pixel>()) as u64);
const _: () = assert!(CHUNK_BYTES <= 65536 && CHUNK_BYTES.is_multiple_of(256));

/// One dispatch's parameters, or one scene's in a batched dispatch (`Params` in
/// common.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct DispatchParams {
    /// Pixels bound (per-pixel passes: one invocation each; backward_texel: looped over);
    /// reduce_slices: the vec4 elements of one slice.
    pub n_pixels: u32,
    /// Texels bound (per-pixel passes: looped over; backward_texel: one invocation each;
    /// reduce_ctrl: summed).
    pub n_texels: u32,
    /// 1 on the first range of a sum: write instead of add.
    pub first: u32,
    /// 1 for a perspective camera.
    pub perspective: u32,
    /// Lobes in `Texel::lobes` (orthographic cameras).
    pub n_lobes: u32,
    /// Lobes after the active ones in `lc` whose exponents are all 0 (perspective cameras).
    pub n_const: u32,
    /// Records of the looped-over list in one slice (the dispatch's y dimension).
    pub slice_len: u32,
    /// Slices (reduce_slices: how many partial sums each element has).
    pub n_slices: u32,
    /// The scene's first pixel in the pixel buffers (a batch's scenes are concatenated).
    pub pixel_base: u32,
    /// The scene's first texel in the texel buffers.
    pub texel_base: u32,
    /// Elements between two slices' partial sums (every scene's outputs).
    pub slice_stride: u32,
    /// Padding to 16 bytes.
    pub _pad: u32,
    /// cc[(k * 2 + t) * 6 + j] = the control points j of coefficient t of channel k's three
    /// lobes, scales times log2(e).
    pub cc: [[f32; 4]; 36],
    /// lc[(q * 2 + t) * 6 + j] = the control points j of coefficient t of the q-th lobe of
    /// the active then the constant lobes, over channels (R, G, B), scales times log2(e).
    pub lc: [[f32; 4]; 36],
}
const _: () = assert!(size_of::<DispatchParams>().is_multiple_of(16));

/// Bytes between two dispatches' [`DispatchParams`] in the params buffer: a multiple of 256, the
/// largest uniform offset alignment wgpu allows.
pub const PARAMS_STRIDE: u64 = size_of::<DispatchParams>().next_multiple_of(256) as u64;

impl DispatchParams {
    /// DispatchParams for a prepared scene.
    pub fn for_scene(prep: &crate::prepare::Prepared) -> Self {
        let mut p = DispatchParams::new(
            &prep.ctrl,
            !prep.camera.is_orthographic(),
            prep.active_lobes.len(),
        );
        p.n_const = prep.const_lobes.len() as u32;
        for (q, &s) in prep
            .active_lobes
            .iter()
            .chain(&prep.const_lobes)
            .enumerate()
        {
            for t in 0..2 {
                for j in 0..6 {
                    for k in 0..3 {
                        p.lc[(q * 2 + t) * 6 + j][k] = for_shader(t, prep.ctrl[idx(k, s, t, j)]);
                    }
                }
            }
        }
        p
    }

    /// DispatchParams with the material's control points rearranged for `pair_coef`.
    pub fn new(ctrl: &[f64; N_PARAMS], perspective: bool, n_lobes: usize) -> Self {
        let mut cc = [[0.0f32; 4]; 36];
        for k in 0..3 {
            for t in 0..2 {
                for j in 0..6 {
                    for s in 0..3 {
                        cc[(k * 2 + t) * 6 + j][s] = for_shader(t, ctrl[idx(k, s, t, j)]);
                    }
                }
            }
        }
        DispatchParams {
            n_pixels: 0,
            n_texels: 0,
            first: 0,
            perspective: perspective as u32,
            n_lobes: n_lobes as u32,
            n_const: 0,
            slice_len: 0,
            n_slices: 1,
            pixel_base: 0,
            texel_base: 0,
            slice_stride: 0,
            _pad: 0,
            cc,
            lc: [[0.0; 4]; 36],
        }
    }
}

/// One environment texel (`Texel` in common.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Texel {
    /// xyz: direction; w: solid angle.
    pub w: [f32; 4],
    /// xyz: orthographic half vector; w: theta_d.
    pub h: [f32; 4],
    /// xyz: L^k d_omega; w: orthographic cameras, 1 where the half vector is undefined
    /// (`lobe_x`'s pad).
    pub ld: [f32; 4],
    /// xyz: per channel, the constant lobes' share of f.
    pub fconst: [f32; 4],
    /// coef[k * 2 + t] = (m_{0,t}^k, m_{1,t}^k, m_{2,t}^k, w), scales times log2(e); w: for
    /// the exponents the least of the three (a channel's lobes are skipped where x^m1
    /// underflows for all three), for channel 0's scales 2 where the three channels have the
    /// same lobes (`SHARES_LOBE`: backward_texel computes them once), else 0.
    pub coef: [[f32; 4]; 6],
    /// The active lobes over channels: lobes[2a] = m0 log2(e) (R, G, B, what the channels
    /// share: 2 both curves, 1 the exponent, else 0) and lobes[2a + 1] = m1 (R, G, B, the
    /// least of the three) of the a-th active lobe.
    pub lobes: [[f32; 4]; 6],
}
const _: () = assert!(size_of::<Texel>().is_multiple_of(16));

impl Texel {
    /// The GPU record of a texel, with `active` the material's active lobes.
    pub fn new(t: &TexelRec, active: &[usize]) -> Self {
        let least = |v: [f32; 4]| v[0].min(v[1]).min(v[2]);
        let mut coef = [[0.0f32; 4]; 6];
        for k in 0..3 {
            for tt in 0..2 {
                for s in 0..3 {
                    coef[k * 2 + tt][s] = for_shader(tt, t.coef[(k * 3 + s) * 2 + tt]);
                }
            }
            coef[k * 2 + 1][3] = least(coef[k * 2 + 1]);
        }
        let grey = (1..3).all(|k| coef[k * 2] == coef[0] && coef[k * 2 + 1] == coef[1]);
        coef[0][3] = if grey { 2.0 } else { 0.0 };
        let mut lobes = [[0.0f32; 4]; 6];
        for (a, &s) in active.iter().enumerate() {
            for tt in 0..2 {
                for k in 0..3 {
                    lobes[a * 2 + tt][k] = for_shader(tt, t.coef[(k * 3 + s) * 2 + tt]);
                }
            }
            lobes[a * 2 + 1][3] = least(lobes[a * 2 + 1]);
            lobes[a * 2][3] = shared(&lobes[a * 2], &lobes[a * 2 + 1]);
        }
        let v4 = |v: [f64; 3], w: f64| [v[0] as f32, v[1] as f32, v[2] as f32, w as f32];
        Texel {
            fconst: v4(t.fconst, 0.0),
            lobes,
            w: [
                t.w[0] as f32,
                t.w[1] as f32,
                t.w[2] as f32,
                t.d_omega as f32,
            ],
            h: [
                t.h[0] as f32,
                t.h[1] as f32,
                t.h[2] as f32,
                t.theta_d as f32,
            ],
            ld: [
                t.ld[0] as f32,
                t.ld[1] as f32,
                t.ld[2] as f32,
                half_vector_pad(t.h),
            ],
            coef,
        }
    }
}

/// One foreground pixel (`Pixel` in common.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct Pixel {
    /// The normal.
    pub n: [f32; 3],
    /// |n|^2 - 1, computed in f64 ([`PixelRec::nn_m1`]), for `lobe_x`.
    pub nn_m1: f32,
    /// xyz: the view direction.
    pub wp: [f32; 4],
    /// xyz: the upstream gradient.
    pub g: [f32; 4],
}
const _: () = assert!(size_of::<Pixel>().is_multiple_of(16));

impl Pixel {
    /// The GPU record of a pixel with upstream gradient `g`.
    pub fn new(p: &PixelRec, g: [f32; 3]) -> Self {
        Pixel {
            n: [p.n[0] as f32, p.n[1] as f32, p.n[2] as f32],
            nn_m1: p.nn_m1 as f32,
            wp: [p.wp[0] as f32, p.wp[1] as f32, p.wp[2] as f32, 0.0],
            g: [g[0], g[1], g[2], 0.0],
        }
    }
}
