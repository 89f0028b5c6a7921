//! Small operations on rasters (row-major pixels): bilinear lookups, box filters (to any
//! size, or by whole factors), a square cut out of an image and put back, and blurs. The
//! photo edit, the datasets' backgrounds, the server and the environment-map sizes use
//! them; where two users need different arithmetic (blending in f64 or in f32, wrapping
//! or clamping at the edges), each has its own named function, so every result is exactly
//! what its user computed on its own.

use std::ops::Range;

use rayon::prelude::*;

use crate::scene::Image;

/// What a bilinear lookup does past a raster's left and right edges (rows always clamp).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Columns {
    /// The edge column continues (an image).
    Clamp,
    /// The last column neighbours the first (a lat-long map).
    Wrap,
}

/// Bilinear lookup in a `w` x `h` raster at (x, y) in texel-centre coordinates (texel
/// (c, r) at x = c, y = r), blended in f64.
pub fn bilinear(px: &[[f32; 3]], w: usize, h: usize, x: f64, y: f64, columns: Columns) -> [f32; 3] {
    let y = y.clamp(0.0, (h - 1) as f64);
    let (y0, fy) = (y.floor() as usize, y - y.floor());
    let y1 = (y0 + 1).min(h - 1);
    let (x0, x1, fx) = match columns {
        Columns::Wrap => {
            let x = x.rem_euclid(w as f64);
            let x0 = (x.floor() as usize).min(w - 1);
            (x0, (x0 + 1) % w, x - x.floor())
        }
        Columns::Clamp => {
            let x = x.clamp(0.0, (w - 1) as f64);
            let x0 = x.floor() as usize;
            (x0, (x0 + 1).min(w - 1), x - x.floor())
        }
    };
    let at = |r: usize, c: usize| px[r * w + c].map(f64::from);
    let (a, b, c, d) = (at(y0, x0), at(y0, x1), at(y1, x0), at(y1, x1));
    [0, 1, 2].map(|k| {
        let top = a[k] + (b[k] - a[k]) * fx;
        let bottom = c[k] + (d[k] - c[k]) * fx;
        (top + (bottom - top) * fy) as f32
    })
}

/// Bilinear lookup in a `w` x `h` raster of one channel at (x, y) in texel-centre
/// coordinates, edges clamped, with f32 weights.
pub fn bilinear_scalar(values: &[f32], w: usize, h: usize, x: f64, y: f64) -> f32 {
    let (x, y) = (x.clamp(0.0, (w - 1) as f64), y.clamp(0.0, (h - 1) as f64));
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let at = |xx: usize, yy: usize| values[yy * w + xx];
    (1.0 - fy) * ((1.0 - fx) * at(x0, y0) + fx * at(x1, y0))
        + fy * ((1.0 - fx) * at(x0, y1) + fx * at(x1, y1))
}

/// A `w` x `h` raster of one channel at the pixel centres of a `width` x `height` one
/// covering the same frame, bilinear ([`bilinear_scalar`]).
pub fn resample_scalar(
    values: &[f32],
    w: usize,
    h: usize,
    width: usize,
    height: usize,
) -> Vec<f32> {
    let (fx, fy) = (w as f64 / width as f64, h as f64 / height as f64);
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64 + 0.5, (i / width) as f64 + 0.5);
            bilinear_scalar(values, w, h, x * fx - 0.5, y * fy - 0.5)
        })
        .collect()
}

/// Box-resamples `image` to `width` x `height`: each output pixel is the mean of the
/// input pixels whose centres fall in it (the nearest one when none does).
pub fn resize(image: &Image, width: usize, height: usize) -> Image {
    let mut out = Image::zeros(width, height);
    let (sx, sy) = (
        image.width as f64 / width as f64,
        image.height as f64 / height as f64,
    );
    out.pixels
        .par_chunks_mut(width.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let (y0, y1) = (y as f64 * sy, (y + 1) as f64 * sy);
            let rows =
                (y0 - 0.5).ceil().max(0.0) as usize..((y1 - 0.5).ceil() as usize).min(image.height);
            for (x, o) in row.iter_mut().enumerate() {
                let (x0, x1) = (x as f64 * sx, (x + 1) as f64 * sx);
                let cols = (x0 - 0.5).ceil().max(0.0) as usize
                    ..((x1 - 0.5).ceil() as usize).min(image.width);
                let (mut sum, mut n) = ([0.0f64; 3], 0usize);
                for yy in rows.clone() {
                    for xx in cols.clone() {
                        for k in 0..3 {
                            sum[k] += f64::from(image.pixels[yy * image.width + xx][k]);
                        }
                        n += 1;
                    }
                }
                *o = if n > 0 {
                    sum.map(|v| (v / n as f64) as f32)
                } else {
                    let yy = (((y as f64 + 0.5) * sy) as usize).min(image.height - 1);
                    let xx = (((x as f64 + 0.5) * sx) as usize).min(image.width - 1);
                    image.pixels[yy * image.width + xx]
                };
            }
        });
    out
}

