//! The inputs of the layer as NumPy arrays: presets, maps and normals loaded from files,
//! and the built-in spheres, surfaces, skies, shapes and procedural lights.

use std::path::PathBuf;

use matedit::io::{self, EnvSize};
use matedit::{Camera, NormalMap};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use crate::convert::{self, invalid, py_err, stack};

/// The presets' names, the default first.
#[pyfunction]
pub(crate) fn presets() -> Vec<&'static str> {
    matedit::presets::names()
}

/// A preset's 108 control points (float64).
#[pyfunction]
pub(crate) fn preset<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
    let m = matedit::presets::lookup(name).ok_or_else(|| {
        invalid(format!(
            "unknown preset '{name}'; matedit.presets() lists them"
        ))
    })?;
    Ok(
        Array::from_shape_vec(IxDyn(&[matedit::N_PARAMS]), m.ctrl.to_vec())
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?
            .into_pyarray(py),
    )
}

/// A lat-long map from an .exr or .npy file, negative values clamped to 0, downsampled
/// to `size` (None: the file's size).
#[pyfunction]
#[pyo3(signature = (path, size = Some((64, 128)), convention = "equirect"))]
pub(crate) fn load_env<'py>(
    py: Python<'py>,
    path: PathBuf,
    size: Option<(usize, usize)>,
    convention: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let conv = convert::convention(convention)?;
    let loaded = io::load_env(&path, conv).map_err(py_err)?;
    let size = match size {
        None => EnvSize::Full,
        Some((height, width)) => EnvSize::Size { height, width },
    };
    let env = io::resample::fit(loaded.env, size, &path).map_err(py_err)?;
    stack(py, false, env.height, env.width, vec![&env.texels[..]])
}

/// A normal map from an .exr, .npy or .png file, normalised (background 0).
#[pyfunction]
pub(crate) fn load_normals<'py>(
    py: Python<'py>,
    path: PathBuf,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let n = io::load_normals(&path).map_err(py_err)?;
    stack(py, false, n.height, n.width, vec![&n.normals[..]])
}

/// The normals of a unit sphere filling an n x n image (background 0).
#[pyfunction]
pub(crate) fn sphere(py: Python<'_>, n: usize) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
    if n == 0 || n > 8192 {
        return Err(invalid(format!("sphere: size {n} is outside 1..=8192")));
    }
    let s = NormalMap::sphere(n);
    stack(py, false, n, n, vec![&s.normals[..]])
}

/// The normals of a bumpy surface of `width` x `height` (a seeded height field, every
/// pixel foreground), as the benchmarks use.
#[pyfunction]
#[pyo3(signature = (width, height, seed = 1))]
pub(crate) fn bumpy(
    py: Python<'_>,
    width: usize,
    height: usize,
    seed: u64,
) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
    if width == 0 || height == 0 || width > 8192 || height > 8192 {
        return Err(invalid(format!(
            "bumpy: size {width}x{height} is outside 1..=8192 x 1..=8192"
        )));
    }
    let s = NormalMap::bumpy(width, height, seed);
    stack(py, false, height, width, vec![&s.normals[..]])
}

/// A seeded random material with nothing to share (108 float64 control points): every
/// lobe of every channel its own scale curve (0.02-1.2) and exponent curve (0.3-80).
#[pyfunction]
pub(crate) fn random_material(py: Python<'_>, seed: u64) -> PyResult<Bound<'_, PyArrayDyn<f64>>> {
    let m = matedit::Material::random(seed);
    Array::from_shape_vec(IxDyn(&[matedit::N_PARAMS]), m.ctrl.to_vec())
        .map(|a| a.into_pyarray(py))
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

/// The built-in procedural sky with its sun, `height` x `width`.
#[pyfunction]
#[pyo3(signature = (height = 64, width = 128, convention = "equirect"))]
pub(crate) fn sky<'py>(
    py: Python<'py>,
    height: usize,
    width: usize,
    convention: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    if height == 0 || width == 0 || height > 4096 || width > 8192 {
        return Err(invalid(format!(
            "sky: size {height}x{width} is outside 1..=4096 x 1..=8192"
        )));
    }
    let env = matedit::builtin_sky::procedural_env(height, width, convert::convention(convention)?);
    stack(py, false, height, width, vec![&env.texels[..]])
}

/// (H, W, 3) normals and an (H, W) mask.
type NormalsAndMask<'py> = (Bound<'py, PyArrayDyn<f32>>, Bound<'py, PyArrayDyn<bool>>);

/// Normals and mask of a procedural shape (`shape`, e.g. "blobby" or "torus:seed=3") or a
/// mesh file (`mesh`), as `matedit normals` draws them: (H, W, 3) float32 normals (0 on the
/// background) and an (H, W) bool mask. `rotate` is (yaw, pitch, roll) in degrees; without
/// it `seed` draws a uniformly random rotation (and a shape's parameters).
#[pyfunction]
#[pyo3(signature = (shape = None, mesh = None, height = 256, width = 256, fov = None, rotate = None, seed = 0, flat = false))]
#[allow(clippy::too_many_arguments)]
pub(crate) fn shape_normals<'py>(
    py: Python<'py>,
    shape: Option<&str>,
    mesh: Option<PathBuf>,
    height: usize,
    width: usize,
    fov: Option<f64>,
    rotate: Option<(f64, f64, f64)>,
    seed: u64,
    flat: bool,
) -> PyResult<NormalsAndMask<'py>> {
    use matedit::shapes::{Rotation, Shape, View};
    let m = match (shape, mesh) {
        (Some(s), None) => s
            .parse::<Shape>()
            .map_err(|e| invalid(format!("shape: {e}")))?
            .mesh(seed),
        (None, Some(p)) => matedit::shapes::load_mesh(&p).map_err(py_err)?,
        _ => return Err(invalid("give one of shape= and mesh=".to_string())),
    };
    let rotation = match rotate {
        Some((yaw, pitch, roll)) => Rotation { yaw, pitch, roll },
        None => Rotation::random(seed),
    };
    let view = View {
        camera: match fov {
            Some(fov_y_deg) => Camera::Perspective { fov_y_deg },
            None => Camera::Orthographic,
        },
        rotation,
        flat,
        ..View::new(width, height)
    };
    let (n, mask) = matedit::shapes::render_normals(&m, &view).map_err(py_err)?;
    let mask = Array::from_shape_vec(IxDyn(&[height, width]), mask)
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))?
        .into_pyarray(py);
    Ok((stack(py, false, height, width, vec![&n.normals[..]])?, mask))
}

/// A procedural HDR light (`kind`: "sun-sky", "overcast", "studio" or "indoor"), its
/// parameters drawn from `seed`, as `matedit env` makes it: (height, width, 3) float32.
#[pyfunction]
#[pyo3(signature = (kind, seed = 0, height = 64, width = 128))]
pub(crate) fn procedural_env<'py>(
    py: Python<'py>,
    kind: &str,
    seed: u64,
    height: usize,
    width: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let kind: matedit::envgen::LightKind =
        kind.parse().map_err(|e| invalid(format!("kind: {e}")))?;
    let env = matedit::envgen::generate(kind, seed, height, width).map_err(py_err)?;
    stack(py, false, height, width, vec![&env.texels[..]])
}
