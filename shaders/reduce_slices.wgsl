// reduce_slices.wgsl: the sum over slices of each element's partial sums, in slice order
// (((s0 + s1) + s2) + ...), so that the result is fixed for a given slice count. One
// invocation per vec4 element; workgroups beyond the x limit go on in y. The reference
// sums in one sequence (src/reference/forward.rs ...): slices only change the f32 order.

@group(0) @binding(0) var<uniform> params: Params;
// [slice * n_pixels + element]
@group(0) @binding(1) var<storage, read> parts: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read_write> total: array<vec4<f32>>;

@compute @workgroup_size(WG)
fn reduce_slices(@builtin(global_invocation_id) gid: vec3<u32>,
                 @builtin(num_workgroups) groups: vec3<u32>) {
    let e = gid.x + gid.y * groups.x * WG;
    let n = params.n_pixels;
    if e >= n {
        return;
    }
    var s = parts[e];
    for (var k = 1u; k < params.n_slices; k++) {
        s += parts[k * n + e];
    }
    total[e] = s;
}
