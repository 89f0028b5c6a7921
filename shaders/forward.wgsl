// forward.wgsl: the image. One invocation per foreground pixel (x) and texel slice (y):
// the workgroup walks its slice's lit texels a tile at a time (`load_tile`: into workgroup
// memory on a GPU, a uniform chunk on a software adapter), every invocation sums over the
// tile, and writes (first range) or adds its slice's sum; reduce_slices adds the slices in
// order. Mirrors src/reference/forward.rs.
// The camera branch is outside the per-texel loop and the channels are unrolled, because
// lavapipe runs invocations as SIMD lanes and private arrays indexed in loops are slow there.

@group(0) @binding(2) var<storage, read> pixels: array<Pixel>;
// [slice * slice_stride + pixel_base + pixel]
@group(0) @binding(3) var<storage, read_write> image: array<vec4<f32>>;

// The lit texels, read through `tile` (tile_workgroup.wgsl or tile_uniform.wgsl).
alias Tiled = Texel;
// Texels per uniform chunk on a software adapter: 252 * 256 bytes = 64512 <= 64 KiB.
const CHUNK: u32 = 252u;

@compute @workgroup_size(WG)
fn forward(@builtin(global_invocation_id) gid: vec3<u32>,
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
                let c = dot(n, tile[base + i].w.xyz);
                // below the horizon: adds nothing
                if c <= 0.0 {
                    continue;
                }
                let ld = tile[base + i].ld;
                let l2 = lobe_x(tile[base + i].h.xyz, n, nn_m1, ld.w).y;
                // constant lobes are in fconst; lobes with scale 0 are left out
                var f = tile[base + i].fconst.xyz;
                for (var a = 0u; a < n_active; a++) {
                    let m1 = tile[base + i].lobes[2u * a + 1u];
                    if underflows(l2 * m1.w) {
                        continue;
                    }
                    // w: what the channels share
                    let m0 = tile[base + i].lobes[2u * a];
                    f += shared_lobe(l2, m0, m1).e;
                }
                acc += f * ld.xyz * c;
            }
        } else {
            for (var i = 0u; i < m; i++) {
                let w = tile[base + i].w.xyz;
                let c = dot(n, w);
                if c <= 0.0 {
                    continue;
                }
                let hv = half_vector(w, wp);
                let b = spline_basis(hv.theta_d);
                let l2 = lobe_x(hv.h, n, nn_m1, hv.pad).y;
                // active lobes, then constant lobes (x^0 = 1); lobes with scale 0 are left out
                var f = vec3<f32>(0.0);
                for (var q = 0u; q < n_active; q++) {
                    let m1 = lobe_coef(b, q * 12u + 6u, z);
                    f += exp2m1_3(lobe_coef(b, q * 12u, z) * lobe_pow(l2, m1));
                }
                for (var q = n_active; q < n_active + n_const; q++) {
                    f += exp2m1_3(lobe_coef(b, q * 12u, z));
                }
                acc += f * tile[base + i].ld.xyz * c;
            }
        }
    }
    if !live {
        return;
    }
    let o = wg.y * scenes[z].slice_stride + scenes[z].pixel_base + p;
    if scenes[z].first == 1u {
        image[o] = vec4<f32>(acc, 0.0);
    } else {
        image[o] += vec4<f32>(acc, 0.0);
    }
}
