//! The brute-force renderer of any isotropic BRDF against the DSBRDF layer: with a DSBRDF
//! material as the BRDF, both must give the same image, since the one sums f over
//! Rusinkiewicz angles and the other evaluates the layer's own formulas.

use matedit::brdf::Isotropic;
use matedit::brdf::render::render_measured;
use matedit::{Batch, Camera, Convention, Device, EnvMap, Material, NormalMap, Renderer, Scene};

/// A small map with light everywhere and a bright patch.
fn env(convention: Convention) -> EnvMap {
    let (h, w) = (8, 16);
    let texels = (0..h * w)
        .map(|i| {
            let (r, c) = (i / w, i % w);
            let base = 0.2 + 0.05 * ((r * 7 + c * 3) % 5) as f32;
            if (r, c) == (2, 5) {
                [30.0, 20.0, 10.0]
            } else {
                [base, base * 0.8, base * 0.6]
            }
        })
        .collect();
    EnvMap::new(h, w, convention, texels).unwrap()
}

/// Within 2e-5 of the image's peak: the layer takes the f32 normals as given, this
/// renderer normalises them, and exponents up to 1e4 amplify that difference.
fn compare(material: Material, convention: Convention) {
    let normals = NormalMap::sphere(16);
    let env = env(convention);
    let measured = render_measured(&material, &normals, &env, Camera::Orthographic).unwrap();
    let scene = Scene {
        normals: normals.clone(),
        env,
        material,
        camera: Camera::Orthographic,
    };
    let layer = Renderer::new(Device::Reference)
        .unwrap()
        .render(&Batch::single(scene).unwrap())
        .unwrap()
        .remove(0);
    let peak = layer.max_value() as f64;
    assert!(peak > 0.0);
    for (i, (a, b)) in measured.pixels.iter().zip(&layer.pixels).enumerate() {
        if normals.normals[i][2] <= 1e-3 {
            continue;
        }
        for k in 0..3 {
            let d = (f64::from(a[k]) - f64::from(b[k])).abs();
            assert!(
                d <= 2e-5 * peak,
                "pixel {i} channel {k}: {} vs {}",
                a[k],
                b[k]
            );
        }
    }
}

#[test]
fn agrees_with_the_layer_on_dsbrdf_materials() {
    for convention in [Convention::Equirect, Convention::Paper] {
        compare(
            Material::constant("c", [(0.3, 0.0), (1.5, 30.0), (0.2, 3.0)]).unwrap(),
            convention,
        );
        compare(matedit::presets::lookup("plastic-red").unwrap(), convention);
        compare(
            matedit::presets::lookup("gold-metallic-paint").unwrap(),
            convention,
        );
    }
}

/// A Lambertian BRDF rho / pi under a constant unit map gives rho on every pixel that
/// sees the whole upper hemisphere, up to the map's quadrature error.
#[test]
fn lambertian_under_uniform_light() {
    struct Lambert;
    impl Isotropic for Lambert {
        fn eval(&self, _: f64, _: f64, _: f64) -> [f64; 3] {
            [0.5 / std::f64::consts::PI; 3]
        }
    }
    let normals = NormalMap::sphere(9);
    let env = EnvMap::constant(64, 128, Convention::Equirect, [1.0; 3]).unwrap();
    let img = render_measured(&Lambert, &normals, &env, Camera::Orthographic).unwrap();
    let centre = img.pixels[4 * 9 + 4];
    assert!((centre[0] - 0.5).abs() < 5e-3, "{centre:?}");
    assert_eq!(img.pixels[0], [0.0; 3], "background");
}
