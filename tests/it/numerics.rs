//! Numerics at the edges of valid input: no NaN or inf anywhere for extreme but valid
//! scenes, and full precision where a naive exp(y) - 1 would lose it (small scales).

use crate::common;

use common::{Rng, assert_close, flat32, flat64, gpu};
use matedit::prepare::Prepared;
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Image, Material, NormalMap, Scene, Wanted,
    reference,
};

fn all_finite(v: &[f64]) -> bool {
    v.iter().all(|x| x.is_finite())
}

/// Scales at +-40, exponents 0 and 1e4, radiance 1e12 at one texel, grazing, back-facing
/// and almost-background normals, a 2 x 4 map (large solid angles).
fn extreme_scenes() -> Vec<Scene> {
    let mut out = Vec::new();
    let normals = vec![
        [0.0, 0.0, 1.0],
        [1.0, 0.0, 0.0],   // grazing
        [0.0, -0.6, -0.8], // back-facing
        [2e-6, 0.0, 0.0],  // just above the background threshold
        [0.0, 0.0, 5e-7],  // background
        [0.577, 0.577, 0.577],
    ];
    for (m0, m1) in [
        (40.0, 0.0),
        (40.0, 1e4),
        (-40.0, 0.5),
        (1e-7, 1e4),
        (40.0, 0.01),
    ] {
        for (hl, wl) in [(2, 4), (8, 16)] {
            for convention in [Convention::Equirect, Convention::Paper] {
                let mut texels = vec![[1.0f32; 3]; hl * wl];
                texels[wl + 1] = [1e12, 0.0, 1e-12];
                out.push(Scene {
                    normals: NormalMap::new(6, 1, normals.clone()).unwrap(),
                    env: EnvMap::new(hl, wl, convention, texels).unwrap(),
                    material: Material::constant("extreme", [(m0, m1), (m0, 0.0), (0.0, 0.0)])
                        .unwrap(),
                    camera: Camera::Perspective { fov_y_deg: 90.0 },
                });
            }
        }
    }
    out
}

#[test]
fn extreme_valid_inputs_give_finite_outputs_cpu() {
    for (i, s) in extreme_scenes().iter().enumerate() {
        let prep = Prepared::new(s);
        let img = reference::forward(&prep);
        assert!(all_finite(&flat64(&img)), "scene {i}: image not finite");
        let g = vec![[1.0; 3]; 6];
        let r = reference::backward(&prep, &g);
        assert!(all_finite(&flat64(&r.d_env)), "scene {i}: dL not finite");
        assert!(
            all_finite(&flat64(&r.d_normals)),
            "scene {i}: dn not finite"
        );
        assert!(all_finite(&r.d_ctrl), "scene {i}: dctrl not finite");
        assert_eq!(img[4], [0.0; 3], "background pixel renders 0");
    }
}

#[test]
fn extreme_valid_inputs_give_finite_outputs_fast_cpu() {
    use matedit::cpu::{FastCpu, SimdLevel};
    for cpu in SimdLevel::ALL.into_iter().filter_map(FastCpu::with_level) {
        let level = cpu.level().name();
        for (i, s) in extreme_scenes().iter().enumerate() {
            let prep = Prepared::new(s);
            let img = flat32(&cpu.forward(&prep));
            assert!(all_finite(&img), "{level} scene {i}: image not finite");
            let want = flat64(&reference::forward(&prep));
            let scale = want.iter().fold(0.0f64, |a, b| a.max(b.abs()));
            assert_close(
                &format!("{level} scene {i} image"),
                &img,
                &want,
                1e-4 * scale,
                0.0,
            );
            let g = cpu.backward(&prep, &[[1.0; 3]; 6], Wanted::ALL);
            assert!(
                all_finite(&flat32(&g.d_env)),
                "{level} scene {i}: dL not finite"
            );
            assert!(
                all_finite(&flat32(&g.d_normals)),
                "{level} scene {i}: dn not finite"
            );
            let dc: Vec<f64> = g.d_ctrl.iter().map(|&v| v as f64).collect();
            assert!(all_finite(&dc), "{level} scene {i}: dctrl not finite");
            assert_eq!(img[12..15], [0.0; 3], "background pixel renders 0");
        }
    }
}

