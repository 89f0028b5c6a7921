//! The continuous light (`matedit::continuous_light`): level 0 and diffuse materials are the
//! layer bit for bit, the corrections converge towards the map's texels as area lights
//! (the map refined uniformly, each texel s x s copies), a tolerance is met there, and the
//! gradients are the adjoint (linearity in L, finite differences in a control point).

use crate::common;

use matedit::continuous_light::{self, Integration};
use matedit::{
    Accuracy, Batch, Camera, Convention, Device, EnvMap, Image, NormalMap, Renderer, Scene, Wanted,
    builtin_sky, presets,
};

fn scene(preset: &str, env: EnvMap) -> Batch {
    Batch::single(Scene {
        normals: NormalMap::sphere(40),
        env,
        material: presets::lookup(preset).expect("a preset"),
        camera: Camera::Orthographic,
    })
    .expect("a valid scene")
}

fn sky() -> EnvMap {
    builtin_sky::procedural_env(16, 32, Convention::Equirect)
}

/// Each texel as s x s texels of its radiance: the layer on it is the area light's sum.
fn refined(env: &EnvMap, s: usize) -> EnvMap {
    let w = env.width * s;
    let texels = (0..env.height * s * w)
        .map(|i| env.texels[(i / w / s) * env.width + (i % w) / s])
        .collect();
    EnvMap::new(env.height * s, w, env.convention, texels).expect("valid")
}

fn render(r: &Renderer, b: &Batch, light: Integration) -> Image {
    continuous_light::render(r, b, &Accuracy::Exact, light, &[])
        .expect("renders")
        .0
        .remove(0)
}

fn backward(r: &Renderer, b: &Batch, up: &Image, light: Integration) -> matedit::Gradients {
    continuous_light::backward(
        r,
        b,
        std::slice::from_ref(up),
        &Accuracy::Exact,
        light,
        Wanted::ALL,
        &[],
    )
    .expect("gradients")
    .0
    .remove(0)
}

/// max |a - b| / max b.
fn rel(a: &Image, b: &Image) -> f64 {
    rel_values(&a.pixels, &b.pixels)
}

/// max |a - b| / max |b| over RGB triples (gradients are signed).
fn rel_values(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let scale = b
        .iter()
        .flatten()
        .fold(0.0f64, |m, &v| m.max(f64::from(v).abs()));
    let diff = a
        .iter()
        .flatten()
        .zip(b.iter().flatten())
        .fold(0.0f64, |m, (&x, &y)| m.max(f64::from(x - y).abs()));
    diff / scale
}

#[test]
fn level_zero_and_diffuse_are_the_layer_bitwise() {
    let r = Renderer::new(Device::Cpu).unwrap();
    let b = scene("red-specular-plastic", sky());
    let layer = r.render(&b).unwrap().remove(0);
    assert_eq!(render(&r, &b, Integration::Level(0)), layer);
    assert_eq!(render(&r, &b, Integration::Discrete), layer);
    // a diffuse material: the measurement finds nothing to gain
    let b = scene("matte-white", sky());
    let c = continuous_light::choose(r.backend(), &b.scenes()[0], None, 1e-4).unwrap();
    assert_eq!(c.level, 0, "{c}");
    assert_eq!(
        render(&r, &b, Integration::Tolerance(1e-4)),
        r.render(&b).unwrap().remove(0)
    );
}

#[test]
fn converges_to_the_area_lights_and_meets_the_tolerance() {
    let r = Renderer::new(Device::Cpu).unwrap();
    let env = sky();
    let b = scene("red-specular-plastic", env.clone());
    let truth = r
        .render(&scene("red-specular-plastic", refined(&env, 16)))
        .unwrap()
        .remove(0);
    let errs: Vec<f64> = [0, 1, 2, 4]
        .map(|q| rel(&render(&r, &b, Integration::Level(q)), &truth))
        .to_vec();
    // measured: 0.52, then 0.063 at every level (a 16 x 32 map: every lobe split at the
    // largest split, 8)
    for w in errs.windows(2) {
        assert!(
            w[1] <= w[0] * 1.0001,
            "errors by level 0, 1, 2, 4: {errs:?}"
        );
    }
    assert!(errs[3] < errs[0] / 5.0, "{errs:?}");
    let tol = 1e-1;
    let c = continuous_light::choose(r.backend(), &b.scenes()[0], None, tol).unwrap();
    let e = rel(&render(&r, &b, Integration::Tolerance(tol)), &truth);
    assert!(c.level > 0 && e <= tol, "{c}: error {e}");
}

