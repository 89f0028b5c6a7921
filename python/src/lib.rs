//! The Python extension `matedit._matedit`: the layer's forward and backward passes on
//! NumPy arrays, a `Renderer` that keeps its device, presets and file loaders. The Python
//! package `matedit` wraps it (argument checks, the PyTorch operator).
//!
//! Errors: the library's one-line messages, as `ValueError` for invalid input and
//! `RuntimeError` for device failures. The GIL is released while the layer runs.

use std::borrow::Cow;
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use matedit::io::{self, EnvSize};
use matedit::{
    Accuracy, Batch, Camera, Convention, Device, EnvMap, Image, Material, NormalMap, Wanted,
};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

fn py_err(e: matedit::Error) -> PyErr {
    if e.is_input_error() {
        PyValueError::new_err(e.to_string())
    } else {
        PyRuntimeError::new_err(e.to_string())
    }
}

fn invalid(msg: String) -> PyErr {
    PyValueError::new_err(msg)
}

/// An array's elements in C order: borrowed when it is C-contiguous, else gathered.
fn elements<'a, T: numpy::Element + Copy>(a: &'a PyReadonlyArrayDyn<'_, T>) -> Cow<'a, [T]> {
    match a.as_slice() {
        Ok(s) => Cow::Borrowed(s),
        Err(_) => Cow::Owned(a.as_array().iter().copied().collect()),
    }
}

/// An (H, W, 3) or (B, H, W, 3) array as per-scene RGB rows.
struct Rgb {
    batched: bool,
    height: usize,
    width: usize,
    rows: Vec<Vec<[f32; 3]>>,
}

