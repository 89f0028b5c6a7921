// forward.wgsl: the image. One invocation per foreground pixel, looping over one uniform
// chunk of lit texels per dispatch and adding into the pixel's sum. Mirrors src/cpu/forward.rs.

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<uniform> texels: array<Texel, TEXEL_CHUNK>;
@group(0) @binding(2) var<storage, read> pixels: array<Pixel>;
@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;

@compute @workgroup_size(WG)
fn forward(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = gid.x;
    if p >= params.n_pixels {
        return;
    }
    let n = pixels[p].n.xyz;
    let wp = pixels[p].wp.xyz;
    var acc = vec3<f32>(0.0);
    for (var i = 0u; i < params.n_texels; i++) {
        let w = texels[i].w.xyz;
        let c = dot(n, w);
        // below the horizon: adds nothing
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
        var f: vec3<f32>;
        for (var k = 0u; k < 3u; k++) {
            let e = stable_expm1(m0[k] * lobe_pow(x, lnx, m1[k]));
            f[k] = e.x + e.y + e.z;
        }
        acc += f * texels[i].ld.xyz * c;
    }
    if params.first == 1u {
        image[p] = vec4<f32>(acc, 0.0);
    } else {
        image[p] += vec4<f32>(acc, 0.0);
    }
}
