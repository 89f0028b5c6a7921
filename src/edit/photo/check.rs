//! The photos and masks an edit takes: sizes within the limits, values finite, an object
//! and a background; and whether a mask the nets found is a single object.

use crate::Image;
use crate::error::{Result, invalid};

/// The largest photo: pixels in all (16.8 million, 4096 x 4096).
pub const MAX_PIXELS: usize = 4096 * 4096;
/// The largest side of a photo, in pixels.
pub const MAX_SIDE: usize = 8192;
/// The smallest side of a photo, in pixels.
pub const MIN_SIDE: usize = 16;
/// The fewest pixels an object may cover.
pub const MIN_OBJECT_PIXELS: usize = 16;

/// The most of the frame a found object may cover.
pub const MAX_FOUND_COVER: f64 = 0.5;
/// A found object touches an edge of the frame when it covers this much of it; it may
/// touch two (a close-up cut by a corner), not three.
pub const EDGE_TOUCH: f64 = 0.1;
/// The least share of a found object in its largest connected part.
pub const MIN_FOUND_PART: f64 = 0.75;

/// Checks that a mask the nets found is one object standing out: it covers at most
/// [`MAX_FOUND_COVER`] of the frame, touches at most two of its edges, and holds at least
/// [`MIN_FOUND_PART`] of its pixels in one connected part (judged on the mask reduced to
/// at most 128 cells a side, each on when most of its pixels are). On a photo where the
/// nets take the table, the wall or a scatter of things for the object, the error asks
/// for a box or a mask.
pub fn single_object(mask: &[bool], width: usize, height: usize) -> Result<()> {
    let k = width.max(height).div_ceil(128).max(1);
    let (w, h) = (width.div_ceil(k), height.div_ceil(k));
    let mut count = vec![(0u32, 0u32); w * h];
    for (i, &m) in mask.iter().enumerate() {
        let c = &mut count[(i / width / k) * w + (i % width) / k];
        c.0 += u32::from(m);
        c.1 += 1;
    }
    let on: Vec<bool> = count.iter().map(|&(m, n)| 2 * m >= n && m > 0).collect();
    let total = on.iter().filter(|&&m| m).count();
    let refuse = || invalid!("no single object found: give --box or --mask");
    if total == 0
        || mask.iter().filter(|&&m| m).count() as f64 > MAX_FOUND_COVER * mask.len() as f64
    {
        return Err(refuse());
    }
    let share = |cells: &mut dyn Iterator<Item = usize>, n: usize| {
        cells.filter(|&i| on[i]).count() as f64 / n as f64
    };
    let edges = [
        share(&mut (0..w), w),
        share(&mut ((h - 1) * w..h * w), w),
        share(&mut (0..h).map(|y| y * w), h),
        share(&mut (0..h).map(|y| y * w + w - 1), h),
    ];
    if edges.iter().filter(|&&s| s >= EDGE_TOUCH).count() > 2 {
        return Err(refuse());
    }
    if (largest_part(&on, w, h) as f64) < MIN_FOUND_PART * total as f64 {
        return Err(refuse());
    }
    Ok(())
}

/// Cells in the largest 8-connected part of `on`.
fn largest_part(on: &[bool], w: usize, h: usize) -> usize {
    let mut seen = vec![false; on.len()];
    let mut best = 0;
    let mut stack = Vec::new();
    for s in 0..on.len() {
        if !on[s] || seen[s] {
            continue;
        }
        seen[s] = true;
        stack.push(s);
        let mut size = 0;
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = (i % w, i / w);
            for ny in y.saturating_sub(1)..(y + 2).min(h) {
                for nx in x.saturating_sub(1)..(x + 2).min(w) {
                    let j = ny * w + nx;
                    if on[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        best = best.max(size);
    }
    best
}

/// Checks that `photo` is one the edit takes: its size within the limits, every value finite.
pub fn check_photo(photo: &Image) -> Result<()> {
    let (w, h) = (photo.width, photo.height);
    if w > MAX_SIDE || h > MAX_SIDE || w * h > MAX_PIXELS {
        return Err(invalid!(
            "image: {w}x{h} is over the limit of {MAX_PIXELS} pixels ({MAX_SIDE} a side); downscale it"
        ));
    }
    if w < MIN_SIDE || h < MIN_SIDE {
        return Err(invalid!(
            "image: {w}x{h} is too small to hold an object (at least {MIN_SIDE} pixels a side)"
        ));
    }
    if let Some((x, y)) = photo.non_finite_pixel() {
        return Err(invalid!("image: pixel (column {x}, row {y}) is not finite"));
    }
    Ok(())
}

/// Checks a mask for `photo`: its size, at least [`MIN_OBJECT_PIXELS`] on the object, and
/// some background.
pub fn check_mask(mask: &[bool], width: usize, height: usize) -> Result<()> {
    if mask.len() != width * height {
        return Err(invalid!(
            "mask: {} pixels for a {width}x{height} image",
            mask.len()
        ));
    }
    let n = mask.iter().filter(|&&m| m).count();
    if n < MIN_OBJECT_PIXELS {
        return Err(invalid!(
            "mask: {n} pixels on the object; at least {MIN_OBJECT_PIXELS} are needed"
        ));
    }
    if n == mask.len() {
        return Err(invalid!(
            "mask: every pixel is on the object; there is no background to keep"
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn masks_are_checked() {
        assert!(
            check_mask(&[false; 100], 10, 10)
                .unwrap_err()
                .to_string()
                .contains("0 pixels on the object")
        );
        assert!(
            check_mask(&[true; 100], 10, 10)
                .unwrap_err()
                .to_string()
                .contains("no background")
        );
        assert!(
            check_mask(&[true; 10], 10, 10)
                .unwrap_err()
                .to_string()
                .contains("10 pixels for a 10x10")
        );
    }

    #[test]
    fn only_a_single_object_stands_out() {
        let (w, h) = (300, 200);
        let disc = |cx: f64, cy: f64, r: f64| -> Vec<bool> {
            (0..w * h)
                .map(|i| ((i % w) as f64 - cx).hypot((i / w) as f64 - cy) < r)
                .collect()
        };
        assert!(single_object(&disc(150.0, 100.0, 60.0), w, h).is_ok());
        // cut by one corner: still one object
        assert!(single_object(&disc(0.0, 0.0, 120.0), w, h).is_ok());
        let refused = |m: &[bool]| {
            single_object(m, w, h).unwrap_err().to_string()
                == "no single object found: give --box or --mask"
        };
        // the table: most of the frame
        assert!(refused(&disc(150.0, 100.0, 200.0)));
        // a band across the bottom and up both sides: three edges
        let band: Vec<bool> = (0..w * h)
            .map(|i| i / w > 150 || i % w < 20 || i % w > 280)
            .collect();
        assert!(refused(&band));
        // two discs alike: scattered
        let two: Vec<bool> = disc(70.0, 100.0, 40.0)
            .iter()
            .zip(disc(230.0, 100.0, 40.0))
            .map(|(a, b)| *a || b)
            .collect();
        assert!(refused(&two));
    }

    #[test]
    fn photos_are_checked() {
        assert!(
            check_photo(&Image::zeros(8, 40))
                .unwrap_err()
                .to_string()
                .contains("too small")
        );
        assert!(
            check_photo(&Image::zeros(8193, 16))
                .unwrap_err()
                .to_string()
                .contains("over the limit")
        );
        let mut img = Image::zeros(16, 16);
        img.pixels[17][1] = f32::NAN;
        assert!(
            check_photo(&img)
                .unwrap_err()
                .to_string()
                .contains("(column 1, row 1)")
        );
    }
}
