//! `matedit edit` from Python: the built-in nets' weights, and a photo's decomposition and
//! its object rendered in another material, on NumPy arrays.

use std::path::PathBuf;

use matedit::{Device, Image, Material};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{elements, images, invalid, py_err, stack};

/// The built-in nets' weights file (data/nets/weights.safetensors) as bytes: the nets that
/// `matedit edit` and `matedit.nets.load()` use.
#[pyfunction]
pub(crate) fn builtin_weights(py: Python<'_>) -> Bound<'_, pyo3::types::PyBytes> {
    pyo3::types::PyBytes::new(py, matedit::nets::BUILTIN_WEIGHTS)
}

/// `matedit edit` on arrays: the photo (H, W, 3) linear float32, the new material's control
/// points (108,), the object's mask (H, W) bool or None (the nets find it), or a box
/// (x0, y0, x1, y1) and points (x, y) on the object or (x, y, False) off it; mirror: the
/// nets also see the photo mirrored (`Nets::with_mirror`); normals (H, W, 3) and env
/// (h, w, 3): known normals and light in place of the nets' (`PhotoOptions`). Returns a
/// dict of NumPy arrays and numbers (see matedit.edit).
#[pyfunction]
#[pyo3(signature = (photo, material, mask = None, steps = None, weights = None, device = "auto", bounds = None, points = None, detail = 1.0, mirror = true, normals = None, env = None))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn edit_photo<'py>(
    py: Python<'py>,
    photo: PyReadonlyArrayDyn<'py, f32>,
    material: PyReadonlyArrayDyn<'py, f64>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    steps: Option<usize>,
    weights: Option<PathBuf>,
    device: &str,
    bounds: Option<(usize, usize, usize, usize)>,
    points: Option<Vec<(usize, usize, bool)>>,
    detail: f32,
    mirror: bool,
    normals: Option<PyReadonlyArrayDyn<'py, f32>>,
    env: Option<PyReadonlyArrayDyn<'py, f32>>,
) -> PyResult<Bound<'py, PyDict>> {
    use matedit::edit::photo::{self, PhotoOptions};
    let img = images("photo", &photo)?;
    if img.batched {
        return Err(invalid("photo: one image (H, W, 3), not a batch".into()));
    }
    let image = Image {
        width: img.width,
        height: img.height,
        pixels: img.rows.into_iter().next().unwrap_or_default(),
    };
    let ctrl = elements(&material);
    let target = Material::new("material", &ctrl).map_err(py_err)?;
    let mask: Option<Vec<bool>> = match &mask {
        None => None,
        Some(m) => {
            if m.shape() != [image.height, image.width] {
                return Err(invalid(format!(
                    "mask: shape {:?}, expected ({}, {})",
                    m.shape(),
                    image.height,
                    image.width
                )));
            }
            Some(elements(m).into_owned())
        }
    };
    let device: Device = device
        .parse()
        .map_err(|e: String| invalid(format!("device: {e}")))?;
    if !(0.0..=1.0).contains(&detail) {
        return Err(invalid(format!("detail: {detail} is outside [0, 1]")));
    }
    let one = |what: &str, a: &PyReadonlyArrayDyn<'py, f32>| -> PyResult<_> {
        let r = images(what, a)?;
        if r.batched {
            return Err(invalid(format!("{what}: one map (H, W, 3), not a batch")));
        }
        Ok((
            r.width,
            r.height,
            r.rows.into_iter().next().unwrap_or_default(),
        ))
    };
    let normals = match &normals {
        Some(a) => {
            let (w, h, n) = one("normals", a)?;
            if (w, h) != (image.width, image.height) {
                return Err(invalid(format!(
                    "normals: shape ({h}, {w}, 3), the photo ({}, {}, 3)",
                    image.height, image.width
                )));
            }
            Some(matedit::NormalMap::new(w, h, n).map_err(py_err)?)
        }
        None => None,
    };
    let env = match &env {
        Some(a) => {
            let (w, h, t) = one("env", a)?;
            Some(
                matedit::EnvMap::new(h, w, matedit::Convention::Equirect, t)
                    .map_err(|e| invalid(format!("env: {e}")))?,
            )
        }
        None => None,
    };
    let steps = steps.unwrap_or_else(|| photo::default_steps(normals.is_some(), env.is_some()));
    let options = PhotoOptions {
        steps,
        detail,
        normals,
        env,
        ..PhotoOptions::default()
    };
    let mut pointing = photo::Pointing {
        bounds: bounds.map(|(x0, y0, x1, y1)| matedit::segment::Rect { x0, y0, x1, y1 }),
        ..photo::Pointing::default()
    };
    for (x, y, on) in points.unwrap_or_default() {
        if on {
            pointing.object.push([x, y]);
        } else {
            pointing.background.push([x, y]);
        }
    }
    if !pointing.is_empty() && mask.is_some() {
        return Err(invalid("give mask, or box and points, not both".into()));
    }
    let (d, edit) = py
        .detach(|| -> matedit::Result<_> {
            let nets = match &weights {
                Some(w) => matedit::nets::Nets::load(w)?,
                None => matedit::nets::Nets::builtin()?,
            }
            .with_mirror(mirror);
            let renderer = matedit::Renderer::new(device)?;
            let object = if pointing.is_empty() {
                mask.as_deref().into()
            } else {
                photo::Object::Pointed(&pointing)
            };
            let d = photo::decompose(&renderer, &nets, &image, object, &options, &mut |_| {})?;
            let edit = d.edit(&renderer, &image, &target, None, matedit::Accuracy::Exact)?;
            Ok((d, edit))
        })
        .map_err(py_err)?;
    let out = PyDict::new(py);
    out.set_item(
        "edit",
        stack(py, false, edit.height, edit.width, vec![&edit.pixels])?,
    )?;
    out.set_item(
        "normals",
        stack(
            py,
            false,
            d.normals.height,
            d.normals.width,
            vec![&d.normals.normals],
        )?,
    )?;
    out.set_item("crop", (d.crop.x0, d.crop.y0, d.crop.size))?;
    let shape = IxDyn(&[d.height, d.width]);
    let as_err = |e: numpy::ndarray::ShapeError| PyRuntimeError::new_err(e.to_string());
    out.set_item(
        "mask",
        Array::from_shape_vec(shape.clone(), d.mask.clone())
            .map_err(as_err)?
            .into_pyarray(py),
    )?;
    out.set_item(
        "alpha",
        Array::from_shape_vec(shape, d.alpha.clone())
            .map_err(as_err)?
            .into_pyarray(py),
    )?;
    out.set_item(
        "env",
        stack(py, false, d.env.height, d.env.width, vec![&d.env.texels])?,
    )?;
    let ctrl = |m: &Material| Array::from_shape_vec(IxDyn(&[matedit::N_PARAMS]), m.ctrl.to_vec());
    out.set_item(
        "material",
        ctrl(&d.material).map_err(as_err)?.into_pyarray(py),
    )?;
    out.set_item(
        "predicted_material",
        ctrl(&d.predicted_material)
            .map_err(as_err)?
            .into_pyarray(py),
    )?;
    out.set_item("psnr_predicted", d.psnr_predicted)?;
    out.set_item("psnr_refined", d.psnr_refined)?;
    out.set_item("losses", d.losses.clone())?;
    out.set_item("normal_losses", d.normal_losses.clone())?;
    let seconds = PyDict::new(py);
    for (k, v) in &d.stages {
        seconds.set_item(*k, v)?;
    }
    out.set_item("seconds", seconds)?;
    Ok(out)
}
