//! The `Renderer` class: the layer's forward and backward passes on NumPy arrays, on one
//! device kept across calls, with the GIL released while the layer runs.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use matedit::{Accuracy, Batch, Device, EnvMap, Image, Material, NormalMap, Wanted};
use numpy::ndarray::{Array, IxDyn};
use numpy::{IntoPyArray, PyArrayDyn, PyReadonlyArrayDyn, PyUntypedArrayMethods};
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

use crate::convert::{Rgb, camera, convention, ctrls, images, invalid, pick, py_err, stack};

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

/// Exact, or within a tolerance.
fn accuracy(tolerance: Option<f64>) -> PyResult<Accuracy> {
    match tolerance {
        None => Ok(Accuracy::Exact),
        Some(t) if t.is_finite() && t > 0.0 => Ok(Accuracy::Tolerance(t)),
        Some(t) => Err(invalid(format!("tolerance: {t} is not a positive number"))),
    }
}

/// Renders and differentiates the layer on one device, kept across calls (the GPU
/// pipelines are built once).
#[pyclass(frozen, module = "matedit._matedit")]
pub(crate) struct Renderer {
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
                self.inner.backward_with(&s.batch, &ups, &acc, wanted)
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
