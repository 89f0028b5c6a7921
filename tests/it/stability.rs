//! Stability: every sweep case of tests/it/sweeps (material, geometry and light at and past
//! the edges of valid input) on the f64 reference, the fast CPU path, the GPU path and
//! three levels of detail: invalid input is rejected, valid input gives finite outputs
//! everywhere, and the exact paths stay within their f32 error of the reference. Also the
//! behaviour where finite differences fail (the kink of max(0, n.w)) and where an
//! environment level fails (a hard sun under a sharp lobe), pinned. docs/stability.md has
//! the measured tables (`cargo xtask stability`).

use crate::common;
use crate::sweeps;

use matedit::lod::{self, Method};
use matedit::{Backend, Camera, Convention, EnvMap, Material, NormalMap, Scene};
use sweeps::Outcome;

/// Largest relative error of an exact f32 path against the reference: image, gradients
/// (measured: 6e-6 and 2e-5).
const IMAGE_TOL: f64 = 3e-5;
const GRAD_TOL: f64 = 1e-4;

/// Every sweep case of sweeps `kind` (`material`, `geometry` or `light`) on `exact` against
/// the reference, and on the fast CPU path through `methods`: invalid input rejected, valid
/// input finite, the exact paths within their f32 error.
fn sweeps_hold(exact: &[(&str, &dyn Backend)], methods: &[&str], kind: &str) {
    let reference = matedit::reference::Reference;
    let cpu = matedit::cpu::FastCpu::new().expect("the fast CPU path");
    let methods: Vec<Method> = methods
        .iter()
        .map(|m| m.parse().expect("a method"))
        .collect();
    let cases: Vec<sweeps::Case> = sweeps::cases()
        .into_iter()
        .filter(|c| kind_of(c) == kind)
        .collect();
    assert!(!cases.is_empty(), "no {kind} sweeps");
    let mut runs = 0;
    for case in &cases {
        let what = format!("{}: {}", case.sweep, case.label);
        assert_eq!(
            case.scene.is_ok(),
            case.valid,
            "{what}: {:?}",
            case.scene.as_ref().err()
        );
        let Ok(scene) = &case.scene else {
            continue;
        };
        let ref_run = sweeps::run(&reference, scene, &Method::EXACT).expect("reference runs");
        let re = sweeps::outputs(&ref_run);
        assert!(
            re.iter().flatten().all(|v| v.is_finite()),
            "{what}: reference not finite"
        );
        for (name, backend) in exact {
            match sweeps::outcome(*backend, &Method::EXACT, case, Some(&re)) {
                Outcome::Ran {
                    finite: true,
                    errors: Some(e),
                } => {
                    assert!(e[0] <= IMAGE_TOL, "{what}: {name} image off by {:e}", e[0]);
                    let g = e[1].max(e[2]).max(e[3]);
                    assert!(g <= GRAD_TOL, "{what}: {name} gradients off by {g:e}");
                }
                other => panic!("{what}: {name}: {other:?}"),
            }
            runs += 1;
        }
        for m in &methods {
            match sweeps::outcome(&cpu, m, case, Some(&re)) {
                Outcome::Ran { finite: true, .. } | Outcome::NotApplicable => {}
                other => panic!("{what}: {m:?}: {other:?}"),
            }
            runs += 1;
        }
    }
    eprintln!("{} cases, {runs} runs off the reference", cases.len());
}

/// The kinds of sweep, a test each, so that they run side by side (all of them in one test
/// were the suite's second-longest, 70 s under nextest on 2 threads).
const KINDS: [&str; 3] = ["material", "geometry", "light"];

/// A case's kind of sweep: its sweep's name up to the colon.
fn kind_of(case: &sweeps::Case) -> &'static str {
    case.sweep.split(':').next().unwrap_or("")
}

/// Sweeps `kind` on the fast CPU path and on the GPU under each plan it runs (on lavapipe
/// its own and a large GPU's), against one reference per case.
fn sweeps_hold_on_every_path(kind: &str) {
    let test = format!("sweeps_hold_on_every_path ({kind})");
    let cpu = matedit::cpu::FastCpu::new().expect("the fast CPU path");
    let gpus = common::gpus(&test);
    let mut exact: Vec<(&str, &dyn Backend)> = vec![("fast CPU", &cpu)];
    exact.extend(gpus.iter().map(|(name, g)| (*name, g as &dyn Backend)));
    sweeps_hold(&exact, &["env2", "keep4", "table16"], kind);
}

#[test]
fn sweeps_hold_on_every_path_material() {
    // every case is of one of the kinds, so the three tests run them all
    for case in sweeps::cases() {
        assert!(
            KINDS.contains(&kind_of(&case)),
            "sweep {:?} of no kind",
            case.sweep
        );
    }
    sweeps_hold_on_every_path(KINDS[0]);
}

