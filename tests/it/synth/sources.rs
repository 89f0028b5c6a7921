//! Shapes, procedural lights and meshes as sources of a spec.

use matedit::synth;

use super::{assert_shards_agree, dir, foreground, synth_cmd};

#[test]
fn shapes_and_procedural_lights_are_sources_and_shards_agree() {
    // procedural shapes (parameters and rotation drawn per sample) and procedural lights
    // (parameters drawn per sample), perspective: the shards write the whole run's bytes
    let t = dir();
    let spec = t.path().join("spec.json");
    std::fs::write(
        &spec,
        r#"{"count": 6, "seed": 3, "image_size": 24, "env_size": "16x32", "chunk_size": 2,
           "fov": 40,
           "normals": [{"shape": "blobby"}, {"shape": "union"}],
           "envs": [{"procedural": "sun-sky"}, {"procedural": "studio"}],
           "materials": [{"preset": "gold"}]}"#,
    )
    .unwrap();
    assert_shards_agree(&spec, t.path(), &[1, 0, 2]);
    let sp = synth::Spec::load(&spec).unwrap();
    let (mut shapes, mut lights) = (Vec::new(), Vec::new());
    for k in 0..6 {
        let x = sp.sample(k).unwrap();
        assert!(x.params["normals"]["shape_seed"].is_u64(), "{}", x.params);
        assert!(x.params["normals"]["rotation"].is_array());
        assert!(x.params["env"]["procedural"].is_string());
        // some pixels are the object and some background
        let fg = foreground(&x.scene.normals);
        assert!(
            fg > 24 && fg < 24 * 24,
            "sample {k}: {fg} foreground pixels"
        );
        assert!(
            x.scene
                .env
                .texels
                .iter()
                .flatten()
                .all(|v| v.is_finite() && *v >= 0.0)
        );
        shapes.push(x.scene.normals.normals.clone());
        lights.push(x.scene.env.texels.clone());
    }
    // each sample its own draw
    assert!(shapes.windows(2).all(|w| w[0] != w[1]));
    assert!(lights.windows(2).all(|w| w[0] != w[1]));
    // bad kinds: one line naming the item
    for (key, value, expect) in [
        ("normals", r#"[{"shape": "blobb"}]"#, "normals[0]: shape:"),
        (
            "envs",
            r#"[{"procedural": "sunny"}]"#,
            "envs[0]: procedural:",
        ),
    ] {
        let mut v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&spec).unwrap()).unwrap();
        v[key] = serde_json::from_str(value).unwrap();
        let bad = t.path().join("bad.json");
        std::fs::write(&bad, v.to_string()).unwrap();
        let o = synth_cmd(&bad, &t.path().join("bad"), &[])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains(expect), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
}

#[test]
fn meshes_are_a_source_turned_per_sample() {
    // a folder of two small meshes (a tetrahedron as OBJ, the same as OFF): each sample
    // picks one and turns it; shards agree with the whole run; a bad mesh names the item
    let t = dir();
    let meshes = t.path().join("meshes");
    std::fs::create_dir_all(&meshes).unwrap();
    std::fs::write(
        meshes.join("tet.obj"),
        "v 1 1 1\nv -1 -1 1\nv -1 1 -1\nv 1 -1 -1\nf 1 2 3\nf 1 4 2\nf 1 3 4\nf 2 4 3\n",
    )
    .unwrap();
    std::fs::write(
        meshes.join("tet.off"),
        "OFF\n4 4 0\n1 1 1\n-1 -1 1\n-1 1 -1\n1 -1 -1\n3 0 1 2\n3 0 3 1\n3 0 2 3\n3 1 3 2\n",
    )
    .unwrap();
    let spec = t.path().join("spec.json");
    let body = |normals: &str| {
        format!(
            r#"{{"count": 4, "seed": 5, "image_size": 20, "env_size": "8x16", "chunk_size": 2,
               "normals": [{normals}], "envs": [{{"procedural": "overcast"}}],
               "materials": [{{"preset": "gold"}}]}}"#
        )
    };
    std::fs::write(&spec, body(r#"{"mesh": "meshes"}"#)).unwrap();
    assert_shards_agree(&spec, t.path(), &[1, 0]);
    let sp = synth::Spec::load(&spec).unwrap();
    for k in 0..4 {
        let x = sp.sample(k).unwrap();
        let label = x.params["normals"]["mesh"].as_str().unwrap().to_string();
        assert!(label.starts_with("meshes/tet."), "{label}");
        let fg = foreground(&x.scene.normals);
        assert!(fg > 20, "sample {k}: {fg} foreground pixels");
    }
    std::fs::write(meshes.join("bad.obj"), "v 0 0 0\nf 1 2 3\n").unwrap();
    let o = synth_cmd(&spec, &t.path().join("bad"), &[])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("normals[0]") && err.contains("bad.obj"),
        "{err}"
    );
}

