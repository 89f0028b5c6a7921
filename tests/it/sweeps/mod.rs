//! Stability sweeps, shared by `tests/it/stability.rs` (which asserts on them) and
//! `xtask/src/bin/stability.rs` (which writes docs/stability.md from them): scenes at and past
//! the edges of valid input, run forward and backward on every backend and level of
//! detail, each output checked for NaN and inf and compared with the f64 reference.

#![allow(dead_code, reason = "each user takes part of the module")]

use matedit::lod::{self, Method};
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Gradients, Image, Material, NormalMap, Scene,
    Wanted,
};

/// One scene of a sweep. `valid` says whether the scene is valid input (an invalid one
/// must be rejected with an error, never rendered).
pub struct Case {
    /// The sweep it belongs to.
    pub sweep: &'static str,
    /// What the case varies, for the report.
    pub label: String,
    /// Valid input, or input that must be rejected.
    pub valid: bool,
    /// Builds the scene (or the error that rejects it).
    pub scene: Result<Scene, String>,
}

fn lobe(m0: f64, m1: f64) -> Result<Material, String> {
    Material::constant("sweep", [(m0, m1), (0.0, 0.0), (0.0, 0.0)]).map_err(|e| e.to_string())
}

fn sky(h: usize, w: usize, convention: Convention) -> EnvMap {
    matedit::builtin_sky::procedural_env(h, w, convention)
}

fn scene(
    normals: NormalMap,
    env: EnvMap,
    material: Result<Material, String>,
    camera: Camera,
) -> Result<Scene, String> {
    let s = Scene {
        normals,
        env,
        material: material?,
        camera,
    };
    s.validate().map_err(|e| e.to_string())?;
    Ok(s)
}

/// A map with one bright texel (row, column) and every other texel black.
fn one_texel(h: usize, w: usize, r: usize, c: usize, value: f32, convention: Convention) -> EnvMap {
    let mut texels = vec![[0.0f32; 3]; h * w];
    texels[r * w + c] = [value; 3];
    EnvMap {
        height: h,
        width: w,
        convention,
        texels,
    }
}

