//! Levels of detail (`matedit::lod`): method names, the exact method against the
//! backends, the adjoints of every approximation (linearity in the map, finite
//! differences), accuracy as the table and the blocks are refined, the pixels a table
//! leaves to per-pixel evaluation, degenerate tables, the choice of a method for a
//! tolerance (two ignored tests show where the gradients' estimate misses), determinism
//! across runs and thread counts, the fast path and the GPU against the reference, and
//! background pixels.

use crate::common;

use common::{Rng, random_material, random_scene, upstream_for};
use matedit::cpu::FastCpu;
use matedit::lod::{self, Method};

/// The chooser on scenes of any size (by default small ones are rendered exactly).
const ALWAYS: lod::Chooser = lod::Chooser {
    min_pairs: 0.0,
    safety: lod::SAFETY,
    safety_sums: lod::SAFETY_SUMS,
};
use matedit::reference::Reference;
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Gradients, Image, Material, NormalMap, Renderer,
    Scene, Wanted,
};

/// The approximations whose adjoints are checked.
const APPROX: [&str; 4] = ["env2", "env4+keep4", "table16", "table24+env2+keep4"];

fn method(s: &str) -> Method {
    s.parse()
        .unwrap_or_else(|e| panic!("method '{s}' should parse: {e}"))
}

/// max |a - b| over max |b|.
fn rel(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    assert_eq!(a.len(), b.len(), "lengths differ");
    let (mut diff, mut scale) = (0.0f64, 0.0f64);
    for (x, y) in a.iter().flatten().zip(b.iter().flatten()) {
        assert!(x.is_finite(), "non-finite value {x}");
        diff = diff.max((f64::from(*x) - f64::from(*y)).abs());
        scale = scale.max(f64::from(*y).abs());
    }
    assert!(scale > 0.0, "the expected values are all zero");
    diff / scale
}

/// max |a - b| over max |b| for dLoss/dctrl.
fn rel_ctrl(a: &[f32], b: &[f32]) -> f64 {
    let t = |v: &[f32]| v.iter().map(|&x| [x, 0.0, 0.0]).collect::<Vec<_>>();
    rel(&t(a), &t(b))
}

/// The four relative errors (image, dL, dn, dctrl) of `got` against `want`.
fn errors(got: &(Image, Gradients), want: &(Image, Gradients)) -> [f64; 4] {
    [
        rel(&got.0.pixels, &want.0.pixels),
        rel(&got.1.d_env, &want.1.d_env),
        rel(&got.1.d_normals, &want.1.d_normals),
        rel_ctrl(&got.1.d_ctrl, &want.1.d_ctrl),
    ]
}

/// The image and the gradients of `scene` under `m`.
fn run(backend: &dyn Backend, scene: &Scene, up: &Image, m: &Method) -> (Image, Gradients) {
    let image = lod::render(backend, scene, m).unwrap_or_else(|e| panic!("render {m}: {e}"));
    let grads =
        lod::backward(backend, scene, up, m).unwrap_or_else(|e| panic!("backward {m}: {e}"));
    (image, grads)
}

/// A seeded random orthographic scene (common::random_scene): `w` x `h` pixels, an
/// equirect `hl` x `wl` map.
fn random_ortho(seed: u64, (w, h): (usize, usize), (hl, wl): (usize, usize)) -> Scene {
    let mut rng = Rng::new(seed);
    let (conv, cam) = (Convention::Equirect, Camera::Orthographic);
    random_scene(&mut rng, w, h, hl, wl, conv, cam)
}

/// A seeded upstream gradient for `scene`.
fn upstream(scene: &Scene, seed: u64) -> Image {
    upstream_for(&Batch::single(scene.clone()).unwrap(), seed).remove(0)
}

/// sum of a . b over pixels and channels, in f64.
fn inner(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    a.iter()
        .flatten()
        .zip(b.iter().flatten())
        .map(|(x, y)| f64::from(*x) * f64::from(*y))
        .sum()
}

fn sphere_scene(n: usize, env: EnvMap, material: Material) -> Scene {
    Scene {
        normals: NormalMap::sphere(n),
        env,
        material,
        camera: Camera::Orthographic,
    }
}

