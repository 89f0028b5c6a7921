//! Clutter (`"clutter"`): deterministic and shardable; the object's mask and normals those
//! of the same sample without clutter wherever clutter is not seen, and never on clutter;
//! clutter seen beside and behind the object in its own material (the true edit leaves
//! it); bad values refused in one line.
//!
//! Tiny datasets: 32 x 32 shapes on a floor under a constant map, 6 samples.

use std::path::{Path, PathBuf};

use matedit::Device;
use matedit::synth::{self, Engine, Sample, tar};

use super::{assert_shards_agree, dir, npy_rgb};

const CLUTTER: &str = r#""clutter": {"count": [2, 3], "size": [0.5, 0.9],
    "normals": [{"shape": "random"}, {"shape": "blobby", "views": "random"}],
    "materials": [{"preset": "clay"}, {"random": "merl"}]}"#;

/// A spec in `root` named `name` with floors, lit by a constant map of 0.5 (`env.npy`),
/// `extra` keys joined.
fn spec(root: &Path, name: &str, extra: &str) -> PathBuf {
    let texels = vec![[0.5f32; 3]; 8 * 16];
    std::fs::write(
        root.join("env.npy"),
        matedit::io::npy::encode_rgb(16, 8, &texels),
    )
    .unwrap();
    let path = root.join(name);
    let sep = if extra.is_empty() { "" } else { "," };
    std::fs::write(
        &path,
        format!(
            r#"{{"count": 6, "seed": 11, "image_size": 32, "env_size": "8x16", "chunk_size": 3,
  "fov": [35, 50], "elevation": [10, 30], "backgrounds": ["env"],
  "floor": [{{"procedural": "wood"}}, {{"procedural": "tiles"}}],
  "normals": [{{"shape": "random", "views": "upright"}}],
  "envs": [{{"file": "env.npy", "rotate": false}}],
  "materials": [{{"preset": "gold"}}]{sep} {extra}}}"#
        ),
    )
    .unwrap();
    path
}

fn engine() -> Engine {
    Engine::new(Device::Cpu).unwrap()
}

/// Sample `k` with its clutter painted into its background.
fn painted(sp: &synth::Spec, k: u64, e: &Engine) -> Sample {
    let mut x = sp.sample(k).unwrap();
    x.paint_clutter(&e.renderer).unwrap();
    x
}

/// Whether some object of the clutter is seen at pixel `i`.
fn clutter_at(x: &Sample, i: usize) -> bool {
    x.clutter.iter().any(|l| l.normals.normals[i] != [0.0; 3])
}

