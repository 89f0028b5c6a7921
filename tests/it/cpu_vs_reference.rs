//! The fast f32 CPU path against the f64 reference on seeded scenes, at every SIMD level
//! this machine has; its determinism across thread counts; sharp lobes.
//!
//! Tolerances: image within 1e-5 of its largest value, each gradient within 1e-4 of its
//! largest value. The image sums run in f32 over groups of 256 texels and then in f64, so
//! its error is a few f32 roundings of the largest terms (~1e-6 at exponents up to 60);
//! gradients add the f32 rounding of x^m1 ln x and of m1 x^(m1 - 1) near x = 0.

use crate::common;

use common::{
    Rng, Truth, assert_close, flat32, flat64, max_abs, random_material, random_scene, scenes,
    upstream_for,
};
use matedit::cpu::dense::Dense;
use matedit::cpu::table::{LobePlan, depends_on_x};
use matedit::cpu::{FastCpu, SimdLevel};
use matedit::prepare::Prepared;
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Jacobian, Material, NormalMap, Scene, Wanted,
    reference,
};

const IMAGE_TOL: f64 = 1e-5;
const GRAD_TOL: f64 = 1e-4;

/// Every level this CPU has, widest first (scalar is always there).
fn levels() -> Vec<FastCpu> {
    let found: Vec<FastCpu> = SimdLevel::ALL
        .into_iter()
        .filter_map(FastCpu::with_level)
        .collect();
    let names: Vec<&str> = found.iter().map(|c| c.level().name()).collect();
    eprintln!("fast CPU levels on this machine: {names:?}");
    assert!(found.iter().any(|c| c.level() == SimdLevel::Scalar));
    found
}

/// Forward and backward of every scene of `batch` at every level against the reference.
fn compare(test: &str, batch: &Batch) {
    compare_tol(test, batch, IMAGE_TOL, GRAD_TOL);
}

fn compare_tol(test: &str, batch: &Batch, image_tol: f64, grad_tol: f64) {
    let ups = upstream_for(batch, 99);
    for (b, scene) in batch.scenes().iter().enumerate() {
        let prep = Prepared::new(scene);
        let up = &ups[b].pixels;
        let truth = Truth::new(&prep, up);
        for cpu in levels() {
            let what = format!("{test} scene {b} {}", cpu.level().name());
            let (image, grads) = (cpu.forward(&prep), cpu.backward(&prep, up, Wanted::ALL));
            truth.check(&what, &image, &grads, image_tol, grad_tol);
        }
    }
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
fn forward_backward_batch_of_3_through_the_renderer() {
    let batch = scenes::batch_of_3();
    compare("batch of 3", &batch);
    // the same through the public API, one call for the batch
    let renderer = matedit::Renderer::with_backend(Box::new(FastCpu::best()));
    let images = renderer.render(&batch).unwrap();
    let ups = upstream_for(&batch, 99);
    let grads = renderer.backward(&batch, &ups).unwrap();
    for (b, scene) in batch.scenes().iter().enumerate() {
        let prep = Prepared::new(scene);
        let want = flat64(&reference::forward(&prep));
        let tol = IMAGE_TOL * max_abs(&want);
        assert_close(
            "renderer image",
            &flat32(&images[b].pixels),
            &want,
            tol,
            0.0,
        );
        let gu: Vec<[f64; 3]> = ups[b].pixels.iter().map(|p| p.map(f64::from)).collect();
        let want = flat64(&reference::backward(&prep, &gu).d_env);
        let tol = GRAD_TOL * max_abs(&want);
        assert_close("renderer dL", &flat32(&grads[b].d_env), &want, tol, 0.0);
    }
}

#[test]
fn forward_backward_perspective_both_conventions() {
    for (conv, batch) in scenes::perspective() {
        compare(&format!("perspective {conv:?}"), &batch);
    }
}

#[test]
fn forward_backward_presets_with_constant_and_zero_lobes() {
    // the built-in presets have diffuse (constant) lobes, unused (scale 0) lobes and
    // exponents shared across channels
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 40.0 },
    ] {
        let mut rng = Rng::new(16);
        let scenes = matedit::presets::names()
            .iter()
            .map(|name| {
                let mut s = random_scene(&mut rng, 8, 8, 16, 32, Convention::Equirect, camera);
                s.material = matedit::presets::lookup(name).expect("preset");
                s
            })
            .collect();
        compare(&format!("presets {camera:?}"), &Batch::new(scenes).unwrap());
    }
}

