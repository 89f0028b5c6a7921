//! The choice of a method for a tolerance (`render_within`, `backward_within`, `Chooser`):
//! the chosen method meets the tolerance, bad tolerances are errors, small scenes are
//! rendered exactly, and the estimate judges every output.

use super::{
    ALWAYS, errors, glossy, method, ortho, random_ortho, rel, run, smooth_env, sphere_scene,
    sun_env, upstream,
};
use matedit::cpu::FastCpu;
use matedit::lod::{self, Method};
use matedit::{Camera, Convention, Material, NormalMap, Scene};

/// A cylinder's normals: they turn about the y axis from -75 to +75 degrees across the
/// image, the same in every row (one line of the normal plane, so a table is cheap).
fn cylinder(w: usize, h: usize) -> NormalMap {
    let normals = (0..w * h)
        .map(|i| {
            let a = ((i % w) as f64 + 0.5) / w as f64 * 2.6 - 1.3;
            [a.sin() as f32, 0.0, a.cos() as f32]
        })
        .collect();
    NormalMap::new(w, h, normals).unwrap()
}

/// A diffuse base and a broad exponent-4 sheen.
fn matte() -> Material {
    Material::constant("matte", [(0.5, 0.0), (0.2, 4.0), (0.0, 0.0)]).unwrap()
}

/// The scenes for the tolerances, two orthographic and one perspective. The trials must fit
/// the estimate's budget (a tenth of the exact layer's work), so below some 3000 pixels
/// every choice is exact: the forward scenes have 4000 to 7000 pixels, and the backward
/// pass has one scene of 9216 (a cylinder, whose table needs few nodes).
fn tolerance_scenes(backward: bool) -> Vec<(&'static str, Scene)> {
    // the backward pass costs more: smaller scenes beside the one that approximates
    let (n, hl) = if backward { (48, 16) } else { (72, 32) };
    let persp = Scene {
        camera: Camera::Perspective { fov_y_deg: 40.0 },
        ..ortho(
            NormalMap::sphere(n),
            smooth_env(hl, 2 * hl, Convention::Equirect, 31),
            matte(),
        )
    };
    let (a, b) = if backward {
        (
            (
                "cylinder sun matte",
                ortho(
                    cylinder(96, 96),
                    sun_env(32, 64, Convention::Paper, 32, 2),
                    matte(),
                ),
            ),
            (
                "sphere smooth glossy",
                ortho(
                    NormalMap::sphere(48),
                    smooth_env(16, 32, Convention::Equirect, 33),
                    glossy(),
                ),
            ),
        )
    } else {
        (
            (
                "sphere sun glossy",
                ortho(
                    NormalMap::sphere(96),
                    sun_env(32, 64, Convention::Paper, 34, 2),
                    glossy(),
                ),
            ),
            (
                "bumpy sun matte",
                ortho(
                    NormalMap::bumpy(80, 80, 3),
                    sun_env(32, 64, Convention::Equirect, 35, 2),
                    matte(),
                ),
            ),
        )
    };
    vec![a, b, ("perspective smooth matte", persp)]
}

/// The checks every choice passes.
fn check_choice(what: &str, scene: &Scene, choice: &lod::Choice, tol: f64) {
    eprintln!("{what}: {choice}");
    let m = choice.method;
    assert_eq!(m.to_string().parse::<Method>().unwrap(), m, "{what}");
    m.validate(scene).unwrap();
    assert_eq!(choice.tolerance, tol, "{what}");
    assert!(
        choice.cost > 0.0 && choice.cost <= 1.0,
        "{what}: cost {}",
        choice.cost
    );
    // a candidate is taken when twice its estimate is within the tolerance
    assert!(choice.estimate.max() * 2.0 <= tol, "{what}: {choice:?}");
    if m.is_exact() {
        assert_eq!(choice.cost, 1.0, "{what}");
    } else {
        // and only if it saves at least half the work
        assert!(choice.cost < 0.5, "{what}: cost {}", choice.cost);
        assert!(choice.estimate.pixels > 0, "{what}: {choice:?}");
    }
    if !scene.camera.is_orthographic() {
        assert_eq!(m.table, None, "{what}: a table for a perspective camera");
    }
}

