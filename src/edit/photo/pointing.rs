//! Pointing at the object: a box around it, points on it and points off it, turned into
//! its mask at the photo's resolution ([`segment_object`]).
//!
//! The nets see the square around the box (or around the points) and their mask
//! probability is the cut's prior; the cut itself ([`crate::segment`]) fits colour models
//! of the object and of what surrounds it and follows the photo's edges. With a box, the
//! cut works on the box with a margin of 15% of its longer side, and nothing outside the
//! box is the object; with points alone, on the whole photo, the object being likely
//! inside the square of a third of the photo's shorter side (or twice the points'
//! spread) around the points.

use super::check::MIN_OBJECT_PIXELS;
use super::crop::square_around;
use crate::Image;
use crate::error::{Result, invalid};
use crate::nets::Nets;
use crate::raster::{self, Crop};
use crate::segment::{self, Hints, Rect, Settings};

/// The narrowest box side, in pixels.
pub const MIN_BOX_SIDE: usize = 4;

/// Where the user says the object is.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Pointing {
    /// A box around the object (columns x0..x1, rows y0..y1: x1 and y1 exclusive);
    /// nothing outside it is the object.
    pub bounds: Option<Rect>,
    /// Pixels (column, row) on the object.
    pub object: Vec<[usize; 2]>,
    /// Pixels (column, row) not on the object.
    pub background: Vec<[usize; 2]>,
}

impl Pointing {
    /// Whether it says nothing (no box, no point).
    pub fn is_empty(&self) -> bool {
        self.bounds.is_none() && self.object.is_empty() && self.background.is_empty()
    }

    /// Checks it against a `width` x `height` photo: the box inside it and at least
    /// [`MIN_BOX_SIDE`] pixels a side, the points inside it, the points on the object inside
    /// the box, and a box or a point on the object. Messages name the item as the command
    /// line spells it without its dashes (`box 10,10,900,50: outside the 600x400 photo`).
    pub fn check(&self, width: usize, height: usize) -> Result<()> {
        let photo = format!("{width}x{height} photo");
        if let Some(b) = self.bounds {
            let item = format!("box {},{},{},{}", b.x0, b.y0, b.x1, b.y1);
            if b.x1 <= b.x0 || b.y1 <= b.y0 {
                return Err(invalid!(
                    "{item}: empty (X0,Y0 is its top left corner, X1,Y1 past its bottom right)"
                ));
            }
            if b.x1 > width || b.y1 > height {
                return Err(invalid!("{item}: outside the {photo}"));
            }
            if b.x1 - b.x0 < MIN_BOX_SIDE || b.y1 - b.y0 < MIN_BOX_SIDE {
                return Err(invalid!(
                    "{item}: {}x{} pixels; at least {MIN_BOX_SIDE} a side",
                    b.x1 - b.x0,
                    b.y1 - b.y0
                ));
            }
        }
        for (points, name) in [(&self.object, "point"), (&self.background, "not")] {
            for p in points {
                let item = format!("{name} {},{}", p[0], p[1]);
                if p[0] >= width || p[1] >= height {
                    return Err(invalid!("{item}: outside the {photo}"));
                }
                if let (Some(b), "point") = (self.bounds, name)
                    && !((b.x0..b.x1).contains(&p[0]) && (b.y0..b.y1).contains(&p[1]))
                {
                    return Err(invalid!(
                        "{item}: outside the box {},{},{},{}",
                        b.x0,
                        b.y0,
                        b.x1,
                        b.y1
                    ));
                }
            }
        }
        if self.bounds.is_none() && self.object.is_empty() {
            return Err(invalid!(
                "not: points off the object need a box or a point on it"
            ));
        }
        Ok(())
    }
}

