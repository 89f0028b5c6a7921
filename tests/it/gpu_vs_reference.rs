//! The GPU path against the f64 CPU reference on seeded random scenes (lavapipe in CI),
//! determinism of the GPU backward pass, and analytic values on both backends.
//!
//! Tolerance: max abs error <= 1e-4 of the largest value of each output. The f32 error
//! floor is about 1e-5 of the largest value (x^m1 with m1 up to 60 multiplies the ~6e-8
//! error of x by up to 60, and sums over 8192 texels add ~1e-6), so 1e-4 leaves 10x room
//! while still catching any wrong term. Sharp lobes (m1 up to 1e4) stay within it only
//! because x and ln x keep their digits near x = 1 (`lobe_x`; docs/CONVENTIONS.md).

use crate::common;

use common::{Rng, Truth, assert_close, flat32, gpu, random_scene, scenes, upstream_for};
use matedit::gpu::Tiles;
use matedit::prepare::Prepared;
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Material, NormalMap, Scene, Wanted, reference,
};

const TOL: f64 = 1e-4;

/// Forward and backward of `batch` on the GPU against the CPU reference.
fn compare(test: &str, batch: &Batch) {
    let Some(g) = gpu(test) else { return };
    compare_on(&g, test, batch);
}

fn compare_on(g: &matedit::gpu::GpuRenderer, test: &str, batch: &Batch) {
    let images = g.render(batch.into()).expect("gpu render");
    let up = upstream_for(batch, 99);
    let grads = g
        .backward(batch.into(), &up, Wanted::ALL)
        .expect("gpu backward");
    for (b, scene) in batch.scenes().iter().enumerate() {
        let truth = Truth::new(&Prepared::new(scene), &up[b].pixels);
        let what = format!("{test} scene {b}");
        truth.check(&what, &images[b].pixels, &grads[b], TOL, TOL);
    }
}

/// A random orthographic scene (seed `seed`, an `hl` x `2 hl` equirect map) seen on a
/// 20 x 20 sphere.
fn sphere_scene(seed: u64, hl: usize) -> Scene {
    let mut rng = Rng::new(seed);
    let mut s = random_scene(
        &mut rng,
        4,
        4,
        hl,
        2 * hl,
        Convention::Equirect,
        Camera::Orthographic,
    );
    s.normals = NormalMap::sphere(20);
    s
}

#[test]
fn forward_backward_64x128_env_equirect() {
    compare("64x128 equirect", &scenes::equirect_64x128());
}

#[test]
fn forward_backward_non_square_paper() {
    compare("13x7 paper", &scenes::non_square_paper());
}

#[test]
fn forward_backward_batch_of_3() {
    compare("batch of 3", &scenes::batch_of_3());
}

#[test]
fn forward_backward_perspective_both_conventions() {
    for (conv, batch) in scenes::perspective() {
        compare(&format!("perspective {conv:?}"), &batch);
    }
}

#[test]
fn forward_splits_more_pixels_than_one_chunk_of_texels() {
    // more lit texels than one uniform chunk (252) or one tile (64) and a sphere: the sums
    // over chunks or tiles must agree
    let s = sphere_scene(16, 32);
    compare("sphere 20 env 32x64", &Batch::single(s).unwrap());
}

