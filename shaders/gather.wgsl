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

// The lobe math's branches. On a GPU (BRANCHES, tile_workgroup.wgsl) a group of lanes skips
// the side of a branch that none of them takes, and the pair loops are limited by
// arithmetic issue, so they branch: one side of 2^u - 1, lobes whose x^m1 underflows
// skipped, lobes whose channels share their exponent or their whole lobe computed once. A
// software adapter (lavapipe, tile_uniform.wgsl) runs every side of every branch under a
// mask, so there a branch only adds work (the forward took a third longer with them):
// there 2^u - 1 computes both sides and selects, and the other branches are left out. The
// constant's other side is folded away when the pipeline is built.

// 2^u - 1 without cancellation: u Q(u) where |u| < 1/2, 2^u - 1 elsewhere (|2^u - 1| >= 0.29
// there, so the subtraction loses under 2 bits).
fn exp2m1(u: f32) -> f32 {
    if BRANCHES {
        if abs(u) < 0.5 {
            return exp2m1_small(u);
        }
        return exp2(u) - 1.0;
    }
    return select(exp2(u) - 1.0, exp2m1_small(u), abs(u) < 0.5);
}

fn exp2m1_3(u: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(exp2m1(u.x), exp2m1(u.y), exp2m1(u.z));
}

// Whether x^m1 = 2^t underflows (t = m1 log2 x < UNDERFLOW) for every exponent of a lobe (or
// a channel's lobes), given t for the least of them: then they add exactly 0 and are skipped.
fn underflows(t: f32) -> bool {
    return BRANCHES && t < UNDERFLOW;
}

// x^m1 and exp(m0 x^m1) - 1 over channels.
struct Lobe {
    p: vec3<f32>,
    e: vec3<f32>,
}

// One lobe over channels from l2 = log2 x, m0 = the scales times log2(e) (w: what the
// channels share) and m1 = the exponents (w: the least of the three): one exp2 where the
// channels share the exponent, and one 2^u - 1 where they share the lobe. The flag is per
// texel and depends on the material, so the lanes of a pixel pass agree on it. Channels
// apart, the most costly case, are tested first.
fn shared_lobe(l2: f32, m0: vec4<f32>, m1: vec4<f32>) -> Lobe {
    if !BRANCHES || m0.w < SHARES_EXPONENT {
        let p = lobe_pow(l2, m1.xyz);
        return Lobe(p, exp2m1_3(m0.xyz * p));
    }
    let p = exp2(m1.w * l2);
    if m0.w < SHARES_LOBE {
        return Lobe(vec3<f32>(p), exp2m1_3(m0.xyz * p));
    }
    return Lobe(vec3<f32>(p), vec3<f32>(exp2m1(m0.x * p)));
}

// One channel's BRDF over its three lobes and d f / d m0 per lobe.
struct LobeGrads {
    // sum_s exp(m0_s x^m1_s) - 1
    f: f32,
    // d f / d m0_s = E_s x^m1_s; d f / d m1_s = E_s m0_s x^m1_s ln x is d0 m0 ln x, which
    // the pass forms (orthographic cameras: m0 once per texel, after the pair loop)
    d0: vec3<f32>,
}

// a = m0 log2(e) and m1 over the lobes, l2 = log2 x, m1_min the least of m1.
fn lobe_grads(l2: f32, a: vec3<f32>, m1: vec3<f32>, m1_min: f32) -> LobeGrads {
    if underflows(l2 * m1_min) {
        return LobeGrads(0.0, vec3<f32>(0.0));
    }
    let p = lobe_pow(l2, m1);
    let e = exp2m1_3(a * p);
    return LobeGrads(e.x + e.y + e.z, e * p + p);
}

// lobe_grads of the three channels of an orthographic texel at one pair: coef as
// `Texel.coef`, whose coef[0].w says whether the three channels have the same lobes (a
// grey material); then they are computed once. The flag depends on the material, not on
// the pair, so neighbouring lanes take the same side.
struct ChannelGrads {
    r: LobeGrads,
    g: LobeGrads,
    b: LobeGrads,
}

fn shared_channels(l2: f32, coef: array<vec4<f32>, 6>) -> ChannelGrads {
    let r = lobe_grads(l2, coef[0].xyz, coef[1].xyz, coef[1].w);
    if BRANCHES && coef[0].w == SHARES_LOBE {
        return ChannelGrads(r, r, r);
    }
    return ChannelGrads(
        r,
        lobe_grads(l2, coef[2].xyz, coef[3].xyz, coef[3].w),
        lobe_grads(l2, coef[4].xyz, coef[5].xyz, coef[5].w),
    );
}
