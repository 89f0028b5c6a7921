//! What is the fast f32 CPU path's own against the f64 reference, at every SIMD level
//! this machine has: its kernels for materials that share little or nothing, the normals'
//! Jacobians, the public API's batches, its determinism across thread counts (what every
//! backend must do: backends).
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
use matedit::{Backend, Batch, Camera, Convention, Jacobian, Material, Wanted, reference};

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

/// The batch of 3 through the public API, one call for the batch (each backend's own
/// comparison on it: backends::seeded).
#[test]
fn the_renderer_renders_a_batch_of_3_in_one_call() {
    let batch = scenes::batch_of_3();
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