#[test]
fn backward_is_deterministic() {
    let Some(g) = gpu("backward_is_deterministic") else {
        return;
    };
    let mut rng = Rng::new(17);
    let s = random_scene(
        &mut rng,
        16,
        16,
        32,
        64,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let batch = Batch::single(s).unwrap();
    assert!(
        output_bits(&g, &batch) == output_bits(&g, &batch),
        "two GPU runs differ"
    );
}

/// Constant light L = 1 and one lobe of exponent 0: f = e^m0 - 1 everywhere, so
/// I = (e^m0 - 1) sum_i max(0, n.w_i) d_omega_i, which is pi (e^m0 - 1) in the limit;
/// within 0.1% at 64 x 128 equirect.
fn constant_light_scene() -> (Scene, f64) {
    let m0: f64 = 0.7;
    let scene = Scene {
        normals: NormalMap::new(1, 1, vec![[0.0, 0.0, 1.0]]).unwrap(),
        env: EnvMap::constant(64, 128, Convention::Equirect, [1.0; 3]).unwrap(),
        material: Material::constant("flat", [(m0, 0.0), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
        camera: Camera::Orthographic,
    };
    (scene, std::f64::consts::PI * m0.exp_m1())
}

#[test]
fn analytic_constant_light_exponent_zero_cpu() {
    let (scene, want) = constant_light_scene();
    let img = reference::forward(&Prepared::new(&scene));
    assert_close("I (cpu)", &img[0], &[want; 3], 0.0, 1e-3);
}

#[test]
fn analytic_constant_light_exponent_zero_gpu() {
    let Some(g) = gpu("analytic_constant_light_exponent_zero_gpu") else {
        return;
    };
    let (scene, want) = constant_light_scene();
    let img = g.render((&Batch::single(scene).unwrap()).into()).unwrap();
    assert_close("I (gpu)", &flat32(&img[0].pixels), &[want; 3], 0.0, 1e-3);
}

/// One lobe (kappa, gamma constant over theta_d) under L = 1 seen along its normal:
/// with n = w_p = z, x = n.h = cos(theta / 2), so
/// I = 2 pi int_0^{pi/2} (exp(kappa cos(theta/2)^gamma) - 1) cos(theta) sin(theta) dtheta,
/// integrated here by composite Simpson with 20000 intervals (independent of the layer's
/// texel sums).
fn one_lobe_quadrature(kappa: f64, gamma: f64) -> f64 {
    let n = 20000;
    let h = std::f64::consts::FRAC_PI_2 / n as f64;
    let f = |t: f64| ((kappa * (t / 2.0).cos().powf(gamma)).exp() - 1.0) * t.cos() * t.sin();
    let mut s = f(0.0) + f(std::f64::consts::FRAC_PI_2);
    for i in 1..n {
        s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    2.0 * std::f64::consts::PI * s * h / 3.0
}

fn one_lobe_scene(kappa: f64, gamma: f64, hl: usize) -> Scene {
    Scene {
        normals: NormalMap::new(1, 1, vec![[0.0, 0.0, 1.0]]).unwrap(),
        env: EnvMap::constant(hl, 2 * hl, Convention::Equirect, [1.0; 3]).unwrap(),
        material: Material::constant("one lobe", [(kappa, gamma), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
        camera: Camera::Orthographic,
    }
}

#[test]
fn analytic_one_lobe_against_quadrature() {
    let (kappa, gamma) = (1.5, 8.0);
    let want = one_lobe_quadrature(kappa, gamma);
    // 64 x 128: the midpoint rule over texels is within 0.2%; at 256 x 512 within 0.02%
    for (hl, rel) in [(64, 2e-3), (256, 2e-4)] {
        let img = reference::forward(&Prepared::new(&one_lobe_scene(kappa, gamma, hl)));
        assert_close(
            &format!("one lobe cpu {hl}"),
            &[img[0][0]],
            &[want],
            0.0,
            rel,
        );
    }
    if let Some(g) = gpu("analytic_one_lobe_against_quadrature") {
        let img = g
            .render((&Batch::single(one_lobe_scene(kappa, gamma, 64)).unwrap()).into())
            .unwrap();
        assert_close(
            "one lobe gpu 64",
            &[img[0].pixels[0][0] as f64],
            &[want],
            0.0,
            2e-3,
        );
    }
}

#[test]
fn inputs_over_the_binding_limit_are_split() {
    let Some(g) = gpu("inputs_over_the_binding_limit_are_split") else {
        return;
    };
    // 64 pixels x 48 bytes and 64 texels x 432 bytes per range: a 20x20 sphere (~300
    // pixels) and a 16x32 map (512 texels) need 5 pixel ranges and 8 texel ranges
    let g = g.with_binding_cap(64 * 48);
    compare_on(
        &g,
        "split ranges",
        &Batch::single(sphere_scene(18, 16)).unwrap(),
    );
}

#[test]
fn forward_backward_presets_with_constant_and_zero_lobes() {
    // the built-in presets have diffuse (constant) lobes and unused (scale 0) lobes
    let mut rng = Rng::new(19);
    for (conv, camera) in [
        (Convention::Equirect, Camera::Orthographic),
        (Convention::Paper, Camera::Perspective { fov_y_deg: 50.0 }),
    ] {
        let scenes = ["plastic-red", "matte-white", "gold"]
            .iter()
            .map(|name| {
                let mut s = random_scene(&mut rng, 10, 9, 16, 32, conv, camera);
                s.material = matedit::presets::lookup(name).expect("preset");
                s
            })
            .collect();
        compare(&format!("presets {camera:?}"), &Batch::new(scenes).unwrap());
    }
}

/// A 32 x 64 equirect map that varies smoothly, and the same with one bright texel.
fn smooth_env(bright: bool) -> EnvMap {
    let (hl, wl) = (32, 64);
    let mut texels: Vec<[f32; 3]> = (0..hl * wl)
        .map(|i| {
            let (r, c) = ((i / wl) as f64, (i % wl) as f64);
            let th = (r + 0.5) / hl as f64 * std::f64::consts::PI;
            let ph = (c + 0.5) / wl as f64 * 2.0 * std::f64::consts::PI;
            [
                1.0 + 0.5 * ph.sin(),
                1.0 + 0.5 * th.cos(),
                0.8 + 0.3 * (th + ph).cos(),
            ]
            .map(|v| v as f32)
        })
        .collect();
    if bright {
        texels[13 * wl + 18] = [60.0, 40.0, 20.0];
    }
    EnvMap::new(hl, wl, Convention::Equirect, texels).unwrap()
}

/// A sharp lobe (scale 5, 4, 3 in R, G, B; the exponent `m1` at every control point) and a
/// weak diffuse lobe (scale 0.3, exponent 0).
fn sharp_material(m1: f64) -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    for k in 0..3 {
        for j in 0..6 {
            ctrl[matedit::material::idx(k, 0, 0, j)] = 5.0 - k as f64;
            ctrl[matedit::material::idx(k, 0, 1, j)] = m1;
            ctrl[matedit::material::idx(k, 1, 0, j)] = 0.3;
        }
    }
    Material::new("sharp", &ctrl).unwrap()
}

/// Exponents 1e3 and 1e4: x^m1 = exp(m1 ln x) multiplies the error of ln x by m1, so x and
/// ln x must keep their digits where x is near 1 (x = 1 - d with d from |h - n|^2, ln x by
/// log1p), or (lavapipe) the image is off by 3e-3 of its max and the gradients by 7e-3.
#[test]
fn sharp_lobes_keep_their_digits() {
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 40.0 },
    ] {
        let mut scenes = Vec::new();
        for m1 in [1e3, 1e4] {
            for bright in [false, true] {
                scenes.push(Scene {
                    normals: NormalMap::sphere(64),
                    env: smooth_env(bright),
                    material: sharp_material(m1),
                    camera,
                });
            }
        }
        compare(
            &format!("sharp lobes {camera:?} (m1 1e3 smooth, bright; 1e4 smooth, bright)"),
            &Batch::new(scenes).unwrap(),
        );
    }
}

// The edges of the shaders' lobe branches (shaders/common.wgsl): 2^u - 1 by its polynomial
// or by exp2, log2 x by its series or by log2, lobes skipped where x^m1 underflows in every
// channel, the half vector's pad.

/// Unit normals at every elevation from facing away (z = -0.9) through grazing (z = +-1e-3,
/// 1e-4 ...) to facing the camera, at azimuths a golden angle apart. Not z = 0: against the
/// texel at w = (0, 0, -1) that puts n . w at 1e-16, on the horizon's kink, where the f32
/// or f64 rounding of w decides whether the pair is lit (dn jumps by L d_omega f w there).
/// Only those with z >= `z_min`.
fn grazing_normals(w: usize, h: usize, z_min: f64) -> NormalMap {
    let zs = [
        -0.9, -0.5, -0.1, -1e-3, -1e-4, 1e-4, 1e-3, 1e-2, 0.05, 0.2, 0.5, 0.8, 0.95, 0.999, 1.0,
    ];
    let zs: Vec<f64> = zs.into_iter().filter(|&z| z >= z_min).collect();
    let normals = (0..w * h)
        .map(|i| {
            let z = zs[i % zs.len()];
            let a = i as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            [r * a.cos(), r * a.sin(), z].map(|v| v as f32)
        })
        .collect();
    NormalMap::new(w, h, normals).unwrap()
}

/// A 9 x 18 equirect map: texel (4, 13) is at w = (0, 0, -1) = -w_p, where the orthographic
/// half vector is undefined.
fn edge_env(rng: &mut Rng) -> EnvMap {
    let texels = (0..9 * 18)
        .map(|_| [0; 3].map(|_: i32| rng.uniform(-1.0, 1.5).exp() as f32))
        .collect();
    EnvMap::new(9, 18, Convention::Equirect, texels).unwrap()
}

/// Lobe 0: scales about +-ln(2)/2 (negative in G), so that u = m0 log2(e) x^m1 is near the
/// 2^u - 1 branch point |u| = 1/2, with exponent 0.02 (R, G) and 0 (B: x^0 = 1 in an active
/// lobe, also at x = 0); lobe 1: scale 0 everywhere (only its scale's gradient); lobe 2:
/// scale 0 at four control points, exponents 1e4, 50 and 1.5. (An exponent below 1 is left
/// out: dn's m1 x^(m1 - 1) multiplies the f32 error of x near 0, about 1e-7 absolute, without
/// bound; with 0.5 here dn was 4e-4 of its max off the reference, with these shaders and
/// with those before them.)
fn branch_point_material() -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    let near_half = [0.30, 0.335, 0.345, 0.3466, 0.35, 0.40];
    for k in 0..3 {
        for j in 0..6 {
            let sign = if k == 1 { -1.0 } else { 1.0 };
            ctrl[matedit::material::idx(k, 0, 0, j)] = sign * near_half[j];
            ctrl[matedit::material::idx(k, 0, 1, j)] = [0.02, 0.02, 0.0][k];
            ctrl[matedit::material::idx(k, 1, 1, j)] = 30.0;
            ctrl[matedit::material::idx(k, 2, 0, j)] = [0.0, 0.0, 0.5, 1.0, 0.0, 0.0][j];
            ctrl[matedit::material::idx(k, 2, 1, j)] = [1e4, 50.0, 1.5][k];
        }
    }
    Material::new("branch point", &ctrl).unwrap()
}

/// Lobe 0: exponent 1e4 in every channel (skipped over most of the hemisphere); lobe 1:
/// exponents 5000, 1e4 and 100 (x^m1 underflows in some channels and not in others);
/// lobe 2: constant.
fn underflow_material() -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    for k in 0..3 {
        for j in 0..6 {
            ctrl[matedit::material::idx(k, 0, 0, j)] = 3.0;
            ctrl[matedit::material::idx(k, 0, 1, j)] = 1e4;
            ctrl[matedit::material::idx(k, 1, 0, j)] = [2.0, 1.0, 0.5][k];
            ctrl[matedit::material::idx(k, 1, 1, j)] = [5000.0, 1e4, 100.0][k];
            ctrl[matedit::material::idx(k, 2, 0, j)] = 0.2;
        }
    }
    Material::new("underflow", &ctrl).unwrap()
}

/// The same lobes in the three channels (a grey material: the passes compute each lobe once
/// for the three channels): a sharp lobe (exponent 1e4), a lobe with scales about ln(2)/2
/// and exponent 0.02 (near the 2^u - 1 branch point) and a broad one.
fn grey_material() -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    let near_half = [0.30, 0.335, 0.345, 0.3466, 0.35, 0.40];
    for k in 0..3 {
        for j in 0..6 {
            ctrl[matedit::material::idx(k, 0, 0, j)] = 3.0;
            ctrl[matedit::material::idx(k, 0, 1, j)] = 1e4;
            ctrl[matedit::material::idx(k, 1, 0, j)] = near_half[j];
            ctrl[matedit::material::idx(k, 1, 1, j)] = 0.02;
            ctrl[matedit::material::idx(k, 2, 0, j)] = 0.5;
            ctrl[matedit::material::idx(k, 2, 1, j)] = 8.0;
        }
    }
    Material::new("grey", &ctrl).unwrap()
}

