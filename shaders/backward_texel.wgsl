// backward_texel.wgsl: dLoss/dL and each texel's share of dLoss/dctrl. One invocation per
// texel, looping over one uniform chunk of pixels per dispatch and adding into the texel's
// sums. Mirrors src/cpu/backward_texel.rs.
//
// dLoss/dL^k(i) = sum_p G^k f^k c d_omega
// share_i[idx(k, s, t, j)] = L^k d_omega sum_p G^k c E_s (x^m1_s, m0_s x^m1_s ln x)[t] B_j(theta_d)
//
// Orthographic cameras (theta_d per texel) sum 6 vectors over pixels and apply the texel's
// basis at the end; perspective cameras apply each pair's basis inside the loop.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> pixels: array<Pixel, PIXEL_CHUNK>;
@group(0) @binding(2) var<storage, read> texels: array<Texel>;
@group(0) @binding(3) var<storage, read_write> d_env: array<vec4<f32>>;
// 108 per texel, in the material's flat order
@group(0) @binding(4) var<storage, read_write> d_share: array<f32>;

@compute @workgroup_size(WG)
fn backward_texel(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n_texels {
        return;
    }
    let w = texels[i].w.xyz;
    var acc_l = vec3<f32>(0.0);
    // acc[(k * 2 + t) * 6 + j], over lobes
    var acc: array<vec3<f32>, 36>;
    if params.perspective == 0u {
        let h = texels[i].h.xyz;
        let m0r = texels[i].coef[0].xyz;
        let m1r = texels[i].coef[1].xyz;
        let m0g = texels[i].coef[2].xyz;
        let m1g = texels[i].coef[3].xyz;
        let m0b = texels[i].coef[4].xyz;
        let m1b = texels[i].coef[5].xyz;
        var d0r = vec3<f32>(0.0);
        var d1r = vec3<f32>(0.0);
        var d0g = vec3<f32>(0.0);
        var d1g = vec3<f32>(0.0);
        var d0b = vec3<f32>(0.0);
        var d1b = vec3<f32>(0.0);
        for (var p = 0u; p < params.n_pixels; p++) {
            let n = pixels[p].n.xyz;
            let c = dot(n, w);
            if c <= 0.0 {
                continue;
            }
            let x = max(0.0, dot(h, n));
            let lnx = lobe_log(x);
            let gc = pixels[p].g.xyz * c;
            let r = lobe_grads(x, lnx, m0r, m1r);
            let g = lobe_grads(x, lnx, m0g, m1g);
            let b = lobe_grads(x, lnx, m0b, m1b);
            acc_l += gc * vec3<f32>(r.f, g.f, b.f);
            d0r += gc.x * r.d0;
            d1r += gc.x * r.d1;
            d0g += gc.y * g.d0;
            d1g += gc.y * g.d1;
            d0b += gc.z * b.d0;
            d1b += gc.z * b.d1;
        }
        let tb = spline_basis(texels[i].h.w);
        for (var j = 0u; j < 6u; j++) {
            acc[j] = d0r * tb[j];
            acc[6u + j] = d1r * tb[j];
            acc[12u + j] = d0g * tb[j];
            acc[18u + j] = d1g * tb[j];
            acc[24u + j] = d0b * tb[j];
            acc[30u + j] = d1b * tb[j];
        }
    } else {
        for (var p = 0u; p < params.n_pixels; p++) {
            let n = pixels[p].n.xyz;
            let c = dot(n, w);
            if c <= 0.0 {
                continue;
            }
            let hv = half_vector(w, pixels[p].wp.xyz);
            let b = spline_basis(hv.w);
            let x = max(0.0, dot(hv.xyz, n));
            let lnx = lobe_log(x);
            let gc = pixels[p].g.xyz * c;
            for (var k = 0u; k < 3u; k++) {
                let base = k * 12u;
                let lg = lobe_grads(x, lnx, pair_coef(b, base), pair_coef(b, base + 6u));
                acc_l[k] += gc[k] * lg.f;
                for (var j = 0u; j < 6u; j++) {
                    acc[base + j] += (gc[k] * b[j]) * lg.d0;
                    acc[base + 6u + j] += (gc[k] * b[j]) * lg.d1;
                }
            }
        }
    }
    let ld = texels[i].ld.xyz;
    let dl = vec4<f32>(acc_l * texels[i].w.w, 0.0);
    let first = params.first == 1u;
    if first {
        d_env[i] = dl;
    } else {
        d_env[i] += dl;
    }
    for (var k = 0u; k < 3u; k++) {
        for (var t = 0u; t < 2u; t++) {
            for (var j = 0u; j < 6u; j++) {
                let a = acc[(k * 2u + t) * 6u + j] * ld[k];
                for (var s = 0u; s < 3u; s++) {
                    let o = i * 108u + ((k * 3u + s) * 2u + t) * 6u + j;
                    if first {
                        d_share[o] = a[s];
                    } else {
                        d_share[o] += a[s];
                    }
                }
            }
        }
    }
}