/// Splits an (H, W, 3) or (B, H, W, 3) array into per-scene RGB rows.
fn images(what: &str, a: &PyReadonlyArrayDyn<'_, f32>) -> PyResult<Rgb> {
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
fn pick<T: Clone>(v: &mut [Vec<T>], i: usize, b: usize) -> Vec<T> {
    if v.len() == 1 && b > 1 {
        v[0].clone()
    } else {
        std::mem::take(&mut v[if v.len() == 1 { 0 } else { i }])
    }
}

/// (108,) or (B, 108) control points.
fn ctrls(a: &PyReadonlyArrayDyn<'_, f64>) -> PyResult<(bool, Vec<Vec<f64>>)> {
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

fn convention(name: &str) -> PyResult<Convention> {
    name.parse()
        .map_err(|e: String| invalid(format!("convention: {e}")))
}

fn camera(fov: Option<f64>) -> PyResult<Camera> {
    let c = match fov {
        None => Camera::Orthographic,
        Some(fov_y_deg) => Camera::Perspective { fov_y_deg },
    };
    c.validate().map_err(py_err)?;
    Ok(c)
}

/// The scenes of a call: normals, maps and materials, each given once or per scene.
struct Scenes {
    batch: Batch,
    batched: bool,
}

fn scenes(
    normals: &PyReadonlyArrayDyn<'_, f32>,
    env: &PyReadonlyArrayDyn<'_, f32>,
    ctrl: &PyReadonlyArrayDyn<'_, f64>,
    fov: Option<f64>,
    conv: &str,
) -> PyResult<Scenes> {
    let Rgb {
        batched: nb,
        height: h,
        width: w,
        rows: mut ns,
    } = images("normals", normals)?;
    let Rgb {
        batched: eb,
        height: hl,
        width: wl,
        rows: mut es,
    } = images("env", env)?;
    let (cb, cs) = ctrls(ctrl)?;
    let b = [ns.len(), es.len(), cs.len()]
        .into_iter()
        .max()
        .unwrap_or(1);
    for (what, n) in [("normals", ns.len()), ("env", es.len()), ("ctrl", cs.len())] {
        if n != 1 && n != b {
            return Err(invalid(format!(
                "{what}: batch of {n} where another input has {b}"
            )));
        }
    }
    let conv = convention(conv)?;
    let cam = camera(fov)?;
    let mut out = Vec::with_capacity(b);
    for i in 0..b {
        let normals = NormalMap::new(w, h, pick(&mut ns, i, b)).map_err(py_err)?;
        let env = EnvMap::new(hl, wl, conv, pick(&mut es, i, b)).map_err(py_err)?;
        let material =
            Material::new("ctrl", &cs[if cs.len() == 1 { 0 } else { i }]).map_err(py_err)?;
        out.push(matedit::Scene {
            normals,
            env,
            material,
            camera: cam,
        });
    }
    Ok(Scenes {
        batch: Batch::new(out).map_err(py_err)?,
        batched: nb || eb || cb,
    })
}

/// The gradients a backward call computes: all three, or those named.
fn wanted_of(names: Option<Vec<String>>) -> PyResult<Wanted> {
    let Some(names) = names else {
        return Ok(Wanted::ALL);
    };
    let mut w = Wanted {
        env: false,
        normals: false,
        ctrl: false,
    };
    for n in &names {
        match n.as_str() {
            "env" => w.env = true,
            "normals" => w.normals = true,
            "ctrl" => w.ctrl = true,
            _ => {
                return Err(invalid(format!(
                    "wanted: unknown gradient '{n}': expected some of env, normals, ctrl"
                )));
            }
        }
    }
    Ok(w)
}

fn accuracy(tolerance: Option<f64>) -> PyResult<Accuracy> {
    match tolerance {
        None => Ok(Accuracy::Exact),
        Some(t) if t.is_finite() && t > 0.0 => Ok(Accuracy::Tolerance(t)),
        Some(t) => Err(invalid(format!("tolerance: {t} is not a positive number"))),
    }
}

/// Stacks per-scene RGB rows into (H, W, 3) or (B, H, W, 3).
fn stack<'py>(
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

/// Renders and differentiates the layer on one device, kept across calls (the GPU
/// pipelines are built once).
#[pyclass(frozen, module = "matedit._matedit")]
struct Renderer {
    inner: matedit::Renderer,
    /// Seconds the last call spent in the layer (GIL released), as f64 bits.
    last: AtomicU64,
}

impl Renderer {
    /// Runs `f` with the GIL released and records how long it took.
    fn timed<T: Send>(&self, py: Python<'_>, f: impl FnOnce() -> T + Send) -> T {
        py.detach(|| {
            let t0 = Instant::now();
            let out = f();
            let s = t0.elapsed().as_secs_f64();
            self.last.store(s.to_bits(), Ordering::Relaxed);
            out
        })
    }
}

type Grads<'py> = (
    Bound<'py, PyArrayDyn<f32>>,
    Bound<'py, PyArrayDyn<f32>>,
    Bound<'py, PyArrayDyn<f32>>,
);

#[pymethods]
impl Renderer {
    #[new]
    #[pyo3(signature = (device = "auto"))]
    fn new(py: Python<'_>, device: &str) -> PyResult<Self> {
        let d: Device = device
            .parse()
            .map_err(|e: String| invalid(format!("device: {e}")))?;
        let inner = py.detach(|| matedit::Renderer::new(d)).map_err(py_err)?;
        Ok(Renderer {
            inner,
            last: AtomicU64::new(0),
        })
    }

    /// Which backend and adapter.
    fn describe(&self) -> String {
        self.inner.describe()
    }

    /// Seconds the last render or backward call spent in the layer itself, with the GIL
    /// released: what a call costs beyond it is the binding's overhead.
    #[getter]
    fn last_seconds(&self) -> f64 {
        f64::from_bits(self.last.load(Ordering::Relaxed))
    }

    /// The image(s): float32 (H, W, 3), or (B, H, W, 3) when an input is batched.
    #[pyo3(signature = (normals, env, ctrl, *, fov = None, convention = "equirect", tolerance = None))]
    #[allow(clippy::too_many_arguments, reason = "the Python signature")]
    fn render<'py>(
        &self,
        py: Python<'py>,
        normals: PyReadonlyArrayDyn<'py, f32>,
        env: PyReadonlyArrayDyn<'py, f32>,
        ctrl: PyReadonlyArrayDyn<'py, f64>,
        fov: Option<f64>,
        convention: &str,
        tolerance: Option<f64>,
    ) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
        let s = scenes(&normals, &env, &ctrl, fov, convention)?;
        let acc = accuracy(tolerance)?;
        let (images, _) = self
            .timed(py, || self.inner.render_with(&s.batch, &acc))
            .map_err(py_err)?;
        let (w, h) = s.batch.image_size();
        stack(
            py,
            s.batched,
            h,
            w,
            images.iter().map(|i| &i.pixels[..]).collect(),
        )
    }

    /// (d_env, d_normals, d_ctrl) for dLoss/dImage `upstream` (the image's shape). With
    /// `wanted` (some of "env", "normals", "ctrl") only those are computed; the others are
    /// zeros.
    #[pyo3(signature = (normals, env, ctrl, upstream, *, fov = None, convention = "equirect", tolerance = None, wanted = None))]
    #[allow(clippy::too_many_arguments, reason = "the Python signature")]
    fn backward<'py>(
        &self,
        py: Python<'py>,
        normals: PyReadonlyArrayDyn<'py, f32>,
        env: PyReadonlyArrayDyn<'py, f32>,
        ctrl: PyReadonlyArrayDyn<'py, f64>,
        upstream: PyReadonlyArrayDyn<'py, f32>,
        fov: Option<f64>,
        convention: &str,
        tolerance: Option<f64>,
        wanted: Option<Vec<String>>,
    ) -> PyResult<Grads<'py>> {
        let wanted = wanted_of(wanted)?;
        let s = scenes(&normals, &env, &ctrl, fov, convention)?;
        let acc = accuracy(tolerance)?;
        let Rgb {
            batched: ub,
            height: uh,
            width: uw,
            rows: mut us,
        } = images("upstream", &upstream)?;
        let b = s.batch.scenes().len();
        let (w, h) = s.batch.image_size();
        if (uh, uw) != (h, w) || (us.len() != b && us.len() != 1) {
            return Err(invalid(format!(
                "upstream: shape {:?} does not match the images ({}{h}, {w}, 3)",
                upstream.shape(),
                if b > 1 {
                    format!("{b}, ")
                } else {
                    String::new()
                }
            )));
        }
        let ups: Vec<Image> = (0..b)
            .map(|i| Image {
                width: w,
                height: h,
                pixels: pick(&mut us, i, b),
            })
            .collect();
        let (grads, _) = self
            .timed(py, || {
                self.inner
                    .backward_with(&s.batch, &ups, &acc, wanted)
            })
            .map_err(py_err)?;
        let batched = s.batched || ub;
        let env0 = &s.batch.scenes()[0].env;
        let d_env = stack(
            py,
            batched,
            env0.height,
            env0.width,
            grads.iter().map(|g| &g.d_env[..]).collect(),
        )?;
        let d_normals = stack(
            py,
            batched,
            h,
            w,
            grads.iter().map(|g| &g.d_normals[..]).collect(),
        )?;
        let ctrl_flat: Vec<f32> = grads.iter().flat_map(|g| g.d_ctrl).collect();
        let shape = if batched {
            vec![b, matedit::N_PARAMS]
        } else {
            vec![matedit::N_PARAMS]
        };
        let d_ctrl = Array::from_shape_vec(IxDyn(&shape), ctrl_flat)
            .map_err(|e| PyRuntimeError::new_err(e.to_string()))?
            .into_pyarray(py);
        Ok((d_env, d_normals, d_ctrl))
    }
}