/// The pixels of a raster under one pixel of its reduction by whole factors: their
/// row-major indices, row by row.
#[derive(Clone, Debug)]
pub struct Block {
    width: usize,
    rows: Range<usize>,
    cols: Range<usize>,
    col: usize,
}

impl Iterator for Block {
    type Item = usize;

    fn next(&mut self) -> Option<usize> {
        if self.col == self.cols.end {
            self.rows.start += 1;
            self.col = self.cols.start;
        }
        if self.rows.is_empty() || self.cols.is_empty() {
            return None;
        }
        let i = self.rows.start * self.width + self.col;
        self.col += 1;
        Some(i)
    }
}

/// A `w` x `h` raster reduced by `fx` x `fy` blocks to `out_w` x `out_h` pixels, row by
/// row: output pixel (x, y) is `block` of the input pixels in columns x fx .. (x + 1) fx and
/// rows y fy .. (y + 1) fy, cut at the raster's edges. The caller sums (weighted, in f32 or
/// f64) as its result needs.
pub fn reduce<T: Send>(
    (w, h): (usize, usize),
    (fx, fy): (usize, usize),
    (out_w, out_h): (usize, usize),
    block: impl Fn(Block) -> T + Sync,
) -> Vec<T> {
    (0..out_w * out_h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % out_w, i / out_w);
            let cols = x * fx..((x + 1) * fx).min(w);
            block(Block {
                width: w,
                rows: y * fy..((y + 1) * fy).min(h),
                col: cols.start,
                cols,
            })
        })
        .collect()
}

/// A square of an image: columns x0 .. x0 + size, rows y0 .. y0 + size; it may reach
/// past the image's edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crop {
    /// First column (may be negative).
    pub x0: i64,
    /// First row (may be negative).
    pub y0: i64,
    /// Side in pixels.
    pub size: usize,
}

impl Crop {
    /// The image pixel (column, row) under pixel `i` of the square, if inside a `w` x `h`
    /// image.
    fn pixel(&self, i: usize, w: usize, h: usize) -> Option<(usize, usize)> {
        let (x, y) = (
            self.x0 + (i % self.size) as i64,
            self.y0 + (i / self.size) as i64,
        );
        ((0..w as i64).contains(&x) && (0..h as i64).contains(&y))
            .then_some((x as usize, y as usize))
    }
}

/// The square `c` of `image`, black past the image's edges.
pub fn crop(image: &Image, c: Crop) -> Image {
    Image {
        width: c.size,
        height: c.size,
        pixels: crop_values(&image.pixels, image.width, image.height, c, [0.0; 3]),
    }
}

/// The values of a `w` x `h` raster under the square `c`, `outside` past its edges.
pub fn crop_values<T: Copy + Send + Sync>(
    values: &[T],
    w: usize,
    h: usize,
    c: Crop,
    outside: T,
) -> Vec<T> {
    (0..c.size * c.size)
        .into_par_iter()
        .map(|i| c.pixel(i, w, h).map_or(outside, |(x, y)| values[y * w + x]))
        .collect()
}

/// `square` (the pixels of `c`) put back into a black `width` x `height` image: the
/// inverse of [`crop`] where the square lies inside.
pub fn uncrop(square: &Image, c: Crop, width: usize, height: usize) -> Image {
    let mut out = Image::zeros(width, height);
    for (i, p) in square.pixels.iter().enumerate() {
        if let Some((x, y)) = c.pixel(i, width, height) {
            out.pixels[y * width + x] = *p;
        }
    }
    out
}

