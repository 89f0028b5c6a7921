// tile_workgroup.wgsl: where a gather pass reads its parameters and its looped-over records
// (`Tiled`) on a GPU: a batch's scenes in one dispatch (one Params each, z = the scene), and
// the records loaded a tile of WG at a time from a storage buffer into workgroup memory,
// once, for every invocation of the workgroup to read.
// Appended to forward, backward_normal and backward_texel (see `Pass::source`).

// One Params per scene of the dispatch (z = the scene), from a dynamic offset.
@group(0) @binding(0) var<storage, read> scenes: array<Params>;
@group(0) @binding(1) var<storage, read> tiled: array<Tiled>;

var<workgroup> tile: array<Tiled, WG>;

// A GPU's lanes skip the side of a branch that none of them takes: the lobe math branches
// (gather.wgsl).
const BRANCHES: bool = true;

// Records per tile: each slice is walked in steps of TILE.
const TILE: u32 = WG;

// Loads records t0 .. min(t0 + TILE, end) into `tile`; returns the index in `tile` of
// record t0. Called in uniform control flow by every invocation of the workgroup.
fn load_tile(t0: u32, end: u32, li: u32) -> u32 {
    workgroupBarrier();
    if t0 + li < end {
        tile[li] = tiled[t0 + li];
    }
    workgroupBarrier();
    return 0u;
}
