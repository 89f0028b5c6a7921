//! Every struct and constant shared with Rust has the same layout and value in WGSL
//! (naga's member offsets and spans against `offset_of!` and `size_of`).

use std::mem::{offset_of, size_of};

use super::module_with;
use matedit::cpu::math::EXP2M1_Q;
use matedit::gpu::layout::{DispatchParams, PIXEL_CHUNK, Pixel, TEXEL_CHUNK, Texel, WG};
use matedit::gpu::{Pass, Tiles};

fn module(pass: Pass) -> naga::Module {
    module_with(pass, Tiles::Workgroup)
}

/// (member name, offset) and span of the WGSL struct `name`.
fn wgsl_struct(m: &naga::Module, name: &str) -> (Vec<(String, u32)>, u32) {
    for (_, ty) in m.types.iter() {
        if ty.name.as_deref() == Some(name)
            && let naga::TypeInner::Struct { members, span } = &ty.inner
        {
            return (
                members
                    .iter()
                    .map(|mb| (mb.name.clone().unwrap_or_default(), mb.offset))
                    .collect(),
                *span,
            );
        }
    }
    panic!("no struct {name}");
}

fn wgsl_f32_const(m: &naga::Module, name: &str) -> f32 {
    for (_, c) in m.constants.iter() {
        if c.name.as_deref() == Some(name)
            && let naga::Expression::Literal(naga::Literal::F32(v)) = m.global_expressions[c.init]
        {
            return v;
        }
    }
    panic!("no f32 constant {name}");
}

fn wgsl_u32_const(m: &naga::Module, name: &str) -> u32 {
    for (_, c) in m.constants.iter() {
        if c.name.as_deref() == Some(name)
            && let naga::Expression::Literal(naga::Literal::U32(v)) = m.global_expressions[c.init]
        {
            return v;
        }
    }
    panic!("no u32 constant {name}");
}

#[test]
fn shared_structs_match_rust_layout() {
    let m = module(Pass::BackwardTexel);
    let check = |name: &str, rust: &[(&str, usize)], size: usize| {
        let (members, span) = wgsl_struct(&m, name);
        let got: Vec<(String, u32)> = members;
        let want: Vec<(String, u32)> = rust
            .iter()
            .map(|(n, o)| (n.to_string(), *o as u32))
            .collect();
        assert_eq!(got, want, "{name}: member offsets");
        assert_eq!(span as usize, size, "{name}: size");
    };
    check(
        "Params",
        &[
            ("n_pixels", offset_of!(DispatchParams, n_pixels)),
            ("n_texels", offset_of!(DispatchParams, n_texels)),
            ("first", offset_of!(DispatchParams, first)),
            ("perspective", offset_of!(DispatchParams, perspective)),
            ("n_lobes", offset_of!(DispatchParams, n_lobes)),
            ("n_const", offset_of!(DispatchParams, n_const)),
            ("slice_len", offset_of!(DispatchParams, slice_len)),
            ("n_slices", offset_of!(DispatchParams, n_slices)),
            ("pixel_base", offset_of!(DispatchParams, pixel_base)),
            ("texel_base", offset_of!(DispatchParams, texel_base)),
            ("slice_stride", offset_of!(DispatchParams, slice_stride)),
            ("_pad", offset_of!(DispatchParams, _pad)),
            ("cc", offset_of!(DispatchParams, cc)),
            ("lc", offset_of!(DispatchParams, lc)),
        ],
        size_of::<DispatchParams>(),
    );
    check(
        "Texel",
        &[
            ("w", offset_of!(Texel, w)),
            ("h", offset_of!(Texel, h)),
            ("ld", offset_of!(Texel, ld)),
            ("fconst", offset_of!(Texel, fconst)),
            ("coef", offset_of!(Texel, coef)),
            ("lobes", offset_of!(Texel, lobes)),
        ],
        size_of::<Texel>(),
    );
    check(
        "Pixel",
        &[
            ("n", offset_of!(Pixel, n)),
            ("nn_m1", offset_of!(Pixel, nn_m1)),
            ("wp", offset_of!(Pixel, wp)),
            ("g", offset_of!(Pixel, g)),
        ],
        size_of::<Pixel>(),
    );
}

#[test]
fn shared_constants_match_rust() {
    let m = module(Pass::Forward);
    assert_eq!(wgsl_u32_const(&m, "WG") as usize, WG);
    for pass in [Pass::Forward, Pass::BackwardNormal] {
        assert_eq!(wgsl_u32_const(&module(pass), "CHUNK") as usize, TEXEL_CHUNK);
    }
    assert_eq!(
        wgsl_u32_const(&module(Pass::BackwardTexel), "CHUNK") as usize,
        PIXEL_CHUNK
    );
    // the shaders' 2^u - 1 is the fast CPU path's polynomial, whose error tests/it/cpu_math.rs sweeps
    for (j, q) in EXP2M1_Q.iter().enumerate() {
        assert_eq!(
            wgsl_f32_const(&m, &format!("EXP2M1_Q{j}")),
            *q,
            "EXP2M1_Q{j}"
        );
    }
}