/// A `w` x `h` mask as 0/1, averaged over each pixel's 3 x 3 neighbourhood (inside the
/// raster).
pub fn blur3(mask: &[bool], w: usize, h: usize) -> Vec<f32> {
    // per row, the count of set pixels in each column's 3 rows and the rows counted;
    // counts are small integers, so the sums are exact and the order does not matter
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w.max(1))
        .enumerate()
        .for_each(|(y, row)| {
            let rows = y.saturating_sub(1)..(y + 2).min(h);
            let n_rows = rows.len() as f32;
            let column: Vec<u8> = (0..w)
                .map(|x| rows.clone().map(|yy| u8::from(mask[yy * w + x])).sum())
                .collect();
            for (x, o) in row.iter_mut().enumerate() {
                let cols = x.saturating_sub(1)..(x + 2).min(w);
                let n = n_rows * cols.len() as f32;
                let s: u8 = column[cols].iter().sum();
                *o = f32::from(s) / n;
            }
        });
    out
}

/// The mean of `v` over the (2r + 1)^2 window around each pixel, clipped at the edges.
pub fn box_mean(v: &[f32], w: usize, h: usize, r: usize) -> Vec<f32> {
    // summed-area table, in f64 so that long rows of sums keep their last digits
    let mut sat = vec![0.0f64; (w + 1) * (h + 1)];
    for y in 0..h {
        let mut row = 0.0;
        for x in 0..w {
            row += f64::from(v[y * w + x]);
            sat[(y + 1) * (w + 1) + x + 1] = sat[y * (w + 1) + x + 1] + row;
        }
    }
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        let (ya, yb) = (y.saturating_sub(r), (y + r + 1).min(h));
        for x in 0..w {
            let (xa, xb) = (x.saturating_sub(r), (x + r + 1).min(w));
            let s = sat[yb * (w + 1) + xb] - sat[ya * (w + 1) + xb] - sat[yb * (w + 1) + xa]
                + sat[ya * (w + 1) + xa];
            out[y * w + x] = (s / ((yb - ya) * (xb - xa)) as f64) as f32;
        }
    }
    out
}

/// A `w` x `h` mask grown by `r` pixels: a pixel is set when any pixel of the
/// (2r + 1)-square around it (inside the raster) is: where the mask's [`box_mean`] there
/// (whose sums of ones and zeros are exact) is above zero.
pub fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let ones: Vec<f32> = mask.iter().map(|&m| f32::from(u8::from(m))).collect();
    box_mean(&ones, w, h, r).iter().map(|&v| v > 0.0).collect()
}

