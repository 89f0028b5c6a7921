//! `matedit::nets` against PyTorch: tests/data/nets/ holds a small `Nets(NetsConfig(width=8,
//! levels=2, env_height=8, env_width=16))` saved by `matedit.nets.save` and PyTorch's
//! predictions on five images (16 x 16, 12 x 20, 8 x 10; with and without a mask; a black
//! object) (python/examples/nets/parity_data.py writes both). The Rust
//! predictions must match within 1e-4; bad weight files must give one-line errors naming
//! the file and the tensor.

use crate::common;

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use common::assert_close;
use matedit::Image;
use matedit::nets::{Frame, Nets, NetsConfig};
use safetensors::SafeTensors;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/nets")
        .join(name)
}

/// Every tensor of a safetensors file as f64 values with its shape.
fn read_all(path: &Path) -> HashMap<String, (Vec<usize>, Vec<f64>)> {
    let bytes = std::fs::read(path).expect("reads the test data");
    let st = SafeTensors::deserialize(&bytes).expect("safetensors");
    st.tensors()
        .into_iter()
        .map(|(name, v)| {
            let d = v.data();
            let values: Vec<f64> = match v.dtype() {
                safetensors::Dtype::F32 => d
                    .chunks_exact(4)
                    .map(|b| f64::from(f32::from_le_bytes(b.try_into().unwrap())))
                    .collect(),
                safetensors::Dtype::F64 => d
                    .chunks_exact(8)
                    .map(|b| f64::from_le_bytes(b.try_into().unwrap()))
                    .collect(),
                safetensors::Dtype::U8 => d.iter().map(|&b| f64::from(b)).collect(),
                t => panic!("{name}: dtype {t:?}"),
            };
            (name, (v.shape().to_vec(), values))
        })
        .collect()
}

/// RGB or xyz values as one f64 slice.
fn widen(v: &[[f32; 3]]) -> Vec<f64> {
    v.as_flattened().iter().map(|&x| f64::from(x)).collect()
}

/// The largest difference, relative to |b| (at least 1) with `relative`.
fn max_diff(a: &[f64], b: &[f64], relative: bool) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs() / if relative { y.abs().max(1.0) } else { 1.0 })
        .fold(0.0, f64::max)
}

/// Tolerance of every comparison with PyTorch: both run float32, in a different order of
/// summation (convolutions, group norm means); 1e-4 absolute, and 1e-4 relative for the
/// light, whose texels are exp of the net's output times the image's scale.
const TOL: f64 = 1e-4;

#[test]
fn predictions_match_pytorch() {
    let nets = Nets::load(&data("weights.safetensors")).expect("loads the weights");
    assert_eq!(
        nets.config(),
        NetsConfig {
            width: 8,
            levels: 2,
            env_height: 8,
            env_width: 16,
            basis: 90,
            image_size: 64,
            frame: Frame::Square,
        }
    );
    check_cases(
        &nets,
        &data("parity.safetensors"),
        &[
            "masked",
            "unmasked",
            "square",
            "wide_masked",
            "black",
            "unmasked_mirror",
            "wide_masked_mirror",
        ],
    );
}

/// The built-in nets (data/nets/weights.safetensors) against PyTorch's `matedit.nets.load()`
/// on five samples of the committed held-out set (python/tests/data/nets_card), four with
/// their masks (`parity_data.py --shipped`).
#[test]
fn builtin_predictions_match_pytorch() {
    let nets = Nets::builtin().expect("the built-in weights load");
    check_cases(
        &nets,
        &data("shipped_parity.safetensors"),
        &["sample0", "sample1", "sample2", "sample3", "sample4"],
    );
}

