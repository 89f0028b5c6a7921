//! The photo-like options: fov and elevation ranges, floors, shadows. Deterministic and
//! shardable; the floor is background (mask and normals 0), seen below the horizon with
//! the map above it; shadows darken the floor under the object; bad values refused.

use matedit::io::npy;
use matedit::synth;

use super::{assert_shards_agree, dir};

/// A spec in `root` lit by a constant map of 0.5 (`env.npy`, 8 x 16), `extra` keys joined.
fn spec_with(root: &std::path::Path, extra: &str) -> std::path::PathBuf {
    let texels = vec![[0.5f32; 3]; 8 * 16];
    std::fs::write(root.join("env.npy"), npy::encode_rgb(16, 8, &texels)).unwrap();
    let spec = root.join("spec.json");
    std::fs::write(
        &spec,
        format!(
            r#"{{"count": 4, "seed": 5, "image_size": 24, "env_size": "8x16", "chunk_size": 2,
               "normals": [{{"shape": "blobby", "views": "upright"}}, {{"shape": "random"}}],
               "envs": [{{"file": "env.npy", "rotate": false}}],
               "materials": [{{"preset": "gold"}}], {extra}}}"#
        ),
    )
    .unwrap();
    spec
}

#[test]
fn photo_options_are_deterministic_and_shards_agree() {
    let t = dir();
    let spec = spec_with(
        t.path(),
        r#""fov": [30, 50], "elevation": [0, 40], "shadows": true, "backgrounds": ["env"],
           "floor": [{"procedural": "wood"}, {"procedural": "tiles"}, {"procedural": "cloth"}, "none"]"#,
    );
    assert_shards_agree(&spec, t.path(), &[1, 0]);
    let sp = synth::Spec::load(&spec).unwrap();
    for k in 0..4 {
        let (a, b) = (sp.sample(k).unwrap(), sp.sample(k).unwrap());
        assert_eq!(a.params, b.params);
        assert_eq!(a.background, b.background);
        assert_eq!(a.shade, b.shade);
        let fov = a.params["fov"].as_f64().unwrap();
        let elevation = a.params["elevation"].as_f64().unwrap();
        assert!((30.0..=50.0).contains(&fov) && (0.0..=40.0).contains(&elevation));
        assert!(a.params["floor"]["item"].is_u64(), "{}", a.params);
        // the mask is the object alone: the floor has normal 0 and mask 0
        let n = &a.scene.normals.normals;
        assert_eq!(n.len(), 24 * 24);
        assert_eq!(a.background.as_ref().unwrap().len(), 24 * 24);
        for (m, v) in a.mask.iter().zip(n) {
            assert_eq!(*m, *v != [0.0; 3]);
        }
    }
}

#[test]
fn floor_below_the_horizon_env_above() {
    let t = dir();
    let spec = spec_with(
        t.path(),
        r#""fov": 40, "backgrounds": ["env"], "floor": [{"procedural": "tiles"}], "shadows": true"#,
    );
    let sp = synth::Spec::load(&spec).unwrap();
    for k in 0..2 {
        let x = sp.sample(k).unwrap();
        let bg = x.background.as_ref().unwrap();
        let vis = x.floor_visibility.as_ref().unwrap();
        let shade = x.shade.as_ref().unwrap();
        assert!(vis.iter().chain(shade).all(|v| (0.0..=1.0).contains(v)));
        let w = 24;
        for y in [0, 1, 22, 23] {
            for c in [0, 1, 22, 23] {
                let i = y * w + c;
                if x.mask[i] {
                    continue;
                }
                if y < 12 {
                    // above the horizon (the image's middle row at elevation 0): the map
                    assert_eq!(bg[i], [0.5; 3], "sample {k} ({c}, {y})");
                } else {
                    // the floor: albedo <= 0.9 times E / pi = 0.5
                    assert!(bg[i][0] < 0.46 && bg[i] != [0.5; 3], "{:?}", bg[i]);
                }
            }
        }
        // darker under the object than far from it: the darkest floor pixel against the
        // bottom corners
        let darkest = (0..24 * 24)
            .filter(|&i| !x.mask[i])
            .map(|i| vis[i])
            .fold(1.0f32, f32::min);
        let far = vis[23 * w].max(vis[23 * w + 23]);
        assert!(darkest + 0.1 < far, "{darkest} {far}");
        // the object's own pixels: some occluded, none above 1
        assert!(shade.iter().zip(&x.mask).any(|(s, m)| *m && *s < 0.95));
    }
}

#[test]
fn bad_photo_options_are_refused() {
    for (extra, expect) in [
        (
            r#""fov": 40, "elevation": [0, 90]"#,
            "spec.json: elevation: [0, 90] must be within [0, 80]",
        ),
        (
            r#""elevation": [0, 30]"#,
            "spec.json: elevation: needs a perspective camera",
        ),
        (r#""fov": [50, 30]"#, "spec.json: fov:"),
        (
            r#""fov": 40, "floor": [{"procedural": "marble"}]"#,
            "spec.json: floor[0]: unknown procedural floor 'marble'",
        ),
        (
            r#""fov": 40, "floor": [{"procedural": "wood", "colour": 1}]"#,
            "spec.json: floor[0]: unknown field `colour`",
        ),
        (
            r#""fov": 40, "floor": ["none"], "normals": [{"sphere": 24}]"#,
            "spec.json: floor: normals[0] is not a shape or a mesh",
        ),
        (
            r#""floor": ["none"]"#,
            "spec.json: floor: needs a perspective camera",
        ),
        (
            r#""fov": 40, "shadows": true"#,
            "spec.json: shadows: needs a \"floor\"",
        ),
    ] {
        let t = dir();
        let spec = spec_with(t.path(), extra);
        // a later key replaces an earlier one: "normals" above replaces the shapes
        let e = synth::Spec::load(&spec).expect_err(extra).to_string();
        assert!(e.contains(expect), "{extra}: expected '{expect}' in: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
}