#[test]
fn forward_backward_mixed_lobes_and_shared_terms() {
    // lobe 0: constant in channel 0, active elsewhere; lobe 1: the same curves in all
    // channels (one shared evaluation); lobe 2: scale 0 in channel 1 only
    let mut rng = Rng::new(17);
    let mut ctrl = random_material(&mut rng, (0.05, 1.5), (1.0, 40.0)).ctrl;
    use matedit::material::idx;
    for j in 0..6 {
        ctrl[idx(0, 0, 1, j)] = 0.0;
        for k in 1..3 {
            ctrl[idx(k, 1, 0, j)] = ctrl[idx(0, 1, 0, j)];
            ctrl[idx(k, 1, 1, j)] = ctrl[idx(0, 1, 1, j)];
        }
        ctrl[idx(1, 2, 0, j)] = 0.0;
    }
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 70.0 },
    ] {
        let mut s = random_scene(&mut rng, 9, 7, 16, 32, Convention::Equirect, camera);
        s.material = Material::new("mixed", &ctrl).unwrap();
        compare(
            &format!("mixed lobes {camera:?}"),
            &Batch::single(s).unwrap(),
        );
    }
}

#[test]
fn forward_backward_non_unit_normals_and_background() {
    let mut rng = Rng::new(18);
    let mut s = random_scene(
        &mut rng,
        11,
        9,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let mut n = s.normals.normals.clone();
    for (i, v) in n.iter_mut().enumerate() {
        // |n| > 1 lets x exceed 1 (up to the 1 + 1e-5 that NormalMap accepts)
        let scale = [0.5f32, 1.0, 1.000_009][i % 3];
        *v = v.map(|c| c * scale);
    }
    s.normals = NormalMap::new(11, 9, n).unwrap();
    compare("non-unit normals", &Batch::single(s).unwrap());
}

/// Normals facing away from the camera: texels above their horizon whose half vector is
/// not (x = max(0, h.n) = 0, log2 x standing in as a large negative number), under nine
/// lobes with exponents to 80, whose x^m1 must come out 0 there, not NaN.
#[test]
fn normals_facing_away_have_lit_texels_with_x_zero() {
    let mut rng = Rng::new(23);
    let mut s = random_scene(
        &mut rng,
        12,
        10,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let n = s.normals.normals.iter().map(|v| [v[0], v[1], -v[2].abs()]);
    s.normals = NormalMap::new(12, 10, n.collect()).unwrap();
    s.material = random_material(&mut rng, (0.02, 1.2), (2.0, 80.0));
    compare("normals facing away", &Batch::single(s).unwrap());
}

/// A sharp lobe under a bright, smooth sky: the lobe argument x is near 1 where it matters.
fn sharp_scene(m1: f64, camera: Camera) -> Scene {
    let m0 = 5.0;
    let (hl, wl) = (32, 64);
    let texels = (0..hl * wl)
        .map(|i| {
            let r = (i / wl) as f32 / hl as f32;
            [1.0 + r, 0.5 + 0.5 * r, 2.0 - r]
        })
        .collect();
    Scene {
        normals: NormalMap::sphere(48),
        env: EnvMap::new(hl, wl, Convention::Equirect, texels).unwrap(),
        material: Material::constant("sharp", [(0.3, 0.0), (m0, m1), (0.0, 0.0)]).unwrap(),
        camera,
    }
}

#[test]
fn sharp_lobes_stay_within_tolerance() {
    for m1 in [1e3, 1e4] {
        for camera in [
            Camera::Orthographic,
            Camera::Perspective { fov_y_deg: 30.0 },
        ] {
            let s = sharp_scene(m1, camera);
            compare_tol(
                &format!("sharp m1 = {m1} {camera:?}"),
                &Batch::single(s).unwrap(),
                GRAD_TOL,
                GRAD_TOL,
            );
        }
    }
}

/// Bitwise-equal results with 1 and 2 threads, and between two runs.
#[test]
fn deterministic_across_threads_and_runs() {
    let mut rng = Rng::new(19);
    // enough pixels (8,229 in the foreground) for three backward chunks
    let s = random_scene(
        &mut rng,
        96,
        100,
        16,
        32,
        Convention::Equirect,
        Camera::Perspective { fov_y_deg: 45.0 },
    );
    let batch = Batch::single(s).unwrap();
    let up = upstream_for(&batch, 5).remove(0).pixels;
    let prep = Prepared::new(&batch.scenes()[0]);
    assert!(prep.pixels.len() > 2 * 4096, "{} pixels", prep.pixels.len());
    let cpu = FastCpu::best();
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| (cpu.forward(&prep), cpu.backward(&prep, &up, Wanted::ALL)))
    };
    let (i1, g1) = run(1);
    let (i2, g2) = run(2);
    let (i3, g3) = run(2);
    let bits = |v: &[[f32; 3]]| v.iter().flatten().map(|x| x.to_bits()).collect::<Vec<_>>();
    for (i, g) in [(&i2, &g2), (&i3, &g3)] {
        assert_eq!(bits(&i1), bits(i), "image differs");
        assert_eq!(bits(&g1.d_env), bits(&g.d_env), "dL differs");
        assert_eq!(bits(&g1.d_normals), bits(&g.d_normals), "dn differs");
        let c = |v: &[f32; 108]| v.map(f32::to_bits);
        assert_eq!(c(&g1.d_ctrl), c(&g.d_ctrl), "dctrl differs");
    }
}