/// A smooth map: a dim constant plus three broad lobes of random colour.
fn smooth_env(hl: usize, wl: usize, convention: Convention, seed: u64) -> EnvMap {
    let mut rng = Rng::new(seed);
    let lobes: Vec<([f64; 3], f64, [f64; 3])> = (0..3)
        .map(|_| {
            let d = rng.unit_facing(-1.0);
            let k = rng.uniform(1.0, 3.0);
            let c = [0; 3].map(|_: i32| rng.uniform(0.5, 3.0));
            (d, k, c)
        })
        .collect();
    let texels = (0..hl * wl)
        .map(|i| {
            let (w, _) = convention.texel(i / wl, i % wl, hl, wl);
            let mut l = [0.2; 3];
            for (d, k, c) in &lobes {
                let e = (k * (w[0] * d[0] + w[1] * d[1] + w[2] * d[2] - 1.0)).exp();
                for ch in 0..3 {
                    l[ch] += c[ch] * e;
                }
            }
            l.map(|v| v as f32)
        })
        .collect();
    EnvMap::new(hl, wl, convention, texels).unwrap()
}

/// A random dim map (radiance 0.37 to 1.65) with `suns` texels of radiance 200 near the
/// equator, on the camera's side: far brighter than anything else, so that they are the
/// kept texels even when the map is perturbed by up to 1.
fn sun_env(hl: usize, wl: usize, convention: Convention, seed: u64, suns: usize) -> EnvMap {
    let mut rng = Rng::new(seed);
    let mut texels: Vec<[f32; 3]> = (0..hl * wl)
        .map(|_| [0; 3].map(|_: i32| rng.uniform(-1.0, 0.5).exp() as f32))
        .collect();
    for s in 0..suns {
        let r = hl / 3 + (s % 2) * hl / 4;
        let c = 1 + s * (wl / 2 - 2) / suns.max(1);
        texels[r * wl + c] = [200.0, 150.0, 180.0];
    }
    EnvMap::new(hl, wl, convention, texels).unwrap()
}

/// A glossy material: a diffuse base and an exponent-30 lobe.
fn glossy() -> Material {
    Material::constant("glossy", [(0.3, 0.0), (1.0, 30.0), (0.0, 0.0)]).unwrap()
}

/// `scene` with every foreground normal scaled to length `len`.
fn rescaled(scene: &Scene, len: f32) -> Scene {
    let mut s = scene.clone();
    for n in &mut s.normals.normals {
        let l = n.iter().map(|v| v * v).sum::<f32>().sqrt();
        if l > 0.0 {
            *n = n.map(|v| v / l * len);
        }
    }
    s
}

// 1. Names.

#[test]
fn method_names_round_trip_and_errors() {
    for s in ["exact", "env4", "keep16", "table32", "table96+env2+keep16"] {
        let m = method(s);
        assert_eq!(m.to_string(), s, "Display of {m:?}");
        assert_eq!(m.to_string().parse::<Method>().unwrap(), m);
    }
    assert_eq!(method("exact"), Method::EXACT);
    assert!(Method::EXACT.is_exact());
    assert_eq!(
        method("table96+env2+keep16"),
        Method {
            env_factor: 2,
            keep: 16,
            table: Some(96),
            cull: None,
        }
    );
    // parts in any order, one canonical name
    assert_eq!(
        method("keep16+env2+table96").to_string(),
        "table96+env2+keep16"
    );
    assert_eq!(method("env1").to_string(), "exact");
    assert_eq!(method("env64").env_factor, 64);
    assert_eq!(method("table4").table, Some(4));
    for bad in [
        "",
        "foo",
        "env0",
        "env65",
        "table2",
        "env2+env4",
        "env2+",
        "+env2",
        "exact+env2",
        "env-1",
        "envx",
        "table4097",
        "keep4+keep8",
        "EXACT",
        " env2",
    ] {
        let e = bad
            .parse::<Method>()
            .expect_err(&format!("'{bad}' should not parse"));
        assert!(e.contains(bad), "the error for '{bad}' names it: {e}");
    }

    let mut rng = Rng::new(1);
    let persp = Camera::Perspective { fov_y_deg: 50.0 };
    let scene = random_scene(&mut rng, 6, 5, 8, 16, Convention::Equirect, persp);
    let e = method("table32+env2")
        .validate(&scene)
        .expect_err("a table needs an orthographic camera")
        .to_string();
    assert!(e.contains("normal tables"), "{e}");
    for ok in ["exact", "env2", "keep4", "env4+keep8"] {
        method(ok).validate(&scene).unwrap();
    }
    // the passes refuse it too, with the same message
    let up = upstream(&scene, 2);
    let e = lod::render(&Reference, &scene, &method("table16")).expect_err("perspective table");
    assert!(e.to_string().contains("normal tables"), "{e}");
    let e = lod::backward(&Reference, &scene, &up, &method("table16")).expect_err("perspective");
    assert!(e.to_string().contains("normal tables"), "{e}");
    let ortho = Scene {
        camera: Camera::Orthographic,
        ..scene
    };
    method("table32+env2").validate(&ortho).unwrap();
    // fields set by hand are checked as well
    let weird = Method {
        env_factor: 0,
        keep: 0,
        table: None,
        cull: None,
    };
    assert!(weird.validate(&ortho).is_err());
    assert!(lod::render(&Reference, &ortho, &weird).is_err());
    let weird = Method {
        env_factor: 1,
        keep: 0,
        table: Some(3),
        cull: None,
    };
    assert!(weird.validate(&ortho).is_err());
    // an upstream of the wrong size is an error, not a panic
    let small = Image::zeros(3, 3);
    assert!(lod::backward(&Reference, &ortho, &small, &method("env2")).is_err());
}