#[test]
fn gradients_are_the_adjoint() {
    let r = Renderer::new(Device::Reference).unwrap();
    let b = scene("red-specular-plastic", sky());
    let light = Integration::Level(2);
    let n = 40 * 40;
    let up = Image {
        width: 40,
        height: 40,
        pixels: (0..n).map(|i| [1.0, (i % 7) as f32 / 7.0, 0.5]).collect(),
    };
    let loss = |b: &Batch| -> f64 { inner(&render(&r, b, light).pixels, &up.pixels) };
    let g = backward(&r, &b, &up, light);
    // the layer is linear in L: the loss of L + dL is the loss of L plus d_env . dL
    let mut env = sky();
    let mut expected = 0.0;
    for (i, t) in env.texels.iter_mut().enumerate() {
        let d = (i % 5) as f32 * 0.1;
        t[1] += d;
        expected += f64::from(g.d_env[i][1] * d);
    }
    let got = loss(&scene("red-specular-plastic", env)) - loss(&b);
    assert!(
        (got - expected).abs() < 1e-4 * expected.abs(),
        "{got} vs {expected}"
    );
    // a control point of the glossy lobe's exponent, by central differences
    let idx = matedit::material::idx(0, 1, 1, 3);
    let mut m = presets::lookup("red-specular-plastic").unwrap();
    let h = 1e-3 * m.ctrl[idx].abs().max(1.0);
    let mut at = |v: f64| {
        m.ctrl[idx] = v;
        let mut s = b.scenes()[0].clone();
        s.material = m.clone();
        loss(&Batch::single(s).unwrap())
    };
    let c = presets::lookup("red-specular-plastic").unwrap().ctrl[idx];
    let fd = (at(c + h) - at(c - h)) / (2.0 * h);
    let an = f64::from(g.d_ctrl[idx]);
    assert!((fd - an).abs() < 1e-3 * an.abs().max(1e-3), "{fd} vs {an}");
}

#[test]
fn bad_values_are_errors() {
    let r = Renderer::new(Device::Cpu).unwrap();
    let mut s = scene("clay", sky()).scenes()[0].clone();
    s.env.convention = Convention::Paper;
    let b = Batch::single(s).unwrap();
    let e =
        continuous_light::render(&r, &b, &Accuracy::Exact, Integration::Level(2), &[]).unwrap_err();
    assert!(e.to_string().contains("equirect"), "{e}");
    let b = scene("clay", sky());
    for light in [
        Integration::Level(65),
        Integration::Tolerance(0.0),
        Integration::Tolerance(f64::NAN),
    ] {
        let e = continuous_light::render(&r, &b, &Accuracy::Exact, light, &[]).unwrap_err();
        assert!(e.to_string().starts_with("light: "), "{e}");
    }
}

#[test]
fn with_a_finer_map_the_continuous_light_approaches_it() {
    // the sky at 16 x 32 and, as its detail, the same sky at 64 x 128 (4 x 4 texels for
    // each): the split texels take their radiance from the finer map (the sun's disc
    // inside its texels), so the result nears the layer under the finer map, which
    // constant radiance per texel cannot; at a level that splits every texel near a
    // peak into the finer map's own texels it is that layer
    let r = Renderer::new(Device::Cpu).unwrap();
    let fine = builtin_sky::procedural_env(64, 128, Convention::Equirect);
    let b = scene("chrome-ish", sky());
    let truth = r
        .render(&scene("chrome-ish", fine.clone()))
        .unwrap()
        .remove(0);
    let detail = [Some(fine)];
    let with = |q| {
        continuous_light::render(&r, &b, &Accuracy::Exact, Integration::Level(q), &detail)
            .unwrap()
            .0
            .remove(0)
    };
    let layer = rel(&render(&r, &b, Integration::Discrete), &truth);
    let constant = rel(&render(&r, &b, Integration::Level(4)), &truth);
    let (e1, e4) = (rel(&with(1), &truth), rel(&with(4), &truth));
    assert!(
        e4 < 0.5 * layer && e4 < 0.5 * constant,
        "{e4} vs {layer}, {constant}"
    );
    assert!(e4 <= e1, "level 4 {e4} vs level 1 {e1}");
    // a detail map that does not refine the scene's: one error
    let bad = [Some(builtin_sky::procedural_env(
        48,
        96,
        Convention::Equirect,
    ))];
    let e = continuous_light::render(&r, &b, &Accuracy::Exact, Integration::Level(2), &bad)
        .unwrap_err();
    assert!(e.to_string().contains("does not refine"), "{e}");
}

