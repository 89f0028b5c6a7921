//! The z-buffer rasteriser: triangles in camera space to the nearest triangle at each
//! pixel centre (edge functions over each triangle's bounding box, rows in bands that
//! rayon draws in parallel), then each covered pixel's normal.
//!
//! A pixel is covered where its centre is inside a triangle or on its edge. Depth is
//! compared as z (orthographic) or 1 / w with w = -z (perspective), both linear across
//! the screen; the nearer triangle wins and, at equal depth, the one listed first, so the
//! result does not depend on the number of threads.

use rayon::prelude::*;

use super::mesh::{V3, add, cross, dot, scale, sub, unit};
use super::view::{Placed, View};
use crate::camera::Camera;

/// Rows per band: a band is one rayon task with its own part of the z-buffer.
const BAND: usize = 8;

/// A triangle projected to the screen: pixel coordinates (x right, y down), the depth key
/// (larger is nearer) and the perspective weight 1 / w of each corner.
#[derive(Clone, Copy)]
struct Screen {
    x: [f64; 3],
    y: [f64; 3],
    depth: [f64; 3],
    inv_w: [f64; 3],
}

/// Projects a camera-space point: (pixel x, pixel y, depth key, 1 / w), or `None` when
/// it is not in front of a pinhole camera.
fn project(p: V3, view: &View) -> Option<[f64; 4]> {
    let (w, h) = (view.width as f64, view.height as f64);
    let (hx, hy) = view.half_extent();
    match view.camera {
        Camera::Orthographic => Some([
            (p[0] / hx + 1.0) / 2.0 * w,
            (1.0 - p[1] / hy) / 2.0 * h,
            p[2],
            1.0,
        ]),
        Camera::Perspective { .. } => {
            let depth = -p[2];
            (depth > 0.0).then(|| {
                let inv = 1.0 / depth;
                [
                    (p[0] * inv / hx + 1.0) / 2.0 * w,
                    (1.0 - p[1] * inv / hy) / 2.0 * h,
                    inv,
                    inv,
                ]
            })
        }
    }
}

fn screen(tri: [u32; 3], placed: &Placed, view: &View) -> Option<Screen> {
    let mut s = Screen {
        x: [0.0; 3],
        y: [0.0; 3],
        depth: [0.0; 3],
        inv_w: [0.0; 3],
    };
    for (k, &v) in tri.iter().enumerate() {
        let [x, y, d, i] = project(placed.positions[v as usize], view)?;
        (s.x[k], s.y[k], s.depth[k], s.inv_w[k]) = (x, y, d, i);
    }
    Some(s)
}

/// Twice the signed area of (a, b, p) in screen coordinates.
fn edge(ax: f64, ay: f64, bx: f64, by: f64, px: f64, py: f64) -> f64 {
    (bx - ax) * (py - ay) - (by - ay) * (px - ax)
}

/// 1 / (twice the signed screen area), if the triangle has an area.
fn inv_area(s: &Screen) -> Option<f64> {
    let area = edge(s.x[0], s.y[0], s.x[1], s.y[1], s.x[2], s.y[2]);
    (area != 0.0 && area.is_finite()).then(|| 1.0 / area)
}

/// Screen-space barycentric weights of point (cx, cy); all >= 0 where it is covered.
fn weights(s: &Screen, inv_area: f64, cx: f64, cy: f64) -> [f64; 3] {
    let b0 = edge(s.x[1], s.y[1], s.x[2], s.y[2], cx, cy) * inv_area;
    let b1 = edge(s.x[2], s.y[2], s.x[0], s.y[0], cx, cy) * inv_area;
    [b0, b1, 1.0 - b0 - b1]
}

/// The inclusive range of pixel indices whose centres (i + 0.5) lie in [lo, hi], clipped
/// to 0..n.
fn pixel_range(lo: f64, hi: f64, n: usize) -> Option<(usize, usize)> {
    let first = (lo - 0.5).ceil().max(0.0);
    let last = (hi - 0.5).floor().min(n as f64 - 1.0);
    (first <= last).then_some((first as usize, last as usize))
}

/// The nearest triangle at each pixel (`u32::MAX` where none), rows first.
pub(crate) fn visible(triangles: &[[u32; 3]], placed: &Placed, view: &View) -> Vec<u32> {
    let (w, h) = (view.width, view.height);
    let screens: Vec<Option<Screen>> = triangles
        .par_iter()
        .map(|&t| screen(t, placed, view))
        .collect();
    // each band's triangles, in order
    let bands = h.div_ceil(BAND);
    let mut binned: Vec<Vec<u32>> = vec![Vec::new(); bands];
    for (t, s) in screens.iter().enumerate() {
        let Some(s) = s else { continue };
        let lo = s.y.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = s.y.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if let Some((r0, r1)) = pixel_range(lo, hi, h) {
            for band in &mut binned[r0 / BAND..=r1 / BAND] {
                band.push(t as u32);
            }
        }
    }
    let mut ids = vec![u32::MAX; w * h];
    ids.par_chunks_mut(BAND * w)
        .zip(binned.par_iter())
        .enumerate()
        .for_each(|(band, (ids, tris))| {
            let row0 = band * BAND;
            let rows = ids.len() / w;
            let mut depth = vec![f64::NEG_INFINITY; ids.len()];
            for &t in tris {
                let Some(s) = &screens[t as usize] else {
                    continue;
                };
                draw(s, t, row0, rows, w, ids, &mut depth);
            }
        });
    ids
}