// 2. The exact method is the layer.

#[test]
fn exact_method_is_the_backend_bitwise() {
    let cpu = FastCpu::new().unwrap();
    let renderer = Renderer::with_backend(Box::new(cpu));
    let mut rng = Rng::new(3);
    for (conv, camera) in [
        (Convention::Equirect, Camera::Orthographic),
        (Convention::Paper, Camera::Perspective { fov_y_deg: 60.0 }),
    ] {
        let scene = random_scene(&mut rng, 13, 11, 16, 32, conv, camera);
        let batch = Batch::single(scene.clone()).unwrap();
        let up = upstream_for(&batch, 4);
        let (image, grads) = run(&cpu, &scene, &up[0], &Method::EXACT);
        assert_eq!(image, renderer.render(&batch).unwrap()[0], "{conv:?}");
        assert_eq!(
            image,
            Backend::render(&cpu, (&batch).into()).unwrap()[0],
            "{conv:?}"
        );
        assert_eq!(
            grads,
            renderer.backward(&batch, &up).unwrap()[0],
            "{conv:?}"
        );
        assert_eq!(
            grads,
            Backend::backward(&cpu, (&batch).into(), &up, Wanted::ALL).unwrap()[0]
        );
    }
}

// 3. Full-resolution blocks with kept texels are the layer.

#[test]
fn full_resolution_with_kept_texels_is_exact() {
    let mut rng = Rng::new(5);
    let cpu = FastCpu::new().unwrap();
    let backends: [(&str, &dyn Backend); 2] = [("reference", &Reference), ("cpu", &cpu)];
    for conv in [Convention::Equirect, Convention::Paper] {
        let scene = random_scene(&mut rng, 12, 10, 16, 32, conv, Camera::Orthographic);
        let up = upstream(&scene, 6);
        // every pixel is off unit length, so a table leaves all of them to per-pixel
        // evaluation: full-resolution blocks (the map less its kept texels) plus the kept
        // texels, which must add up to the layer
        let off_unit = rescaled(&scene, 0.8);
        for (name, b) in backends {
            // and with every texel kept, the blocks are dark and the kept texels are the map
            for (s, m) in [
                (&scene, "keep8"),
                (&off_unit, "table16+keep8"),
                (&scene, "env4+keep512"),
            ] {
                let exact = run(b, s, &up, &Method::EXACT);
                let got = run(b, s, &up, &method(m));
                let e = errors(&got, &exact);
                eprintln!(
                    "{name} {conv:?} {m}: errors (image, dL, dn, dctrl) {:?}",
                    e.map(|v| format!("{v:.1e}"))
                );
                for (what, e) in ["image", "dL", "dn", "dctrl"].iter().zip(e) {
                    assert!(e <= 1e-5, "{name} {conv:?} {m} {what}: error {e:e}");
                }
            }
        }
    }
}

// 4. Adjoints.

/// The scene the adjoints are checked on: a 16-pixel sphere, a dim 16 x 32 map with four
/// suns, a random material with exponents up to 20.
fn adjoint_scene(seed: u64, convention: Convention) -> Scene {
    let mut rng = Rng::new(seed);
    sphere_scene(
        16,
        sun_env(16, 32, convention, seed, 4),
        random_material(&mut rng, (0.05, 1.5), (1.0, 20.0)),
    )
}

