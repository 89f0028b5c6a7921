//! Validators accept exactly the valid inputs, loaders exactly the documented values;
//! what they accept renders finite.

use matedit::envmap::MAX_RADIANCE;
use matedit::io::{self, npy};
use matedit::scene::MAX_NORMAL_LENGTH;
use matedit::{Batch, Camera, Convention, Device, EnvMap, Material, NormalMap, Renderer, Scene};
use proptest::prelude::*;
use proptest::sample::{Index, select};
use proptest::test_runner::TestCaseError;

use crate::binary_files::{npy_bytes, npy_data, npy_header};
use crate::clean;
use crate::json_files::{valid_ctrl, valid_material};
use crate::mutations::value;

fn valid_scale(v: f64) -> bool {
    v.is_finite() && v.abs() <= 40.0
}
fn valid_exponent(v: f64) -> bool {
    v.is_finite() && (0.0..=1.0e4).contains(&v)
}
fn valid_normal(n: [f32; 3]) -> bool {
    n.iter().all(|v| v.is_finite())
        && n.iter()
            .map(|&v| f64::from(v) * f64::from(v))
            .sum::<f64>()
            .sqrt()
            <= MAX_NORMAL_LENGTH
}
fn valid_radiance(v: f32) -> bool {
    v.is_finite() && (0.0..=MAX_RADIANCE).contains(&v)
}
fn valid_fov(f: f64) -> bool {
    f.is_finite() && f > 0.0 && f < 180.0
}

/// A valid material with a few control points set to arbitrary values, and a length that
/// is sometimes not 108.
fn any_ctrl() -> impl Strategy<Value = Vec<f64>> {
    (
        valid_ctrl(),
        prop::collection::vec((any::<Index>(), value()), 0..3),
        prop_oneof![8 => Just(108usize), 1 => select(&[0usize, 107, 109][..])],
    )
        .prop_map(|(mut c, edits, len)| {
            for (i, v) in edits {
                let k = i.index(c.len());
                c[k] = v;
            }
            c.resize(len, 0.5);
            c
        })
}

/// A normal: unit, background, a hair longer than the limit or within it, or arbitrary.
fn any_normal() -> impl Strategy<Value = [f32; 3]> + Clone {
    let unit = (0.0..std::f64::consts::TAU, -1.0..1.0f64).prop_map(|(phi, z)| {
        let r = (1.0 - z * z).sqrt();
        [r * phi.cos(), r * phi.sin(), z]
    });
    prop_oneof![
        4 => (unit.clone(), select(&[1.0, 1.0 + 5e-6, 1.0 + 2e-5, 0.5, 100.0][..]))
            .prop_map(|(n, s)| n.map(|v| (v * s) as f32)),
        1 => Just([0.0f32; 3]),
        1 => prop::array::uniform3(value().prop_map(|v| v as f32)),
    ]
}

fn any_texel() -> impl Strategy<Value = [f32; 3]> + Clone {
    prop::array::uniform3(prop_oneof![
        4 => 0.0..10.0f32,
        1 => select(vec![0.0, -0.0, -1e-3, MAX_RADIANCE, MAX_RADIANCE.next_up(), f32::INFINITY, f32::NAN, f32::MAX]),
    ])
}

fn sized<T: std::fmt::Debug + Clone>(
    item: impl Strategy<Value = T> + Clone,
) -> impl Strategy<Value = (usize, usize, Vec<T>)> {
    (
        1usize..4,
        1usize..4,
        prop_oneof![6 => Just(0i32), 1 => -1i32..=1],
    )
        .prop_flat_map(move |(a, b, off)| {
            let n = ((a * b) as i32 + off).max(0) as usize;
            (Just(a), Just(b), prop::collection::vec(item.clone(), n))
        })
}

