//! The fast CPU path and the GPU run every approximation like the reference.

use super::{errors, method, random_ortho, rescaled, run, upstream};
use crate::common;
use matedit::cpu::FastCpu;
use matedit::reference::Reference;
use matedit::{Backend, Camera, Scene};

/// A scene for comparing backends, and the same with every normal off unit length (a
/// table then has no node at all).
fn backend_scenes() -> [Scene; 2] {
    let scene = random_ortho(27, (16, 14), (16, 32));
    let off_unit = rescaled(&scene, 0.9);
    [scene, off_unit]
}

/// `backend` against the reference on the backend scenes, within `tol` of each output's
/// largest value.
fn check_backend(name: &str, backend: &dyn Backend, tol: f64) {
    let [scene, off_unit] = backend_scenes();
    let persp = Scene {
        camera: Camera::Perspective { fov_y_deg: 50.0 },
        ..scene.clone()
    };
    for (s, m) in [
        (&scene, "table24+keep4"),
        (&scene, "table16+env2+keep8"),
        (&scene, "env4+keep8"),
        (&persp, "env2+keep4"),
        (&off_unit, "table16+env2"),
    ] {
        let (m, up) = (method(m), upstream(s, 28));
        let want = run(&Reference, s, &up, &m);
        let got = run(backend, s, &up, &m);
        let e = errors(&got, &want);
        eprintln!(
            "{name} {m}: errors (image, dL, dn, dctrl) {:?}",
            e.map(|v| format!("{v:.1e}"))
        );
        for (output, e) in ["image", "dL", "dn", "dctrl"].iter().zip(e) {
            assert!(e <= tol, "{name} {m} {output}: error {e:e}");
        }
    }
}

#[test]
fn fast_cpu_runs_approximations_like_the_reference() {
    // tables' dLoss/dn come from the fast path's own Jacobian kernel
    check_backend("cpu", &FastCpu::new().unwrap(), 1e-5);
}

#[test]
fn gpu_runs_approximations_like_the_reference() {
    let Some(gpu) = common::gpu("gpu_runs_approximations_like_the_reference") else {
        return;
    };
    check_backend("gpu", &gpu, 1e-4);
}