#[test]
fn approximations_are_linear_in_the_map_and_d_env_is_their_adjoint() {
    for (seed, conv) in [(7, Convention::Equirect), (8, Convention::Paper)] {
        let scene = adjoint_scene(seed, conv);
        let up = upstream(&scene, seed + 100);
        for m in APPROX.map(method) {
            let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
            let a = lod::render(&Reference, &scene, &m).unwrap();
            // a random non-negative step (the map stays valid) where dLoss/dL is
            // positive, so that <dL, d> is a sum of positive terms and does not cancel
            let mut rng = Rng::new(seed + 200);
            let d: Vec<[f32; 3]> = g
                .d_env
                .iter()
                .map(|dl| {
                    dl.map(|v| {
                        if v > 0.0 {
                            rng.uniform(0.0, 1.0) as f32
                        } else {
                            0.0
                        }
                    })
                })
                .collect();
            let mut moved = scene.clone();
            for (t, d) in moved.env.texels.iter_mut().zip(&d) {
                for k in 0..3 {
                    t[k] += d[k];
                }
            }
            let b = lod::render(&Reference, &moved, &m).unwrap();
            let lhs = inner(&up.pixels, &b.pixels) - inner(&up.pixels, &a.pixels);
            let rhs = inner(&g.d_env, &d);
            let e = (lhs - rhs).abs() / rhs.abs();
            eprintln!("{conv:?} {m}: <up, F(L + d) - F(L)> {lhs:.6e}, <dL, d> {rhs:.6e}: {e:.1e}");
            assert!(rhs > 0.0 && e <= 1e-5, "{conv:?} {m}: {lhs:e} vs {rhs:e}");
        }
    }
}

#[test]
fn d_ctrl_matches_finite_differences_of_every_approximation() {
    let scene = adjoint_scene(9, Convention::Equirect);
    let up = upstream(&scene, 10);
    let loss = |ctrl: &[f64], m: &Method| {
        let s = Scene {
            material: Material::new("fd", ctrl).unwrap(),
            ..scene.clone()
        };
        inner(&up.pixels, &lod::render(&Reference, &s, m).unwrap().pixels)
    };
    let eps = 1e-3;
    for m in APPROX.map(method) {
        let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
        let scale = g
            .d_ctrl
            .iter()
            .fold(0.0f64, |a, &v| a.max(f64::from(v).abs()));
        let mut worst = (0, 0.0f64);
        for i in 0..matedit::N_PARAMS {
            let mut c = scene.material.ctrl;
            c[i] += eps;
            let plus = loss(&c, &m);
            c[i] -= 2.0 * eps;
            let minus = loss(&c, &m);
            let fd = (plus - minus) / (2.0 * eps);
            let e = (fd - f64::from(g.d_ctrl[i])).abs() / scale;
            if e > worst.1 {
                worst = (i, e);
            }
        }
        eprintln!(
            "{m}: d_ctrl worst error {:.1e} of max {scale:.3e} at {}",
            worst.1, worst.0
        );
        assert!(
            worst.1 <= 1e-3,
            "{m}: d_ctrl[{}] off by {:e}",
            worst.0,
            worst.1
        );
    }
}

/// Unit directions of the `factor` x `factor` blocks of a map: their solid-angle-weighted
/// mean texel direction.
fn block_dirs(env: &EnvMap, factor: usize) -> Vec<[f64; 3]> {
    let (h, w) = (env.height, env.width);
    let cols = w.div_ceil(factor);
    let mut acc = vec![[0.0f64; 3]; h.div_ceil(factor) * cols];
    for r in 0..h {
        for c in 0..w {
            let (d, dw) = env.convention.texel(r, c, h, w);
            let a = &mut acc[(r / factor) * cols + c / factor];
            for k in 0..3 {
                a[k] += d[k] * dw;
            }
        }
    }
    acc.into_iter()
        .filter_map(|a| {
            let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
            (l > 0.0).then(|| a.map(|v| v / l))
        })
        .collect()
}

