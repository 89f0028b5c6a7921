// backward_texel.wgsl: dLoss/dL and each texel's share of dLoss/dctrl. One invocation per
// texel (x) and pixel slice (y): the workgroup walks its slice's pixels a tile at a time
// (`load_tile`, as forward.wgsl) and every invocation sums over the tile; each writes
// (first range) or adds its slice's sums, and reduce_slices adds the slices in order.
// Mirrors src/reference/backward_texel.rs.
//
// dLoss/dL^k(i) = sum_p G^k f^k c d_omega
// share_i[idx(k, s, t, j)] = L^k d_omega sum_p G^k c E_s (x^m1_s, m0_s x^m1_s ln x)[t] B_j(theta_d)
//
// Orthographic cameras (theta_d per texel) sum 6 vectors over pixels and apply the texel's
// basis and scales at the end; perspective cameras apply each pair's basis inside the loop.
// The scales are stored times log2(e) and the loops take log2 x, so the t = 1 sums are
// m0 x^m1 ln x / ln(2)^2, multiplied by ln(2)^2 when written. The 36
// sums are named variables, not an indexed private array: that is slow on SIMD backends
// such as lavapipe.

@group(0) @binding(2) var<storage, read> texels: array<Texel>;
// [slice * slice_stride + texel_base + texel]
@group(0) @binding(3) var<storage, read_write> d_env: array<vec4<f32>>;
// 108 per slice and texel, [slice * slice_stride + texel_base + texel], in the material's
// flat order
@group(0) @binding(4) var<storage, read_write> d_share: array<f32>;

// The pixels with a non-zero upstream gradient, read through `tile` (tile_workgroup.wgsl
// or tile_uniform.wgsl).
alias Tiled = Pixel;
// Pixels per uniform chunk on a software adapter: 1344 * 48 bytes = 64512 <= 64 KiB.
const CHUNK: u32 = 1344u;

// Writes (first range) or adds the share of channel k, coefficient t, control point j of
// record o (slice * slice_stride + texel_base + texel), given over the three lobes.
fn put_share(o: u32, k: u32, t: u32, j: u32, v: vec3<f32>, first: bool) {
    let at = o * 108u + (k * 6u + t) * 6u + j;
    if first {
        d_share[at] = v.x;
        d_share[at + 12u] = v.y;
        d_share[at + 24u] = v.z;
    } else {
        d_share[at] += v.x;
        d_share[at + 12u] += v.y;
        d_share[at + 24u] += v.z;
    }
}

