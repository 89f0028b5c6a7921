// reduce_ctrl.wgsl: dLoss/dctrl = the sum over texels of each texel's share. One workgroup
// per control point (x) and scene of a batch (z, n_texels shares each): each thread sums a
// strided slice, then a tree in workgroup memory, so the order of additions is fixed.
// Mirrors src/reference/reduce_ctrl.rs.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> d_share: array<f32>;
@group(0) @binding(2) var<storage, read_write> d_ctrl: array<f32>;

var<workgroup> partial: array<f32, WG>;

@compute @workgroup_size(WG)
fn reduce_ctrl(@builtin(workgroup_id) wg: vec3<u32>,
               @builtin(local_invocation_index) li: u32) {
    let col = wg.x;
    let base = wg.z * params.n_texels;
    var s = 0.0;
    for (var i = li; i < params.n_texels; i += WG) {
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
        if params.first == 1u {
            d_ctrl[o] = partial[0];
        } else {
            d_ctrl[o] += partial[0];
        }
    }
}
