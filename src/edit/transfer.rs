//! Transfer and the grid of transfers: one fit's shape and light with another fit's
//! material, and every fit against every other as one picture (the paper's supplemental
//! figure 4).

use super::dir::{FitDir, GAP};
use crate::error::Result;
use crate::io::{self, Preview};
use crate::{Batch, Image, Material, Renderer, Scene};

/// `shape_light`'s normals, light and camera with `material`.
pub fn transfer(renderer: &Renderer, shape_light: &FitDir, material: &Material) -> Result<Image> {
    let batch = Batch::single(Scene {
        normals: shape_light.normals.clone(),
        env: shape_light.env.clone(),
        material: material.clone(),
        camera: shape_light.camera,
    })?;
    Ok(renderer.render(&batch)?.remove(0))
}

/// Box-resamples `image` to `width` x `height`: each output pixel is the mean of the
/// input pixels whose centres fall in it (the nearest one when none does).
pub fn resize(image: &Image, width: usize, height: usize) -> Image {
    let mut out = Image::zeros(width, height);
    let (sx, sy) = (
        image.width as f64 / width as f64,
        image.height as f64 / height as f64,
    );
    for y in 0..height {
        let (y0, y1) = (y as f64 * sy, (y + 1) as f64 * sy);
        let rows =
            (y0 - 0.5).ceil().max(0.0) as usize..((y1 - 0.5).ceil() as usize).min(image.height);
        for x in 0..width {
            let (x0, x1) = (x as f64 * sx, (x + 1) as f64 * sx);
            let cols =
                (x0 - 0.5).ceil().max(0.0) as usize..((x1 - 0.5).ceil() as usize).min(image.width);
            let (mut sum, mut n) = ([0.0f64; 3], 0usize);
            for yy in rows.clone() {
                for xx in cols.clone() {
                    for k in 0..3 {
                        sum[k] += f64::from(image.pixels[yy * image.width + xx][k]);
                    }
                    n += 1;
                }
            }
            out.pixels[y * width + x] = if n > 0 {
                sum.map(|v| (v / n as f64) as f32)
            } else {
                let yy = (((y as f64 + 0.5) * sy) as usize).min(image.height - 1);
                let xx = (((x as f64 + 0.5) * sx) as usize).min(image.width - 1);
                image.pixels[yy * image.width + xx]
            };
        }
    }
    out
}

/// The grid of transfers as an 8-bit RGB picture: row i keeps fit i's shape and light,
/// column j brings fit j's material, and the diagonal shows the images fitted to. Cells
/// are `cell` pixels square (each image resampled), on a dark background.
pub fn grid(
    renderer: &Renderer,
    fits: &[FitDir],
    cell: usize,
    preview: &Preview,
) -> Result<(usize, usize, Vec<u8>)> {
    grid_of(fits.len(), cell, preview, |i, j| {
        if i == j {
            Ok(fits[i].target.clone())
        } else {
            transfer(renderer, &fits[i], &fits[j].material)
        }
    })
}

/// An `n` x `n` grid of the images `image(row, column)` as an 8-bit RGB picture, each
/// resampled to `cell` pixels square, on a dark background.
pub fn grid_of(
    n: usize,
    cell: usize,
    preview: &Preview,
    mut image: impl FnMut(usize, usize) -> Result<Image>,
) -> Result<(usize, usize, Vec<u8>)> {
    let side = n * cell + (n + 1) * GAP;
    let mut rgb = vec![24u8; side * side * 3];
    for i in 0..n {
        for j in 0..n {
            let small = resize(&image(i, j)?, cell, cell);
            let (ox, oy) = (GAP + j * (cell + GAP), GAP + i * (cell + GAP));
            for y in 0..cell {
                for x in 0..cell {
                    let p = small.pixels[y * cell + x];
                    let o = ((oy + y) * side + ox + x) * 3;
                    for k in 0..3 {
                        rgb[o + k] = io::png::display_value(p[k], preview);
                    }
                }
            }
        }
    }
    Ok((side, side, rgb))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resize_averages_blocks_and_keeps_sizes() {
        let img = Image {
            width: 4,
            height: 2,
            pixels: (0..8).map(|i| [i as f32, 0.0, 1.0]).collect(),
        };
        let half = resize(&img, 2, 1);
        assert_eq!(half.pixels, vec![[2.5, 0.0, 1.0], [4.5, 0.0, 1.0]]);
        let up = resize(&img, 8, 4);
        assert_eq!(up.pixels[0], [0.0, 0.0, 1.0]);
        assert_eq!(up.pixels[8 * 4 - 1], [7.0, 0.0, 1.0]);
    }
}