/// Every sweep's cases.
pub fn cases() -> Vec<Case> {
    let mut out = Vec::new();
    let ortho = Camera::Orthographic;
    let sphere = || NormalMap::sphere(8);
    let env = || sky(8, 16, Convention::Equirect);
    // material: scales
    for m0 in [0.0f64, 1e-8, 1e-3, 1.0, 5.0, 20.0, 40.0, 40.5, -1.0, -40.0] {
        out.push(Case {
            sweep: "material: scale m0 (exponent 10)",
            label: format!("m0 = {m0:e}"),
            valid: m0.abs() <= matedit::material::MAX_ABS_SCALE,
            scene: scene(sphere(), env(), lobe(m0, 10.0), ortho),
        });
    }
    // material: exponents
    for m1 in [
        0.0f64, 1e-6, 0.01, 0.5, 0.999, 1.0, 2.0, 100.0, 1e3, 1e4, 1.0001e4, -0.5,
    ] {
        out.push(Case {
            sweep: "material: exponent m1 (scale 1)",
            label: format!("m1 = {m1:e}"),
            valid: (0.0..=matedit::material::MAX_EXPONENT).contains(&m1),
            scene: scene(sphere(), env(), lobe(1.0, m1), ortho),
        });
    }
    // the sharp lobe of the issue, on a sphere large enough to resolve it
    for (m0, m1) in [(5.0, 1e3), (5.0, 1e4), (40.0, 1e4)] {
        out.push(Case {
            sweep: "material: sharp lobes (16 x 16 sphere, 16 x 32 sky)",
            label: format!("m0 = {m0}, m1 = {m1:e}"),
            valid: true,
            scene: scene(
                NormalMap::sphere(16),
                sky(16, 32, Convention::Equirect),
                lobe(m0, m1),
                ortho,
            ),
        });
    }
    let glossy = || {
        Material::constant("glossy", [(0.3, 0.0), (2.0, 50.0), (0.0, 0.0)])
            .map_err(|e| e.to_string())
    };
    // geometry: grazing views, x -> 0
    for deg in [0.0f64, 45.0, 80.0, 89.0, 89.9, 90.0, 100.0] {
        let a = deg.to_radians();
        let n = [a.sin() as f32, 0.0, a.cos() as f32];
        out.push(Case {
            sweep: "geometry: normal tilted from the view (degrees)",
            label: format!("{deg} deg"),
            valid: true,
            scene: scene(
                NormalMap::new(2, 2, vec![n; 4]).expect("valid"),
                env(),
                glossy(),
                ortho,
            ),
        });
    }
    // geometry: |n| far from 1
    for len in [0.0f32, 1e-7, 1e-3, 0.01, 1.0, 1.00002, 100.0, 1e4] {
        let normals = NormalMap {
            normals: sphere()
                .normals
                .iter()
                .map(|n| n.map(|v| v * len))
                .collect(),
            ..sphere()
        };
        out.push(Case {
            sweep: "geometry: normal length |n|",
            label: format!("|n| = {len:e}"),
            valid: f64::from(len) <= matedit::scene::MAX_NORMAL_LENGTH,
            scene: scene(normals, env(), glossy(), ortho),
        });
    }
    // geometry: perspective cameras
    for fov in [0.5, 40.0, 120.0, 170.0, 179.9, 180.0] {
        out.push(Case {
            sweep: "geometry: perspective field of view (degrees)",
            label: format!("{fov} deg"),
            valid: fov < 180.0,
            scene: scene(
                sphere(),
                env(),
                glossy(),
                Camera::Perspective { fov_y_deg: fov },
            ),
        });
    }
    // geometry: the light exactly opposite the view (w_i = -w_p: no half vector). Texel
    // (0, 1) of a 1 x 2 equirect map is at theta = 90, phi = 270 degrees: -z, straight
    // away from the orthographic camera. Normals facing away from the camera see it.
    for (what, n) in [
        ("normal (0.3, 0, -1), back-facing", [0.3f32, 0.0, -1.0]),
        ("normal (0, 0, -1), facing the light", [0.0, 0.0, -1.0]),
        ("normal (1, 0, 0), light on its horizon", [1.0, 0.0, 0.0]),
    ] {
        let len = n.iter().map(|v| v * v).sum::<f32>().sqrt();
        out.push(Case {
            sweep: "geometry: light exactly opposite the view (1 x 2 map, texel at -z)",
            label: what.to_string(),
            valid: true,
            scene: scene(
                NormalMap::new(1, 1, vec![n.map(|v| v / len)]).expect("valid"),
                one_texel(1, 2, 0, 1, 1.0, Convention::Equirect),
                glossy(),
                ortho,
            ),
        });
    }
    // light: radiance scale
    for v in [0.0f32, 1e-30, 1e-20, 1e-10, 1.0, 1e3, 6e4, 1e12, 1e13] {
        out.push(Case {
            sweep: "light: uniform radiance (4 x 8 map)",
            label: format!("L = {v:e}"),
            valid: v <= matedit::envmap::MAX_RADIANCE,
            scene: (|| {
                let env = EnvMap::new(4, 8, Convention::Equirect, vec![[v; 3]; 32])
                    .map_err(|e| e.to_string())?;
                scene(sphere(), env, glossy(), ortho)
            })(),
        });
    }
    // light: one texel, a sun
    for v in [1.0f32, 6e4, 1e9] {
        out.push(Case {
            sweep: "light: a single bright texel (8 x 16 map, the rest black)",
            label: format!("L = {v:e}"),
            valid: true,
            scene: scene(
                sphere(),
                one_texel(8, 16, 2, 5, v, Convention::Equirect),
                glossy(),
                ortho,
            ),
        });
    }
    // light: map sizes, both conventions
    for convention in [Convention::Equirect, Convention::Paper] {
        for (h, w) in [(1, 2), (2, 4), (8, 16), (64, 128), (512, 1024)] {
            out.push(Case {
                sweep: "light: map size and convention (built-in sky)",
                label: format!("{h} x {w} {}", convention.name()),
                valid: true,
                scene: scene(NormalMap::sphere(4), sky(h, w, convention), glossy(), ortho),
            });
        }
    }
    out
}

