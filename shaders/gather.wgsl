// gather.wgsl: what the gather passes (forward, backward_normal, backward_texel) share:
// the material's coefficients at a pair's theta_d, read from the parameters of scene z
// (`scenes`: declared by tile_workgroup.wgsl or tile_uniform.wgsl).

// The coefficient vector (over lobes) at cc[base..base + 6] and the basis b, where
// base = (k * 2 + t) * 6 for channel k, coefficient t, and z the scene. Unrolled: private
// arrays indexed in loops are slow on SIMD backends such as lavapipe.
fn pair_coef(b: array<f32, 6>, base: u32, z: u32) -> vec3<f32> {
    return b[0] * scenes[z].cc[base].xyz + b[1] * scenes[z].cc[base + 1u].xyz
        + b[2] * scenes[z].cc[base + 2u].xyz + b[3] * scenes[z].cc[base + 3u].xyz
        + b[4] * scenes[z].cc[base + 4u].xyz + b[5] * scenes[z].cc[base + 5u].xyz;
}

// The coefficient vector (over channels) of lobe q, coefficient t at the basis b, where
// base = (q * 2 + t) * 6 indexes lc; z: the scene.
fn lobe_coef(b: array<f32, 6>, base: u32, z: u32) -> vec3<f32> {
    return b[0] * scenes[z].lc[base].xyz + b[1] * scenes[z].lc[base + 1u].xyz
        + b[2] * scenes[z].lc[base + 2u].xyz + b[3] * scenes[z].lc[base + 3u].xyz
        + b[4] * scenes[z].lc[base + 4u].xyz + b[5] * scenes[z].lc[base + 5u].xyz;
}