/// Over the lit pairs (n . w > 0) of an orthographic scene: how many have u = m0 log2(e)
/// x^m1 of lobe 0 in some channel within 10% below and above |u| = 1/2, how many have an
/// undefined half vector, and how many have lobe 1's x^m1 underflowing (m1 log2 x < -150)
/// in some channel but not in all.
fn edge_coverage(scene: &Scene) -> ([usize; 2], usize, usize) {
    let prep = Prepared::new(scene);
    let (mut near, mut no_half, mut some_underflow) = ([0; 2], 0, 0);
    for &i in &prep.lit {
        let t = &prep.texels[i];
        for p in &prep.pixels {
            if matedit::prepare::dot(p.n, t.w) <= 0.0 {
                continue;
            }
            no_half += usize::from(t.h == [0.0; 3]);
            let (x, lnx) = reference::common::lobe_x(t.h, p.n, p.nn_m1);
            for k in 0..3 {
                let coef = |s: usize, tt: usize| t.coef[(k * 3 + s) * 2 + tt];
                let pw = reference::common::lobe_pow(x, lnx, coef(0, 1));
                let u = (coef(0, 0) * std::f64::consts::LOG2_E * pw).abs();
                if (0.45..0.5).contains(&u) {
                    near[0] += 1;
                } else if (0.5..0.55).contains(&u) {
                    near[1] += 1;
                }
            }
            let under =
                |k: usize| t.coef[(k * 3 + 1) * 2 + 1] * lnx / std::f64::consts::LN_2 < -150.0;
            let n_under = (0..3).filter(|&k| under(k)).count();
            some_underflow += usize::from(x > 0.0 && n_under > 0 && n_under < 3);
        }
    }
    (near, no_half, some_underflow)
}