#[test]
fn clutter_is_deterministic_and_shards_agree() {
    let t = dir();
    let sp_path = spec(
        t.path(),
        "spec.json",
        &format!(r#""shadows": true, {CLUTTER}"#),
    );
    assert_shards_agree(&sp_path, t.path(), &[1, 0]);
    let sp = synth::Spec::load(&sp_path).unwrap();
    let e = engine();
    for k in 0..6 {
        let (a, b) = (painted(&sp, k, &e), painted(&sp, k, &e));
        assert_eq!(a.params, b.params);
        assert_eq!(a.background, b.background);
        assert_eq!(a.scene.normals.normals, b.scene.normals.normals);
        let objects = a.params["clutter"]["objects"].as_array().unwrap();
        assert_eq!(objects.len(), a.clutter.len());
        for o in objects {
            // beside or behind the object, never in front of it
            let angle = o["angle"].as_f64().unwrap();
            assert!(angle.abs() <= 90.0, "{o}");
        }
        for l in &a.clutter {
            let shade = l.shade.as_ref().expect("shadows on: a shade");
            assert!(shade.iter().all(|s| (0.0..=1.0).contains(s)));
        }
    }
}

#[test]
fn the_object_is_unchanged_where_clutter_is_not_and_clutter_shows() {
    let t = dir();
    let with = synth::Spec::load(&spec(t.path(), "with.json", CLUTTER)).unwrap();
    let without = synth::Spec::load(&spec(t.path(), "without.json", "")).unwrap();
    let e = engine();
    let (mut seen, mut hidden, mut differ) = (0, 0, 0);
    for k in 0..6 {
        let (a, b) = (painted(&with, k, &e), painted(&without, k, &e));
        // the other draws are the spec's without clutter
        let mut p = a.params.clone();
        assert!(p.as_object_mut().unwrap().remove("clutter").is_some());
        assert_eq!(p, b.params);
        let (bg_a, bg_b) = (
            a.background.as_ref().unwrap(),
            b.background.as_ref().unwrap(),
        );
        for i in 0..32 * 32 {
            let (na, nb) = (a.scene.normals.normals[i], b.scene.normals.normals[i]);
            assert_eq!(a.mask[i], na != [0.0; 3]);
            if clutter_at(&a, i) {
                // the mask never covers clutter; the object is hidden where clutter is
                // nearer
                assert!(!a.mask[i] && na == [0.0; 3], "sample {k} pixel {i}");
                seen += 1;
                hidden += usize::from(b.mask[i]);
                differ += usize::from(bg_a[i] != bg_b[i]);
            } else {
                // without shadows, the floor and the map are what they were
                assert_eq!((a.mask[i], na), (b.mask[i], nb), "sample {k} pixel {i}");
                if !a.mask[i] {
                    assert_eq!(bg_a[i], bg_b[i], "sample {k} pixel {i}");
                }
            }
        }
    }
    // clutter shows, in colours of its own, mostly off the object
    assert!(seen > 100, "{seen} clutter pixels in 6 samples");
    assert!(differ * 10 > seen * 9, "{differ} of {seen} differ");
    assert!(
        hidden * 5 < seen,
        "{hidden} of {seen} clutter pixels hide the object"
    );
}

#[test]
fn the_true_edit_changes_the_object_only() {
    let t = dir();
    let sp = synth::Spec::load(&spec(
        t.path(),
        "spec.json",
        &format!(r#"{CLUTTER}, "edit": {{"materials": [{{"preset": "clay"}}]}}"#),
    ))
    .unwrap();
    let bytes = synth::render_chunk(&sp, &engine(), 0, &|_| {}).unwrap();
    let members = tar::decode(&bytes).unwrap();
    let get = |k: usize, suffix: &str| -> &[u8] {
        let name = format!("{k:08}.{suffix}");
        &members.iter().find(|(n, _)| *n == name).unwrap().1
    };
    let mut clutter_pixels = 0;
    for k in 0..3 {
        let (_, _, image) = npy_rgb(get(k, "image.npy"));
        let (_, _, edit) = npy_rgb(get(k, "edit.npy"));
        let x = sp.sample(k as u64).unwrap();
        for i in 0..32 * 32 {
            if !x.mask[i] {
                assert_eq!(image[i], edit[i], "sample {k} pixel {i}");
            }
            clutter_pixels += usize::from(clutter_at(&x, i));
        }
    }
    assert!(clutter_pixels > 0);
}

#[test]
fn bad_clutter_is_refused_in_one_line() {
    for (extra, expect) in [
        (
            r#""clutter": {"count": [3, 1]}"#,
            "spec.json: clutter.count: [3,1]: expected a whole number or [LO, HI]",
        ),
        (r#""clutter": {"count": 9}"#, "spec.json: clutter.count: 9:"),
        (
            r#""clutter": {"count": 1.5}"#,
            "spec.json: clutter.count: 1.5:",
        ),
        (
            r#""clutter": {"size": [0, 1]}"#,
            "spec.json: clutter.size: [0,1]:",
        ),
        (
            r#""clutter": {"amount": 2}"#,
            "spec.json: clutter.amount: unknown field `amount`",
        ),
        (
            r#""clutter": {"normals": [{"sphere": 32}]}"#,
            "spec.json: clutter.normals[0]: not a shape or a mesh",
        ),
        (
            r#""clutter": {"normals": []}"#,
            "spec.json: clutter.normals: the list is empty",
        ),
        (
            r#""clutter": {"materials": [{"preset": "golden"}]}"#,
            "spec.json: clutter.materials[0]: unknown preset 'golden'",
        ),
        (
            r#""clutter": {"normals": [{"mesh": "nowhere.obj"}]}"#,
            "spec.json: clutter.normals[0]: mesh:",
        ),
    ] {
        let t = dir();
        let e = synth::Spec::load(&spec(t.path(), "spec.json", extra))
            .expect_err(extra)
            .to_string();
        assert!(e.contains(expect), "{extra}: expected '{expect}' in: {e}");
        assert_eq!(e.lines().count(), 1, "{e}");
    }
    // no floor: the spec of photo.rs's kind without one
    let t = dir();
    let path = t.path().join("spec.json");
    std::fs::write(
        &path,
        r#"{"count": 1, "image_size": 16, "fov": 40, "normals": [{"shape": "random"}],
            "envs": [{"procedural": "sun-sky"}], "materials": [{"preset": "gold"}],
            "clutter": {"count": 2}}"#,
    )
    .unwrap();
    let e = synth::Spec::load(&path).expect_err("no floor").to_string();
    assert!(e.contains("spec.json: clutter: needs a \"floor\""), "{e}");
    assert_eq!(e.lines().count(), 1, "{e}");
}
