//! Culling by bound: the image stays within the bound of its largest value, some work is
//! skipped, and the method names and cameras are checked.

use super::{glossy, method, rel, smooth_env, sphere_scene, sun_env, upstream};
use matedit::cpu::FastCpu;
use matedit::lod::{self, Method};
use matedit::{Camera, Convention, Material, Scene};

#[test]
fn culling_stays_within_its_bound_and_skips_work() {
    let cpu = FastCpu::new().unwrap();
    // a sharp lobe (chrome-like, no diffuse) and a glossy one, under suns and a smooth sky
    let sharp = Material::constant("sharp", [(0.0, 0.0), (3.0, 400.0), (0.0, 0.0)]).unwrap();
    let cases = [
        (
            "sharp suns",
            sphere_scene(
                64,
                sun_env(32, 64, Convention::Equirect, 41, 3),
                sharp.clone(),
            ),
        ),
        (
            "sharp smooth",
            sphere_scene(64, smooth_env(32, 64, Convention::Equirect, 42), sharp),
        ),
        (
            "glossy suns",
            sphere_scene(64, sun_env(32, 64, Convention::Equirect, 43, 2), glossy()),
        ),
        (
            "glossy smooth paper",
            sphere_scene(48, smooth_env(16, 32, Convention::Paper, 44), glossy()),
        ),
    ];
    let mut culled_any = false;
    for (what, scene) in &cases {
        let exact = lod::render(&cpu, scene, &Method::EXACT).unwrap();
        for m in ["cull1e-2", "cull1e-3", "table48+keep4+cull1e-3"] {
            let m = method(m);
            let img = lod::render(&cpu, scene, &m).unwrap();
            let err = rel(&img.pixels, &exact.pixels);
            let base = lod::render(&cpu, scene, &Method { cull: None, ..m }).unwrap();
            let cull_err = rel(&img.pixels, &base.pixels);
            // the bound is against the image's largest value, estimated from below
            assert!(
                cull_err <= m.cull_budget() * (1.0 + 1e-4) + 1e-6,
                "{what} {m}: culling changed the image by {cull_err:e} of its largest value"
            );
            culled_any |= cull_err > 0.0;
            eprintln!("{what} {m}: error {err:.2e}, culling's share {cull_err:.2e}");
            // the same bits twice, and the backward runs (a culled light has dL = 0)
            assert_eq!(img, lod::render(&cpu, scene, &m).unwrap(), "{what} {m}");
            let up = upstream(scene, 7);
            let g = lod::backward(&cpu, scene, &up, &m).unwrap();
            assert!(g.d_env.iter().flatten().all(|v| v.is_finite()));
        }
    }
    assert!(culled_any, "no case culled anything");
    // names, and cameras
    assert_eq!(method("cull2.5e-4").to_string(), "cull2.5e-4");
    assert_eq!(method("table64+cull1e-3").cull, Some(1_000_000));
    for bad in ["cull0", "cull1", "cull-1e-3", "cullx", "cull1e-3+cull1e-4"] {
        assert!(bad.parse::<Method>().is_err(), "{bad}");
    }
    let persp = Scene {
        camera: Camera::Perspective { fov_y_deg: 40.0 },
        ..cases[0].1.clone()
    };
    let e = lod::render(&cpu, &persp, &method("cull1e-3")).unwrap_err();
    assert!(e.to_string().contains("orthographic"), "{e}");
}