/// The presets' names, the default first.
#[pyfunction]
fn presets() -> Vec<&'static str> {
    matedit::presets::names()
}

/// A preset's 108 control points (float64).
#[pyfunction]
fn preset<'py>(py: Python<'py>, name: &str) -> PyResult<Bound<'py, PyArrayDyn<f64>>> {
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
fn load_env<'py>(
    py: Python<'py>,
    path: PathBuf,
    size: Option<(usize, usize)>,
    convention: &str,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let conv = self::convention(convention)?;
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
fn load_normals<'py>(py: Python<'py>, path: PathBuf) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let n = io::load_normals(&path).map_err(py_err)?;
    stack(py, false, n.height, n.width, vec![&n.normals[..]])
}

/// The normals of a unit sphere filling an n x n image (background 0).
#[pyfunction]
fn sphere(py: Python<'_>, n: usize) -> PyResult<Bound<'_, PyArrayDyn<f32>>> {
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
fn bumpy(
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
fn random_material(py: Python<'_>, seed: u64) -> PyResult<Bound<'_, PyArrayDyn<f64>>> {
    let m = matedit::Material::random(seed);
    Array::from_shape_vec(IxDyn(&[matedit::N_PARAMS]), m.ctrl.to_vec())
        .map(|a| a.into_pyarray(py))
        .map_err(|e| PyRuntimeError::new_err(e.to_string()))
}

/// The built-in procedural sky with its sun, `height` x `width`.
#[pyfunction]
#[pyo3(signature = (height = 64, width = 128, convention = "equirect"))]
fn sky<'py>(
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
    let env = matedit::defaults::procedural_env(height, width, self::convention(convention)?);
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
fn shape_normals<'py>(
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
fn procedural_env<'py>(
    py: Python<'py>,
    kind: &str,
    seed: u64,
    height: usize,
    width: usize,
) -> PyResult<Bound<'py, PyArrayDyn<f32>>> {
    let kind: matedit::envgen::Kind = kind.parse().map_err(|e| invalid(format!("kind: {e}")))?;
    let env = matedit::envgen::generate(kind, seed, height, width).map_err(py_err)?;
    stack(py, false, height, width, vec![&env.texels[..]])
}

fn synth_engine(device: &str) -> PyResult<matedit::synth::Engine> {
    let d: Device = device
        .parse()
        .map_err(|e: String| invalid(format!("device: {e}")))?;
    matedit::synth::Engine::new(d).map_err(py_err)
}

fn synth_shard(shard: (u64, u64)) -> PyResult<matedit::synth::Shard> {
    matedit::synth::Shard::new(shard.0, shard.1).map_err(invalid)
}

/// Checks a dataset spec and every input it names, and that shard `shard` = (I, N) can
/// run into `out_dir`; writes nothing. Raises ValueError naming the item.
#[pyfunction]
#[pyo3(signature = (spec, out_dir, shard = (0, 1), device = "cpu"))]
fn synth_check(
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
fn synth<'py>(
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
fn synth_verify<'py>(
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

/// The built-in nets' weights file (data/nets/weights.safetensors) as bytes: the nets that
/// `matedit edit` and `matedit.nets.load()` use.
#[pyfunction]
fn builtin_weights(py: Python<'_>) -> Bound<'_, pyo3::types::PyBytes> {
    pyo3::types::PyBytes::new(py, matedit::nets::BUILTIN_WEIGHTS)
}

/// `matedit edit` on arrays: the photo (H, W, 3) linear float32, the new material's control
/// points (108,), the object's mask (H, W) bool or None (the nets find it). Returns a dict
/// of NumPy arrays and numbers (see matedit.edit).
#[pyfunction]
#[pyo3(signature = (photo, material, mask = None, steps = 150, weights = None, device = "auto"))]
fn edit_photo<'py>(
    py: Python<'py>,
    photo: PyReadonlyArrayDyn<'py, f32>,
    material: PyReadonlyArrayDyn<'py, f64>,
    mask: Option<PyReadonlyArrayDyn<'py, bool>>,
    steps: usize,
    weights: Option<PathBuf>,
    device: &str,
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
    let options = PhotoOptions {
        steps,
        ..PhotoOptions::default()
    };
    let (d, edit) = py
        .detach(|| -> matedit::Result<_> {
            let nets = match &weights {
                Some(w) => matedit::nets::Nets::load(w)?,
                None => matedit::nets::Nets::builtin()?,
            };
            let renderer = matedit::Renderer::new(device)?;
            let d = photo::decompose(&renderer, &nets, &image, mask.as_deref(), &options)?;
            let object = photo::render_object(&renderer, &d, &target)?;
            let edit = photo::composite(&image, &object, &d.alpha);
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

#[pymodule]
fn _matedit(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Renderer>()?;
    m.add_function(wrap_pyfunction!(presets, m)?)?;
    m.add_function(wrap_pyfunction!(preset, m)?)?;
    m.add_function(wrap_pyfunction!(load_env, m)?)?;
    m.add_function(wrap_pyfunction!(load_normals, m)?)?;
    m.add_function(wrap_pyfunction!(sphere, m)?)?;
    m.add_function(wrap_pyfunction!(bumpy, m)?)?;
    m.add_function(wrap_pyfunction!(random_material, m)?)?;
    m.add_function(wrap_pyfunction!(sky, m)?)?;
    m.add_function(wrap_pyfunction!(shape_normals, m)?)?;
    m.add_function(wrap_pyfunction!(procedural_env, m)?)?;
    m.add_function(wrap_pyfunction!(synth, m)?)?;
    m.add_function(wrap_pyfunction!(synth_check, m)?)?;
    m.add_function(wrap_pyfunction!(synth_verify, m)?)?;
    m.add_function(wrap_pyfunction!(builtin_weights, m)?)?;
    m.add_function(wrap_pyfunction!(edit_photo, m)?)?;
    Ok(())
}
