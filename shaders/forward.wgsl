// forward.wgsl: the image. One invocation per foreground pixel, looping over one uniform
// chunk of lit texels per dispatch and adding into the pixel's sum. Mirrors src/reference/forward.rs.
// The camera branch is outside the texel loop and the channels are unrolled, because
// lavapipe runs invocations as SIMD lanes and private arrays indexed in loops are slow there.

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
    let n = pixels[p].n;
    let nn_m1 = pixels[p].nn_m1;
    let wp = pixels[p].wp.xyz;
    var acc = vec3<f32>(0.0);
    if params.perspective == 0u {
        for (var i = 0u; i < params.n_texels; i++) {
            let c = dot(n, texels[i].w.xyz);
            // below the horizon: adds nothing
            if c <= 0.0 {
                continue;
            }
            let xl = lobe_x(texels[i].h.xyz, n, nn_m1);
            let x = xl.x;
            let lnx = xl.y;
            // constant lobes are in fconst; lobes with scale 0 are left out
            var f = texels[i].fconst.xyz;
            for (var a = 0u; a < params.n_lobes; a++) {
                let m0 = texels[i].lobes[2u * a].xyz;
                let m1 = texels[i].lobes[2u * a + 1u].xyz;
                f += stable_expm1(m0 * lobe_pow(x, lnx, m1));
            }
            acc += f * texels[i].ld.xyz * c;
        }
    } else {
        for (var i = 0u; i < params.n_texels; i++) {
            let w = texels[i].w.xyz;
            let c = dot(n, w);
            if c <= 0.0 {
                continue;
            }
            let hv = half_vector(w, wp);
            let b = spline_basis(hv.w);
            let xl = lobe_x(hv.xyz, n, nn_m1);
            let x = xl.x;
            let lnx = xl.y;
            // active lobes, then constant lobes (x^0 = 1); lobes with scale 0 are left out
            var f = vec3<f32>(0.0);
            for (var q = 0u; q < params.n_lobes; q++) {
                let m1 = lobe_coef(b, q * 12u + 6u);
                f += stable_expm1(lobe_coef(b, q * 12u) * lobe_pow(x, lnx, m1));
            }
            for (var q = params.n_lobes; q < params.n_lobes + params.n_const; q++) {
                f += stable_expm1(lobe_coef(b, q * 12u));
            }
            acc += f * texels[i].ld.xyz * c;
        }
    }
    if params.first == 1u {
        image[p] = vec4<f32>(acc, 0.0);
    } else {
        image[p] += vec4<f32>(acc, 0.0);
    }
}