/// Both sides of each branch, and the edge cases around them, against the reference on both
/// cameras and both tile kinds: 2^u - 1 on both sides of |u| = 1/2, lobes with zero scales,
/// exponents up to 1e4 that underflow in some channels only, grey lobes (computed once for
/// the three channels), normals facing away and grazing, and a texel with an undefined half
/// vector. The perspective camera gets only normals facing it (z >= 0.2): its half vector
/// is computed in f32 from w + w_p, whose length 2 n . w_p is small where h is near a normal
/// facing away or grazing, and there the 1e4 lobe's dn was 7e-3 of its max off the
/// reference, with these shaders and with those before them.
#[test]
fn lobe_branches_at_their_edges() {
    let mut rng = Rng::new(28);
    for (camera, z_min) in [
        (Camera::Orthographic, -1.0),
        (Camera::Perspective { fov_y_deg: 50.0 }, 0.2),
    ] {
        let scenes: Vec<Scene> = [
            branch_point_material(),
            underflow_material(),
            grey_material(),
        ]
        .into_iter()
        .map(|material| Scene {
            normals: grazing_normals(24, 24, z_min),
            env: edge_env(&mut rng),
            material,
            camera,
        })
        .collect();
        if camera == Camera::Orthographic {
            let (near, no_half, _) = edge_coverage(&scenes[0]);
            assert!(
                near[0] > 0 && near[1] > 0,
                "lobe 0's |u| within 10% of 1/2: {near:?} pairs below and above"
            );
            assert!(no_half > 0, "no lit pair with an undefined half vector");
            let (_, _, some_underflow) = edge_coverage(&scenes[1]);
            assert!(
                some_underflow > 0,
                "no pair where lobe 1 underflows in some channels only"
            );
        }
        // both tile kinds: the branches are taken on workgroup tiles (GPUs) only
        let batch = Batch::new(scenes).unwrap();
        for tiles in [Tiles::Workgroup, Tiles::Uniform] {
            let test =
                format!("lobe branches {camera:?} {tiles:?} (branch point, underflow, grey)");
            let Some(g) = gpu(&test) else { return };
            compare_on(&g.with_tiles(tiles).expect("pipelines"), &test, &batch);
        }
    }
}