#[test]
fn a_crease_keeps_a_mesh_s_edges_sharp() {
    // a cube whose faces share their eight corners (as CGAL's cube.off): its smooth normals
    // bend across every face; with "crease" each visible face has one normal
    let t = dir();
    std::fs::write(
        t.path().join("cube.off"),
        "OFF\n8 6 0\n-1 -1 -1\n1 -1 -1\n1 1 -1\n-1 1 -1\n-1 -1 1\n1 -1 1\n1 1 1\n-1 1 1\n\
         4 0 3 2 1\n4 4 5 6 7\n4 0 1 5 4\n4 2 3 7 6\n4 1 2 6 5\n4 0 4 7 3\n",
    )
    .unwrap();
    let spec = t.path().join("spec.json");
    let write = |extra: &str| {
        let body = format!(
            r#"{{"count": 2, "seed": 5, "image_size": 24, "env_size": "8x16",
               "normals": [{{"mesh": "cube.off", "views": [[35, 25, 0]]{extra}}}],
               "envs": [{{"procedural": "overcast"}}], "materials": [{{"preset": "gold"}}]}}"#
        );
        std::fs::write(&spec, body).unwrap();
    };
    let distinct = |extra: &str| {
        write(extra);
        let x = synth::Spec::load(&spec).unwrap().sample(0).unwrap();
        let mut seen: Vec<[i32; 3]> = (x.scene.normals.normals.iter())
            .filter(|n| n.iter().any(|&c| c != 0.0))
            .map(|n| n.map(|c| (c * 1000.0).round() as i32))
            .collect();
        seen.sort_unstable();
        seen.dedup();
        let on = (x.scene.normals.normals.iter()).filter(|n| n.iter().any(|&c| c != 0.0));
        (seen.len(), on.count())
    };
    let (smooth, fg) = distinct("");
    let (creased, fg_creased) = distinct(r#", "crease": 40"#);
    assert_eq!(fg, fg_creased, "the same silhouette");
    assert!(smooth > 50, "{smooth} distinct smooth normals");
    assert!(
        creased <= 3,
        "{creased} distinct normals on three visible faces"
    );
    for (extra, what) in [
        (
            r#", "crease": 0"#,
            "crease: 0 is not an angle in (0, 180] degrees",
        ),
        (
            r#", "crease": 200"#,
            "crease: 200 is not an angle in (0, 180] degrees",
        ),
    ] {
        write(extra);
        let o = synth_cmd(&spec, &t.path().join("bad"), &[])
            .output()
            .unwrap();
        let err = String::from_utf8_lossy(&o.stderr);
        assert_eq!(o.status.code(), Some(2), "{err}");
        assert!(err.contains("normals[0]") && err.contains(what), "{err}");
        assert_eq!(err.trim().lines().count(), 1, "{err}");
    }
    std::fs::write(
        &spec,
        r#"{"count": 2, "image_size": 24, "env_size": "8x16",
            "normals": [{"shape": "box", "crease": 30}],
            "envs": [{"procedural": "overcast"}], "materials": [{"preset": "gold"}]}"#,
    )
    .unwrap();
    let o = synth_cmd(&spec, &t.path().join("bad2"), &[])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("\"crease\" goes with \"mesh\" only"), "{err}");
}
