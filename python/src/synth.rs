//! `matedit synth` from Python: checking a dataset spec, writing a shard of its chunks and
//! verifying them, with the GIL released while they run.

use std::path::PathBuf;

use matedit::Device;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::convert::{invalid, py_err};

/// The renderer of a dataset's samples on `device`.
fn synth_engine(device: &str) -> PyResult<matedit::synth::Engine> {
    let d: Device = device
        .parse()
        .map_err(|e: String| invalid(format!("device: {e}")))?;
    matedit::synth::Engine::new(d).map_err(py_err)
}

/// Shard (I, N) of a dataset.
fn synth_shard(shard: (u64, u64)) -> PyResult<matedit::synth::Shard> {
    matedit::synth::Shard::new(shard.0, shard.1).map_err(invalid)
}

/// Checks a dataset spec and every input it names, and that shard `shard` = (I, N) can
/// run into `out_dir`; writes nothing. Raises ValueError naming the item.
#[pyfunction]
#[pyo3(signature = (spec, out_dir, shard = (0, 1), device = "cpu"))]
pub(crate) fn synth_check(
    py: Python<'_>,
    spec: PathBuf,
    out_dir: PathBuf,
    shard: (u64, u64),
    device: &str,
) -> PyResult<()> {
    // any shard I/N with I below N can run, with or without chunks to write
    synth_shard(shard)?;
    py.detach(|| {
        let s = matedit::synth::Spec::load(&spec)?;
        let engine = matedit::synth::Engine::new(device.parse().map_err(matedit::Error::Invalid)?)?;
        matedit::synth::check_output(&s, &out_dir, &engine.label)
    })
    .map_err(py_err)
}

/// Writes shard `shard` = (I, N) of the dataset `spec` into `out_dir`, like `matedit
/// synth SPEC -o OUT_DIR --shard I/N`: the chunks c with c mod N = I that are not yet
/// complete, then the manifest. Returns a summary dict (samples, seconds,
/// samples_per_second, chunks_written, chunks_skipped, chunks_total, chunks_present,
/// renderer, shard). `threads`: the CPU paths' worker threads (the first call's value
/// holds for the process). The GIL is released while it runs.
#[pyfunction]
#[pyo3(signature = (spec, out_dir, shard = (0, 1), device = "cpu", threads = None))]
pub(crate) fn synth<'py>(
    py: Python<'py>,
    spec: PathBuf,
    out_dir: PathBuf,
    shard: (u64, u64),
    device: &str,
    threads: Option<usize>,
) -> PyResult<Bound<'py, PyDict>> {
    let shard = synth_shard(shard)?;
    if let Some(n) = threads {
        // only fails if the pool was already built: the first value holds
        let _ = rayon::ThreadPoolBuilder::new()
            .num_threads(n.max(1))
            .build_global();
    }
    let engine = synth_engine(device)?;
    let summary = py
        .detach(|| {
            let s = matedit::synth::Spec::load(&spec)?;
            matedit::synth::run(&s, &out_dir, shard, &engine, &|_| {})
        })
        .map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item("shard", &summary.shard)?;
    d.set_item("samples", summary.samples)?;
    d.set_item("seconds", summary.seconds)?;
    d.set_item("samples_per_second", summary.samples_per_second())?;
    d.set_item("chunks_written", summary.chunks_written)?;
    d.set_item("chunks_skipped", summary.chunks_skipped)?;
    d.set_item("chunks_total", summary.chunks_total)?;
    d.set_item("chunks_present", summary.chunks_present)?;
    d.set_item("renderer", &summary.renderer)?;
    Ok(d)
}

/// Checks every chunk of the dataset in `out_dir` against its record and rewrites the
/// manifest listing those that match, like `matedit synth SPEC -o OUT_DIR --verify`:
/// the last step after shards ran at the same time. Returns a dict (chunks_total,
/// chunks_present, missing: the chunk indices missing or damaged, complete).
#[pyfunction]
#[pyo3(signature = (spec, out_dir, device = "cpu"))]
pub(crate) fn synth_verify<'py>(
    py: Python<'py>,
    spec: PathBuf,
    out_dir: PathBuf,
    device: &str,
) -> PyResult<Bound<'py, PyDict>> {
    let engine = synth_engine(device)?;
    let v = py
        .detach(|| {
            let s = matedit::synth::Spec::load(&spec)?;
            matedit::synth::verify(&s, &out_dir, &engine.label)
        })
        .map_err(py_err)?;
    let d = PyDict::new(py);
    d.set_item("chunks_total", v.chunks_total)?;
    d.set_item("chunks_present", v.chunks_present)?;
    d.set_item("complete", v.missing.is_empty())?;
    d.set_item("missing", v.missing)?;
    Ok(d)
}