#[test]
fn render_within_meets_the_tolerance() {
    let cpu = FastCpu::new().unwrap();
    let mut approximated = 0;
    for (name, scene) in tolerance_scenes(false) {
        let exact = lod::render(&cpu, &scene, &Method::EXACT).unwrap();
        for tol in [1e-2, 1e-3] {
            let what = format!("{name} render tol {tol:e}");
            let (image, choice) = ALWAYS.render_within(&cpu, &scene, tol).unwrap();
            check_choice(&what, &scene, &choice, tol);
            let e = rel(&image.pixels, &exact.pixels);
            eprintln!("{what}: measured error {e:.2e}");
            assert!(e <= tol, "{what}: {} has error {e:e}", choice.method);
            // the image is the chosen method's, and the choice is the same again
            assert_eq!(
                image,
                lod::render(&cpu, &scene, &choice.method).unwrap(),
                "{what}"
            );
            assert_eq!(
                ALWAYS.choose(&cpu, &scene, tol, None).unwrap(),
                choice,
                "{what}"
            );
            approximated += usize::from(!choice.method.is_exact());
        }
    }
    assert!(approximated >= 3, "only {approximated} choices approximate");
}

/// backward_within on `scene` at `tol`: the choice's checks, and the measured error of
/// the image and of each gradient against the exact layer's. Returns the choice.
fn backward_within_errors(what: &str, scene: &Scene, tol: f64) -> (lod::Choice, [f64; 4]) {
    let cpu = FastCpu::new().unwrap();
    let up = upstream(scene, 36);
    let (grads, choice) = ALWAYS.backward_within(&cpu, scene, &up, tol).unwrap();
    check_choice(what, scene, &choice, tol);
    let est = &choice.estimate;
    if !choice.method.is_exact() {
        assert!(
            est.d_env.is_some() && est.d_normals.is_some() && est.d_ctrl.is_some(),
            "{what}: {est:?}"
        );
    }
    let got = run(&cpu, scene, &up, &choice.method);
    assert_eq!(
        grads, got.1,
        "{what}: the gradients are the chosen method's"
    );
    let e = errors(&got, &run(&cpu, scene, &up, &Method::EXACT));
    eprintln!(
        "{what}: estimated {est:?}, measured errors (image, dL, dn, dctrl) {:?}",
        e.map(|v| format!("{v:.2e}"))
    );
    (choice, e)
}

#[test]
fn backward_within_meets_the_tolerance() {
    let mut approximated = 0;
    for (name, scene) in tolerance_scenes(true) {
        for tol in [1e-2, 1e-3] {
            let what = format!("{name} backward tol {tol:e}");
            let (choice, e) = backward_within_errors(&what, &scene, tol);
            for (output, e) in ["image", "dL", "dn", "dctrl"].iter().zip(e) {
                assert!(e <= tol, "{what}: {} {output} error {e:e}", choice.method);
            }
            approximated += usize::from(!choice.method.is_exact());
        }
    }
    assert!(approximated >= 1, "only {approximated} choices approximate");
}

#[test]
fn backward_within_d_env_on_a_small_map() {
    let scene = ortho(
        NormalMap::sphere(96),
        sun_env(8, 16, Convention::Paper, 21, 2),
        glossy(),
    );
    let (choice, e) = backward_within_errors("sphere96 8x16 map tol 0.03", &scene, 0.03);
    assert!(e[1] <= 0.03, "{}: dL error {:e}", choice.method, e[1]);
}

#[test]
fn backward_within_d_env_of_a_table() {
    let scene = ortho(
        cylinder(96, 96),
        sun_env(32, 64, Convention::Paper, 21, 2),
        glossy(),
    );
    let (choice, e) = backward_within_errors("cylinder glossy tol 1e-2", &scene, 1e-2);
    assert!(e[1] <= 1e-2, "{}: dL error {:e}", choice.method, e[1]);
}