#[test]
fn sweeps_hold_on_every_path_geometry() {
    sweeps_hold_on_every_path(KINDS[1]);
}

#[test]
fn sweeps_hold_on_every_path_light() {
    sweeps_hold_on_every_path(KINDS[2]);
}

/// At n.w = 0 the cosine max(0, n.w) has a kink: central finite differences see half a
/// slope there. The layer returns the one-sided derivative from the lit side (the texel's
/// direction is 6e-17 off the horizon in f64, on the lit side): pinned.
#[test]
fn the_kink_of_the_cosine_takes_the_lit_side() {
    // texel (0, 0) of a 1 x 2 equirect map: theta = 90, phi = 90 degrees: +z, the view
    let mut texels = vec![[0.0f32; 3]; 2];
    texels[0] = [1.0; 3];
    let env = EnvMap::new(1, 2, Convention::Equirect, texels).expect("valid");
    let material = Material::constant("m", [(0.5, 0.0), (1.0, 4.0), (0.0, 0.0)]).expect("valid");
    let scene = |n: [f32; 3]| Scene {
        normals: NormalMap::new(1, 1, vec![n]).expect("valid"),
        env: env.clone(),
        material: material.clone(),
        camera: Camera::Orthographic,
    };
    let reference = matedit::reference::Reference;
    let up = sweeps::upstream(1, 1).pixels[0];
    // the loss the upstream gradient belongs to: sum_k up_k I_k
    let loss = |n| {
        let p = sweeps::run(&reference, &scene(n), &Method::EXACT)
            .expect("runs")
            .0
            .pixels[0];
        (0..3)
            .map(|k| f64::from(up[k]) * f64::from(p[k]))
            .sum::<f64>()
    };
    // n = (1, 0, 0): the light (+z) on the horizon; moving n towards +z lights it
    let n = [1.0f32, 0.0, 0.0];
    let eps = 1e-4f32;
    let (_, g) = sweeps::run(&reference, &scene(n), &Method::EXACT).expect("runs");
    let analytic = f64::from(g.d_normals[0][2]);
    let lit = (loss([1.0, 0.0, eps]) - loss(n)) / f64::from(eps);
    let dark = (loss(n) - loss([1.0, 0.0, -eps])) / f64::from(eps);
    // (I(n) itself is 4e-13: the light is 6e-17 above the horizon)
    assert!(
        lit.abs() > 0.0 && dark.abs() <= 1e-6 * lit.abs(),
        "lit {lit}, dark {dark}"
    );
    assert!(
        (analytic - lit).abs() <= 1e-3 * lit.abs(),
        "analytic {analytic}, lit side {lit}"
    );
    // and so central differences are half the layer's gradient here
    let central = (lit + dark) / 2.0;
    assert!((central - analytic / 2.0).abs() <= 1e-3 * lit.abs());
}

/// A hard sun under a sharp lobe is where averaging the map fails: the sun's block spreads
/// it over 16 texels' directions and the highlight moves and widens. Pinned: env4 is more
/// than 10% off there, and the choice under a 1% tolerance never takes it (it keeps the
/// sun, or stays exact) and stays within 1%.
#[test]
fn env_levels_fail_under_a_hard_sun_and_the_choice_avoids_them() {
    let mut env = matedit::builtin_sky::procedural_env(64, 128, Convention::Equirect);
    env.texels
        .iter_mut()
        .for_each(|t| *t = t.map(|v| v.min(2.0)));
    env.texels[20 * 128 + 40] = [6e4; 3];
    let scene = Scene {
        normals: NormalMap::sphere(48),
        env,
        material: Material::constant("sharp", [(0.1, 0.0), (3.0, 2000.0), (0.0, 0.0)])
            .expect("valid"),
        camera: Camera::Orthographic,
    };
    let cpu = matedit::cpu::FastCpu::new().expect("cpu");
    let exact = sweeps::run(&cpu, &scene, &Method::EXACT).expect("runs");
    let exact_img = sweeps::outputs(&exact)[0].clone();
    let env4 = lod::render(&cpu, &scene, &"env4".parse().expect("method")).expect("runs");
    let off = |i: &matedit::Image| {
        let v: Vec<f64> = i.pixels.iter().flatten().map(|&v| f64::from(v)).collect();
        sweeps::rel_err(&v, &exact_img)
    };
    let err = off(&env4);
    assert!(err > 0.1, "env4 under a hard sun is only {err:e} off");
    let (chosen, choice) = lod::render_within(&cpu, &scene, 1e-2).expect("chooses");
    let err = off(&chosen);
    eprintln!("chosen {choice}: {err:e}");
    assert!(err <= 1e-2, "chosen {choice} is {err:e} off");
    assert!(
        choice.method.env_factor == 1 || choice.method.keep > 0,
        "chose {choice}: an env level without the sun kept"
    );
}