/// `nets`' predictions on every case of `file` against PyTorch's, within [`TOL`].
fn check_cases(nets: &Nets, file: &Path, cases: &[&str]) {
    let all = read_all(file);
    for &case in cases {
        let get = |k: &str| &all[&format!("{case}.{k}")];
        let image = case_image(&all, case);
        let mask_in: Option<Vec<bool>> = all
            .get(&format!("{case}.mask_in"))
            .map(|(_, m)| m.iter().map(|&v| v != 0.0).collect());
        let mirror = case.ends_with("_mirror");
        let p = nets
            .predict_with(&image, mask_in.as_deref(), mirror)
            .expect("predicts");

        let mask: Vec<bool> = get("mask").1.iter().map(|&v| v != 0.0).collect();
        let flips = p.mask.iter().zip(&mask).filter(|(a, b)| a != b).count();
        assert_eq!(
            flips, 0,
            "{case}: {flips} mask pixels differ from PyTorch's"
        );
        let prob: Vec<f64> = p.mask_prob.iter().map(|&v| f64::from(v)).collect();
        let normals = widen(&p.normals.normals);
        let env = widen(&p.env.texels);
        // the figures docs/nets.md quotes (`cargo test --release --test nets -- --nocapture`)
        println!(
            "{case}: max |diff| mask_prob {:.1e}, normals {:.1e}, env {:.1e}, ctrl {:.1e} (relative)",
            max_diff(&prob, &get("mask_prob").1, false),
            max_diff(&normals, &get("normals").1, false),
            max_diff(&env, &get("env").1, true),
            max_diff(&p.material.ctrl, &get("ctrl").1, true),
        );
        assert_close(
            &format!("{case} mask_prob"),
            &prob,
            &get("mask_prob").1,
            TOL,
            0.0,
        );
        assert_close(
            &format!("{case} normals"),
            &normals,
            &get("normals").1,
            TOL,
            0.0,
        );
        assert_eq!(
            (p.env.height, p.env.width),
            (get("env").0[0], get("env").0[1])
        );
        assert_close(&format!("{case} env"), &env, &get("env").1, TOL, TOL);
        assert_close(
            &format!("{case} ctrl"),
            &p.material.ctrl,
            &get("ctrl").1,
            TOL,
            TOL,
        );
        // the test means something: every case has an object and a background
        assert!(
            mask.iter().any(|&m| m) && mask.iter().any(|&m| !m),
            "{case}"
        );
        assert!(
            p.normals.normals[0] == [0.0; 3],
            "{case}: a corner is background"
        );
        if case == "black" {
            assert_eq!(p.scale, 1.0, "a black object keeps its image");
        }
    }
}

/// Case `case`'s input image in a parity file read by [`read_all`].
fn case_image(all: &HashMap<String, (Vec<usize>, Vec<f64>)>, case: &str) -> Image {
    let (shape, pixels) = &all[&format!("{case}.image")];
    Image {
        width: shape[1],
        height: shape[0],
        pixels: pixels
            .chunks_exact(3)
            .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
            .collect(),
    }
}

/// The test weights rewritten with `edit` applied to their tensors and metadata.
fn rewritten(
    dir: &Path,
    name: &str,
    edit: impl FnOnce(&mut common::Tensors, &mut HashMap<String, String>),
) -> PathBuf {
    let bytes = std::fs::read(data("weights.safetensors")).unwrap();
    common::rewritten_weights(&bytes, &dir.join(name), edit)
}

fn load_error(path: &Path) -> String {
    match Nets::load(path) {
        Ok(_) => panic!("{} loaded", path.display()),
        Err(e) => {
            let msg = e.to_string();
            assert!(!msg.contains('\n'), "one line: {msg}");
            assert!(
                msg.contains(&path.display().to_string()),
                "names the file: {msg}"
            );
            msg
        }
    }
}

