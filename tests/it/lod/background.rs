//! Background pixels stay zero under every approximation, on both cameras.

use super::{method, run, upstream};
use crate::common::{Rng, random_scene};
use matedit::cpu::FastCpu;
use matedit::reference::Reference;
use matedit::{Backend, Camera, Convention};

#[test]
fn background_stays_zero() {
    let mut rng = Rng::new(29);
    let cpu = FastCpu::new().unwrap();
    let backends: [(&str, &dyn Backend); 2] = [("reference", &Reference), ("cpu", &cpu)];
    for camera in [
        Camera::Orthographic,
        Camera::Perspective { fov_y_deg: 40.0 },
    ] {
        let scene = random_scene(&mut rng, 14, 12, 16, 32, Convention::Paper, camera);
        let up = upstream(&scene, 30);
        let background: Vec<usize> = (0..14 * 12)
            .filter(|&p| scene.normals.is_background(p))
            .collect();
        assert!(background.len() > 10);
        for (name, b) in backends {
            for m in [
                "env2",
                "env4+keep4",
                "keep8",
                "env64",
                "table16",
                "table24+env2+keep4",
            ] {
                let m = method(m);
                if m.validate(&scene).is_err() {
                    continue;
                }
                let (image, grads) = run(b, &scene, &up, &m);
                for &p in &background {
                    assert_eq!(image.pixels[p], [0.0; 3], "{name} {m} image pixel {p}");
                    assert_eq!(grads.d_normals[p], [0.0; 3], "{name} {m} dn pixel {p}");
                }
                assert!(image.max_value() > 0.0, "{name} {m}: all dark");
            }
        }
    }
}
