//! Shared test fixtures: a seeded generator, small random scenes, the GPU fixture and
//! `assert_close`.
#![allow(dead_code, reason = "each test file uses a part")]

use matedit::{Camera, Convention, EnvMap, Material, NormalMap, Scene, material::idx};

/// SplitMix64: a tiny seeded generator, enough for test inputs.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Self {
        Rng(seed)
    }
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * ((self.next_u64() >> 11) as f64 / (1u64 << 53) as f64)
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

/// Flattens RGB triples.
pub fn flat32(v: &[[f32; 3]]) -> Vec<f64> {
    v.iter().flatten().map(|&x| x as f64).collect()
}

/// Flattens RGB triples.
pub fn flat64(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}
