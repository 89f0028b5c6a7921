//! Method names: they round-trip through Display and FromStr, bad ones are errors that
//! name them, and a table needs an orthographic camera.

use super::{method, upstream};
use crate::common::{Rng, random_scene};
use matedit::lod::{self, Method};
use matedit::reference::Reference;
use matedit::{Camera, Convention, Image, Scene};

#[test]
fn method_names_round_trip_and_errors() {
    for s in ["exact", "env4", "keep16", "table32", "table96+env2+keep16"] {
        let m = method(s);
        assert_eq!(m.to_string(), s, "Display of {m:?}");
        assert_eq!(m.to_string().parse::<Method>().unwrap(), m);
    }
    assert_eq!(method("exact"), Method::EXACT);
    assert!(Method::EXACT.is_exact());
    assert_eq!(
        method("table96+env2+keep16"),
        Method {
            env_factor: 2,
            keep: 16,
            table: Some(96),
            cull: None,
        }
    );
    // parts in any order, one canonical name
    assert_eq!(
        method("keep16+env2+table96").to_string(),
        "table96+env2+keep16"
    );
    assert_eq!(method("env1").to_string(), "exact");
    assert_eq!(method("env64").env_factor, 64);
    assert_eq!(method("table4").table, Some(4));
    for bad in [
        "",
        "foo",
        "env0",
        "env65",
        "table2",
        "env2+env4",
        "env2+",
        "+env2",
        "exact+env2",
        "env-1",
        "envx",
        "table4097",
        "keep4+keep8",
        "EXACT",
        " env2",
    ] {
        let e = bad
            .parse::<Method>()
            .expect_err(&format!("'{bad}' should not parse"));
        assert!(e.contains(bad), "the error for '{bad}' names it: {e}");
    }

    let mut rng = Rng::new(1);
    let persp = Camera::Perspective { fov_y_deg: 50.0 };
    let scene = random_scene(&mut rng, 6, 5, 8, 16, Convention::Equirect, persp);
    let e = method("table32+env2")
        .validate(&scene)
        .expect_err("a table needs an orthographic camera")
        .to_string();
    assert!(e.contains("normal tables"), "{e}");
    for ok in ["exact", "env2", "keep4", "env4+keep8"] {
        method(ok).validate(&scene).unwrap();
    }
    // the passes refuse it too, with the same message
    let up = upstream(&scene, 2);
    let e = lod::render(&Reference, &scene, &method("table16")).expect_err("perspective table");
    assert!(e.to_string().contains("normal tables"), "{e}");
    let e = lod::backward(&Reference, &scene, &up, &method("table16")).expect_err("perspective");
    assert!(e.to_string().contains("normal tables"), "{e}");
    let ortho = Scene {
        camera: Camera::Orthographic,
        ..scene
    };
    method("table32+env2").validate(&ortho).unwrap();
    // fields set by hand are checked as well
    let weird = Method {
        env_factor: 0,
        keep: 0,
        table: None,
        cull: None,
    };
    assert!(weird.validate(&ortho).is_err());
    assert!(lod::render(&Reference, &ortho, &weird).is_err());
    let weird = Method {
        env_factor: 1,
        keep: 0,
        table: Some(3),
        cull: None,
    };
    assert!(weird.validate(&ortho).is_err());
    // an upstream of the wrong size is an error, not a panic
    let small = Image::zeros(3, 3);
    assert!(lod::backward(&Reference, &ortho, &small, &method("env2")).is_err());
}
