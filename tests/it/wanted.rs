//! Backward calls for some of the gradients (`Wanted`): what is wanted equals the full
//! backward's (bit for bit on the GPU, whose passes are separate; to f32 rounding on the
//! fast CPU path, which visits fewer texels and lobes), what is not is zeros, on every
//! backend, for orthographic and perspective cameras, with black texels and a lobe
//! without a scale in the scene (what the fast CPU path leaves out without dLoss/dL and
//! dLoss/dctrl).

use crate::common;

use common::{Rng, assert_close, flat32, gpu, random_scene, upstream_for};
use matedit::material::idx;
use matedit::{
    Accuracy, Backend, Batch, Camera, Convention, EnvMap, Gradients, Material, Renderer, Wanted,
    cpu::FastCpu, reference::Reference,
};

/// A scene with every third texel black and lobe (channel 1, lobe 2) without a scale.
fn scene(camera: Camera, seed: u64) -> Batch {
    let mut rng = Rng::new(seed);
    let mut s = random_scene(&mut rng, 11, 9, 16, 32, Convention::Equirect, camera);
    let mut texels = s.env.texels.clone();
    for (i, t) in texels.iter_mut().enumerate() {
        if i % 3 == 0 {
            *t = [0.0; 3];
        }
    }
    s.env = EnvMap::new(16, 32, Convention::Equirect, texels).unwrap();
    let mut ctrl = s.material.ctrl;
    for j in 0..6 {
        ctrl[idx(1, 2, 0, j)] = 0.0;
    }
    s.material = Material::new("test", &ctrl).unwrap();
    Batch::single(s).unwrap()
}

fn subsets() -> Vec<Wanted> {
    (0..8)
        .map(|m| Wanted {
            env: m & 1 != 0,
            normals: m & 2 != 0,
            ctrl: m & 4 != 0,
        })
        .collect()
}

/// Checks `backend`'s backward for every subset against its full backward.
fn check(name: &str, backend: Box<dyn Backend>, bitwise: bool) {
    let r = Renderer::with_backend(backend);
    for (camera, seed) in [
        (Camera::Orthographic, 31),
        (Camera::Perspective { fov_y_deg: 60.0 }, 32),
    ] {
        let batch = scene(camera, seed);
        let up = upstream_for(&batch, seed);
        let full = r.backward(&batch, &up).unwrap().remove(0);
        for wanted in subsets() {
            let what = format!("{name} {camera:?} {wanted:?}");
            let (mut g, _) = r
                .backward_with(&batch, &up, &Accuracy::Exact, wanted)
                .unwrap();
            let g: Gradients = g.remove(0);
            let parts: [(bool, Vec<f64>, Vec<f64>, &str); 3] = [
                (wanted.env, flat32(&g.d_env), flat32(&full.d_env), "d_env"),
                (
                    wanted.normals,
                    flat32(&g.d_normals),
                    flat32(&full.d_normals),
                    "d_normals",
                ),
                (
                    wanted.ctrl,
                    g.d_ctrl.iter().map(|&v| v as f64).collect(),
                    full.d_ctrl.iter().map(|&v| v as f64).collect(),
                    "d_ctrl",
                ),
            ];
            for (want, got, all, part) in parts {
                let what = format!("{what} {part}");
                if !want {
                    assert!(got.iter().all(|&v| v == 0.0), "{what}: not zeros");
                } else if bitwise {
                    assert!(
                        got.iter()
                            .zip(&all)
                            .all(|(a, b)| a.to_bits() == b.to_bits()),
                        "{what}: differs from the full backward"
                    );
                } else {
                    let scale = all.iter().fold(0.0f64, |m, v| m.max(v.abs()));
                    assert!(scale > 0.0, "{what}: the full gradient is zero");
                    assert_close(&what, &got, &all, 1e-5 * scale, 1e-5);
                }
            }
        }
    }
}

#[test]
fn some_gradients_on_the_fast_cpu_path() {
    check("cpu", Box::new(FastCpu::best()), false);
}

#[test]
fn some_gradients_on_the_reference() {
    check("reference", Box::new(Reference), true);
}

#[test]
fn some_gradients_on_the_gpu() {
    let Some(g) = gpu("some_gradients_on_the_gpu") else {
        return;
    };
    check("gpu", Box::new(g), true);
}