#[test]
fn describe_names_the_level_and_threads() {
    let d = FastCpu::best().describe();
    assert!(d.starts_with("cpu: f32 "), "{d}");
    assert!(d.contains("thread"), "{d}");
}

#[test]
fn constant_light_matches_the_analytic_value() {
    let m0 = 0.7;
    let scene = Scene {
        normals: NormalMap::sphere(16),
        env: EnvMap::constant(64, 128, Convention::Equirect, [1.0; 3]).unwrap(),
        material: Material::constant("flat", [(m0, 0.0), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
        camera: Camera::Orthographic,
    };
    let want = std::f64::consts::PI * f64::exp_m1(m0);
    let img = FastCpu::best().forward(&Prepared::new(&scene));
    let centre = img[8 * 16 + 8][0] as f64;
    assert!((centre / want - 1.0).abs() < 1e-3, "{centre} vs {want}");
}

fn flat_jacobians(j: &[matedit::Jacobian]) -> Vec<f64> {
    j.iter().flatten().flatten().map(|&v| v.into()).collect()
}

/// dI/dn per pixel of each scene on `backend`, without a backward pass.
fn jacobians(backend: &dyn Backend, preps: &[Prepared]) -> Vec<Vec<Jacobian>> {
    let got = backend.normal_jacobians(preps, None).unwrap();
    got.into_iter().map(|(j, _)| j).collect()
}

#[test]
fn normal_jacobians_match_the_reference_backward() {
    // the fast path's one-pass dI^k/dn against the f64 reference's three backward passes
    // (the trait's default), on random, preset, perspective and non-unit-normal scenes
    let mut rng = Rng::new(21);
    let mut cases = Vec::new();
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 50.0 },
    ] {
        cases.push(random_scene(
            &mut rng,
            9,
            8,
            16,
            32,
            Convention::Equirect,
            camera,
        ));
        let mut s = random_scene(&mut rng, 8, 8, 16, 32, Convention::Paper, camera);
        s.material = matedit::presets::lookup("plastic-red").expect("preset");
        cases.push(s);
    }
    let mut s = random_scene(
        &mut rng,
        7,
        7,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    s.normals
        .normals
        .iter_mut()
        .for_each(|n| *n = n.map(|c| c * 0.9));
    cases.push(s);
    let preps: Vec<Prepared> = cases.iter().map(Prepared::new).collect();
    let want = jacobians(&reference::Reference, &preps);
    for cpu in levels() {
        let got = jacobians(&cpu, &preps);
        for (c, (g, w)) in got.iter().zip(&want).enumerate() {
            assert_eq!(g.len(), preps[c].pixels.len());
            let (g, w) = (flat_jacobians(g), flat_jacobians(w));
            let what = format!("case {c} {} dI/dn", cpu.level().name());
            assert!(max_abs(&w) > 0.0, "{what}: all zero");
            assert_close(&what, &g, &w, GRAD_TOL * max_abs(&w), 0.0);
        }
    }
}

#[test]
fn normal_jacobians_with_backward_is_both_passes_in_one() {
    // the Jacobian from the backward pass's own lobe terms, through the plan kernels (a
    // preset sharing its exponents) and the dense ones (nine lobes of their own): the
    // reference's Jacobian, and gradients bitwise those of the backward pass alone
    let mut rng = Rng::new(23);
    let mut cases = Vec::new();
    for preset in [Some("plastic-red"), None] {
        let ortho = Camera::Orthographic;
        let mut s = random_scene(&mut rng, 9, 8, 16, 32, Convention::Equirect, ortho);
        s.material = match preset {
            Some(p) => matedit::presets::lookup(p).expect("preset"),
            None => random_material(&mut rng, (0.05, 1.5), (0.3, 80.0)),
        };
        cases.push(s);
    }
    let preps: Vec<Prepared> = cases.iter().map(Prepared::new).collect();
    let ups: Vec<matedit::Image> = preps
        .iter()
        .map(|p| matedit::Image {
            width: p.width,
            height: p.height,
            pixels: (0..p.width * p.height)
                .map(|_| [0, 1, 2].map(|_| rng.uniform(-1.0, 1.0) as f32))
                .collect(),
        })
        .collect();
    let want = jacobians(&reference::Reference, &preps);
    let sums = Wanted {
        normals: false,
        ..Wanted::ALL
    };
    for cpu in levels() {
        for wanted in [sums, Wanted::ALL] {
            let both = Backend::normal_jacobians(&cpu, &preps, Some((&ups, wanted))).unwrap();
            let alone = Backend::backward(&cpu, (&preps).into(), &ups, wanted).unwrap();
            for (c, ((j, g), (a, w))) in both.iter().zip(alone.iter().zip(&want)).enumerate() {
                let what = format!("case {c} {} {wanted:?}", cpu.level().name());
                let g = g.as_ref().expect("gradients");
                assert_eq!(g, a, "{what}: gradients");
                let (j, w) = (flat_jacobians(j), flat_jacobians(w));
                assert!(max_abs(&w) > 0.0, "{what}: all zero");
                assert_close(
                    &format!("{what} dI/dn"),
                    &j,
                    &w,
                    GRAD_TOL * max_abs(&w),
                    0.0,
                );
            }
        }
    }
}

#[test]
fn materials_with_nothing_to_share_take_the_dense_kernels() {
    // every lobe its own curves (three per channel; two where one lobe per channel has no
    // scale, which the image leaves out), sharp and negative lobes among them
    let mut rng = Rng::new(21);
    let mut two = random_material(&mut rng, (0.05, 1.5), (0.3, 80.0)).ctrl;
    for k in 0..3 {
        for j in 0..6 {
            two[matedit::material::idx(k, 1, 0, j)] = 0.0;
        }
    }
    let cases = [
        (Material::random(3), 3),
        (random_material(&mut rng, (-1.0, 5.0), (0.3, 1e4)), 3),
        (Material::new("two lobes", &two).unwrap(), 2),
    ];
    for (material, l) in cases {
        let ctrl = &material.ctrl;
        let plan = LobePlan::new(ctrl, |k, s| depends_on_x(ctrl, k, s));
        let dense = Dense::of(&plan, ctrl).expect("the image's lobes are dense");
        assert_eq!(dense.l, l, "{}", material.name);
        let mut s = random_scene(
            &mut rng,
            16,
            12,
            16,
            32,
            Convention::Equirect,
            Camera::Orthographic,
        );
        s.material = material;
        let name = s.material.name.clone();
        let batch = Batch::single(s).unwrap();
        compare(&format!("dense {name}"), &batch);
        // the plan kernels compute the same sums in other orders
        let prep = Prepared::new(&batch.scenes()[0]);
        let up = &upstream_for(&batch, 5)[0].pixels;
        for cpu in levels() {
            let plan = cpu.plan_kernels_only();
            let what = format!(
                "dense {name} {} against the plan kernels",
                cpu.level().name()
            );
            let want = flat32(&plan.forward(&prep));
            let tol = 1e-6 * max_abs(&want);
            assert_close(&what, &flat32(&cpu.forward(&prep)), &want, tol, 0.0);
            let all = Wanted::ALL;
            let (got, want) = (cpu.backward(&prep, up, all), plan.backward(&prep, up, all));
            for (part, g, w) in [
                ("dL", &got.d_env, &want.d_env),
                ("dn", &got.d_normals, &want.d_normals),
            ] {
                let w = flat32(w);
                let tol = 1e-5 * max_abs(&w);
                assert_close(&format!("{what} {part}"), &flat32(g), &w, tol, 0.0);
            }
            let (g, w): (Vec<f64>, Vec<f64>) = (
                got.d_ctrl.iter().map(|&v| v as f64).collect(),
                want.d_ctrl.iter().map(|&v| v as f64).collect(),
            );
            assert_close(&format!("{what} dctrl"), &g, &w, 1e-5 * max_abs(&w), 0.0);
        }
    }
}

#[test]
fn backward_of_a_material_sharing_little_runs_every_lobe_densely() {
    // a shared lobe, a lobe without scale and one without exponent among nine: the
    // backward pass runs all nine through the dense kernels (x^0 = 1, scale 0 adds 0)
    let mut rng = Rng::new(22);
    let mut ctrl = random_material(&mut rng, (0.05, 1.5), (0.3, 300.0)).ctrl;
    use matedit::material::idx;
    for j in 0..6 {
        ctrl[idx(0, 2, 0, j)] = 0.0;
        ctrl[idx(1, 0, 1, j)] = 0.0;
        for t in 0..2 {
            ctrl[idx(2, 1, t, j)] = ctrl[idx(0, 1, t, j)];
        }
    }
    let plan = LobePlan::new(&ctrl, |_, _| true);
    assert!(Dense::of(&plan, &ctrl).is_none());
    let dense = Dense::for_backward(&plan, &ctrl).expect("enough exponent groups");
    assert_eq!((dense.l, dense.lobes.len()), (3, 9));
    let mut s = random_scene(
        &mut rng,
        16,
        12,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    s.material = Material::new("sharing little", &ctrl).unwrap();
    compare("sharing little", &Batch::single(s).unwrap());
}
