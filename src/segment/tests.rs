//! The cut on drawn photos: a disc on a cluttered background, with a box or with points.

use super::*;
use crate::splitmix::SplitMix;

/// A `w` x `h` photo of random-coloured squares (8 pixels) with a reddish disc of radius
/// `r` at (cx, cy), and the disc's pixels.
pub(crate) fn disc_on_clutter(w: usize, h: usize, cx: f64, cy: f64, r: f64) -> (Image, Vec<bool>) {
    let mut rng = SplitMix(3);
    let tiles: Vec<[f32; 3]> = (0..w.div_ceil(8) * h.div_ceil(8))
        .map(|_| {
            [
                rng.uniform() as f32 * 0.5,
                rng.uniform() as f32 * 0.6,
                rng.uniform() as f32 * 0.6,
            ]
        })
        .collect();
    let mut img = Image::zeros(w, h);
    let mut truth = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let on = (x as f64 + 0.5 - cx).hypot(y as f64 + 0.5 - cy) < r;
            truth[i] = on;
            img.pixels[i] = if on {
                let shade = 0.5 + 0.4 * ((x as f64 - cx) / r) as f32;
                [0.8 * shade, 0.15 * shade, 0.1 * shade]
            } else {
                tiles[(y / 8) * w.div_ceil(8) + x / 8]
            };
        }
    }
    (img, truth)
}

pub(crate) fn iou(a: &[bool], b: &[bool]) -> f64 {
    let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let any = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    both as f64 / any.max(1) as f64
}

#[test]
fn a_box_cuts_the_disc_out_of_clutter() {
    let (img, truth) = disc_on_clutter(300, 200, 140.0, 100.0, 60.0);
    let hints = Hints {
        bounds: Rect {
            x0: 70,
            y0: 30,
            x1: 215,
            y1: 172,
        },
        hard_bounds: true,
        area: Rect {
            x0: 50,
            y0: 10,
            x1: 235,
            y1: 192,
        },
        object: &[],
        background: &[],
        prior: None,
    };
    let m = cut(&img, &hints, &Settings::default());
    let j = iou(&m, &truth);
    assert!(j > 0.95, "IoU {j}");
}

#[test]
fn points_alone_find_the_disc() {
    let (img, truth) = disc_on_clutter(300, 200, 140.0, 100.0, 60.0);
    let hints = Hints {
        bounds: Rect {
            x0: 60,
            y0: 20,
            x1: 220,
            y1: 180,
        },
        hard_bounds: false,
        area: Rect {
            x0: 0,
            y0: 0,
            x1: 300,
            y1: 200,
        },
        object: &[[140, 100], [110, 90]],
        background: &[],
        prior: None,
    };
    let m = cut(&img, &hints, &Settings::default());
    let j = iou(&m, &truth);
    assert!(j > 0.9, "IoU {j}");
}
