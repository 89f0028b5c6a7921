//! Between NumPy and the library: arrays of images, normals and control points into the
//! library's types and images back into arrays, and the library's errors as Python's.

use std::borrow::Cow;

use matedit::{Camera, Convention};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;

/// The library's error as Python's: `ValueError` for invalid input, `RuntimeError` for
/// the rest.
pub(crate) fn py_err(e: matedit::Error) -> PyErr {
    if e.is_input_error() {
        PyValueError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

/// A `ValueError` with `msg`.
pub(crate) fn invalid(msg: String) -> PyErr {
    PyValueError::new_err(msg)
}

/// An array's elements in C order: borrowed when it is C-contiguous, else gathered.
pub(crate) fn elements<'a, T: numpy::Element + Copy>(
    a: &'a PyReadonlyArrayDyn<'_, T>,
) -> Cow<'a, [T]> {
    match a.as_slice() {
        Ok(s) => Cow::Borrowed(s),
        Err(_) => Cow::Owned(a.as_array().iter().copied().collect()),
    }
}

/// An (H, W, 3) or (B, H, W, 3) array as per-scene RGB rows.
pub(crate) struct Rgb {
    pub(crate) batched: bool,
    pub(crate) height: usize,
    pub(crate) width: usize,
    pub(crate) rows: Vec<Vec<[f32; 3]>>,
}

/// Splits an (H, W, 3) or (B, H, W, 3) array into per-scene RGB rows.
pub(crate) fn images(what: &str, a: &PyReadonlyArrayDyn<'_, f32>) -> PyResult<Rgb> {
    let shape = a.shape().to_vec();
    let (batched, b, h, w) = match shape[..] {
        [h, w, 3] => (false, 1, h, w),
        [b, h, w, 3] => (true, b, h, w),
        _ => {
            return Err(invalid(format!(
                "{what}: shape {shape:?} is not (H, W, 3) or (B, H, W, 3)"
            )));
        }
    };
    if b == 0 || h == 0 || w == 0 {
        return Err(invalid(format!("{what}: shape {shape:?} is empty")));
    }
    // one copy, into the library's types (which own their data)
    let e = elements(a);
    let rgb: &[[f32; 3]] = bytemuck::cast_slice(&e);
    Ok(Rgb {
        batched,
        height: h,
        width: w,
        rows: rgb.chunks_exact(h * w).map(<[[f32; 3]]>::to_vec).collect(),
    })
}

/// Scene `i`'s row of an input given once (shared by a batch of `b`) or per scene: moved
/// out when it is used once, copied when it is shared.
pub(crate) fn pick<T: Clone>(v: &mut [Vec<T>], i: usize, b: usize) -> Vec<T> {
    if v.len() == 1 && b > 1 {
        v[0].clone()
    } else {
        std::mem::take(&mut v[if v.len() == 1 { 0 } else { i }])
    }
}

/// (108,) or (B, 108) control points.
pub(crate) fn ctrls(a: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<(bool, Vec<Vec<f64>>)> {
    let shape = a.shape().to_vec();
    let v = elements(a);
    match shape[..] {
        [n] if n == matedit::N_PARAMS => Ok((false, vec![v.to_vec()])),
        [b, n] if n == matedit::N_PARAMS && b > 0 => {
            Ok((true, v.chunks_exact(n).map(<[f64]>::to_vec).collect()))
        }
        _ => Err(invalid(format!(
            "ctrl: shape {shape:?} is not ({0},) or (B, {0})",
            matedit::N_PARAMS
        ))),
    }
}

/// A map's convention by name.
pub(crate) fn convention(name: &str) -> PyResult<Convention> {
    name.parse()
        .map_err(|e: String| invalid(format!("convention: {e}")))
}

/// Orthographic, or perspective with a vertical field of view of `fov` degrees.
pub(crate) fn camera(fov: Option<f64>) -> PyResult<Camera> {
    let c = match fov {
        None => Camera::Orthographic,
        Some(fov_y_deg) => Camera::Perspective { fov_y_deg },
    };
    c.validate().map_err(py_err)?;
    Ok(c)
}

/// Stacks per-scene RGB rows into (H, W, 3) or (B, H, W, 3).
pub(crate) fn stack<'py>(
    py: Python<'py>,
    batched: bool,
    h: usize,
    w: usize,
    rows: Vec<&[[f32; 3]]>,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let b = rows.len();
    let mut flat: Vec<f32> = Vec::with_capacity(b * h * w * 3);
    for r in rows {
        flat.extend_from_slice(bytemuck::cast_slice(r));
    }
    let shape = if batched {
        vec![b, h, w, 3]
    } else {
        vec![h, w, 3]
    };
    let a = Array::from_shape_vec(IxDyn(&shape), flat)
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))?;
    Ok(a.into_pyarray(py))
}
