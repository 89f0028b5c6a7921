// backward_normal.wgsl: dLoss/dn. One invocation per foreground pixel, looping over one
// uniform chunk of lit texels per dispatch. Mirrors src/cpu/backward_normal.rs.
//
// dLoss/dn = sum_i [ (sum_k G^k L^k d_omega f^k) w_i
//                    + c_i (sum_k G^k L^k d_omega sum_s E_s m0_s m1_s x^(m1_s - 1)) h ]

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> texels: array<Texel, TEXEL_CHUNK>;
@group(0) @binding(2) var<storage, read> pixels: array<Pixel>;
@group(0) @binding(3) var<storage, read_write> d_normals: array<vec4<f32>>;

@compute @workgroup_size(WG)
fn backward_normal(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if p >= params.n_pixels {
        return;
    }
    let n = pixels[p].n.xyz;
    let wp = pixels[p].wp.xyz;
    let g = pixels[p].g.xyz;
    var acc = vec3<f32>(0.0);
    for (var i = 0u; i < params.n_texels; i++) {
        let w = texels[i].w.xyz;
        let c = dot(n, w);
        if c <= 0.0 {
            continue;
        }
        var h: vec3<f32>;
        var m0: array<vec3<f32>, 3>;
        var m1: array<vec3<f32>, 3>;
        if params.perspective == 0u {
            h = texels[i].h.xyz;
            for (var k = 0u; k < 3u; k++) {
                m0[k] = texels[i].coef[k * 2u].xyz;
                m1[k] = texels[i].coef[k * 2u + 1u].xyz;
            }
        } else {
            let hv = half_vector(w, wp);
            h = hv.xyz;
            let b = spline_basis(hv.w);
            for (var k = 0u; k < 3u; k++) {
                m0[k] = pair_coef(b, k, 0u);
                m1[k] = pair_coef(b, k, 1u);
            }
        }
        let x = max(0.0, dot(h, n));
        let lnx = lobe_log(x);
        let gl = g * texels[i].ld.xyz;
        var along_w = 0.0;
        var along_h = 0.0;
        for (var k = 0u; k < 3u; k++) {
            let e = stable_expm1(m0[k] * lobe_pow(x, lnx, m1[k]));
            along_w += gl[k] * (e.x + e.y + e.z);
            let dx = (e + 1.0) * m0[k] * lobe_dpow(x, lnx, m1[k]);
            along_h += gl[k] * (dx.x + dx.y + dx.z);
        }
        acc += along_w * w + (c * along_h) * h;
    }
    if params.first == 1u {
        d_normals[p] = vec4<f32>(acc, 0.0);
    } else {
        d_normals[p] += vec4<f32>(acc, 0.0);
    }
}
