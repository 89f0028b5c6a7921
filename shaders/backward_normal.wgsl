// backward_normal.wgsl: dLoss/dn. One invocation per foreground pixel (x) and texel slice
// (y), over the slice's lit texels a tile at a time, as forward.wgsl; writes (first
// range) or adds the slice's sum, and reduce_slices adds the slices in order.
// Mirrors src/reference/backward_normal.rs.
//
// dLoss/dn = sum_i [ (sum_k G^k L^k d_omega f^k) w_i
//                    + c_i (sum_k G^k L^k d_omega sum_s E_s m0_s m1_s x^(m1_s - 1)) h ]

@group(0) @binding(2) var<storage, read> pixels: array<Pixel>;
// [slice * slice_stride + pixel_base + pixel]
@group(0) @binding(3) var<storage, read_write> d_normals: array<vec4<f32>>;

// The lit texels, read through `tile` (tile_workgroup.wgsl or tile_uniform.wgsl).
alias Tiled = Texel;
// Texels per uniform chunk on a software adapter: 252 * 256 bytes = 64512 <= 64 KiB.
const CHUNK: u32 = 252u;

@compute @workgroup_size(WG)
fn backward_normal(@builtin(global_invocation_id) gid: vec3<u32>,
                   @builtin(workgroup_id) wg: vec3<u32>,
                   @builtin(local_invocation_index) li: u32) {
    let z = wg.z;
    let n_pixels = scenes[z].n_pixels;
    let p = gid.x;
    let live = p < n_pixels;
    // lanes past the end load the last pixel and add nothing: they still load tiles
    let px = pixels[scenes[z].pixel_base + min(p, max(n_pixels, 1u) - 1u)];
    let n = px.n;
    let nn_m1 = px.nn_m1;
    let wp = px.wp.xyz;
    let g = px.g.xyz;
    let start = scenes[z].texel_base + wg.y * scenes[z].slice_len;
    let end = min(start + scenes[z].slice_len, scenes[z].texel_base + scenes[z].n_texels);
    // the scene's lobe counts, read once, not in every pair's lobe loop
    let n_active = scenes[z].n_lobes;
    let n_const = scenes[z].n_const;
    var acc = vec3<f32>(0.0);
    for (var t0 = start; t0 < end; t0 += TILE) {
        let base = load_tile(t0, end, li);
        let m = select(0u, min(TILE, end - t0), live);
        if scenes[z].perspective == 0u {
            for (var i = 0u; i < m; i++) {
                let w = tile[base + i].w.xyz;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let h = tile[base + i].h.xyz;
                let ld = tile[base + i].ld;
                let xl = lobe_x(h, n, nn_m1, ld.w);
                let l2 = xl.y;
                let ix = inv_x(xl.x);
                // constant lobes are in fconst (no dependence on x); lobes with scale 0 are left out
                var f = tile[base + i].fconst.xyz;
                // sum_s E_s m0_s m1_s x^m1_s log2(e) (the scales are stored times log2(e)),
                // times ln(2) / x below
                var dx = vec3<f32>(0.0);
                for (var a = 0u; a < n_active; a++) {
                    let m1 = tile[base + i].lobes[2u * a + 1u];
                    // x^m1 underflows in every channel: adds nothing (x^(m1 - 1) = x^m1 / x
                    // is then under 2^-126, x being 0 or at least 2^-24)
                    if underflows(l2 * m1.w) {
                        continue;
                    }
                    // w: what the channels share
                    let m0 = tile[base + i].lobes[2u * a];
                    let lobe = shared_lobe(l2, m0, m1);
                    f += lobe.e;
                    let q = m0.xyz * m1.xyz * lobe.p;
                    dx += lobe.e * q + q;
                }
                let gl = g * ld.xyz;
                acc += dot(gl, f) * w + (c * LN_2 * ix * dot(gl, dx)) * h;
            }
        } else {
            for (var i = 0u; i < m; i++) {
                let w = tile[base + i].w.xyz;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let hv = half_vector(w, wp);
                let h = hv.h;
                let b = spline_basis(hv.theta_d);
                let xl = lobe_x(h, n, nn_m1, hv.pad);
                let l2 = xl.y;
                let ix = inv_x(xl.x);
                // active lobes, then constant lobes (no dependence on x); scale 0 left out
                var f = vec3<f32>(0.0);
                var dx = vec3<f32>(0.0);
                for (var q = 0u; q < n_active; q++) {
                    let m0 = lobe_coef(b, q * 12u, z);
                    let m1 = lobe_coef(b, q * 12u + 6u, z);
                    let p = lobe_pow(l2, m1);
                    let e = exp2m1_3(m0 * p);
                    f += e;
                    let q = m0 * m1 * p;
                    dx += e * q + q;
                }
                for (var q = n_active; q < n_active + n_const; q++) {
                    f += exp2m1_3(lobe_coef(b, q * 12u, z));
                }
                let gl = g * tile[base + i].ld.xyz;
                acc += dot(gl, f) * w + (c * LN_2 * ix * dot(gl, dx)) * h;
            }
        }
    }
    if !live {
        return;
    }
    let o = wg.y * scenes[z].slice_stride + scenes[z].pixel_base + p;
    if scenes[z].first == 1u {
        d_normals[o] = vec4<f32>(acc, 0.0);
    } else {
        d_normals[o] += vec4<f32>(acc, 0.0);
    }
}