// Slices: the looped-over records of each gather pass split into independent partial sums
// (the dispatch's y dimension), added in slice order by reduce_slices.

/// The scenes the slice tests run on: orthographic, perspective, a batch of 3, and a 20 x 20
/// sphere against 32 x 64 texels (slices that do not end on a tile).
fn slice_scenes() -> Vec<(String, Batch)> {
    let mut out = vec![
        ("64x128 equirect".to_string(), scenes::equirect_64x128()),
        ("batch of 3".to_string(), scenes::batch_of_3()),
        (
            "sphere 20".to_string(),
            Batch::single(sphere_scene(21, 32)).unwrap(),
        ),
    ];
    for (conv, batch) in scenes::perspective() {
        out.push((format!("perspective {conv:?}"), batch));
    }
    out
}

/// A renderer reading through `tiles` with `slices` slices; `None` without an adapter.
fn sliced(test: &str, tiles: Tiles, slices: u32) -> Option<matedit::gpu::GpuRenderer> {
    let g = gpu(test)?.with_tiles(tiles).expect("pipelines");
    Some(g.with_slices(slices))
}

#[test]
fn slices_forced_to_1_2_and_several() {
    // both ways of reading the looped-over records, whatever the adapter's default
    for tiles in [Tiles::Workgroup, Tiles::Uniform] {
        for s in [1, 2, 7] {
            let Some(g) = sliced("slices_forced_to_1_2_and_several", tiles, s) else {
                return;
            };
            for (name, batch) in slice_scenes() {
                compare_on(&g, &format!("{tiles:?}, {s} slices, {name}"), &batch);
            }
        }
    }
}