#[test]
fn d_normals_match_finite_differences_of_env_levels() {
    let scene = adjoint_scene(11, Convention::Equirect);
    let up = upstream(&scene, 12);
    let eps = 2f32.powi(-11);
    for m in ["env2", "env4+keep4"].map(method) {
        let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
        // light directions: the blocks' and every texel's (the kept ones)
        let mut dirs = block_dirs(&scene.env, m.env_factor);
        dirs.extend(block_dirs(&scene.env, 1));
        // pixels at least 4 steps away from every kink (n.w = 0, n.h = 0)
        let margin = |n: [f32; 3]| {
            let n = n.map(f64::from);
            dirs.iter()
                .map(|w| {
                    let h = [w[0], w[1], w[2] + 1.0];
                    let hl = (h[0] * h[0] + h[1] * h[1] + h[2] * h[2]).sqrt();
                    let c = n[0] * w[0] + n[1] * w[1] + n[2] * w[2];
                    let x = (n[0] * h[0] + n[1] * h[1] + n[2] * h[2]) / hl;
                    c.abs().min(x.abs())
                })
                .fold(f64::INFINITY, f64::min)
        };
        let pixels: Vec<usize> = (0..scene.normals.normals.len())
            .filter(|&p| !scene.normals.is_background(p))
            .filter(|&p| margin(scene.normals.normals[p]) > 4.0 * f64::from(eps))
            .step_by(7)
            .take(5)
            .collect();
        assert!(
            pixels.len() >= 3,
            "{m}: only {} pixels away from kinks",
            pixels.len()
        );
        for &p in &pixels {
            let want = g.d_normals[p].map(f64::from);
            let scale = want.iter().fold(0.0f64, |a, v| a.max(v.abs()));
            for (c, &want) in want.iter().enumerate() {
                let at = |delta: f32| {
                    let mut s = scene.clone();
                    s.normals.normals[p][c] += delta;
                    let img = lod::render(&Reference, &s, &m).unwrap();
                    (
                        inner(&[up.pixels[p]], &[img.pixels[p]]),
                        s.normals.normals[p][c],
                    )
                };
                let ((lp, np), (lm, nm)) = (at(eps), at(-eps));
                let fd = (lp - lm) / f64::from(np - nm);
                let e = (fd - want).abs() / scale;
                assert!(
                    e <= 2e-3,
                    "{m} pixel {p} dn[{c}]: fd {fd:e} vs {want:e} ({e:.1e})"
                );
            }
        }
    }
}

#[test]
fn table_d_normals_approach_the_exact_ones() {
    // dLoss/dn of a table interpolates the nodes' exact Jacobians (not the derivative of
    // the interpolated image): it must converge to the layer's as the table grows
    let scene = sphere_scene(32, smooth_env(16, 32, Convention::Equirect, 13), glossy());
    let up = upstream(&scene, 14);
    let exact = lod::backward(&Reference, &scene, &up, &Method::EXACT).unwrap();
    let err = |r: usize| {
        let m = Method {
            table: Some(r),
            ..Method::EXACT
        };
        let g = lod::backward(&Reference, &scene, &up, &m).unwrap();
        rel(&g.d_normals, &exact.d_normals)
    };
    let (e16, e64) = (err(16), err(64));
    eprintln!("d_normals error: table16 {e16:.2e}, table64 {e64:.2e}");
    assert!(e64 < e16 / 4.0, "table64 {e64:e} vs table16 {e16:e}");
    assert!(e64 <= 1e-2, "table64: {e64:e}");
}

// 5. Accuracy.

#[test]
fn finer_tables_and_blocks_are_more_accurate() {
    let cpu = FastCpu::new().unwrap();
    let scene = sphere_scene(48, smooth_env(32, 64, Convention::Equirect, 15), glossy());
    let exact = lod::render(&cpu, &scene, &Method::EXACT).unwrap();
    let err = |m: &str| {
        rel(
            &lod::render(&cpu, &scene, &method(m)).unwrap().pixels,
            &exact.pixels,
        )
    };
    let e = ["table16", "table32", "table64"].map(err);
    eprintln!(
        "smooth scene: table16 {:.2e}, table32 {:.2e}, table64 {:.2e}",
        e[0], e[1], e[2]
    );
    // the horizon kinks of max(0, n.w) (one per texel) keep the convergence well below
    // the interpolation's own rate (h^6): 4.8x, then 1.17x here (table64 is finer than
    // the 48 pixels)
    assert!(e[0] > 4.0 * e[1] && e[1] > 1.1 * e[2], "{e:?}");
    assert!(e[2] <= 5e-4, "table64: {:e}", e[2]);

    // one bright texel on a dim map: coarse blocks move it, kept texels put it back
    let (hl, wl) = (16, 32);
    let mut texels = vec![[0.05f32; 3]; hl * wl];
    texels[(hl / 3) * wl + wl / 4 + 1] = [500.0; 3];
    let env = EnvMap::new(hl, wl, Convention::Equirect, texels).unwrap();
    let scene = sphere_scene(24, env, glossy());
    let exact = lod::render(&cpu, &scene, &Method::EXACT).unwrap();
    let err = |m: &str| {
        rel(
            &lod::render(&cpu, &scene, &method(m)).unwrap().pixels,
            &exact.pixels,
        )
    };
    let e = ["env2", "env8", "env8+keep16", "env2+keep1"].map(err);
    eprintln!(
        "bright texel: env2 {:.2e}, env8 {:.2e}, env8+keep16 {:.2e}, env2+keep1 {:.2e}",
        e[0], e[1], e[2], e[3]
    );
    assert!(e[1] > 2.0 * e[0], "{e:?}");
    assert!(e[2] < e[1] / 10.0, "{e:?}");
    assert!(e[3] < e[0] / 10.0, "{e:?}");
}