/// The object's mask at `photo`'s pixels from `pointing`, with the nets (input `n` x `n`)
/// for a prior (left out when the cut with it keeps nothing); an error if the pointing does
/// not fit the photo or nothing is found.
pub fn segment_object(
    nets: &Nets,
    photo: &Image,
    pointing: &Pointing,
    n: usize,
) -> Result<Vec<bool>> {
    let (w, h) = (photo.width, photo.height);
    pointing.check(w, h)?;
    let clip = |x0: f64, y0: f64, x1: f64, y1: f64| Rect {
        x0: x0.max(0.0) as usize,
        y0: y0.max(0.0) as usize,
        x1: (x1.ceil() as usize).clamp(1, w),
        y1: (y1.ceil() as usize).clamp(1, h),
    };
    let (bounds, hard_bounds, area) = match pointing.bounds {
        Some(b) => {
            let m = (0.15 * (b.x1 - b.x0).max(b.y1 - b.y0) as f64).max(8.0);
            let (x0, y0, x1, y1) = (b.x0 as f64, b.y0 as f64, b.x1 as f64, b.y1 as f64);
            (b, true, clip(x0 - m, y0 - m, x1 + m, y1 + m))
        }
        None => {
            let xs = pointing.object.iter().map(|p| p[0] as f64);
            let ys = pointing.object.iter().map(|p| p[1] as f64);
            let (x0, x1) = (xs.clone().fold(f64::MAX, f64::min), xs.fold(0.0, f64::max));
            let (y0, y1) = (ys.clone().fold(f64::MAX, f64::min), ys.fold(0.0, f64::max));
            let half = ((x1 - x0).max(y1 - y0)).max(w.min(h) as f64 / 3.0) / 2.0 + 1.0;
            let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            let bounds = clip(cx - half, cy - half, cx + half, cy + half);
            (bounds, false, clip(0.0, 0.0, w as f64, h as f64))
        }
    };

    // the nets' mask on the square around the bounds, normalised by the bounds and then
    // by the mask found (as find_object does)
    let crop = square_around(bounds.x0, bounds.y0, bounds.x1, bounds.y1);
    let input = box_filtered(photo, crop, n);
    let f = n as f64 / crop.size as f64;
    let inside: Vec<bool> = (0..n * n)
        .map(|i| {
            let x = crop.x0 as f64 + ((i % n) as f64 + 0.5) / f;
            let y = crop.y0 as f64 + ((i / n) as f64 + 0.5) / f;
            x >= bounds.x0 as f64
                && x < bounds.x1 as f64
                && y >= bounds.y0 as f64
                && y < bounds.y1 as f64
        })
        .collect();
    let mut prob = nets.mask_prob(&input, Some(&inside))?;
    let found: Vec<bool> = prob.iter().map(|&p| p > 0.5).collect();
    if found.iter().any(|&m| m) {
        prob = nets.mask_prob(&input, Some(&found))?;
    }
    let prior = |x: f64, y: f64| -> f32 {
        let (u, v) = (
            (x - crop.x0 as f64) * f - 0.5,
            (y - crop.y0 as f64) * f - 0.5,
        );
        if u < -0.5 || v < -0.5 || u > n as f64 - 0.5 || v > n as f64 - 0.5 {
            return 0.5;
        }
        raster::bilinear_scalar(&prob, n, n, u, v)
    };
    let hints = Hints {
        bounds,
        hard_bounds,
        area,
        object: &pointing.object,
        background: &pointing.background,
        prior: Some(&prior),
    };
    let found = |m: &[bool]| m.iter().filter(|&&m| m).count() >= MIN_OBJECT_PIXELS;
    let mut mask = segment::cut(photo, &hints, &Settings::default());
    if !found(&mask) {
        // the nets saw nothing where the user points (a close-up unlike their training
        // frames): the photo's colours and edges alone
        let hints = Hints {
            prior: None,
            ..hints
        };
        mask = segment::cut(photo, &hints, &Settings::default());
    }
    if !found(&mask) {
        return Err(invalid!(
            "no object found where pointed at: draw the box closer around it, or give --point on it or --mask"
        ));
    }
    Ok(mask)
}

/// The square `crop` of `photo` box-filtered to `n` x `n` (black past its edges), reading
/// each pixel once: the crop around a box on a large photo is never copied whole.
fn box_filtered(photo: &Image, crop: Crop, n: usize) -> Image {
    use rayon::prelude::*;
    let (w, h) = (photo.width as i64, photo.height as i64);
    let edge = |i: usize, o: i64| o + (i * crop.size / n) as i64;
    let mut out = Image::zeros(n, n);
    out.pixels
        .par_chunks_mut(n)
        .enumerate()
        .for_each(|(j, row)| {
            let (ya, yb) = (
                edge(j, crop.y0),
                edge(j + 1, crop.y0).max(edge(j, crop.y0) + 1),
            );
            for (i, o) in row.iter_mut().enumerate() {
                let (xa, xb) = (
                    edge(i, crop.x0),
                    edge(i + 1, crop.x0).max(edge(i, crop.x0) + 1),
                );
                let mut sum = [0.0f64; 3];
                for y in ya.max(0)..yb.min(h) {
                    for x in xa.max(0)..xb.min(w) {
                        let p = photo.pixels[(y * w + x) as usize];
                        for k in 0..3 {
                            sum[k] += f64::from(p[k]);
                        }
                    }
                }
                let count = ((yb - ya) * (xb - xa)) as f64;
                *o = sum.map(|s| (s / count) as f32);
            }
        });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(p: &Pointing) -> String {
        p.check(600, 400).unwrap_err().to_string()
    }

    #[test]
    fn pointings_are_checked() {
        let boxed = |x0, y0, x1, y1| Pointing {
            bounds: Some(Rect { x0, y0, x1, y1 }),
            ..Pointing::default()
        };
        assert_eq!(
            err(&boxed(10, 10, 900, 50)),
            "box 10,10,900,50: outside the 600x400 photo"
        );
        assert!(err(&boxed(50, 10, 10, 50)).contains("empty"));
        assert!(err(&boxed(10, 10, 12, 50)).contains("2x40 pixels; at least 4"));
        let mut p = boxed(10, 10, 100, 100);
        assert!(p.check(600, 400).is_ok());
        p.object.push([700, 20]);
        assert_eq!(err(&p), "point 700,20: outside the 600x400 photo");
        p.object[0] = [200, 20];
        assert_eq!(err(&p), "point 200,20: outside the box 10,10,100,100");
        p.object.clear();
        p.background.push([600, 0]);
        assert_eq!(err(&p), "not 600,0: outside the 600x400 photo");
        let only_not = Pointing {
            background: vec![[1, 1]],
            ..Pointing::default()
        };
        assert!(err(&only_not).contains("need a box or a point"));
        assert!(Pointing::default().is_empty());
    }
}