#[test]
fn batches_of_1_and_5_with_slices() {
    let mut rng = Rng::new(22);
    let five: Vec<Scene> = (0..5)
        .map(|_| {
            let mut s = random_scene(
                &mut rng,
                4,
                4,
                16,
                32,
                Convention::Equirect,
                Camera::Perspective { fov_y_deg: 45.0 },
            );
            s.normals = NormalMap::sphere(14);
            s
        })
        .collect();
    for (tiles, s) in [
        (Tiles::Workgroup, 1),
        (Tiles::Workgroup, 3),
        (Tiles::Uniform, 3),
    ] {
        let Some(g) = sliced("batches_of_1_and_5_with_slices", tiles, s) else {
            return;
        };
        compare_on(
            &g,
            &format!("batch of 1, {s} slices"),
            &Batch::single(five[0].clone()).unwrap(),
        );
        compare_on(
            &g,
            &format!("batch of 5, {s} slices"),
            &Batch::new(five.clone()).unwrap(),
        );
    }
}

#[test]
fn a_batch_is_one_dispatch_per_pass_with_each_scenes_own_sums() {
    // on workgroup tiles a batch's scenes go in z: one dispatch of each gather pass, and
    // each scene's outputs bit for bit what it gets alone with the same slice count (its
    // slices are as long; a scene with fewer leaves its last slices zero)
    let five: Vec<Scene> = (0..5)
        .map(|k| {
            let mut s = sphere_scene(23 + k as u64, 16);
            // foreground pixels differ: scene k loses its first 40 k pixels
            for n in s.normals.normals.iter_mut().take(40 * k) {
                *n = [0.0; 3];
            }
            s
        })
        .collect();
    let batch = Batch::new(five.clone()).unwrap();
    let test = "a_batch_is_one_dispatch_per_pass_with_each_scenes_own_sums";
    for s in [1, 3] {
        let Some(g) = sliced(test, Tiles::Workgroup, s) else {
            return;
        };
        let whole = output_bits(&g, &batch);
        let zs = |pass| {
            g.last_dispatches()
                .iter()
                .filter(|d| d.pass == pass)
                .map(|d| d.workgroups[2])
                .collect::<Vec<u32>>()
        };
        assert_eq!(zs(matedit::gpu::Pass::BackwardTexel), [5], "{s} slices");
        assert_eq!(zs(matedit::gpu::Pass::BackwardNormal), [5], "{s} slices");
        assert_eq!(zs(matedit::gpu::Pass::ReduceCtrl), [5], "{s} slices");
        g.render((&batch).into()).unwrap();
        assert_eq!(zs(matedit::gpu::Pass::Forward), [5], "{s} slices");
        // output_bits orders images, then gradients, scene by scene
        let up = upstream_for(&batch, 5);
        let mut alone: (Vec<u32>, Vec<u32>) = Default::default();
        for (b, scene) in five.iter().enumerate() {
            let one = Batch::single(scene.clone()).unwrap();
            let img = g.render((&one).into()).unwrap();
            let grad = g
                .backward((&one).into(), std::slice::from_ref(&up[b]), Wanted::ALL)
                .unwrap();
            alone
                .0
                .extend(img[0].pixels.iter().flatten().map(|x| x.to_bits()));
            alone.1.extend(
                grad[0]
                    .d_env
                    .iter()
                    .flatten()
                    .chain(grad[0].d_normals.iter().flatten())
                    .chain(grad[0].d_ctrl.iter())
                    .map(|x| x.to_bits()),
            );
        }
        let alone: Vec<u32> = alone.0.into_iter().chain(alone.1).collect();
        let first = whole.iter().zip(&alone).position(|(a, b)| a != b);
        assert!(
            whole.len() == alone.len() && first.is_none(),
            "{s} slices: the batch differs from its scenes alone, first at {first:?}"
        );
    }
}

