//! Analytic values on the reference and every backend: a constant light with a lobe of
//! exponent 0, and one lobe against quadrature.

use super::backends;
use crate::common::{assert_close, flat32};
use matedit::prepare::Prepared;
use matedit::{Batch, Camera, Convention, EnvMap, Material, NormalMap, Scene, reference};

/// Constant light L = 1 and one lobe of exponent 0: f = e^m0 - 1 everywhere, so
/// I = (e^m0 - 1) sum_i max(0, n.w_i) d_omega_i, which is pi (e^m0 - 1) in the limit;
/// within 0.1% at 64 x 128 equirect, for a normal facing the camera and at the centre of a
/// 16 x 16 sphere.
#[test]
fn constant_light_exponent_zero() {
    let m0: f64 = 0.7;
    let want = std::f64::consts::PI * m0.exp_m1();
    let scene = |normals: NormalMap| Scene {
        normals,
        env: EnvMap::constant(64, 128, Convention::Equirect, [1.0; 3]).unwrap(),
        material: Material::constant("flat", [(m0, 0.0), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
        camera: Camera::Orthographic,
    };
    let facing = scene(NormalMap::new(1, 1, vec![[0.0, 0.0, 1.0]]).unwrap());
    let img = reference::forward(&Prepared::new(&facing));
    assert_close("I (reference)", &img[0], &[want; 3], 0.0, 1e-3);
    let facing = Batch::single(facing).unwrap();
    let sphere = Batch::single(scene(NormalMap::sphere(16))).unwrap();
    for u in backends("constant_light_exponent_zero") {
        let img = u.backend.render((&facing).into()).unwrap();
        let what = format!("I ({})", u.name);
        assert_close(&what, &flat32(&img[0].pixels), &[want; 3], 0.0, 1e-3);
        let img = u.backend.render((&sphere).into()).unwrap();
        let centre = f64::from(img[0].pixels[8 * 16 + 8][0]);
        assert!(
            (centre / want - 1.0).abs() < 1e-3,
            "{what}, sphere centre: {centre} vs {want}"
        );
    }
}

/// One lobe (kappa, gamma constant over theta_d) under L = 1 seen along its normal:
/// with n = w_p = z, x = n.h = cos(theta / 2), so
/// I = 2 pi int_0^{pi/2} (exp(kappa cos(theta/2)^gamma) - 1) cos(theta) sin(theta) dtheta,
/// integrated here by composite Simpson with 20000 intervals (independent of the layer's
/// texel sums).
fn one_lobe_quadrature(kappa: f64, gamma: f64) -> f64 {
    let n = 20000;
    let h = std::f64::consts::FRAC_PI_2 / n as f64;
    let f = |t: f64| ((kappa * (t / 2.0).cos().powf(gamma)).exp() - 1.0) * t.cos() * t.sin();
    let mut s = f(0.0) + f(std::f64::consts::FRAC_PI_2);
    for i in 1..n {
        s += f(i as f64 * h) * if i % 2 == 1 { 4.0 } else { 2.0 };
    }
    2.0 * std::f64::consts::PI * s * h / 3.0
}

fn one_lobe_scene(kappa: f64, gamma: f64, hl: usize) -> Scene {
    Scene {
        normals: NormalMap::new(1, 1, vec![[0.0, 0.0, 1.0]]).unwrap(),
        env: EnvMap::constant(hl, 2 * hl, Convention::Equirect, [1.0; 3]).unwrap(),
        material: Material::constant("one lobe", [(kappa, gamma), (0.0, 0.0), (0.0, 0.0)]).unwrap(),
        camera: Camera::Orthographic,
    }
}

#[test]
fn one_lobe_against_quadrature() {
    let (kappa, gamma) = (1.5, 8.0);
    let want = one_lobe_quadrature(kappa, gamma);
    // 64 x 128: the midpoint rule over texels is within 0.2%; at 256 x 512 within 0.02%
    for (hl, rel) in [(64, 2e-3), (256, 2e-4)] {
        let img = reference::forward(&Prepared::new(&one_lobe_scene(kappa, gamma, hl)));
        let what = format!("one lobe reference {hl}");
        assert_close(&what, &[img[0][0]], &[want], 0.0, rel);
    }
    let batch = Batch::single(one_lobe_scene(kappa, gamma, 64)).unwrap();
    for u in backends("one_lobe_against_quadrature") {
        let img = u.backend.render((&batch).into()).unwrap();
        let got = f64::from(img[0].pixels[0][0]);
        assert_close(
            &format!("one lobe {} 64", u.name),
            &[got],
            &[want],
            0.0,
            2e-3,
        );
    }
}
