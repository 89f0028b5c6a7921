// tile_uniform.wgsl: where a gather pass reads its parameters and its looped-over records
// (`Tiled`) on a software adapter (lavapipe): one scene per dispatch, and one uniform chunk
// of CHUNK records bound per dispatch. Its invocations are SIMD lanes, and it reads uniform
// memory at an index common to all lanes once, but storage and workgroup memory inside a
// loop lane by lane, which costs it a third or more of its speed (docs/gpu.md). Appended
// instead of tile_workgroup.wgsl (see `Pass::source`).

// One scene per dispatch (z = 0), from a dynamic offset.
@group(0) @binding(0) var<uniform> scenes: array<Params, 1>;
@group(0) @binding(1) var<uniform> tile: array<Tiled, CHUNK>;

// Lavapipe runs every side of every branch under a mask: the lobe math selects instead
// (gather.wgsl).
const BRANCHES: bool = false;

// Records per tile: a slice never spans more than the chunk bound.
const TILE: u32 = CHUNK;

// The chunk is already in place: record t0 is at index t0.
fn load_tile(t0: u32, end: u32, li: u32) -> u32 {
    return t0;
}
