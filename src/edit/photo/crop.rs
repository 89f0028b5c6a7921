//! The square around the object that the nets see, and values carried between it and the
//! photo: the photo and the mask cut out and box-filtered to the nets' size, the nets'
//! mask and normals brought back bilinear to the photo's pixels.

use rayon::prelude::*;

use crate::raster::{self, Crop};
use crate::{Image, NormalMap};

/// The margin of the nets' training images: the object fills the frame but this fraction
/// of the half-size on each side (`matedit normals --margin`).
const MARGIN: f64 = 0.05;

/// The square around the mask's bounding box, with the nets' margin.
pub(super) fn crop_around(mask: &[bool], w: usize, h: usize) -> Crop {
    let (mut x0, mut x1, mut y0, mut y1) = (w, 0, h, 0);
    for (i, _) in mask.iter().enumerate().filter(|(_, m)| **m) {
        let (x, y) = (i % w, i / w);
        (x0, x1, y0, y1) = (x0.min(x), x1.max(x + 1), y0.min(y), y1.max(y + 1));
    }
    square_around(x0, y0, x1, y1)
}

/// The square around columns `x0..x1` and rows `y0..y1`, with the nets' margin.
pub(super) fn square_around(x0: usize, y0: usize, x1: usize, y1: usize) -> Crop {
    let side = (x1 - x0).max(y1 - y0) as f64 / (1.0 - MARGIN);
    let size = side.ceil() as usize;
    let cx = (x0 + x1) as f64 / 2.0;
    let cy = (y0 + y1) as f64 / 2.0;
    Crop {
        x0: (cx - size as f64 / 2.0).round() as i64,
        y0: (cy - size as f64 / 2.0).round() as i64,
        size,
    }
}

/// The mask as an image: 1 on the object, 0 off it.
pub(super) fn mask_image(mask: &[bool], w: usize, h: usize) -> Image {
    Image {
        width: w,
        height: h,
        pixels: mask.iter().map(|&m| [f32::from(u8::from(m)); 3]).collect(),
    }
}

/// The crop box-filtered (or, when it is smaller, enlarged by nearest pixels) to `n` x `n`.
pub(super) fn crop_image(photo: &Image, crop: Crop, n: usize) -> Image {
    raster::resize(&raster::crop(photo, crop), n, n)
}

/// Values at `n` x `n` over `crop`, bilinear at the photo's pixels (0 off the crop).
pub(super) fn paste_scalar(values: &[f32], n: usize, crop: Crop, w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0; w * h];
    let f = n as f64 / crop.size as f64;
    for (i, o) in out.iter_mut().enumerate() {
        let u = ((i % w) as i64 - crop.x0) as f64 + 0.5;
        let v = ((i / w) as i64 - crop.y0) as f64 + 0.5;
        if u < 0.0 || v < 0.0 || u >= crop.size as f64 || v >= crop.size as f64 {
            continue;
        }
        *o = raster::bilinear_scalar(values, n, n, u * f - 0.5, v * f - 0.5);
    }
    out
}

/// The nets' normals (n x n over the crop) at the crop's pixels: bilinear, renormalised,
/// on the object only (`mask`: the crop's pixels; facing the camera where the nets saw
/// background).
pub(super) fn upsample_normals(small: &NormalMap, crop: Crop, mask: &[bool]) -> NormalMap {
    let n = small.width;
    let channel = |k: usize| -> Vec<f32> { small.normals.iter().map(|v| v[k]).collect() };
    let comps = [channel(0), channel(1), channel(2)];
    let f = n as f64 / crop.size as f64;
    let normals = (0..crop.size * crop.size)
        .into_par_iter()
        .map(|i| {
            let (u, v) = (i % crop.size, i / crop.size);
            if !mask[i] {
                return [0.0; 3];
            }
            let (sx, sy) = ((u as f64 + 0.5) * f - 0.5, (v as f64 + 0.5) * f - 0.5);
            let c: [f32; 3] =
                std::array::from_fn(|k| raster::bilinear_scalar(&comps[k], n, n, sx, sy));
            let len = c.iter().map(|a| a * a).sum::<f32>().sqrt();
            if len > 1e-3 {
                c.map(|a| a / len)
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect();
    NormalMap {
        width: crop.size,
        height: crop.size,
        normals,
    }
}

/// The crop's normals and mask box-filtered to `s` x `s`: the normals renormalised where
/// the object covers part of a pixel (zero where it covers none), and the fraction of each
/// pixel on the object.
pub(super) fn render_grid(normals: &NormalMap, mask: &[bool], s: usize) -> (NormalMap, Vec<f32>) {
    let n = normals.width;
    let as_image = Image {
        width: n,
        height: n,
        pixels: normals.normals.clone(),
    };
    let coverage: Vec<f32> = raster::resize(&mask_image(mask, n, n), s, s)
        .pixels
        .iter()
        .map(|p| p[0])
        .collect();
    let small = raster::resize(&as_image, s, s);
    let normals = small
        .pixels
        .iter()
        .zip(&coverage)
        .map(|(c, &cov)| {
            let len = c.iter().map(|a| a * a).sum::<f32>().sqrt();
            if cov > 0.0 && len > 1e-3 {
                c.map(|a| a / len)
            } else if cov > 0.0 {
                [0.0, 0.0, 1.0]
            } else {
                [0.0; 3]
            }
        })
        .collect();
    (
        NormalMap {
            width: s,
            height: s,
            normals,
        },
        coverage,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_crop_holds_the_object_with_the_margin() {
        let (w, h) = (40, 30);
        let mask: Vec<bool> = (0..w * h)
            .map(|i| (10..20).contains(&(i % w)) && (5..25).contains(&(i / w)))
            .collect();
        let c = crop_around(&mask, w, h);
        assert_eq!(c.size, 22); // 20 / 0.95 = 21.05, rounded up
        assert!(
            c.x0 <= 10 && c.x0 + c.size as i64 >= 20 && c.y0 <= 5 && c.y0 + c.size as i64 >= 25
        );
        let img = raster::crop(&mask_image(&mask, w, h), c);
        assert_eq!(img.pixels.iter().filter(|p| p[0] > 0.5).count(), 200);
    }
}
