//! Errors against the exact layer on the same path, and the exact path's own error
//! against the f64 reference.

use matedit::cpu::FastCpu;
use matedit::lod::{self, Method};
use matedit::prepare::Prepared;
use matedit::{Camera, Gradients, Image, Material, NormalMap, Scene};
use serde_json::{Value, json};

use crate::common::{flat3, rel_errors, upstream_for};
use crate::inputs::Env;
use crate::report::sci;

/// The outputs errors are measured on; `fb` records have all four.
pub const OUTPUTS: [&str; 4] = ["image", "d_env", "d_normals", "d_ctrl"];

/// Per output: {"max": max |x - x_exact| / max |x_exact|, "mean": mean |x - x_exact| /
/// max |x_exact|}, for the image and, with `grads`, (d_env, d_normals, d_ctrl), every
/// output as flat f64 values.
pub fn errors(exact: &[Vec<f64>; 4], image: &[f64], grads: Option<[&[f64]; 3]>) -> Value {
    let mut e = serde_json::Map::new();
    let got = std::iter::once(image).chain(grads.into_iter().flatten());
    for ((name, want), got) in OUTPUTS.iter().zip(exact).zip(got) {
        if got.len() == want.len() {
            let (max, mean) = rel_errors(got.iter().copied(), want.iter().copied());
            e.insert(name.to_string(), json!({"max": max, "mean": mean}));
        } else {
            e.insert(
                format!("{name}_shape_mismatch"),
                json!([got.len(), want.len()]),
            );
        }
    }
    Value::Object(e)
}

/// The outputs of a render and backward as flat f64 values, as [`errors`] takes them.
pub fn flat(image: &Image, grads: &Gradients) -> [Vec<f64>; 4] {
    [
        flat3(&image.pixels).collect(),
        flat3(&grads.d_env).collect(),
        flat3(&grads.d_normals).collect(),
        grads.d_ctrl.iter().map(|&v| f64::from(v)).collect(),
    ]
}

/// [`errors`] of an image and (optionally) gradients as the layer returns them.
pub fn errors_of(exact: &[Vec<f64>; 4], image: &Image, grads: Option<&Gradients>) -> Value {
    let img: Vec<f64> = flat3(&image.pixels).collect();
    match grads.map(|g| flat(image, g)) {
        None => errors(exact, &img, None),
        Some([_, e, n, c]) => errors(exact, &img, Some([&e, &n, &c])),
    }
}

/// The largest of a record's max errors (infinite where an output could not be compared).
pub fn worst(errors: &Value) -> f64 {
    match errors.as_object() {
        Some(o) if !o.keys().any(|k| k.ends_with("_shape_mismatch")) => o
            .values()
            .filter_map(|v| v["max"].as_f64())
            .fold(0.0, f64::max),
        _ => f64::INFINITY,
    }
}

/// The exact fast path against the f64 reference on the 128 sphere, per material, with
/// the first env map: max errors per output.
pub fn reference_check(cpu: &FastCpu, env: &Env, materials: &[Material]) -> Vec<Value> {
    let normals = NormalMap::sphere(128);
    let upstream = upstream_for(128, 128);
    let g64: Vec<[f64; 3]> = upstream.pixels.iter().map(|p| p.map(f64::from)).collect();
    let mut out = Vec::new();
    for material in materials {
        let scene = Scene {
            normals: normals.clone(),
            env: env.env.clone(),
            material: material.clone(),
            camera: Camera::Orthographic,
        };
        let prep = Prepared::new(&scene);
        let image = matedit::reference::forward(&prep);
        let g = matedit::reference::backward(&prep, &g64);
        let truth = [
            flat3(&image).collect(),
            flat3(&g.d_env).collect(),
            flat3(&g.d_normals).collect(),
            g.d_ctrl.to_vec(),
        ];
        let got = lod::render(cpu, &scene, &Method::EXACT).and_then(|img| {
            let g = lod::backward(cpu, &scene, &upstream, &Method::EXACT)?;
            Ok(errors_of(&truth, &img, Some(&g)))
        });
        let errs = got.unwrap_or_else(|e| json!({"failed": e.to_string()}));
        println!(
            "exact fast path vs f64 reference, sphere128 {} {}: max error image {} d_env {} \
             d_normals {} d_ctrl {}",
            env.name,
            material.name,
            sci(errs["image"]["max"].as_f64()),
            sci(errs["d_env"]["max"].as_f64()),
            sci(errs["d_normals"]["max"].as_f64()),
            sci(errs["d_ctrl"]["max"].as_f64()),
        );
        out.push(json!({
            "scene": "sphere128", "env": env.name, "material": material.name, "errors": errs,
        }));
    }
    out
}