/// Renders `scene` on the fast CPU path and the reference; both must give finite images.
fn renders_finite(scene: Scene) -> Result<(), TestCaseError> {
    let batch = Batch::single(scene).expect("valid scene");
    for device in [Device::Cpu, Device::Reference] {
        let r = Renderer::new(device).expect("CPU renderer");
        let images = r.render(&batch);
        prop_assert!(images.is_ok(), "{device:?}: {}", images.unwrap_err());
        for img in images.expect("checked") {
            prop_assert!(
                img.pixels.iter().flatten().all(|v| v.is_finite()),
                "{device:?}"
            );
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn validators_accept_exactly_the_valid_scenes(
        ctrl in any_ctrl(),
        (nw, nh, ns) in sized(any_normal()),
        (eh, ew, texels) in sized(any_texel()),
        conv in select(&[Convention::Equirect, Convention::Paper][..]),
        fov in prop::option::of(prop_oneof![1.0..179.0f64, select(&[0.0, 180.0, -1.0, 1e-9, 179.999, f64::NAN, f64::INFINITY][..])]),
    ) {
        let ctrl_ok = ctrl.len() == 108
            && ctrl.iter().enumerate().all(|(i, &v)| {
                if (i / 6) % 2 == 1 { valid_exponent(v) } else { valid_scale(v) }
            });
        let normals_ok = ns.len() == nw * nh && ns.iter().all(|&n| valid_normal(n));
        let env_ok = texels.len() == eh * ew && texels.iter().flatten().all(|&v| valid_radiance(v));
        let camera = fov.map_or(Camera::Orthographic, |f| Camera::Perspective { fov_y_deg: f });
        let camera_ok = fov.is_none_or(valid_fov);

        let m = Material::new("m", &ctrl);
        prop_assert_eq!(m.is_ok(), ctrl_ok, "material {:?}", m.as_ref().err());
        let from_json = io::json::material_from_ctrl("m".into(), &ctrl);
        prop_assert_eq!(from_json.is_ok(), ctrl_ok, "material file {:?}", from_json.err());
        let n = NormalMap::new(nw, nh, ns);
        prop_assert_eq!(n.is_ok(), normals_ok, "normals {:?}", n.as_ref().err());
        let e = EnvMap::new(eh, ew, conv, texels);
        prop_assert_eq!(e.is_ok(), env_ok, "env {:?}", e.as_ref().err());
        prop_assert_eq!(camera.validate().is_ok(), camera_ok);
        for err in [m.as_ref().err(), n.as_ref().err(), e.as_ref().err()].into_iter().flatten() {
            prop_assert!(err.is_input_error() && !err.to_string().contains('\n'), "{err}");
        }
        if let (Ok(material), Ok(normals), Ok(env), true) = (m, n, e, camera_ok) {
            renders_finite(Scene { normals, env, material, camera })?;
        }
    }
}

/// What the loaders must make of an H x W x 3 float64 array.
fn expect_loaded(values: &[[f64; 3]]) -> (bool, bool, bool) {
    let finite = values.iter().flatten().all(|v| v.is_finite());
    let env_ok = finite && values.iter().flatten().all(|&v| (v as f32) <= MAX_RADIANCE);
    let f32_ok = finite && values.iter().flatten().all(|v| v.abs() <= f32::MAX as f64);
    (finite, env_ok, f32_ok)
}

/// |n| (inf past f64's range) and n / |n| (zeros for a zero vector), without overflow in
/// the direction: the components are scaled by the largest first.
fn length(n: [f64; 3]) -> (f64, [f64; 3]) {
    let big = n.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if big == 0.0 {
        return (0.0, [0.0; 3]);
    }
    let s = n.map(|v| v / big);
    let l = s.iter().map(|v| v * v).sum::<f64>().sqrt();
    (big * l, s.map(|v| v / l))
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    /// Float64 files through the file loaders: normals, env maps, images, upstream
    /// gradients and masks are accepted exactly as docs/FORMATS.md says, with the values
    /// it says, and what is accepted renders finite.
    #[test]
    fn loaders_accept_exactly_the_documented_values(
        (h, w, values) in (1usize..4, 1usize..4).prop_flat_map(|(h, w)| {
            (Just(h), Just(w), prop::collection::vec(prop::array::uniform3(value()), h * w))
        }),
        m in valid_material(),
    ) {
        let dir = tempfile::tempdir().expect("temp dir");
        let p = dir.path().join("a.npy");
        let header = npy_header("<f8", "False", &npy::shape_str(&[h, w, 3]));
        std::fs::write(&p, npy_bytes(1, &header, &npy_data("<f8", values.as_flattened())))
            .expect("write");
        let (finite, env_ok, f32_ok) = expect_loaded(&values);

        let n = clean(&p, io::load_normals(&p))?;
        prop_assert_eq!(n.is_some(), finite);
        if let Some(n) = &n {
            for (got, raw) in n.normals.iter().zip(&values) {
                let (len, dir) = length(*raw);
                let g = got.map(f64::from);
                if len < 1e-6 {
                    prop_assert_eq!(*got, [0.0; 3], "{:?}", raw);
                } else {
                    prop_assert!((length(g).0 - 1.0).abs() < 1e-6, "{:?} -> {:?}", raw, got);
                    prop_assert!((0..3).all(|k| (g[k] - dir[k]).abs() < 1e-6), "{:?} -> {:?}", raw, got);
                }
            }
        }
        let e = clean(&p, io::load_env(&p, Convention::Equirect))?;
        prop_assert_eq!(e.is_some(), env_ok);
        if let Some(e) = &e {
            let negative = values.iter().flatten().filter(|&&v| (v as f32) < 0.0).count();
            prop_assert_eq!(e.clamped, negative);
            for (t, raw) in e.env.texels.iter().zip(&values) {
                prop_assert!((0..3).all(|k| t[k].to_bits() == (raw[k] as f32).max(0.0).to_bits()
                    || (t[k] == 0.0 && raw[k] as f32 == 0.0)));
            }
        }
        for (what, r) in [("image", io::load_image(&p)), ("upstream", io::load_upstream(&p))] {
            let img = clean(&p, r)?;
            prop_assert_eq!(img.is_some(), f32_ok, "{}", what);
            if let Some(img) = img {
                prop_assert!(img.pixels.iter().flatten().all(|v| v.is_finite()), "{}", what);
            }
        }
        let mask = clean(&p, io::load_mask(&p))?;
        prop_assert_eq!(mask.is_some(), finite);
        if let Some((_, _, mask)) = mask {
            prop_assert!(mask.iter().zip(&values).all(|(&k, v)| k == (v[0] > 0.5)));
        }
        if let (Some(normals), Some(e)) = (n, e) {
            renders_finite(Scene { normals, env: e.env, material: m, camera: Camera::Orthographic })?;
        }
    }
}
