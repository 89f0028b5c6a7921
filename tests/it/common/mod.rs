//! Shared test fixtures: a seeded generator, small random scenes, the GPU fixture and
//! `assert_close`.
#![allow(dead_code, reason = "each test file uses a part")]

use matedit::splitmix::SplitMix;
use matedit::{Camera, Convention, EnvMap, Material, NormalMap, Scene, material::idx};

/// A seeded generator for test inputs (the library's splitmix64).
pub struct Rng(SplitMix);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(SplitMix(seed))
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0.next_u64()
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.0.uniform()
    }
    /// A unit vector with z >= zmin.
    pub fn unit_facing(&mut self, zmin: f64) -> [f64; 3] {
        loop {
            let v = [
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
                self.uniform(-1.0, 1.0),
            ];
            let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if l > 0.1 && l <= 1.0 && v[2] / l >= zmin {
                return [v[0] / l, v[1] / l, v[2] / l];
            }
        }
    }
}

/// A random material: scales in [m0_lo, m0_hi], exponents in [m1_lo, m1_hi].
pub fn random_material(rng: &mut Rng, m0: (f64, f64), m1: (f64, f64)) -> Material {
    let mut ctrl = [0.0; 108];
    for k in 0..3 {
        for s in 0..3 {
            for j in 0..6 {
                ctrl[idx(k, s, 0, j)] = rng.uniform(m0.0, m0.1);
                ctrl[idx(k, s, 1, j)] = rng.uniform(m1.0, m1.1);
            }
        }
    }
    Material::new("random", &ctrl).expect("valid random material")
}

/// A random scene: `w` x `h` normals facing the camera (a few background pixels),
/// an `hl` x `wl` log-normal-ish env map, a random material.
#[allow(clippy::too_many_arguments, reason = "test scene knobs")]
pub fn random_scene(
    rng: &mut Rng,
    w: usize,
    h: usize,
    hl: usize,
    wl: usize,
    convention: Convention,
    camera: Camera,
) -> Scene {
    let mut normals = Vec::with_capacity(w * h);
    for i in 0..w * h {
        if i % 7 == 3 {
            normals.push([0.0; 3]);
        } else {
            let n = rng.unit_facing(0.2);
            normals.push(n.map(|v| v as f32));
        }
    }
    let texels = (0..hl * wl)
        .map(|_| {
            [
                rng.uniform(-1.0, 1.5).exp() as f32,
                rng.uniform(-1.0, 1.5).exp() as f32,
                rng.uniform(-1.0, 1.5).exp() as f32,
            ]
        })
        .collect();
    Scene {
        normals: NormalMap::new(w, h, normals).unwrap(),
        env: EnvMap::new(hl, wl, convention, texels).unwrap(),
        material: random_material(rng, (0.05, 2.0), (1.0, 60.0)),
        camera,
    }
}

/// Asserts |a - b| <= abs + rel * |b| elementwise; reports the worst element.
pub fn assert_close(what: &str, actual: &[f64], expected: &[f64], abs: f64, rel: f64) {
    assert_eq!(actual.len(), expected.len(), "{what}: lengths differ");
    let mut worst: Option<(usize, f64)> = None;
    for (i, (&a, &b)) in actual.iter().zip(expected).enumerate() {
        assert!(a.is_finite(), "{what}[{i}] = {a} is not finite");
        let excess = (a - b).abs() - (abs + rel * b.abs());
        if excess > 0.0 && worst.is_none_or(|(_, e)| excess > e) {
            worst = Some((i, excess));
        }
    }
    if let Some((i, _)) = worst {
        panic!(
            "{what}: element {i}: actual {} vs expected {} (|diff| {:e} > abs {abs:e} + rel {rel:e} * |expected|)",
            actual[i],
            expected[i],
            (actual[i] - expected[i]).abs()
        );
    }
}

