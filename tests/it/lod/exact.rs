//! The exact method is the layer, and so are full-resolution blocks with kept texels.

use super::{errors, method, rescaled, run, upstream};
use crate::common::{Rng, random_scene, upstream_for};
use matedit::cpu::FastCpu;
use matedit::lod::Method;
use matedit::reference::Reference;
use matedit::{Backend, Batch, Camera, Convention, Renderer, Wanted};

#[test]
fn exact_method_is_the_backend_bitwise() {
    let cpu = FastCpu::new().unwrap();
    let renderer = Renderer::with_backend(Box::new(cpu));
    let mut rng = Rng::new(3);
    for (conv, camera) in [
        (Convention::Equirect, Camera::Orthographic),
        (Convention::Paper, Camera::Perspective { fov_y_deg: 60.0 }),
    ] {
        let scene = random_scene(&mut rng, 13, 11, 16, 32, conv, camera);
        let batch = Batch::single(scene.clone()).unwrap();
        let up = upstream_for(&batch, 4);
        let (image, grads) = run(&cpu, &scene, &up[0], &Method::EXACT);
        assert_eq!(image, renderer.render(&batch).unwrap()[0], "{conv:?}");
        assert_eq!(
            image,
            Backend::render(&cpu, (&batch).into()).unwrap()[0],
            "{conv:?}"
        );
        assert_eq!(
            grads,
            renderer.backward(&batch, &up).unwrap()[0],
            "{conv:?}"
        );
        assert_eq!(
            grads,
            Backend::backward(&cpu, (&batch).into(), &up, Wanted::ALL).unwrap()[0]
        );
    }
}

// Full-resolution blocks with kept texels are the layer.

#[test]
fn full_resolution_with_kept_texels_is_exact() {
    let mut rng = Rng::new(5);
    let cpu = FastCpu::new().unwrap();
    let backends: [(&str, &dyn Backend); 2] = [("reference", &Reference), ("cpu", &cpu)];
    for conv in [Convention::Equirect, Convention::Paper] {
        let scene = random_scene(&mut rng, 12, 10, 16, 32, conv, Camera::Orthographic);
        let up = upstream(&scene, 6);
        // every pixel is off unit length, so a table leaves all of them to per-pixel
        // evaluation: full-resolution blocks (the map less its kept texels) plus the kept
        // texels, which must add up to the layer
        let off_unit = rescaled(&scene, 0.8);
        for (name, b) in backends {
            // and with every texel kept, the blocks are dark and the kept texels are the map
            for (s, m) in [
                (&scene, "keep8"),
                (&off_unit, "table16+keep8"),
                (&scene, "env4+keep512"),
            ] {
                let exact = run(b, s, &up, &Method::EXACT);
                let got = run(b, s, &up, &method(m));
                let e = errors(&got, &exact);
                eprintln!(
                    "{name} {conv:?} {m}: errors (image, dL, dn, dctrl) {:?}",
                    e.map(|v| format!("{v:.1e}"))
                );
                for (what, e) in ["image", "dL", "dn", "dctrl"].iter().zip(e) {
                    assert!(e <= 1e-5, "{name} {conv:?} {m} {what}: error {e:e}");
                }
            }
        }
    }
}
