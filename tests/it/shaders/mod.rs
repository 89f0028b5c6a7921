//! The WGSL modules with naga, no GPU needed, a module per idea: every module, as assembled,
//! parses and validates (`validate`); every struct and constant shared with Rust has the
//! same layout and value on both sides (`layout`); the operations per lit pair of each
//! gather pass stay under bounds (`op_counts`). Here: the modules as naga parses them.

mod layout;
mod op_counts;
mod validate;

use matedit::gpu::{Pass, Tiles};

pub(super) fn module_with(pass: Pass, tiles: Tiles) -> naga::Module {
    validated(pass, tiles).0
}

/// The module of `pass` on `tiles`, and naga's analysis of it (expression types, uses).
pub(super) fn validated(pass: Pass, tiles: Tiles) -> (naga::Module, naga::valid::ModuleInfo) {
    let src = pass.source(tiles);
    let module = naga::front::wgsl::parse_str(&src)
        .unwrap_or_else(|e| panic!("{}: {}", pass.name(), e.emit_to_string(&src)));
    let info = naga::valid::Validator::new(
        naga::valid::ValidationFlags::all(),
        naga::valid::Capabilities::empty(),
    )
    .validate(&module)
    .unwrap_or_else(|e| panic!("{}: {}", pass.name(), e.emit_to_string(&src)));
    (module, info)
}
