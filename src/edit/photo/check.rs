//! The photos and masks an edit takes: sizes within the limits, values finite, an object
//! and a background.

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