@compute @workgroup_size(WG)
fn backward_texel(@builtin(global_invocation_id) gid: vec3<u32>,
                  @builtin(workgroup_id) wg: vec3<u32>,
                  @builtin(local_invocation_index) li: u32) {
    let z = wg.z;
    let n_texels = scenes[z].n_texels;
    let live = gid.x < n_texels;
    // lanes past the end read the last texel and add nothing: they still load tiles
    let i = scenes[z].texel_base + min(gid.x, max(n_texels, 1u) - 1u);
    let w = texels[i].w.xyz;
    var acc_l = vec3<f32>(0.0);
    // a_KT_J: channel K, coefficient T (0 scale, 1 exponent), control point J; over lobes
    var a_r0_0 = vec3<f32>(0.0);
    var a_r0_1 = vec3<f32>(0.0);
    var a_r0_2 = vec3<f32>(0.0);
    var a_r0_3 = vec3<f32>(0.0);
    var a_r0_4 = vec3<f32>(0.0);
    var a_r0_5 = vec3<f32>(0.0);
    var a_r1_0 = vec3<f32>(0.0);
    var a_r1_1 = vec3<f32>(0.0);
    var a_r1_2 = vec3<f32>(0.0);
    var a_r1_3 = vec3<f32>(0.0);
    var a_r1_4 = vec3<f32>(0.0);
    var a_r1_5 = vec3<f32>(0.0);
    var a_g0_0 = vec3<f32>(0.0);
    var a_g0_1 = vec3<f32>(0.0);
    var a_g0_2 = vec3<f32>(0.0);
    var a_g0_3 = vec3<f32>(0.0);
    var a_g0_4 = vec3<f32>(0.0);
    var a_g0_5 = vec3<f32>(0.0);
    var a_g1_0 = vec3<f32>(0.0);
    var a_g1_1 = vec3<f32>(0.0);
    var a_g1_2 = vec3<f32>(0.0);
    var a_g1_3 = vec3<f32>(0.0);
    var a_g1_4 = vec3<f32>(0.0);
    var a_g1_5 = vec3<f32>(0.0);
    var a_b0_0 = vec3<f32>(0.0);
    var a_b0_1 = vec3<f32>(0.0);
    var a_b0_2 = vec3<f32>(0.0);
    var a_b0_3 = vec3<f32>(0.0);
    var a_b0_4 = vec3<f32>(0.0);
    var a_b0_5 = vec3<f32>(0.0);
    var a_b1_0 = vec3<f32>(0.0);
    var a_b1_1 = vec3<f32>(0.0);
    var a_b1_2 = vec3<f32>(0.0);
    var a_b1_3 = vec3<f32>(0.0);
    var a_b1_4 = vec3<f32>(0.0);
    var a_b1_5 = vec3<f32>(0.0);
    // orthographic cameras: the pair's coefficients are the texel's (`Texel.coef`)
    let h = texels[i].h.xyz;
    let pad = texels[i].ld.w;
    let coef = texels[i].coef;
    let m0r = coef[0].xyz;
    let m0g = coef[2].xyz;
    let m0b = coef[4].xyz;
    // per channel over lobes: sum_p G c E x^m1 (d0) and sum_p G c E x^m1 log2 x (d1, times
    // m0 log2(e) after the loop)
    var d0r = vec3<f32>(0.0);
    var d1r = vec3<f32>(0.0);
    var d0g = vec3<f32>(0.0);
    var d1g = vec3<f32>(0.0);
    var d0b = vec3<f32>(0.0);
    var d1b = vec3<f32>(0.0);
    let start = scenes[z].pixel_base + wg.y * scenes[z].slice_len;
    let end = min(start + scenes[z].slice_len, scenes[z].pixel_base + scenes[z].n_pixels);
    for (var p0 = start; p0 < end; p0 += TILE) {
        let base = load_tile(p0, end, li);
        let m = select(0u, min(TILE, end - p0), live);
        if scenes[z].perspective == 0u {
            for (var p = 0u; p < m; p++) {
                let n = tile[base + p].n;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let xl = lobe_x(h, n, tile[base + p].nn_m1, pad);
                let l2 = xl.y;
                let gc = tile[base + p].g.xyz * c;
                // x^m1 ln x is taken as 0 at x = 0
                let gl = gc * select(0.0, l2, xl.x > 0.0);
                let lk = shared_channels(l2, coef);
                let lr = lk.r;
                let lg = lk.g;
                let lb = lk.b;
                acc_l += gc * vec3<f32>(lr.f, lg.f, lb.f);
                d0r += gc.x * lr.d0;
                d1r += gl.x * lr.d0;
                d0g += gc.y * lg.d0;
                d1g += gl.y * lg.d0;
                d0b += gc.z * lb.d0;
                d1b += gl.z * lb.d0;
            }
        } else {
            for (var p = 0u; p < m; p++) {
                let n = tile[base + p].n;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let hv = half_vector(w, tile[base + p].wp.xyz);
                let b = spline_basis(hv.theta_d);
                let xl = lobe_x(hv.h, n, tile[base + p].nn_m1, hv.pad);
                let l2 = xl.y;
                let gc = tile[base + p].g.xyz * c;
                let gl = gc * select(0.0, l2, xl.x > 0.0);
                let m0r = pair_coef(b, 0u, z);
                let m1r = pair_coef(b, 6u, z);
                let m0g = pair_coef(b, 12u, z);
                let m1g = pair_coef(b, 18u, z);
                let m0b = pair_coef(b, 24u, z);
                let m1b = pair_coef(b, 30u, z);
                let lr = lobe_grads(l2, m0r, m1r, least(m1r));
                let lg = lobe_grads(l2, m0g, m1g, least(m1g));
                let lb = lobe_grads(l2, m0b, m1b, least(m1b));
                acc_l += gc * vec3<f32>(lr.f, lg.f, lb.f);
                let wr0 = gc.x * lr.d0;
                let wr1 = gl.x * m0r * lr.d0;
                let wg0 = gc.y * lg.d0;
                let wg1 = gl.y * m0g * lg.d0;
                let wb0 = gc.z * lb.d0;
                let wb1 = gl.z * m0b * lb.d0;
                a_r0_0 += b[0] * wr0;
                a_r0_1 += b[1] * wr0;
                a_r0_2 += b[2] * wr0;
                a_r0_3 += b[3] * wr0;
                a_r0_4 += b[4] * wr0;
                a_r0_5 += b[5] * wr0;
                a_r1_0 += b[0] * wr1;
                a_r1_1 += b[1] * wr1;
                a_r1_2 += b[2] * wr1;
                a_r1_3 += b[3] * wr1;
                a_r1_4 += b[4] * wr1;
                a_r1_5 += b[5] * wr1;
                a_g0_0 += b[0] * wg0;
                a_g0_1 += b[1] * wg0;
                a_g0_2 += b[2] * wg0;
                a_g0_3 += b[3] * wg0;
                a_g0_4 += b[4] * wg0;
                a_g0_5 += b[5] * wg0;
                a_g1_0 += b[0] * wg1;
                a_g1_1 += b[1] * wg1;
                a_g1_2 += b[2] * wg1;
                a_g1_3 += b[3] * wg1;
                a_g1_4 += b[4] * wg1;
                a_g1_5 += b[5] * wg1;
                a_b0_0 += b[0] * wb0;
                a_b0_1 += b[1] * wb0;
                a_b0_2 += b[2] * wb0;
                a_b0_3 += b[3] * wb0;
                a_b0_4 += b[4] * wb0;
                a_b0_5 += b[5] * wb0;
                a_b1_0 += b[0] * wb1;
                a_b1_1 += b[1] * wb1;
                a_b1_2 += b[2] * wb1;
                a_b1_3 += b[3] * wb1;
                a_b1_4 += b[4] * wb1;
                a_b1_5 += b[5] * wb1;
            }
        }
    }
    if !live {
        return;
    }
    if scenes[z].perspective == 0u {
        d1r *= m0r;
        d1g *= m0g;
        d1b *= m0b;
        let tb = spline_basis(texels[i].h.w);
        a_r0_0 = d0r * tb[0];
        a_r0_1 = d0r * tb[1];
        a_r0_2 = d0r * tb[2];
        a_r0_3 = d0r * tb[3];
        a_r0_4 = d0r * tb[4];
        a_r0_5 = d0r * tb[5];
        a_r1_0 = d1r * tb[0];
        a_r1_1 = d1r * tb[1];
        a_r1_2 = d1r * tb[2];
        a_r1_3 = d1r * tb[3];
        a_r1_4 = d1r * tb[4];
        a_r1_5 = d1r * tb[5];
        a_g0_0 = d0g * tb[0];
        a_g0_1 = d0g * tb[1];
        a_g0_2 = d0g * tb[2];
        a_g0_3 = d0g * tb[3];
        a_g0_4 = d0g * tb[4];
        a_g0_5 = d0g * tb[5];
        a_g1_0 = d1g * tb[0];
        a_g1_1 = d1g * tb[1];
        a_g1_2 = d1g * tb[2];
        a_g1_3 = d1g * tb[3];
        a_g1_4 = d1g * tb[4];
        a_g1_5 = d1g * tb[5];
        a_b0_0 = d0b * tb[0];
        a_b0_1 = d0b * tb[1];
        a_b0_2 = d0b * tb[2];
        a_b0_3 = d0b * tb[3];
        a_b0_4 = d0b * tb[4];
        a_b0_5 = d0b * tb[5];
        a_b1_0 = d1b * tb[0];
        a_b1_1 = d1b * tb[1];
        a_b1_2 = d1b * tb[2];
        a_b1_3 = d1b * tb[3];
        a_b1_4 = d1b * tb[4];
        a_b1_5 = d1b * tb[5];
    }
    let ld = texels[i].ld.xyz;
    // the t = 1 sums are m0 x^m1 log2 x log2(e) = m0 x^m1 ln x / ln(2)^2
    let ld1 = ld * (LN_2 * LN_2);
    let dl = vec4<f32>(acc_l * texels[i].w.w, 0.0);
    let first = scenes[z].first == 1u;
    let o = wg.y * scenes[z].slice_stride + scenes[z].texel_base + gid.x;
    if first {
        d_env[o] = dl;
    } else {
        d_env[o] += dl;
    }
    put_share(o, 0u, 0u, 0u, a_r0_0 * ld.x, first);
    put_share(o, 0u, 0u, 1u, a_r0_1 * ld.x, first);
    put_share(o, 0u, 0u, 2u, a_r0_2 * ld.x, first);
    put_share(o, 0u, 0u, 3u, a_r0_3 * ld.x, first);
    put_share(o, 0u, 0u, 4u, a_r0_4 * ld.x, first);
    put_share(o, 0u, 0u, 5u, a_r0_5 * ld.x, first);
    put_share(o, 0u, 1u, 0u, a_r1_0 * ld1.x, first);
    put_share(o, 0u, 1u, 1u, a_r1_1 * ld1.x, first);
    put_share(o, 0u, 1u, 2u, a_r1_2 * ld1.x, first);
    put_share(o, 0u, 1u, 3u, a_r1_3 * ld1.x, first);
    put_share(o, 0u, 1u, 4u, a_r1_4 * ld1.x, first);
    put_share(o, 0u, 1u, 5u, a_r1_5 * ld1.x, first);
    put_share(o, 1u, 0u, 0u, a_g0_0 * ld.y, first);
    put_share(o, 1u, 0u, 1u, a_g0_1 * ld.y, first);
    put_share(o, 1u, 0u, 2u, a_g0_2 * ld.y, first);
    put_share(o, 1u, 0u, 3u, a_g0_3 * ld.y, first);
    put_share(o, 1u, 0u, 4u, a_g0_4 * ld.y, first);
    put_share(o, 1u, 0u, 5u, a_g0_5 * ld.y, first);
    put_share(o, 1u, 1u, 0u, a_g1_0 * ld1.y, first);
    put_share(o, 1u, 1u, 1u, a_g1_1 * ld1.y, first);
    put_share(o, 1u, 1u, 2u, a_g1_2 * ld1.y, first);
    put_share(o, 1u, 1u, 3u, a_g1_3 * ld1.y, first);
    put_share(o, 1u, 1u, 4u, a_g1_4 * ld1.y, first);
    put_share(o, 1u, 1u, 5u, a_g1_5 * ld1.y, first);
    put_share(o, 2u, 0u, 0u, a_b0_0 * ld.z, first);
    put_share(o, 2u, 0u, 1u, a_b0_1 * ld.z, first);
    put_share(o, 2u, 0u, 2u, a_b0_2 * ld.z, first);
    put_share(o, 2u, 0u, 3u, a_b0_3 * ld.z, first);
    put_share(o, 2u, 0u, 4u, a_b0_4 * ld.z, first);
    put_share(o, 2u, 0u, 5u, a_b0_5 * ld.z, first);
    put_share(o, 2u, 1u, 0u, a_b1_0 * ld1.z, first);
    put_share(o, 2u, 1u, 1u, a_b1_1 * ld1.z, first);
    put_share(o, 2u, 1u, 2u, a_b1_2 * ld1.z, first);
    put_share(o, 2u, 1u, 3u, a_b1_3 * ld1.z, first);
    put_share(o, 2u, 1u, 4u, a_b1_4 * ld1.z, first);
    put_share(o, 2u, 1u, 5u, a_b1_5 * ld1.z, first);
}
