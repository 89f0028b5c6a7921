//! Accuracy: finer tables and blocks are more accurate, the pixels a table cannot hold are
//! evaluated per pixel, and degenerate tables stay within bounds.

use super::{errors, glossy, method, ortho, rel, run, smooth_env, sphere_scene, sun_env, upstream};
use crate::common::{Rng, random_material};
use matedit::cpu::FastCpu;
use matedit::lod::{self, Method};
use matedit::reference::Reference;
use matedit::{Backend, Camera, Convention, EnvMap, NormalMap, Scene};

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

// Pixels a table cannot hold.

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