/// Separable Gaussian blur of sigma `s` pixels of a `w` x `h` raster, edges clamped.
pub fn gaussian_blur(px: &mut [[f32; 3]], w: usize, h: usize, s: f64) {
    if s <= 0.0 {
        return;
    }
    let r = (3.0 * s).ceil() as isize;
    let k: Vec<f64> = (-r..=r)
        .map(|i| (-(i * i) as f64 / (2.0 * s * s)).exp())
        .collect();
    let norm: f64 = k.iter().sum();
    let pass = |px: &[[f32; 3]], along_x: bool| -> Vec<[f32; 3]> {
        let mut out = vec![[0.0f32; 3]; px.len()];
        for y in 0..h as isize {
            for x in 0..w as isize {
                let mut acc = [0.0f64; 3];
                for (i, kv) in (-r..=r).zip(&k) {
                    let (xx, yy) = if along_x {
                        ((x + i).clamp(0, w as isize - 1), y)
                    } else {
                        (x, (y + i).clamp(0, h as isize - 1))
                    };
                    let p = px[yy as usize * w + xx as usize];
                    for c in 0..3 {
                        acc[c] += kv * p[c] as f64;
                    }
                }
                out[y as usize * w + x as usize] = acc.map(|v| (v / norm) as f32);
            }
        }
        out
    };
    let tmp = pass(px, true);
    px.copy_from_slice(&pass(&tmp, false));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_means_are_window_means() {
        let v: Vec<f32> = (0..20).map(|i| i as f32).collect();
        let m = box_mean(&v, 5, 4, 1);
        // (0, 0): pixels 0, 1, 5, 6
        assert_eq!(m[0], 3.0);
        // (2, 1): 1 2 3 6 7 8 11 12 13
        assert_eq!(m[7], 7.0);
    }

    #[test]
    fn dilate_sets_the_square_around_each_set_pixel() {
        let (w, h) = (7, 13);
        let mut mask = vec![false; w * h];
        mask[2 * w + 1] = true;
        mask[12 * w + 6] = true;
        for r in 0..15 {
            let grown = dilate(&mask, w, h, r);
            for y in 0..h {
                for x in 0..w {
                    let near =
                        |(px, py): (usize, usize)| x.abs_diff(px) <= r && y.abs_diff(py) <= r;
                    let want = near((1, 2)) || near((6, 12));
                    assert_eq!(grown[y * w + x], want, "r {r} at ({x}, {y})");
                }
            }
        }
    }

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

    #[test]
    fn blocks_cover_the_raster_row_by_row_and_stop_at_its_edges() {
        // 5 x 3 by 2 x 2 blocks, rounded up: the last column and row are cut
        let blocks = reduce((5, 3), (2, 2), (3, 2), |b| b.collect::<Vec<_>>());
        assert_eq!(blocks[0], vec![0, 1, 5, 6]);
        assert_eq!(blocks[2], vec![4, 9]);
        assert_eq!(blocks[3], vec![10, 11]);
        assert_eq!(blocks[5], vec![14]);
        let mut all: Vec<usize> = blocks.into_iter().flatten().collect();
        all.sort_unstable();
        assert_eq!(all, (0..15).collect::<Vec<_>>());
        // a block past the raster is empty
        assert!(reduce((2, 2), (2, 2), (2, 1), |b| b.count())[1] == 0);
    }

    #[test]
    fn a_crop_put_back_is_the_image_inside_and_black_outside() {
        let img = Image {
            width: 4,
            height: 3,
            pixels: (0..12).map(|i| [i as f32 + 1.0; 3]).collect(),
        };
        let c = Crop {
            x0: -1,
            y0: 1,
            size: 3,
        };
        let sq = crop(&img, c);
        assert_eq!(sq.pixels[0], [0.0; 3]);
        assert_eq!(sq.pixels[1], [5.0; 3]);
        assert_eq!(sq.pixels[6], [0.0; 3]);
        let back = uncrop(&sq, c, 4, 3);
        for (i, p) in back.pixels.iter().enumerate() {
            let inside = (4..6).contains(&i) || (8..10).contains(&i);
            assert_eq!(*p, if inside { img.pixels[i] } else { [0.0; 3] });
        }
    }

    #[test]
    fn bilinear_hits_texel_centres_and_wraps_or_clamps() {
        let px: Vec<[f32; 3]> = (0..8).map(|i| [i as f32; 3]).collect();
        assert_eq!(bilinear(&px, 4, 2, 1.0, 1.0, Columns::Clamp), [5.0; 3]);
        assert_eq!(bilinear(&px, 4, 2, 3.5, 0.0, Columns::Clamp), [3.0; 3]);
        assert_eq!(bilinear(&px, 4, 2, 3.5, 0.0, Columns::Wrap), [1.5; 3]);
        let one: Vec<f32> = px.iter().map(|p| p[0]).collect();
        assert_eq!(bilinear_scalar(&one, 4, 2, 0.5, 0.5), 2.5);
        assert_eq!(bilinear_scalar(&one, 4, 2, 9.0, -1.0), 3.0);
    }

    #[test]
    fn blur_keeps_a_constant_and_spreads_a_spike() {
        let mut px = vec![[2.0f32; 3]; 9 * 7];
        gaussian_blur(&mut px, 9, 7, 1.5);
        assert!(px.iter().all(|p| (p[0] - 2.0).abs() < 1e-5));
        let mut px = vec![[0.0f32; 3]; 9 * 9];
        px[40] = [1.0; 3];
        gaussian_blur(&mut px, 9, 9, 1.0);
        let total: f32 = px.iter().map(|p| p[0]).sum();
        assert!((total - 1.0).abs() < 1e-4 && px[40][0] < 0.2 && px[41][0] > 0.05);
    }

    #[test]
    fn blur3_is_the_mean_over_the_neighbours_inside() {
        let mut mask = vec![false; 9];
        mask[4] = true;
        let a = blur3(&mask, 3, 3);
        assert_eq!(a[0], 1.0 / 4.0);
        assert_eq!(a[1], 1.0 / 6.0);
        assert_eq!(a[4], 1.0 / 9.0);
    }
}