// 6. Pixels a table cannot hold.

#[test]
fn pixels_off_the_table_are_evaluated_per_pixel() {
    let mut rng = Rng::new(16);
    let (w, h) = (12, 12);
    // per pixel: 0 unit and facing (tabled), 1 of length 0.8, 2 unit with n.z < -0.6,
    // 3 background
    let kind = |p: usize| (p * 7 + p / w) % 4;
    let normals: Vec<[f32; 3]> = (0..w * h)
        .map(|p| {
            let n = match kind(p) {
                0 => rng.unit_facing(0.1),
                1 => rng.unit_facing(-0.3).map(|v| 0.8 * v),
                2 => {
                    let n = rng.unit_facing(0.65);
                    [n[0], n[1], -n[2]]
                }
                _ => [0.0; 3],
            };
            n.map(|v| v as f32)
        })
        .collect();
    // a diffuse lobe (exponent 0) lights the normals facing away too
    let mut material = random_material(&mut rng, (0.05, 1.5), (1.0, 30.0));
    for k in 0..3 {
        for j in 0..6 {
            material.ctrl[matedit::material::idx(k, 0, 1, j)] = 0.0;
        }
    }
    let scene = Scene {
        normals: NormalMap::new(w, h, normals).unwrap(),
        env: sun_env(16, 32, Convention::Equirect, 17, 3),
        material,
        camera: Camera::Orthographic,
    };
    let up = upstream(&scene, 18);
    let cpu = FastCpu::new().unwrap();
    let backends: [(&str, &dyn Backend); 2] = [("reference", &Reference), ("cpu", &cpu)];
    for (name, b) in backends {
        for (table, plain) in [("table16+env2+keep4", "env2+keep4"), ("table24", "exact")] {
            let t = run(b, &scene, &up, &method(table));
            let p = run(b, &scene, &up, &method(plain));
            let close = |a: [f32; 3], b: [f32; 3]| {
                a.iter()
                    .zip(&b)
                    .all(|(x, y)| (x - y).abs() <= 1e-6 * y.abs().max(1e-30))
            };
            let (mut off, mut differ) = (0, 0);
            for q in 0..w * h {
                match kind(q) {
                    1 | 2 => {
                        off += 1;
                        let (a, b) = (t.0.pixels[q], p.0.pixels[q]);
                        assert!(close(a, b), "{name} {table} pixel {q}: {a:?} vs {b:?}");
                        assert!(b.iter().any(|&v| v > 0.0), "{name} pixel {q} is dark");
                        let (a, b) = (t.1.d_normals[q], p.1.d_normals[q]);
                        assert!(close(a, b), "{name} {table} dn pixel {q}: {a:?} vs {b:?}");
                    }
                    0 => differ += usize::from(t.0.pixels[q] != p.0.pixels[q]),
                    _ => {}
                }
            }
            eprintln!("{name} {table}: {off} pixels off the table, {differ} tabled ones differ");
            // the tabled pixels are interpolated (not all of them land on a node)
            assert!(differ > 0, "{name} {table}: no pixel was tabled");
        }
    }
}

