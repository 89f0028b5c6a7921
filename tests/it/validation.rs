//! The library's input validation: each invalid input is a typed error whose message names
//! the input and the item.

use matedit::{Batch, Camera, Convention, EnvMap, Error, Image, Material, NormalMap, Scene};

fn msg<T: std::fmt::Debug>(r: Result<T, Error>) -> String {
    let e = r.expect_err("must be invalid");
    assert!(e.is_input_error(), "{e:?} should be an input error");
    e.to_string()
}

fn scene() -> Scene {
    Scene {
        normals: NormalMap::sphere(4),
        env: EnvMap::constant(2, 4, Convention::Equirect, [1.0; 3]).unwrap(),
        material: Material::constant("m", [(0.5, 0.0), (1.0, 10.0), (0.0, 0.0)]).unwrap(),
        camera: Camera::Orthographic,
    }
}

#[test]
fn normals_name_the_pixel() {
    let mut n = vec![[0.0, 0.0, 1.0]; 12];
    n[4 * 2 + 3] = [f32::NAN, 0.0, 1.0];
    assert_eq!(msg(NormalMap::new(4, 3, n)), "normals: pixel (3, 2) is NaN");
    assert!(
        msg(NormalMap::new(4, 3, vec![[0.0; 3]; 11])).contains("11 pixels given for a 4x3 map")
    );
}

#[test]
fn materials_name_the_control_point() {
    let mut ctrl = Material::constant("m", [(0.5, 1.0); 3]).unwrap().ctrl;
    ctrl[matedit::material::idx(0, 0, 1, 1)] = -0.5; // idx 7: channel R, lobe 0, exponent, point 1
    assert_eq!(
        msg(Material::new("m", &ctrl)),
        "material: exponent control point idx 7 is -0.5; exponents must be >= 0"
    );
    assert!(msg(Material::new("m", &ctrl[..107])).contains("107 control points given"));
    let mut big = Material::constant("m", [(0.5, 1.0); 3]).unwrap().ctrl;
    big[0] = 41.0;
    assert!(msg(Material::new("m", &big)).contains("scale control point idx 0 is 41"));
}

#[test]
fn env_maps_name_the_texel() {
    let mut t = vec![[1.0f32; 3]; 8];
    t[5] = [1.0, -0.25, 1.0];
    assert_eq!(
        msg(EnvMap::new(2, 4, Convention::Equirect, t.clone())),
        "env: texel (row 1, column 1) channel G is -0.25; radiance must be >= 0 (loaders clamp negative texels)"
    );
    assert_eq!(EnvMap::clamp_negative(&mut t), 1);
    assert!(EnvMap::new(2, 4, Convention::Equirect, t).is_ok());
}

#[test]
fn cameras_and_batches_are_checked() {
    let mut s = scene();
    s.camera = Camera::Perspective { fov_y_deg: 180.0 };
    assert!(msg(Batch::single(s)).contains("field of view 180"));
    let mut other = scene();
    other.normals = NormalMap::sphere(5);
    assert!(
        msg(Batch::new(vec![scene(), other])).starts_with("batch: scene 1 differs from scene 0")
    );
    assert!(msg(Batch::new(vec![])).contains("at least one scene"));
}

#[test]
fn upstream_gradients_are_checked() {
    let batch = Batch::single(scene()).unwrap();
    let r = matedit::Renderer::new(matedit::Device::Cpu).unwrap();
    assert!(msg(r.backward(&batch, &[])).contains("0 images given for a batch of 1"));
    let mut up = Image::zeros(4, 4);
    up.pixels[6] = [0.0, f32::INFINITY, 0.0];
    assert_eq!(
        msg(r.backward(&batch, &[up])),
        "upstream: image 0 pixel (2, 1) is not finite"
    );
    assert!(msg(r.backward(&batch, &[Image::zeros(3, 4)])).contains("is 3x4"));
}
