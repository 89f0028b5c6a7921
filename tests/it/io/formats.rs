//! The image formats: NPY and EXR round trips and their refusals (shape, dtype, channels,
//! compressions), DWA files decoded, and the values of a PNG preview.

use exr::prelude::*;
use matedit::io::{self, Preview, Tonemap};
use matedit::{Convention, Image};

use super::{dir, image, msg, patch_compression, write_exr};

#[test]
fn npy_round_trip() {
    let d = dir();
    let p = d.path().join("a.npy");
    let img = image(5, 3);
    io::write_atomic(&p, &io::npy::encode_rgb(5, 3, &img.pixels)).unwrap();
    let r = io::read_raster(&p, "test").unwrap();
    assert_eq!((r.width, r.height), (5, 3));
    for (a, b) in r.pixels.iter().zip(&img.pixels) {
        assert_eq!(a.map(|v| v as f32), *b);
    }
    // The upstream loader keeps the values as they are.
    assert_eq!(io::load_upstream(&p).unwrap(), img);
}

#[test]
fn npy_shape_and_dtype_errors() {
    let d = dir();
    let p = d.path().join("bad.npy");
    std::fs::write(&p, io::npy::encode_f32(&[4, 3], &[0.0; 12])).unwrap();
    let e = msg(io::load_normals(&p).unwrap_err());
    assert!(
        e.contains("bad.npy") && e.contains("(4, 3)") && e.contains("(height, width, 3)"),
        "{e}"
    );
    std::fs::write(&p, b"not numpy").unwrap();
    let e = msg(io::load_normals(&p).unwrap_err());
    assert!(e.contains("not a NumPy"), "{e}");
}

#[test]
fn exr_round_trip_and_f16() {
    let d = dir();
    let p = d.path().join("a.exr");
    let img = image(7, 4);
    io::write_atomic(&p, &io::exr::encode_rgb(7, 4, &img.pixels).unwrap()).unwrap();
    assert_eq!(io::load_upstream(&p).unwrap(), img);

    // Half-float channels are widened.
    let p16 = d.path().join("half.exr");
    let channels = SpecificChannels::rgb(|pos: Vec2<usize>| {
        let v = (pos.x() + 10 * pos.y()) as f32 * 0.5;
        (f16::from_f32(v), f16::from_f32(-v), f16::from_f32(1.0))
    });
    exr::prelude::Image::from_channels((3, 2), channels)
        .write()
        .to_file(&p16)
        .unwrap();
    let r = io::read_raster(&p16, "test").unwrap();
    assert_eq!(r.pixels[4], [5.5, -5.5, 1.0]); // x = 1, y = 1
}

#[test]
fn exr_without_rgb_is_refused() {
    let d = dir();
    let p = d.path().join("depth.exr");
    let channels = SpecificChannels::build()
        .with_channel("Z")
        .with_pixel_fn(|_pos| (1.0f32,));
    exr::prelude::Image::from_channels((2, 2), channels)
        .write()
        .to_file(&p)
        .unwrap();
    let e = msg(io::load_env(&p, Convention::Equirect).unwrap_err());
    assert!(
        e.contains("depth.exr") && e.contains("R, G, B") && e.contains("Z"),
        "{e}"
    );
}

#[test]
fn exr_unsupported_compressions_are_named_with_a_fix() {
    let d = dir();
    let img = image(4, 2);
    for (code, name) in [
        (10u8, "HTJ2K256"),
        (11, "HTJ2K32"),
        (42, "unknown (code 42)"),
    ] {
        let p = d.path().join(format!("c{code}.exr"));
        write_exr(&p, &img, Compression::ZIP16);
        patch_compression(&p, code);
        for e in [
            msg(io::load_env(&p, Convention::Equirect).unwrap_err()),
            msg(io::load_normals(&p).unwrap_err()),
            msg(io::exr::read_info(&p).unwrap_err()),
        ] {
            assert!(e.contains(&format!("c{code}.exr")), "{e}");
            assert!(e.contains(name), "{e}");
            assert!(e.contains("oiiotool"), "{e}");
        }
    }
}

#[test]
fn exr_dwa_files_decode() {
    // exr 1.74 decodes (and writes) DWAA and DWAB: such files are read, not refused.
    let d = dir();
    // A smooth image: DWA is a lossy DCT, fine on smooth content, rough on noise.
    let img = Image {
        width: 8,
        height: 40,
        pixels: (0..8 * 40)
            .map(|i| {
                [
                    0.5 + 0.01 * (i % 8) as f32,
                    1.0 + 0.02 * (i / 8) as f32,
                    2.0,
                ]
            })
            .collect(),
    };
    for c in [Compression::DWAA(None), Compression::DWAB(None)] {
        let p = d.path().join("dwa.exr");
        write_exr(&p, &img, c);
        let got = io::load_upstream(&p).unwrap();
        for (a, b) in got.pixels.iter().zip(&img.pixels) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() <= 1e-2 * b[k], "{a:?} vs {b:?}");
            }
        }
    }
}

#[test]
fn exr_mislabelled_dwa_is_an_error_not_garbage() {
    // ZIP data whose header claims DWAA: the decoder must fail cleanly.
    let d = dir();
    let p = d.path().join("liar.exr");
    write_exr(&p, &image(8, 40), Compression::ZIP16);
    patch_compression(&p, 8);
    let e = msg(io::load_upstream(&p).unwrap_err());
    assert!(e.contains("liar.exr"), "{e}");
}

#[test]
fn png_preview_values() {
    let d = dir();
    let p = d.path().join("p.png");
    let img = Image {
        width: 3,
        height: 1,
        pixels: vec![[0.0, 0.5, 1.0], [2.0, -1.0, 0.25], [f32::NAN, 1e9, 0.01]],
    };
    let preview = Preview {
        exposure: 1.0,
        tonemap: Tonemap::Reinhard,
    };
    io::write_atomic(&p, &io::encode_image(&p, &img, &preview).unwrap()).unwrap();
    let dec = io::png::decode(&p).unwrap();
    assert_eq!(
        (dec.width, dec.height, dec.channels, dec.bit_depth),
        (3, 1, 3, 8)
    );
    let want: Vec<u16> = img
        .pixels
        .iter()
        .flatten()
        .map(|&v| io::png::display_value(v, &preview) as u16)
        .collect();
    assert_eq!(dec.samples, want);
    // 0.5 * 2 = 1 -> reinhard 0.5 -> sRGB 188
    assert_eq!(dec.samples[1], 188);
}