#[test]
fn bad_weight_files_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let missing = rewritten(dir.path(), "missing.safetensors", |t, _| {
        t.retain(|(n, ..)| n != "normals.head.weight")
    });
    let msg = load_error(&missing);
    assert!(
        msg.contains("tensor normals.head.weight is missing"),
        "{msg}"
    );

    let shape = rewritten(dir.path(), "shape.safetensors", |t, _| {
        let e = t
            .iter_mut()
            .find(|(n, ..)| n == "light.net.head.2.bias")
            .unwrap();
        e.2 = vec![e.2[0] / 2];
        e.3.truncate(e.3.len() / 2);
    });
    let msg = load_error(&shape);
    assert!(
        msg.contains("tensor light.net.head.2.bias: shape [192], expected [384]"),
        "{msg}"
    );

    let extra = rewritten(dir.path(), "extra.safetensors", |t, _| {
        t.push((
            "normals.extra".into(),
            safetensors::Dtype::F32,
            vec![1],
            vec![0; 4],
        ))
    });
    let msg = load_error(&extra);
    assert!(
        msg.contains("tensor normals.extra is not part of the nets"),
        "{msg}"
    );

    let config = rewritten(dir.path(), "config.safetensors", |_, m| {
        m.insert("config".into(), r#"{"width": -8, "levels": 2}"#.into());
    });
    let msg = load_error(&config);
    assert!(
        msg.contains("metadata config: invalid value: integer `-8`"),
        "{msg}"
    );

    let huge = rewritten(dir.path(), "huge.safetensors", |_, m| {
        m.insert(
            "config".into(),
            r#"{"width": 8, "levels": 2, "env_height": 1e20}"#.into(),
        );
    });
    let msg = load_error(&huge);
    assert!(msg.contains("metadata config:"), "{msg}");

    let wide = rewritten(dir.path(), "wide.safetensors", |_, m| {
        let big = usize::MAX / 2;
        m.insert(
            "config".into(),
            format!(r#"{{"width": {big}, "levels": 2}}"#),
        );
    });
    let msg = load_error(&wide);
    assert!(msg.contains("is too large"), "{msg}");

    // the size the nets were trained at: what photos are analysed at; 64 when not given
    let sized = |name: &str, size: usize| {
        rewritten(dir.path(), name, |_, m| {
            m.insert(
                "config".into(),
                format!(
                    r#"{{"width": 8, "levels": 2, "env_height": 8, "env_width": 16, "image_size": {size}}}"#
                ),
            );
        })
    };
    assert_eq!(
        Nets::load(&sized("s128.safetensors", 128))
            .unwrap()
            .image_size(),
        128
    );
    assert_eq!(
        Nets::load(&data("weights.safetensors"))
            .unwrap()
            .image_size(),
        64
    );
    // how the nets saw whole photos: square frames unless the metadata says "photo"
    let framed = |name: &str, frame: &str| {
        rewritten(dir.path(), name, |_, m| {
            m.insert(
                "config".into(),
                format!(
                    r#"{{"width": 8, "levels": 2, "env_height": 8, "env_width": 16, "frame": "{frame}"}}"#
                ),
            );
        })
    };
    let photo = Nets::load(&framed("photo.safetensors", "photo")).unwrap();
    assert_eq!(photo.config().frame, Frame::Photo);
    let msg = load_error(&framed("round.safetensors", "round"));
    assert!(
        msg.contains("metadata config: unknown variant `round`, expected `square` or `photo`"),
        "{msg}"
    );
    let msg = load_error(&sized("odd.safetensors", 63));
    assert!(
        msg.contains("image_size 63 is not a multiple of 2^(levels - 1)"),
        "{msg}"
    );

    let format = rewritten(dir.path(), "format.safetensors", |_, m| {
        m.insert("format".into(), "matedit-nets 2".into());
    });
    let msg = load_error(&format);
    assert!(
        msg.contains(r#"metadata format Some("matedit-nets 2")"#),
        "{msg}"
    );

    let text = dir.path().join("text.safetensors");
    std::fs::write(&text, "not weights at all").unwrap();
    let msg = load_error(&text);
    assert!(msg.contains("not a safetensors file"), "{msg}");

    let none = dir.path().join("absent.safetensors");
    load_error(&none);

    // a safetensors file of other tensors: its metadata has no matedit format
    let msg = load_error(&data("parity.safetensors"));
    assert!(msg.contains("not matedit nets weights"), "{msg}");
}

#[test]
fn bad_inputs_are_refused() {
    let nets = Nets::load(&data("weights.safetensors")).unwrap();
    let odd = Image::zeros(9, 8);
    let e = nets.predict(&odd, None).unwrap_err().to_string();
    assert!(e.contains("image: size 9x8"), "{e}");
    let mut nan = Image::zeros(8, 8);
    nan.pixels[10][1] = f32::NAN;
    let e = nets.predict(&nan, None).unwrap_err().to_string();
    assert!(e.contains("image: pixel (2, 1)"), "{e}");
    let e = nets
        .predict(&Image::zeros(8, 8), Some(&[true; 10]))
        .unwrap_err()
        .to_string();
    assert!(e.contains("mask: 10 values, expected 64"), "{e}");
}

/// `mask_prob` is `predict`'s mask probability without the material and light nets, with
/// and without a mask, mirrored or not.
#[test]
fn mask_prob_is_the_prediction_s() {
    let all = read_all(&data("parity.safetensors"));
    let disc: Vec<bool> = all["masked.mask_in"].1.iter().map(|&v| v != 0.0).collect();
    for mirror in [false, true] {
        let nets = Nets::load(&data("weights.safetensors"))
            .expect("loads the weights")
            .with_mirror(mirror);
        for (case, mask) in [("masked", Some(&disc[..])), ("unmasked", None)] {
            let img = case_image(&all, case);
            let p = nets.predict(&img, mask).expect("predicts");
            let prob = nets.mask_prob(&img, mask).expect("predicts");
            assert_eq!(prob, p.mask_prob, "{case}, mirror {mirror}");
        }
    }
}
