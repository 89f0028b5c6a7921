// backward_normal.wgsl: dLoss/dn. One invocation per foreground pixel, looping over one
// uniform chunk of lit texels per dispatch. Mirrors src/reference/backward_normal.rs.
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
    let n = pixels[p].n;
    let nn_m1 = pixels[p].nn_m1;
    let wp = pixels[p].wp.xyz;
    let g = pixels[p].g.xyz;
    var acc = vec3<f32>(0.0);
    if params.perspective == 0u {
        for (var i = 0u; i < params.n_texels; i++) {
            let w = texels[i].w.xyz;
            let c = dot(n, w);
            if c <= 0.0 {
                continue;
            }
            let h = texels[i].h.xyz;
            let xl = lobe_x(h, n, nn_m1);
            let x = xl.x;
            let lnx = xl.y;
            // constant lobes are in fconst (no dependence on x); lobes with scale 0 are left out
            var f = texels[i].fconst.xyz;
            var dx = vec3<f32>(0.0);
            for (var a = 0u; a < params.n_lobes; a++) {
                let m0 = texels[i].lobes[2u * a].xyz;
                let m1 = texels[i].lobes[2u * a + 1u].xyz;
                let e = stable_expm1(m0 * lobe_pow(x, lnx, m1));
                f += e;
                dx += (e + 1.0) * m0 * lobe_dpow(x, lnx, m1);
            }
            let gl = g * texels[i].ld.xyz;
            acc += dot(gl, f) * w + (c * dot(gl, dx)) * h;
        }
    } else {
        for (var i = 0u; i < params.n_texels; i++) {
            let w = texels[i].w.xyz;
            let c = dot(n, w);
            if c <= 0.0 {
                continue;
            }
            let hv = half_vector(w, wp);
            let h = hv.xyz;
            let b = spline_basis(hv.w);
            let xl = lobe_x(h, n, nn_m1);
            let x = xl.x;
            let lnx = xl.y;
            // active lobes, then constant lobes (no dependence on x); scale 0 left out
            var f = vec3<f32>(0.0);
            var dx = vec3<f32>(0.0);
            for (var q = 0u; q < params.n_lobes; q++) {
                let m0 = lobe_coef(b, q * 12u);
                let m1 = lobe_coef(b, q * 12u + 6u);
                let e = stable_expm1(m0 * lobe_pow(x, lnx, m1));
                f += e;
                dx += (e + 1.0) * m0 * lobe_dpow(x, lnx, m1);
            }
            for (var q = params.n_lobes; q < params.n_lobes + params.n_const; q++) {
                f += stable_expm1(lobe_coef(b, q * 12u));
            }
            let gl = g * texels[i].ld.xyz;
            let along_w = dot(gl, f);
            let along_h = dot(gl, dx);
            acc += along_w * w + (c * along_h) * h;
        }
    }
    if params.first == 1u {
        d_normals[p] = vec4<f32>(acc, 0.0);
    } else {
        d_normals[p] += vec4<f32>(acc, 0.0);
    }
}
