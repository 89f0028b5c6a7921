// reduce_ctrl.wgsl: dLoss/dctrl = the sum over texels of each texel's share. One workgroup
// per control point (x) and scene of a batch (z): each thread sums a strided slice of the
// scene's n_texels shares (from its texel_base: a batch's scenes may have different texel
// counts, e.g. the parts of a level of detail), then a tree in workgroup memory, so the
// order of additions is fixed. Mirrors src/reference/reduce_ctrl.rs.

// One Params per scene (z), from a dynamic offset.
@group(0) @binding(0) var<storage, read> scenes: array<Params>;
@group(0) @binding(1) var<storage, read> d_share: array<f32>;
@group(0) @binding(2) var<storage, read_write> d_ctrl: array<f32>;

var<workgroup> partial: array<f32, WG>;

@compute @workgroup_size(WG)
fn reduce_ctrl(@builtin(workgroup_id) wg: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let col = wg.x;
    let base = scenes[wg.z].texel_base;
    let n = scenes[wg.z].n_texels;
    var s = 0.0;
    for (var i = li; i < n; i += WG) {
        s += d_share[(base + i) * 108u + col];
    }
    partial[li] = s;
    workgroupBarrier();
    for (var stride = WG / 2u; stride > 0u; stride /= 2u) {
        if li < stride {
            partial[li] += partial[li + stride];
        }
        workgroupBarrier();
    }
    if li == 0u {
        let o = wg.z * 108u + col;
        if scenes[wg.z].first == 1u {
            d_ctrl[o] = partial[0];
        } else {
            d_ctrl[o] += partial[0];
        }
    }
}
