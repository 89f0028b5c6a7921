//! What the writers write (NPY, EXR, PNG, material JSON) reads back exactly.

use std::path::Path;

use matedit::io::{self, npy};
use proptest::prelude::*;

use crate::json_files::valid_material;

/// Equal bits, or both NaN (widening to f64 and back may quiet a signalling NaN).
fn same(a: f32, b: f32) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn npy_round_trips(
        (shape, data) in prop::collection::vec(0usize..5, 0..4).prop_flat_map(|s| {
            let n = s.iter().product::<usize>();
            (Just(s), prop::collection::vec(any::<f32>(), n))
        })
    ) {
        let a = npy::parse(&npy::encode_f32(&shape, &data)).expect("own file");
        prop_assert_eq!(&a.shape, &shape);
        prop_assert_eq!(a.dtype, npy::Dtype::F32);
        prop_assert_eq!(a.data.len(), data.len());
        for (x, y) in a.data.iter().zip(&data) {
            prop_assert!(same(*x as f32, *y), "{x} vs {y}");
        }
    }

    #[test]
    fn exr_round_trips(
        (w, h, px) in (1usize..9, 1usize..9).prop_flat_map(|(w, h)| {
            (Just(w), Just(h), prop::collection::vec(prop::array::uniform3(any::<f32>()), w * h))
        })
    ) {
        let p = Path::new("in/a.exr");
        let r = io::exr::decode_rgb(p, &io::exr::encode_rgb(w, h, &px).expect("encode"))
            .expect("own file");
        prop_assert_eq!((r.width, r.height), (w, h));
        for (a, b) in r.pixels.iter().zip(&px) {
            prop_assert!((0..3).all(|k| same(a[k] as f32, b[k])), "{a:?} vs {b:?}");
        }
    }

    #[test]
    fn png_round_trips(
        (w, h, data) in (1usize..9, 1usize..9).prop_flat_map(|(w, h)| {
            (Just(w), Just(h), prop::collection::vec(any::<u8>(), 3 * w * h))
        })
    ) {
        let p = Path::new("in/a.png");
        let d = io::png::decode_bytes(p, &io::png::encode_rgb8(w, h, &data).expect("encode"))
            .expect("own file");
        prop_assert_eq!((d.width, d.height, d.channels, d.bit_depth), (w, h, 3, 8));
        prop_assert!(d.samples.iter().map(|&v| v as u8).eq(data.iter().copied()));
    }

    #[test]
    fn material_json_round_trips(m in valid_material(), description in prop::option::of(any::<String>())) {
        let p = Path::new("in/a.json");
        let bytes = io::json::encode_material(&m, description.as_deref());
        let back = io::json::parse_material(p, &bytes).expect("own file");
        prop_assert_eq!(&back.name, &m.name);
        prop_assert!(back.ctrl.iter().zip(&m.ctrl).all(|(a, b)| a.to_bits() == b.to_bits()));
    }
}