#[test]
fn gradients_with_a_detail_map_are_the_adjoint() {
    // the layer is linear in L: <dLoss/dL, L> is the loss itself, with the detail too
    let r = Renderer::new(Device::Cpu).unwrap();
    let b = scene("red-specular-plastic", sky());
    let detail = [Some(builtin_sky::procedural_env(
        32,
        64,
        Convention::Equirect,
    ))];
    let light = Integration::Level(2);
    let image = continuous_light::render(&r, &b, &Accuracy::Exact, light, &detail)
        .unwrap()
        .0
        .remove(0);
    let up = Image {
        width: image.width,
        height: image.height,
        pixels: (0..image.pixels.len())
            .map(|i| [0.3 + (i % 7) as f32 * 0.1, 1.0, -0.5 + (i % 3) as f32 * 0.2])
            .collect(),
    };
    let loss = inner(&image.pixels, &up.pixels);
    let g = continuous_light::backward(
        &r,
        &b,
        std::slice::from_ref(&up),
        &Accuracy::Exact,
        light,
        Wanted::ALL,
        &detail,
    )
    .unwrap()
    .0
    .remove(0);
    let env = &b.scenes()[0].env;
    let dot = inner(&g.d_env, &env.texels);
    assert!((dot - loss).abs() <= 1e-4 * loss.abs(), "{dot} vs {loss}");
}

#[test]
fn a_chosen_level_is_within_its_tolerance_of_the_finest_on_every_pixel() {
    // a sharp lobe under a sun: the highlight is a few pixels, which evenly spread
    // samples can miss; the choice also samples the pixels whose peak is on the brightest
    // texels, and measures each level against the finest
    let r = Renderer::new(Device::Cpu).unwrap();
    let coarse = builtin_sky::procedural_env(64, 128, Convention::Equirect);
    let detail = [Some(builtin_sky::procedural_env(
        256,
        512,
        Convention::Equirect,
    ))];
    for preset in ["chrome-ish", "red-specular-plastic"] {
        let b = Batch::single(Scene {
            normals: NormalMap::sphere(128),
            env: coarse.clone(),
            material: presets::lookup(preset).expect("a preset"),
            camera: Camera::Orthographic,
        })
        .unwrap();
        // each level's whole image, rendered once (both tolerances may choose one level)
        let mut images = std::collections::HashMap::new();
        let mut level = |q| -> Image {
            images
                .entry(q)
                .or_insert_with(|| {
                    continuous_light::render(
                        &r,
                        &b,
                        &Accuracy::Exact,
                        Integration::Level(q),
                        &detail,
                    )
                    .unwrap()
                    .0
                    .remove(0)
                })
                .clone()
        };
        let finest = level(continuous_light::LEVELS[continuous_light::LEVELS.len() - 1]);
        for tol in [1e-2, 1e-3] {
            let c = continuous_light::choose(r.backend(), &b.scenes()[0], detail[0].as_ref(), tol)
                .unwrap();
            let e = rel(&level(c.level), &finest);
            assert!(
                e <= tol,
                "{preset} at {tol}: level {} is {e} from the finest",
                c.level
            );
        }
    }
}

/// sum over elements and channels of a * b, in f64.
fn inner(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            (0..3)
                .map(|k| f64::from(x[k]) * f64::from(y[k]))
                .sum::<f64>()
        })
        .sum()
}

/// The corrections' scenes hold lights of negated radiance (the texels' point lights):
/// the fast CPU path and the GPU path (lavapipe in CI; skipped without an adapter unless
/// MATEDIT_REQUIRE_GPU=1) give the f64 reference's image and gradients.
#[test]
fn every_backend_gives_the_references_corrections() {
    let b = scene("red-specular-plastic", sky());
    let light = Integration::Level(2);
    let up = Image {
        width: 40,
        height: 40,
        pixels: (0..40 * 40)
            .map(|i| [1.0, (i % 7) as f32 / 7.0 - 0.5, 0.5])
            .collect(),
    };
    let run = |r: &Renderer| (render(r, &b, light), backward(r, &b, &up, light));
    let reference = run(&Renderer::new(Device::Reference).unwrap());
    let layer = Renderer::new(Device::Reference)
        .unwrap()
        .render(&b)
        .unwrap()
        .remove(0);
    // the level changes the image: the corrections are compared, not only the layer
    assert!(
        rel(&reference.0, &layer) > 1e-3,
        "{}",
        rel(&reference.0, &layer)
    );
    let mut renderers = vec![("cpu", Renderer::new(Device::Cpu).unwrap())];
    for (name, g) in common::gpus("every_backend_gives_the_references_corrections") {
        renderers.push((name, Renderer::with_backend(Box::new(g))));
    }
    for (name, r) in &renderers {
        let (image, g) = run(r);
        let (want_image, want) = &reference;
        let e = [
            rel(&image, want_image),
            rel_values(&g.d_env, &want.d_env),
            rel_values(&g.d_normals, &want.d_normals),
        ];
        assert!(e[0] < 1e-5 && e[1] < 1e-4 && e[2] < 1e-4, "{name}: {e:?}");
        let ctrl = g.d_ctrl.iter().zip(&want.d_ctrl);
        let scale = want.d_ctrl.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        for (i, (x, y)) in ctrl.enumerate() {
            assert!(
                (x - y).abs() <= 1e-4 * scale,
                "{name}: d_ctrl[{i}] {x} vs {y}"
            );
        }
    }
}
