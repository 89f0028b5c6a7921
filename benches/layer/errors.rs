//! Errors against the f64 reference, whose results are computed once per scene and
//! material.

use matedit::reference::GradientsF64;
use matedit::{Gradients, Image};
use serde_json::{Value, json};

use crate::common::{flat3, rel_err};

/// The reference's results for one scene and material.
pub struct Truth {
    pub image: Vec<[f64; 3]>,
    pub grads: GradientsF64,
    pub fwd_s: f64,
    pub bwd_s: f64,
}

/// Errors of an image and (optionally) gradients, each as f64 slices.
pub struct Got<'a> {
    pub image: &'a [f64],
    pub grads: Option<(&'a [f64], &'a [f64], &'a [f64])>,
}

/// Per output, max abs error / max abs value of the reference's output.
pub fn errors(t: &Truth, got: Got) -> Value {
    let mut e = serde_json::Map::new();
    if got.image.len() == t.image.len() * 3 {
        e.insert(
            "image".into(),
            json!(rel_err(got.image.iter().copied(), flat3(&t.image))),
        );
    } else {
        e.insert("image_shape_mismatch".into(), json!(got.image.len()));
    }
    if let Some((d_env, d_n, d_ctrl)) = got.grads {
        let g = &t.grads;
        let pairs: [(&str, &[f64], Vec<f64>); 3] = [
            ("d_env", d_env, flat3(&g.d_env).collect()),
            ("d_normals", d_n, flat3(&g.d_normals).collect()),
            ("d_ctrl", d_ctrl, g.d_ctrl.to_vec()),
        ];
        for (name, got, want) in pairs {
            if got.len() == want.len() {
                e.insert(
                    name.into(),
                    json!(rel_err(got.iter().copied(), want.into_iter())),
                );
            } else {
                e.insert(format!("{name}_shape_mismatch"), json!(got.len()));
            }
        }
    }
    Value::Object(e)
}

/// RGB values as flat f64 values.
pub fn f64s(v: &[[f32; 3]]) -> Vec<f64> {
    flat3(v).collect()
}

/// [`errors`] of an image and (optionally) gradients as a `Renderer` returns them.
pub fn errors_f32(t: &Truth, image: &Image, grads: Option<&Gradients>) -> Value {
    let img = f64s(&image.pixels);
    match grads {
        None => errors(
            t,
            Got {
                image: &img,
                grads: None,
            },
        ),
        Some(g) => {
            let (e, n) = (f64s(&g.d_env), f64s(&g.d_normals));
            let c: Vec<f64> = g.d_ctrl.iter().map(|&v| v as f64).collect();
            errors(
                t,
                Got {
                    image: &img,
                    grads: Some((&e, &n, &c)),
                },
            )
        }
    }
}