#[test]
fn degenerate_tables() {
    let cpu = FastCpu::new().unwrap();
    let env = smooth_env(8, 16, Convention::Equirect, 38);
    // every normal the same: the grid shrinks to its least extent around it
    let flat = ortho(
        NormalMap::new(6, 5, vec![[0.0, 0.0, 1.0]; 30]).unwrap(),
        env.clone(),
        glossy(),
    );
    // the coarsest table there is, and a table over a handful of pixels
    let sphere = ortho(NormalMap::sphere(20), env.clone(), glossy());
    let few = ortho(NormalMap::sphere(3), env, glossy());
    // (tolerance of the image, of the gradients): 4 x 4 nodes are coarse but finite
    for (name, scene, m, tol) in [
        ("flat", &flat, "table16", (1e-5, 1e-5)),
        ("flat", &flat, "table4096", (1e-5, 1e-5)),
        ("sphere", &sphere, "table4", (0.2, 2.0)),
        ("3 x 3 sphere", &few, "table8+keep2", (5e-2, 0.5)),
    ] {
        let up = upstream(scene, 39);
        let exact = run(&cpu, scene, &up, &Method::EXACT);
        let e = errors(&run(&cpu, scene, &up, &method(m)), &exact);
        eprintln!("{name} {m}: errors {:?}", e.map(|v| format!("{v:.1e}")));
        for (output, e) in ["image", "dL", "dn", "dctrl"].iter().zip(e) {
            let tol = if *output == "image" { tol.0 } else { tol.1 };
            assert!(e <= tol, "{name} {m} {output}: error {e:e}");
        }
    }
}

// 7. The choice for a tolerance.

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

fn ortho(normals: NormalMap, env: EnvMap, material: Material) -> Scene {
    Scene {
        normals,
        env,
        material,
        camera: Camera::Orthographic,
    }
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

// 8. Determinism.

#[test]
fn results_are_deterministic_across_runs_and_threads() {
    let scene = random_ortho(25, (20, 18), (16, 32));
    let up = upstream(&scene, 26);
    let cpu = FastCpu::new().unwrap();
    let pool = |n: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
    };
    for m in ["exact", "env4", "table24+env2+keep4", "table16+keep8"].map(method) {
        let first = run(&Reference, &scene, &up, &m);
        assert_eq!(first, run(&Reference, &scene, &up, &m), "reference {m}");
        let one = pool(1).install(|| run(&cpu, &scene, &up, &m));
        let two = pool(2).install(|| (run(&cpu, &scene, &up, &m), run(&cpu, &scene, &up, &m)));
        assert_eq!(two.0, two.1, "cpu {m}: twice on 2 threads");
        assert_eq!(one, two.0, "cpu {m}: 1 vs 2 threads");
    }
    let within = |n: usize| {
        pool(n).install(|| {
            let (g, c) = ALWAYS.backward_within(&cpu, &scene, &up, 1e-2).unwrap();
            let (i, d) = ALWAYS.render_within(&cpu, &scene, 1e-2).unwrap();
            (g, c, i, d)
        })
    };
    assert_eq!(
        within(1),
        within(2),
        "the choices and their results, 1 vs 2 threads"
    );
}

// 9. The backends.

/// A scene for comparing backends, and the same with every normal off unit length (a
/// table then has no node at all).
fn backend_scenes() -> [Scene; 2] {
    let scene = random_ortho(27, (16, 14), (16, 32));
    let off_unit = rescaled(&scene, 0.9);
    [scene, off_unit]
}

/// `backend` against the reference on the backend scenes, within `tol` of each output's
/// largest value.
fn check_backend(name: &str, backend: &dyn Backend, tol: f64) {
    let [scene, off_unit] = backend_scenes();
    let persp = Scene {
        camera: Camera::Perspective { fov_y_deg: 50.0 },
        ..scene.clone()
    };
    for (s, m) in [
        (&scene, "table24+keep4"),
        (&scene, "table16+env2+keep8"),
        (&scene, "env4+keep8"),
        (&persp, "env2+keep4"),
        (&off_unit, "table16+env2"),
    ] {
        let (m, up) = (method(m), upstream(s, 28));
        let want = run(&Reference, s, &up, &m);
        let got = run(backend, s, &up, &m);
        let e = errors(&got, &want);
        eprintln!(
            "{name} {m}: errors (image, dL, dn, dctrl) {:?}",
            e.map(|v| format!("{v:.1e}"))
        );
        for (output, e) in ["image", "dL", "dn", "dctrl"].iter().zip(e) {
            assert!(e <= tol, "{name} {m} {output}: error {e:e}");
        }
    }
}

#[test]
fn fast_cpu_runs_approximations_like_the_reference() {
    // tables' dLoss/dn come from the fast path's own Jacobian kernel
    check_backend("cpu", &FastCpu::new().unwrap(), 1e-5);
}

#[test]
fn gpu_runs_approximations_like_the_reference() {
    let Some(gpu) = common::gpu("gpu_runs_approximations_like_the_reference") else {
        return;
    };
    check_backend("gpu", &gpu, 1e-4);
}