/// What one backend did with one case.
#[derive(Clone, Debug)]
pub enum Outcome {
    /// Rejected with this error.
    Rejected(String),
    /// Ran: whether every output was finite, and the relative errors against the
    /// reference (image, dL, dn, dctrl; None for the reference itself).
    Ran {
        finite: bool,
        errors: Option<[f64; 4]>,
    },
    /// Not applicable (e.g. a normal table under a perspective camera).
    NotApplicable,
}

/// A deterministic upstream gradient in [-1, 1].
pub fn upstream(width: usize, height: usize) -> Image {
    let mut img = Image::zeros(width, height);
    for (i, p) in img.pixels.iter_mut().enumerate() {
        for (k, v) in p.iter_mut().enumerate() {
            let x = ((i * 3 + k) as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) >> 40;
            *v = (x as f64 / (1u64 << 24) as f64 * 2.0 - 1.0) as f32;
        }
    }
    img
}

fn flat(v: &[[f32; 3]]) -> Vec<f64> {
    v.iter().flatten().map(|&x| f64::from(x)).collect()
}

/// max |a - b| / max |b| (|a - b| where b is all 0).
pub fn rel_err(a: &[f64], b: &[f64]) -> f64 {
    let scale = b.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let diff = a
        .iter()
        .zip(b)
        .fold(0.0f64, |m, (x, y)| m.max((x - y).abs()));
    if scale > 0.0 { diff / scale } else { diff }
}

/// Forward and backward of `scene` on `backend` under `method`.
pub fn run(
    backend: &dyn Backend,
    scene: &Scene,
    method: &Method,
) -> Result<(Image, Gradients), String> {
    let up = upstream(scene.normals.width, scene.normals.height);
    if *method == Method::EXACT {
        let batch = Batch::single(scene.clone()).map_err(|e| e.to_string())?;
        let img = backend
            .render((&batch).into())
            .map_err(|e| e.to_string())?
            .remove(0);
        let g = backend
            .backward((&batch).into(), &[up], Wanted::ALL)
            .map_err(|e| e.to_string())?
            .remove(0);
        Ok((img, g))
    } else {
        method.validate(scene).map_err(|e| e.to_string())?;
        let img = lod::render(backend, scene, method).map_err(|e| e.to_string())?;
        let g = lod::backward(backend, scene, &up, method).map_err(|e| e.to_string())?;
        Ok((img, g))
    }
}

/// Every output of a run, flattened: image, dL, dn, dctrl.
pub fn outputs(r: &(Image, Gradients)) -> [Vec<f64>; 4] {
    [
        flat(&r.0.pixels),
        flat(&r.1.d_env),
        flat(&r.1.d_normals),
        r.1.d_ctrl.iter().map(|&v| f64::from(v)).collect(),
    ]
}

/// The outcome of `backend` (under `method`) on `case`, given the reference's outputs.
pub fn outcome(
    backend: &dyn Backend,
    method: &Method,
    case: &Case,
    reference: Option<&[Vec<f64>; 4]>,
) -> Outcome {
    let scene = match &case.scene {
        Err(e) => return Outcome::Rejected(e.clone()),
        Ok(s) => s,
    };
    if *method != Method::EXACT && method.validate(scene).is_err() {
        return Outcome::NotApplicable;
    }
    match run(backend, scene, method) {
        Err(e) => Outcome::Rejected(e),
        Ok(r) => {
            let o = outputs(&r);
            let finite = o.iter().all(|v| v.iter().all(|x| x.is_finite()));
            let errors = reference.map(|re| std::array::from_fn(|i| rel_err(&o[i], &re[i])));
            Outcome::Ran { finite, errors }
        }
    }
}