/// Draws one triangle into a band of `rows` rows starting at `row0`.
fn draw(
    s: &Screen,
    t: u32,
    row0: usize,
    rows: usize,
    w: usize,
    ids: &mut [u32],
    depth: &mut [f64],
) {
    let Some(inv_area) = inv_area(s) else {
        return;
    };
    let min = |v: &[f64; 3]| v[0].min(v[1]).min(v[2]);
    let max = |v: &[f64; 3]| v[0].max(v[1]).max(v[2]);
    let Some((x0, x1)) = pixel_range(min(&s.x), max(&s.x), w) else {
        return;
    };
    let Some((y0, y1)) = pixel_range(min(&s.y), max(&s.y), row0 + rows) else {
        return;
    };
    for py in y0.max(row0)..=y1 {
        let cy = py as f64 + 0.5;
        for px in x0..=x1 {
            let [b0, b1, b2] = weights(s, inv_area, px as f64 + 0.5, cy);
            if b0 < 0.0 || b1 < 0.0 || b2 < 0.0 {
                continue;
            }
            let z = b0 * s.depth[0] + b1 * s.depth[1] + b2 * s.depth[2];
            let i = (py - row0) * w + px;
            if z > depth[i] {
                depth[i] = z;
                ids[i] = t;
            }
        }
    }
}

/// The camera-space point of triangle `tri` seen at the centre of pixel (px, py): its
/// corners interpolated with the perspective-correct weights [`normal_at`] uses. `None`
/// where the triangle has no area.
pub(crate) fn position_at(
    tri: [u32; 3],
    placed: &Placed,
    view: &View,
    px: usize,
    py: usize,
) -> Option<V3> {
    let w = corner_weights(tri, placed, view, px, py)?;
    Some(blend(&placed.positions, tri, w))
}

/// The perspective-correct weights of `tri`'s corners at the centre of pixel (px, py):
/// the screen-space weights b_k / w_k, renormalised (1 / w = 1 when orthographic).
fn corner_weights(tri: [u32; 3], placed: &Placed, view: &View, px: usize, py: usize) -> Option<V3> {
    let s = screen(tri, placed, view)?;
    let b = weights(&s, inv_area(&s)?, px as f64 + 0.5, py as f64 + 0.5);
    let lw = [0, 1, 2].map(|k| b[k] * s.inv_w[k]);
    let total = lw[0] + lw[1] + lw[2];
    Some(lw.map(|l| l / total))
}

/// The corners' `values` of `tri` weighted by `w`.
fn blend(values: &[V3], tri: [u32; 3], w: V3) -> V3 {
    let mut v = [0.0; 3];
    for k in 0..3 {
        v = add(v, scale(values[tri[k] as usize], w[k]));
    }
    v
}

/// The normal at pixel (px, py) of triangle `tri`: the vertex normals interpolated
/// (perspective-correct) and normalised, or the face normal when `flat`; then turned to
/// face the viewer: the face normal is flipped if it faces away from the pixel's view
/// direction w_p, an interpolated normal is flipped if it disagrees with that face normal
/// (a face wound against its vertex normals), and one that still faces away (near a
/// silhouette) loses its component along w_p. `None` where the triangle has no area (then
/// [`visible`] draws nothing of it).
pub(crate) fn normal_at(
    tri: [u32; 3],
    placed: &Placed,
    view: &View,
    px: usize,
    py: usize,
) -> Option<V3> {
    let w = corner_weights(tri, placed, view, px, py)?;
    let [p0, p1, p2] = tri.map(|v| placed.positions[v as usize]);
    let wp = view.camera.view_dir(px, py, view.width, view.height);
    let mut face = unit(cross(sub(p1, p0), sub(p2, p0)))?;
    if dot(face, wp) < 0.0 {
        face = scale(face, -1.0);
    }
    if view.flat {
        return Some(face);
    }
    let Some(mut n) = unit(blend(&placed.normals, tri, w)) else {
        return Some(face);
    };
    if dot(n, face) < 0.0 {
        n = scale(n, -1.0);
    }
    let along = dot(n, wp);
    if along < 0.0 {
        n = sub(n, scale(wp, along));
    }
    Some(unit(n).unwrap_or(face))
}
