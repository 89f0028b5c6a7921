//! Every WGSL module, as assembled, parses and validates with naga; every struct and
//! constant shared with Rust has the same layout and value on both sides. No GPU needed.

use std::mem::{offset_of, size_of};

use matedit::gpu::layout::{PIXEL_CHUNK, Params, Pixel, TEXEL_CHUNK, Texel, WG};
use matedit::gpu::{Pass, Tiles};

fn module(pass: Pass) -> naga::Module {
    module_with(pass, Tiles::Workgroup)
}

fn module_with(pass: Pass, tiles: Tiles) -> naga::Module {
    let src = pass.source(tiles);
    let module = naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{}: {}", pass.name(), e.emit_to_string(&src)));
    naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}: {}", pass.name(), e.emit_to_string(&src)));
    module
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
fn every_pass_parses_and_validates() {
    for (pass, tiles) in Pass::ALL
        .into_iter()
        .flat_map(|p| [(p, Tiles::Workgroup), (p, Tiles::Uniform)])
    {
        let m = module_with(pass, tiles);
        assert!(
            m.entry_points.iter().any(|e| e.name == pass.name()),
            "{} has no entry point of its name",
            pass.name()
        );
        assert_eq!(
            m.entry_points.len(),
            1,
            "{}: one entry point per file",
            pass.name()
        );
    }
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
            ("n_pixels", offset_of!(Params, n_pixels)),
            ("n_texels", offset_of!(Params, n_texels)),
            ("first", offset_of!(Params, first)),
            ("perspective", offset_of!(Params, perspective)),
            ("n_lobes", offset_of!(Params, n_lobes)),
            ("n_const", offset_of!(Params, n_const)),
            ("slice_len", offset_of!(Params, slice_len)),
            ("n_slices", offset_of!(Params, n_slices)),
            ("pixel_base", offset_of!(Params, pixel_base)),
            ("texel_base", offset_of!(Params, texel_base)),
            ("slice_stride", offset_of!(Params, slice_stride)),
            ("_pad", offset_of!(Params, _pad)),
            ("cc", offset_of!(Params, cc)),
            ("lc", offset_of!(Params, lc)),
        ],
        size_of::<Params>(),
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
}
