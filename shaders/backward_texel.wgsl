// backward_texel.wgsl: dLoss/dL and each texel's share of dLoss/dctrl. One invocation per
// texel, looping over one uniform chunk of pixels per dispatch and adding into the texel's
// sums. Mirrors src/cpu/backward_texel.rs.
//
// dLoss/dL^k(i) = sum_p G^k f^k c d_omega
// share_i[idx(k, s, t, j)] = L^k d_omega sum_p G^k c E_s (x^m1_s, m0_s x^m1_s ln x)[t] B_j(theta_d)

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
    // acc[(k * 2 + t) * 6 + j], over lobes; orthographic cameras use j = 0 only and
    // apply the texel's basis at the end.
    var acc: array<vec3<f32>, 36>;
    for (var p = 0u; p < params.n_pixels; p++) {
        let n = pixels[p].n.xyz;
        let c = dot(n, w);
        if c <= 0.0 {
            continue;
        }
        var h: vec3<f32>;
        var b: array<f32, 6>;
        var m0: array<vec3<f32>, 3>;
        var m1: array<vec3<f32>, 3>;
        if params.perspective == 0u {
            h = texels[i].h.xyz;
            for (var k = 0u; k < 3u; k++) {
                m0[k] = texels[i].coef[k * 2u].xyz;
                m1[k] = texels[i].coef[k * 2u + 1u].xyz;
            }
        } else {
            let hv = half_vector(w, pixels[p].wp.xyz);
            h = hv.xyz;
            b = spline_basis(hv.w);
            for (var k = 0u; k < 3u; k++) {
                m0[k] = pair_coef(b, k, 0u);
                m1[k] = pair_coef(b, k, 1u);
            }
        }
        let x = max(0.0, dot(h, n));
        let lnx = lobe_log(x);
        let gc = pixels[p].g.xyz * c;
        for (var k = 0u; k < 3u; k++) {
            let pw = lobe_pow(x, lnx, m1[k]);
            let e = stable_expm1(m0[k] * pw);
            acc_l[k] += gc[k] * (e.x + e.y + e.z);
            let d0 = gc[k] * (e + 1.0) * pw;
            let d1 = gc[k] * (e + 1.0) * m0[k] * lobe_pow_log(x, lnx, pw);
            if params.perspective == 0u {
                acc[(k * 2u) * 6u] += d0;
                acc[(k * 2u + 1u) * 6u] += d1;
            } else {
                for (var j = 0u; j < 6u; j++) {
                    acc[(k * 2u) * 6u + j] += b[j] * d0;
                    acc[(k * 2u + 1u) * 6u + j] += b[j] * d1;
                }
            }
        }
    }
    let ld = texels[i].ld.xyz;
    let dl = vec4<f32>(acc_l * texels[i].w.w, 0.0);
    var tb = array<f32, 6>(1.0, 1.0, 1.0, 1.0, 1.0, 1.0);
    if params.perspective == 0u {
        tb = spline_basis(texels[i].h.w);
    }
    let first = params.first == 1u;
    if first {
        d_env[i] = dl;
    } else {
        d_env[i] += dl;
    }
    for (var k = 0u; k < 3u; k++) {
        for (var t = 0u; t < 2u; t++) {
            for (var j = 0u; j < 6u; j++) {
                var a: vec3<f32>;
                if params.perspective == 0u {
                    a = acc[(k * 2u + t) * 6u] * tb[j];
                } else {
                    a = acc[(k * 2u + t) * 6u + j];
                }
                a *= ld[k];
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
