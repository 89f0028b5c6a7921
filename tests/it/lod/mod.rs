//! Levels of detail (`matedit::lod`), a module per idea: method names (`names`), the exact
//! method against the backends (`exact`), the adjoints of every approximation (`adjoints`),
//! accuracy as the table and the blocks are refined and the pixels a table leaves to
//! per-pixel evaluation (`accuracy`), the choice of a method for a tolerance (`choice`),
//! determinism across runs and thread counts (`determinism`), the fast path and the GPU
//! against the reference (`backends`), background pixels (`background`) and culling by
//! bound (`culling`). Here: the helpers they share.

mod accuracy;
mod adjoints;
mod backends;
mod background;
mod choice;
mod culling;
mod determinism;
mod exact;
mod names;

use crate::common::{Rng, random_scene, upstream_for};
use matedit::lod::{self, Method};
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Gradients, Image, Material, NormalMap, Scene,
};

/// The chooser on scenes of any size (by default small ones are rendered exactly).
pub(super) const ALWAYS: lod::Chooser = lod::Chooser {
    min_pairs: 0.0,
    safety: lod::SAFETY,
    safety_sums: lod::SAFETY_SUMS,
};

pub(super) fn method(s: &str) -> Method {
    s.parse()
        .unwrap_or_else(|e| panic!("method '{s}' should parse: {e}"))
}

/// max |a - b| over max |b|.
pub(super) fn rel(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
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
pub(super) fn rel_ctrl(a: &[f32], b: &[f32]) -> f64 {
    let t = |v: &[f32]| v.iter().map(|&x| [x, 0.0, 0.0]).collect::<Vec<_>>();
    rel(&t(a), &t(b))
}

/// The four relative errors (image, dL, dn, dctrl) of `got` against `want`.
pub(super) fn errors(got: &(Image, Gradients), want: &(Image, Gradients)) -> [f64; 4] {
    [
        rel(&got.0.pixels, &want.0.pixels),
        rel(&got.1.d_env, &want.1.d_env),
        rel(&got.1.d_normals, &want.1.d_normals),
        rel_ctrl(&got.1.d_ctrl, &want.1.d_ctrl),
    ]
}

/// The image and the gradients of `scene` under `m`.
pub(super) fn run(
    backend: &dyn Backend,
    scene: &Scene,
    up: &Image,
    m: &Method,
) -> (Image, Gradients) {
    let image = lod::render(backend, scene, m).unwrap_or_else(|e| panic!("render {m}: {e}"));
    let grads =
        lod::backward(backend, scene, up, m).unwrap_or_else(|e| panic!("backward {m}: {e}"));
    (image, grads)
}

/// A seeded random orthographic scene (common::random_scene): `w` x `h` pixels, an
/// equirect `hl` x `wl` map.
pub(super) fn random_ortho(seed: u64, (w, h): (usize, usize), (hl, wl): (usize, usize)) -> Scene {
    let mut rng = Rng::new(seed);
    let (conv, cam) = (Convention::Equirect, Camera::Orthographic);
    random_scene(&mut rng, w, h, hl, wl, conv, cam)
}

/// A seeded upstream gradient for `scene`.
pub(super) fn upstream(scene: &Scene, seed: u64) -> Image {
    upstream_for(&Batch::single(scene.clone()).unwrap(), seed).remove(0)
}

pub(super) fn sphere_scene(n: usize, env: EnvMap, material: Material) -> Scene {
    Scene {
        normals: NormalMap::sphere(n),
        env,
        material,
        camera: Camera::Orthographic,
    }
}

/// A smooth map: a dim constant plus three broad lobes of random colour.
pub(super) fn smooth_env(hl: usize, wl: usize, convention: Convention, seed: u64) -> EnvMap {
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
pub(super) fn sun_env(
    hl: usize,
    wl: usize,
    convention: Convention,
    seed: u64,
    suns: usize,
) -> EnvMap {
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
pub(super) fn glossy() -> Material {
    Material::constant("glossy", [(0.3, 0.0), (1.0, 30.0), (0.0, 0.0)]).unwrap()
}

/// `scene` with every foreground normal scaled to length `len`.
pub(super) fn rescaled(scene: &Scene, len: f32) -> Scene {
    let mut s = scene.clone();
    for n in &mut s.normals.normals {
        let l = n.iter().map(|v| v * v).sum::<f32>().sqrt();
        if l > 0.0 {
            *n = n.map(|v| v / l * len);
        }
    }
    s
}

pub(super) fn ortho(normals: NormalMap, env: EnvMap, material: Material) -> Scene {
    Scene {
        normals,
        env,
        material,
        camera: Camera::Orthographic,
    }
}