#[test]
fn extreme_valid_inputs_give_finite_outputs_gpu() {
    let Some(g) = gpu("extreme_valid_inputs_give_finite_outputs_gpu") else {
        return;
    };
    for (i, s) in extreme_scenes().into_iter().enumerate() {
        let batch = Batch::single(s).unwrap();
        let img = g.render((&batch).into()).unwrap();
        assert!(
            all_finite(&flat32(&img[0].pixels)),
            "scene {i}: image not finite"
        );
        let up = vec![Image {
            width: 6,
            height: 1,
            pixels: vec![[1.0; 3]; 6],
        }];
        let r = g.backward((&batch).into(), &up, Wanted::ALL).unwrap();
        assert!(all_finite(&flat32(&r[0].d_env)), "scene {i}: dL not finite");
        assert!(
            all_finite(&flat32(&r[0].d_normals)),
            "scene {i}: dn not finite"
        );
        assert!(
            r[0].d_ctrl.iter().all(|x| x.is_finite()),
            "scene {i}: dctrl not finite"
        );
    }
}

/// With scale 1e-6, f = exp(1e-6 x^m1) - 1 ~ 1e-6 x^m1: f32 exp(y) - 1 would be off by up
/// to 5% (exp(1e-6) rounds to 1 + 9.5e-7); the stable expm1 keeps the GPU within 1e-5.
#[test]
fn small_scale_lobes_keep_their_digits_on_gpu() {
    let Some(g) = gpu("small_scale_lobes_keep_their_digits_on_gpu") else {
        return;
    };
    let mut rng = Rng::new(3);
    let mut s = common::random_scene(
        &mut rng,
        8,
        8,
        16,
        32,
        Convention::Equirect,
        Camera::Orthographic,
    );
    s.material = Material::constant("faint", [(1e-6, 0.0), (3e-6, 4.0), (0.0, 0.0)]).unwrap();
    let want = flat64(&reference::forward(&Prepared::new(&s)));
    let got = flat32(&g.render((&Batch::single(s).unwrap()).into()).unwrap()[0].pixels);
    assert_close("faint image", &got, &want, 1e-30, 1e-5);
}

/// An output that overflows f32 (here: a huge but finite upstream gradient) is an error
/// naming it, not a silent inf.
#[test]
fn overflowing_outputs_are_errors_not_inf() {
    let renderer = matedit::Renderer::with_backend(Box::new(reference::Reference));
    let mut rng = Rng::new(4);
    let s = common::random_scene(
        &mut rng,
        4,
        4,
        8,
        16,
        Convention::Equirect,
        Camera::Orthographic,
    );
    let batch = Batch::single(s).unwrap();
    let up = vec![Image {
        width: 4,
        height: 4,
        pixels: vec![[3e38; 3]; 16],
    }];
    let err = renderer.backward(&batch, &up).expect_err("must overflow");
    let msg = err.to_string();
    assert!(msg.contains("overflowed f32"), "{msg}");
    // and a normal upstream works
    let up = vec![Image {
        width: 4,
        height: 4,
        pixels: vec![[1.0; 3]; 16],
    }];
    assert!(renderer.backward(&batch, &up).is_ok());
}

#[test]
fn small_scale_lobes_keep_their_digits_on_the_fast_cpu() {
    use matedit::cpu::{FastCpu, SimdLevel};
    let mut rng = Rng::new(3);
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 60.0 },
    ] {
        let mut s = common::random_scene(&mut rng, 8, 8, 16, 32, Convention::Equirect, camera);
        s.material = Material::constant("faint", [(1e-6, 0.0), (3e-6, 4.0), (0.0, 0.0)]).unwrap();
        let prep = Prepared::new(&s);
        let want = flat64(&reference::forward(&prep));
        for cpu in SimdLevel::ALL.into_iter().filter_map(FastCpu::with_level) {
            let got = flat32(&cpu.forward(&prep));
            let what = format!("faint image {} {camera:?}", cpu.level().name());
            assert_close(&what, &got, &want, 1e-30, 1e-5);
        }
    }
}
