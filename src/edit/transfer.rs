//! Transfer and the grid of transfers: one fit's shape and light with another fit's
//! material, and every fit against every other as one picture (the paper's supplemental
//! figure 4).

use super::dir::{FitDir, GAP};
use crate::error::Result;
use crate::io::{self, Preview};
use crate::raster;
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
            let small = raster::resize(&image(i, j)?, cell, cell);
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