#[test]
fn slices_under_forced_caps() {
    // bindings of 64 pixels (per-pixel partial sums: at most 3 slices; shares: 1 slice)
    // and of 2 workgroups of shares (2 texel slices); 2 and 3 workgroups per dimension
    // (more ranges, and reductions that go on in y)
    let batch = Batch::single(sphere_scene(18, 16)).unwrap();
    let caps: [(Option<u64>, Option<u32>); 4] = [
        (Some(64 * 48), None),
        (Some(2 * 64 * 432), None),
        (None, Some(2)),
        (Some(64 * 48), Some(3)),
    ];
    for (bytes, groups) in caps {
        for slices in [2, 5] {
            let Some(mut g) = sliced("slices_under_forced_caps", Tiles::Workgroup, slices) else {
                return;
            };
            if let Some(b) = bytes {
                g = g.with_binding_cap(b);
            }
            if let Some(n) = groups {
                g = g.with_workgroup_cap(n);
            }
            compare_on(
                &g,
                &format!("cap {bytes:?} bytes, {groups:?} groups, {slices} slices"),
                &batch,
            );
        }
    }
}

/// Every output of a forward and a backward call, as bits.
fn output_bits(g: &matedit::gpu::GpuRenderer, batch: &Batch) -> Vec<u32> {
    let up = upstream_for(batch, 5);
    let images = g.render(batch.into()).unwrap();
    let grads = g.backward(batch.into(), &up, Wanted::ALL).unwrap();
    images
        .iter()
        .flat_map(|i| i.pixels.iter().flatten())
        .chain(grads.iter().flat_map(|v| {
            v.d_env
                .iter()
                .flatten()
                .chain(v.d_normals.iter().flatten())
                .chain(v.d_ctrl.iter())
        }))
        .map(|x| x.to_bits())
        .collect()
}

