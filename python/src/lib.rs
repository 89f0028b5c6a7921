//! The Python extension `matedit._matedit`: the layer's forward and backward passes on
//! NumPy arrays, a `Renderer` that keeps its device, presets and file loaders. The Python
//! package `matedit` wraps it (argument checks, the PyTorch operator).
//!
//! Errors: the library's one-line messages, as `ValueError` for invalid input and
//! `RuntimeError` for device failures. The GIL is released while the layer runs.

mod convert;
mod edit;
mod inputs;
mod render;
mod synth;

use pyo3::prelude::*;

#[pymodule]
fn _matedit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<render::Renderer>()?;
    m.add_function(wrap_pyfunction!(inputs::presets, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::preset, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::load_env, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::load_normals, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::sphere, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::bumpy, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::random_material, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::sky, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::shape_normals, m)?)?;
    m.add_function(wrap_pyfunction!(inputs::procedural_env, m)?)?;
    m.add_function(wrap_pyfunction!(synth::synth, m)?)?;
    m.add_function(wrap_pyfunction!(synth::synth_check, m)?)?;
    m.add_function(wrap_pyfunction!(synth::synth_verify, m)?)?;
    m.add_function(wrap_pyfunction!(edit::builtin_weights, m)?)?;
    m.add_function(wrap_pyfunction!(edit::edit_photo, m)?)?;
    Ok(())
}