// Background.

#[test]
fn background_stays_zero() {
    let mut rng = Rng::new(29);
    let cpu = FastCpu::new().unwrap();
    let backends: [(&str, &dyn Backend); 2] = [("reference", &Reference), ("cpu", &cpu)];
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 40.0 },
    ] {
        let scene = random_scene(&mut rng, 14, 12, 16, 32, Convention::Paper, camera);
        let up = upstream(&scene, 30);
        let background: Vec<usize> = (0..14 * 12)
            .filter(|&p| scene.normals.is_background(p))
            .collect();
        assert!(background.len() > 10);
        for (name, b) in backends {
            for m in [
                "env2",
                "env4+keep4",
                "keep8",
                "env64",
                "table16",
                "table24+env2+keep4",
            ] {
                let m = method(m);
                if m.validate(&scene).is_err() {
                    continue;
                }
                let (image, grads) = run(b, &scene, &up, &m);
                for &p in &background {
                    assert_eq!(image.pixels[p], [0.0; 3], "{name} {m} image pixel {p}");
                    assert_eq!(grads.d_normals[p], [0.0; 3], "{name} {m} dn pixel {p}");
                }
                assert!(image.max_value() > 0.0, "{name} {m}: all dark");
            }
        }
    }
}

// Culling by bound.

#[test]
fn culling_stays_within_its_bound_and_skips_work() {
    let cpu = FastCpu::new().unwrap();
    // a sharp lobe (chrome-like, no diffuse) and a glossy one, under suns and a smooth sky
    let sharp = Material::constant("sharp", [(0.0, 0.0), (3.0, 400.0), (0.0, 0.0)]).unwrap();
    let cases = [
        (
            "sharp suns",
            sphere_scene(
                64,
                sun_env(32, 64, Convention::Equirect, 41, 3),
                sharp.clone(),
            ),
        ),
        (
            "sharp smooth",
            sphere_scene(64, smooth_env(32, 64, Convention::Equirect, 42), sharp),
        ),
        (
            "glossy suns",
            sphere_scene(64, sun_env(32, 64, Convention::Equirect, 43, 2), glossy()),
        ),
        (
            "glossy smooth paper",
            sphere_scene(48, smooth_env(16, 32, Convention::Paper, 44), glossy()),
        ),
    ];
    let mut culled_any = false;
    for (what, scene) in &cases {
        let exact = lod::render(&cpu, scene, &Method::EXACT).unwrap();
        for m in ["cull1e-2", "cull1e-3", "table48+keep4+cull1e-3"] {
            let m = method(m);
            let img = lod::render(&cpu, scene, &m).unwrap();
            let err = rel(&img.pixels, &exact.pixels);
            let base = lod::render(&cpu, scene, &Method { cull: None, ..m }).unwrap();
            let cull_err = rel(&img.pixels, &base.pixels);
            // the bound is against the image's largest value, estimated from below
            assert!(
                cull_err <= m.cull_budget() * (1.0 + 1e-4) + 1e-6,
                "{what} {m}: culling changed the image by {cull_err:e} of its largest value"
            );
            culled_any |= cull_err > 0.0;
            eprintln!("{what} {m}: error {err:.2e}, culling's share {cull_err:.2e}");
            // the same bits twice, and the backward runs (a culled light has dL = 0)
            assert_eq!(img, lod::render(&cpu, scene, &m).unwrap(), "{what} {m}");
            let up = upstream(scene, 7);
            let g = lod::backward(&cpu, scene, &up, &m).unwrap();
            assert!(g.d_env.iter().flatten().all(|v| v.is_finite()));
        }
    }
    assert!(culled_any, "no case culled anything");
    // names, and cameras
    assert_eq!(method("cull2.5e-4").to_string(), "cull2.5e-4");
    assert_eq!(method("table64+cull1e-3").cull, Some(1_000_000));
    for bad in ["cull0", "cull1", "cull-1e-3", "cullx", "cull1e-3+cull1e-4"] {
        assert!(bad.parse::<Method>().is_err(), "{bad}");
    }
    let persp = Scene {
        camera: Camera::Perspective { fov_y_deg: 40.0 },
        ..cases[0].1.clone()
    };
    let e = lod::render(&cpu, &persp, &method("cull1e-3")).unwrap_err();
    assert!(e.to_string().contains("orthographic"), "{e}");
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