#[test]
fn bad_tolerances_are_errors() {
    let cpu = FastCpu::new().unwrap();
    let scene = random_ortho(37, (12, 10), (8, 16));
    let up = upstream(&scene, 24);
    for tol in [0.0, -1.0, f64::NAN, f64::INFINITY, f64::NEG_INFINITY, -0.0] {
        let e = ALWAYS
            .render_within(&cpu, &scene, tol)
            .expect_err("render_within");
        assert!(e.to_string().contains("tolerance"), "{tol}: {e}");
        assert!(
            ALWAYS.backward_within(&cpu, &scene, &up, tol).is_err(),
            "{tol}"
        );
        assert!(
            ALWAYS.choose(&cpu, &scene, tol, Some(&up)).is_err(),
            "{tol}"
        );
        assert!(ALWAYS.choose(&cpu, &scene, tol, None).is_err(), "{tol}");
    }
    // a huge tolerance is fine (whatever is chosen)
    let (_, choice) = ALWAYS.render_within(&cpu, &scene, 1e6).unwrap();
    check_choice("tol 1e6", &scene, &choice, 1e6);
}

#[test]
fn small_scenes_are_rendered_exactly_without_an_estimate() {
    // a 96 x 96 sphere against 32 x 64: below the default's pairs; the choice costs nothing
    let cpu = FastCpu::new().unwrap();
    let scene = sphere_scene(96, sun_env(32, 64, Convention::Equirect, 35, 2), glossy());
    let (image, choice) = lod::render_within(&cpu, &scene, 1e-2).unwrap();
    assert!(choice.method.is_exact(), "{choice}");
    assert_eq!(choice.estimate.pixels, 0, "{choice}");
    assert_eq!(image, lod::render(&cpu, &scene, &Method::EXACT).unwrap());
    // the same scene with the estimate forced does approximate it
    let forced = ALWAYS.choose(&cpu, &scene, 1e-2, None).unwrap();
    assert!(!forced.method.is_exact(), "{forced}");
}

#[test]
fn backward_within_tries_no_table_when_the_finest_misses_dl() {
    // with gradients, the finest table within the work allowed is judged on dLoss/dL
    // first; at a tolerance it misses, no other candidate is tried
    let scene = ortho(
        NormalMap::sphere(96),
        sun_env(64, 128, Convention::Paper, 5, 2),
        glossy(),
    );
    let cpu = FastCpu::new().unwrap();
    let up = upstream(&scene, 7);
    let (_, tight) = ALWAYS.backward_within(&cpu, &scene, &up, 1e-6).unwrap();
    assert!(tight.method.is_exact(), "{tight}");
    assert_eq!(tight.trials, 1, "{tight:?}");
    // where it passes, the tables are tried from the coarsest as before
    let (_, loose) = ALWAYS.backward_within(&cpu, &scene, &up, 0.1).unwrap();
    assert!(loose.trials > 1, "{loose:?}");
}

/// `Chooser::estimate` judges every output of a table, on the samples the choice uses: errors
/// of the same order as the ones measured on every pixel (not above them by much, not far
/// below); a per-pixel method's image alone, and without an upstream gradient no gradient.
#[test]
fn the_estimate_of_a_method_judges_every_output() {
    let cpu = FastCpu::new().unwrap();
    let scene = sphere_scene(96, smooth_env(16, 32, Convention::Equirect, 3), glossy());
    let up = upstream(&scene, 5);
    let chooser = lod::Chooser::default();
    let blocks = chooser
        .estimate(&cpu, &scene, &method("env2"), None)
        .unwrap();
    assert!(
        blocks.image > 0.0 && blocks.d_normals.is_none(),
        "{blocks:?}"
    );
    let m = method("table16");
    let e = chooser.estimate(&cpu, &scene, &m, Some(&up)).unwrap();
    let got = errors(
        &run(&cpu, &scene, &up, &m),
        &run(&cpu, &scene, &up, &Method::EXACT),
    );
    let est = [
        e.image,
        e.d_env.unwrap(),
        e.d_normals.unwrap(),
        e.d_ctrl.unwrap(),
    ];
    for (k, (g, x)) in got.iter().zip(est).enumerate() {
        assert!(
            *g > 0.0 && x > 0.0,
            "output {k}: measured {g:e}, estimated {x:e}"
        );
        assert!(
            x <= 1.5 * g,
            "output {k}: estimated {x:e} above measured {g:e}"
        );
        assert!(
            x * 10.0 >= *g,
            "output {k}: estimated {x:e}, measured {g:e}"
        );
    }
    assert!(
        chooser
            .estimate(&cpu, &scene, &method("table16"), None)
            .unwrap()
            .d_env
            .is_none()
    );
}