#[test]
fn sliced_sums_are_deterministic() {
    // two runs with the same slice count give the same bits; so do slice counts whose
    // slices are the same (the same slice length in every pass: e.g. 120 pixels in 12 or
    // 13 slices are 12 slices of 10; the pair is searched for), because each slice sums its records in order and
    // reduce_slices adds the slices in order
    let Some(g) = gpu("sliced_sums_are_deterministic") else {
        return;
    };
    let batch = scenes::equirect_64x128();
    let prep = Prepared::new(&batch.scenes()[0]);
    let (np, nl, nt) = (prep.pixels.len(), prep.lit.len(), prep.texels.len());
    let test = "sliced_sums_are_deterministic";
    let same = |a: &[u32], b: &[u32], what: &str| {
        let first = a.iter().zip(b).position(|(x, y)| x != y);
        assert!(
            a.len() == b.len() && first.is_none(),
            "{what}: outputs differ, first at {first:?}"
        );
    };
    for tiles in [Tiles::Workgroup, Tiles::Uniform] {
        let mut planner = g.planner().clone();
        planner.tiles = tiles;
        let shapes = |s: u32| {
            let p = planner.clone().with_slices(s);
            (
                p.gather(matedit::gpu::Pass::Forward, np, nl),
                p.gather(matedit::gpu::Pass::BackwardTexel, nt, np),
            )
        };
        let pair = (2..400)
            .find(|&s| shapes(s) == shapes(s + 1) && shapes(s).0.slices > 1)
            .expect("two slice counts with the same slices");
        let bits = |s| output_bits(&sliced(test, tiles, s).unwrap(), &batch);
        let a = bits(pair);
        same(
            &a,
            &bits(pair),
            &format!("{tiles:?}: two runs, {pair} slices"),
        );
        same(
            &a,
            &bits(pair + 1),
            &format!(
                "{tiles:?}: {pair} and {} slices (the same slices)",
                pair + 1
            ),
        );
    }
    if g.planner().software {
        // the automatic count on a software adapter is 1 (on the tile kind it uses:
        // MATEDIT_GPU_TILES may have changed it)
        let one = output_bits(&sliced(test, g.planner().tiles, 1).unwrap(), &batch);
        same(&output_bits(&g, &batch), &one, "automatic and 1 slice");
    }
}

#[test]
fn dispatches_follow_the_plan_and_passes_are_timed() {
    let Some(g) = sliced(
        "dispatches_follow_the_plan_and_passes_are_timed",
        Tiles::Workgroup,
        3,
    ) else {
        return;
    };
    let batch = scenes::equirect_64x128();
    let prep = Prepared::new(&batch.scenes()[0]);
    let (np, nl, nt) = (prep.pixels.len(), prep.lit.len(), prep.texels.len());
    g.render((&batch).into()).unwrap();
    assert_eq!(g.last_dispatches(), g.planner().forward(np, nl));
    let timed = g.context().timestamps;
    let t = g.last_timings();
    if timed {
        let names: Vec<&str> = t.iter().map(|t| t.pass).collect();
        assert_eq!(names, ["forward", "reduce_slices"]);
        assert_eq!(t[0].pairs, (np * nl) as u64);
        assert!(t.iter().all(|t| t.seconds > 0.0), "{t:?}");
    } else {
        assert!(t.is_empty());
    }
    let up = upstream_for(&batch, 3);
    let active = prep
        .pixels
        .iter()
        .filter(|p| up[0].pixels[p.index].iter().any(|&v| v != 0.0))
        .count();
    g.backward((&batch).into(), &up, Wanted::ALL).unwrap();
    assert_eq!(
        g.last_dispatches(),
        g.planner().backward(np, nl, nt, active)
    );
    if timed {
        let names: Vec<&str> = g.last_timings().iter().map(|t| t.pass).collect();
        assert_eq!(
            names,
            [
                "backward_texel",
                "reduce_slices",
                "reduce_ctrl",
                "backward_normal"
            ]
        );
    }
}