/// The GPU renderer, or None (printing SKIPPED) when there is no adapter, unless
/// MATEDIT_REQUIRE_GPU=1, where a missing adapter fails the test.
pub fn gpu(test: &str) -> Option<matedit::gpu::GpuRenderer> {
    match matedit::gpu::GpuRenderer::new() {
        Ok(g) => Some(g),
        Err(e) => {
            if std::env::var("MATEDIT_REQUIRE_GPU").as_deref() == Ok("1") {
                panic!("{test}: MATEDIT_REQUIRE_GPU=1 but no GPU: {e}");
            }
            eprintln!("SKIPPED {test}: {e}");
            None
        }
    }
}

/// Every GPU plan this machine runs, named: the adapter's own and, on a software adapter
/// (lavapipe), also a large GPU's (slices, batches in one dispatch, workgroup tiles), which
/// a hardware adapter plans already. Empty as [`gpu`] is.
pub fn gpus(test: &str) -> Vec<(&'static str, matedit::gpu::GpuRenderer)> {
    let Some(g) = gpu(test) else {
        return Vec::new();
    };
    // a hardware adapter, or MATEDIT_GPU_PLAN=large, plans as a large GPU already
    let software = g.planner().software;
    let mut out = vec![("gpu", g)];
    if software {
        let g = gpu(test)
            .expect("a second renderer on the adapter")
            .as_large_gpu()
            .expect("the large GPU's plan");
        out.push(("gpu, a large GPU's plan", g));
    }
    out
}

/// Flattens RGB triples.
pub fn flat32(v: &[[f32; 3]]) -> Vec<f64> {
    v.iter().flatten().map(|&x| x as f64).collect()
}

/// Flattens RGB triples.
pub fn flat64(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

/// The largest |v|.
pub fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0f64, |a, b| a.max(b.abs()))
}

/// A seeded upstream gradient in [-1, 1] for every scene of `batch`.
pub fn upstream_for(batch: &matedit::Batch, seed: u64) -> Vec<matedit::Image> {
    let mut rng = Rng::new(seed);
    let (w, h) = batch.image_size();
    batch
        .scenes()
        .iter()
        .map(|_| matedit::Image {
            width: w,
            height: h,
            pixels: (0..w * h)
                .map(|_| [0; 3].map(|_: i32| rng.uniform(-1.0, 1.0) as f32))
                .collect(),
        })
        .collect()
}

/// The seeded scenes every backend is compared with the reference on.
pub mod scenes {
    use super::{Rng, random_scene};
    use matedit::{Batch, Camera, Convention};

    /// 12 x 10 normals against a 64 x 128 equirect map.
    pub fn equirect_64x128() -> Batch {
        let mut rng = Rng::new(11);
        let cam = Camera::Orthographic;
        Batch::single(random_scene(
            &mut rng,
            12,
            10,
            64,
            128,
            Convention::Equirect,
            cam,
        ))
        .unwrap()
    }

    /// A non-square 13 x 7 image, `paper` convention.
    pub fn non_square_paper() -> Batch {
        let mut rng = Rng::new(12);
        let cam = Camera::Orthographic;
        Batch::single(random_scene(
            &mut rng,
            13,
            7,
            16,
            32,
            Convention::Paper,
            cam,
        ))
        .unwrap()
    }

    /// Three scenes in one batch.
    pub fn batch_of_3() -> Batch {
        let mut rng = Rng::new(13);
        let cam = Camera::Orthographic;
        let scenes = (0..3)
            .map(|_| random_scene(&mut rng, 9, 11, 16, 32, Convention::Equirect, cam))
            .collect();
        Batch::new(scenes).unwrap()
    }

    /// A 60-degree perspective camera, both conventions.
    pub fn perspective() -> Vec<(Convention, Batch)> {
        [(14, Convention::Equirect), (15, Convention::Paper)]
            .into_iter()
            .map(|(seed, conv)| {
                let mut rng = Rng::new(seed);
                let cam = Camera::Perspective { fov_y_deg: 60.0 };
                let s = random_scene(&mut rng, 10, 8, 16, 32, conv, cam);
                (conv, Batch::single(s).unwrap())
            })
            .collect()
    }
}

/// The f64 reference's image and gradients of one scene for upstream `up`.
pub struct Truth {
    pub image: Vec<f64>,
    pub grads: matedit::reference::GradientsF64,
}

impl Truth {
    pub fn new(prep: &matedit::prepare::Prepared, up: &[[f32; 3]]) -> Self {
        let gu: Vec<[f64; 3]> = up.iter().map(|p| p.map(f64::from)).collect();
        Truth {
            image: flat64(&matedit::reference::forward(prep)),
            grads: matedit::reference::backward(prep, &gu),
        }
    }

    /// Asserts that `image` is within `image_tol` and each gradient within `grad_tol` of
    /// that output's largest value, printing each worst error (seen with --nocapture).
    pub fn check(
        &self,
        what: &str,
        image: &[[f32; 3]],
        grads: &matedit::Gradients,
        image_tol: f64,
        grad_tol: f64,
    ) {
        let r = &self.grads;
        for (name, got, want, tol) in [
            ("image", flat32(image), self.image.clone(), image_tol),
            ("dL", flat32(&grads.d_env), flat64(&r.d_env), grad_tol),
            (
                "dn",
                flat32(&grads.d_normals),
                flat64(&r.d_normals),
                grad_tol,
            ),
            (
                "dctrl",
                grads.d_ctrl.iter().map(|&v| v as f64).collect(),
                r.d_ctrl.to_vec(),
                grad_tol,
            ),
        ] {
            let scale = max_abs(&want);
            assert!(scale > 0.0, "{what}: the reference's {name} is all zero");
            let err = got
                .iter()
                .zip(&want)
                .fold(0.0f64, |a, (g, w)| a.max((g - w).abs()));
            eprintln!(
                "{what} {name}: max error {:.2e} of max {scale:.3e}",
                err / scale
            );
            assert_close(&format!("{what} {name}"), &got, &want, tol * scale, 0.0);
        }
    }
}

/// An H x W x 3 float `.npy` file's bytes as (H, W, pixels).
pub fn npy_rgb(bytes: &[u8]) -> (usize, usize, Vec<[f32; 3]>) {
    let a = matedit::io::npy::parse(bytes).expect("an .npy file");
    let px = a
        .data
        .chunks_exact(3)
        .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
        .collect();
    (a.shape[0], a.shape[1], px)
}

/// `matedit synth SPEC -o OUT --device cpu EXTRA...`.
pub fn synth_cmd(
    spec: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
) -> assert_cmd::Command {
    let mut cmd = assert_cmd::cargo::cargo_bin_cmd!("matedit");
    cmd.arg("synth")
        .arg(spec)
        .arg("-o")
        .arg(out)
        .args(["--device", "cpu"]);
    cmd.args(extra);
    cmd
}

/// A weights file's tensors as [`rewritten_weights`] hands them out: name, dtype, shape,
/// bytes.
pub type Tensors = Vec<(String, safetensors::Dtype, Vec<usize>, Vec<u8>)>;

/// The safetensors file `bytes` written to `out` with `edit` applied to its tensors and
/// its metadata; returns `out`.
pub fn rewritten_weights(
    bytes: &[u8],
    out: &std::path::Path,
    edit: impl FnOnce(&mut Tensors, &mut std::collections::HashMap<String, String>),
) -> std::path::PathBuf {
    let (_, meta) = safetensors::SafeTensors::read_metadata(bytes).unwrap();
    let st = safetensors::SafeTensors::deserialize(bytes).unwrap();
    let mut tensors: Tensors = st
        .tensors()
        .into_iter()
        .map(|(n, v)| (n, v.dtype(), v.shape().to_vec(), v.data().to_vec()))
        .collect();
    let mut meta = meta.metadata().clone().unwrap_or_default();
    edit(&mut tensors, &mut meta);
    let views: Vec<_> = tensors
        .iter()
        .map(|(n, d, s, b)| {
            let view = safetensors::tensor::TensorView::new(*d, s.clone(), b).unwrap();
            (n.clone(), view)
        })
        .collect();
    safetensors::serialize_to_file(views, Some(meta), out).unwrap();
    out.to_path_buf()
}
