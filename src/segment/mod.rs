//! An object cut out of a photo from hints (GrabCut, Rother, Kolmogorov and Blake 2004,
//! with a prior): a box outside which is background, points on the object and points off
//! it, and, if given, a probability of each pixel being on the object (the nets' mask).
//!
//! The work is done on a grid of at most [`Settings::work_size`] cells a side (256) over the
//! area around the box (each cell the mean of its pixels' display colours): colour models
//! of the object and the background (mixtures of Gaussians, [`gmm`]), then a minimum cut
//! ([`maxflow`]) of a graph whose terminal arcs are each cell's colour cost (and the
//! prior's) and whose 8-neighbour arcs cost more where colours are alike (a cut runs
//! along the photo's edges); the models are refitted to the cut and the cut taken again,
//! a few times. The connected part of the object that holds the points (else the box's
//! centre, else the largest) is kept, and brought back to the photo's pixels by a guided
//! filter ([`guided`]) with the photo's brightness as guide, thresholded at one half.

pub mod gmm;
pub mod guided;
pub mod maxflow;

use rayon::prelude::*;

use crate::Image;
use gmm::ColourModel;
use maxflow::FlowGraph;

/// A rectangle of pixels: columns `x0..x1`, rows `y0..y1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// First column.
    pub x0: usize,
    /// First row.
    pub y0: usize,
    /// One past the last column.
    pub x1: usize,
    /// One past the last row.
    pub y1: usize,
}

impl Rect {
    fn contains(&self, x: f64, y: f64) -> bool {
        x >= self.x0 as f64 && x < self.x1 as f64 && y >= self.y0 as f64 && y < self.y1 as f64
    }
}

/// What is known of the object before the cut.
pub struct Hints<'a> {
    /// The object lies inside.
    pub bounds: Rect,
    /// Whether the pixels outside `bounds` are background for certain (a box drawn around
    /// the object) or only likely to be (bounds guessed from points).
    pub hard_bounds: bool,
    /// The pixels looked at (holds `bounds`); outside it nothing is on the object.
    pub area: Rect,
    /// Pixels (column, row) on the object.
    pub object: &'a [[usize; 2]],
    /// Pixels (column, row) off the object.
    pub background: &'a [[usize; 2]],
    /// The probability of the photo's point (x, y) (pixel units, 0 at the left edge)
    /// being on the object, from elsewhere (`None`: none).
    pub prior: Option<&'a (dyn Fn(f64, f64) -> f32 + Sync)>,
}

/// How to cut.
#[derive(Clone, Debug)]
pub struct Settings {
    /// The working grid's longest side, in cells.
    pub work_size: usize,
    /// Colour models fitted and cuts taken.
    pub iterations: usize,
    /// Components of each colour model.
    pub components: usize,
    /// Weight of the neighbours' arcs (GrabCut's gamma).
    pub smoothness: f32,
    /// Weight of the prior's cost, -ln p, beside the colour models'.
    pub prior_weight: f32,
    /// Cost of the object outside soft bounds, per cell.
    pub outside_cost: f32,
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            work_size: 256,
            iterations: 3,
            components: 5,
            smoothness: 50.0,
            prior_weight: 1.0,
            outside_cost: 2.0,
        }
    }
}

/// A cost that no cut pays (a hard constraint).
const HARD: f32 = 1e6;

/// The grid the cut is taken on: `w` x `h` cells, each `1 / scale` pixels a side.
struct Grid {
    w: usize,
    h: usize,
    scale: f64,
    area: Rect,
    /// Mean display colour per cell.
    colour: Vec<[f32; 3]>,
    /// Mean display brightness per cell (the guided filter's coarse guide).
    luma: Vec<f32>,
}

impl Grid {
    /// The photo's point at the centre of cell (gx, gy).
    fn centre(&self, gx: usize, gy: usize) -> (f64, f64) {
        (
            self.area.x0 as f64 + (gx as f64 + 0.5) / self.scale,
            self.area.y0 as f64 + (gy as f64 + 0.5) / self.scale,
        )
    }

    /// The cell under pixel (x, y), clamped to the grid.
    fn cell(&self, x: usize, y: usize) -> (usize, usize) {
        let c = |v: usize, o: usize, n: usize| {
            (((v.saturating_sub(o)) as f64 * self.scale) as usize).min(n - 1)
        };
        (c(x, self.area.x0, self.w), c(y, self.area.y0, self.h))
    }
}

/// A display value of a linear one (a square root: about sRGB's curve, and cheap).
fn display(v: f32) -> f32 {
    v.clamp(0.0, 1.0).sqrt()
}

fn luma(c: &[f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The object's pixels in `photo` (row-major, its size) from `hints`.
pub fn cut(photo: &Image, hints: &Hints, settings: &Settings) -> Vec<bool> {
    let grid = grid(photo, hints.area, settings.work_size);
    let fg = cut_grid(&grid, hints, settings);
    let kept = keep_part(&grid, &fg, hints);
    upsample(photo, &grid, &kept, hints)
}

/// The photo's area box-filtered to the grid.
fn grid(photo: &Image, area: Rect, work_size: usize) -> Grid {
    let (aw, ah) = (area.x1 - area.x0, area.y1 - area.y0);
    let scale = (work_size as f64 / aw.max(ah) as f64).min(1.0);
    let (w, h) = (
        ((aw as f64 * scale).ceil() as usize).max(1),
        ((ah as f64 * scale).ceil() as usize).max(1),
    );
    let mut g = Grid {
        w,
        h,
        scale,
        area,
        colour: vec![[0.0; 3]; w * h],
        luma: vec![0.0; w * h],
    };
    let col: Vec<usize> = (area.x0..area.x1).map(|x| g.cell(x, area.y0).0).collect();
    let row: Vec<usize> = (area.y0..area.y1).map(|y| g.cell(area.x0, y).1).collect();
    let (mut colours, mut lumas) = (std::mem::take(&mut g.colour), std::mem::take(&mut g.luma));
    colours
        .par_chunks_mut(w)
        .zip(lumas.par_chunks_mut(w))
        .enumerate()
        .for_each(|(gy, (colour, lum))| {
            let start = row.partition_point(|&r| r < gy);
            let end = row.partition_point(|&r| r <= gy);
            let mut sum = vec![[0.0f32; 4]; w];
            let mut n = vec![0u32; w];
            for y in area.y0 + start..area.y0 + end {
                let line = &photo.pixels[y * photo.width + area.x0..y * photo.width + area.x1];
                for (p, &gx) in line.iter().zip(&col) {
                    let d = p.map(display);
                    let s = &mut sum[gx];
                    s[0] += d[0];
                    s[1] += d[1];
                    s[2] += d[2];
                    s[3] += luma(&d);
                    n[gx] += 1;
                }
            }
            for gx in 0..w {
                let k = n[gx].max(1) as f32;
                colour[gx] = [sum[gx][0] / k, sum[gx][1] / k, sum[gx][2] / k];
                lum[gx] = sum[gx][3] / k;
            }
        });
    (g.colour, g.luma) = (colours, lumas);
    g
}

/// The cells on the object: GrabCut's iterations on the grid.
fn cut_grid(g: &Grid, hints: &Hints, settings: &Settings) -> Vec<bool> {
    let n = g.w * g.h;
    // hard labels: 1 object, 2 background, 0 unknown
    let mut fixed = vec![0u8; n];
    let mut prior = vec![0.5f32; n];
    let mut outside = vec![false; n];
    for gy in 0..g.h {
        for gx in 0..g.w {
            let i = gy * g.w + gx;
            let (x, y) = g.centre(gx, gy);
            outside[i] = !hints.bounds.contains(x, y);
            if outside[i] && hints.hard_bounds {
                fixed[i] = 2;
            }
            if let Some(p) = hints.prior {
                prior[i] = p(x, y).clamp(0.05, 0.95);
            }
        }
    }
    // points hold a small disc of cells
    let radius = ((g.w.max(g.h) as f64) * 0.012).max(1.0) as i64;
    for (points, label) in [(hints.background, 2u8), (hints.object, 1u8)] {
        for p in points {
            let (cx, cy) = g.cell(p[0], p[1]);
            for dy in -radius..=radius {
                for dx in -radius..=radius {
                    let (x, y) = (cx as i64 + dx, cy as i64 + dy);
                    if dx * dx + dy * dy <= radius * radius
                        && (0..g.w as i64).contains(&x)
                        && (0..g.h as i64).contains(&y)
                    {
                        fixed[y as usize * g.w + x as usize] = label;
                    }
                }
            }
        }
    }
    // the first guess: inside the bounds where the prior does not rule it out
    let mut fg: Vec<bool> = (0..n)
        .map(|i| fixed[i] == 1 || (fixed[i] == 0 && !outside[i] && prior[i] > 0.2))
        .collect();

    let pairs = neighbour_pairs(g);
    let mean_d2 = pairs.iter().map(|p| p.2).sum::<f32>() / pairs.len().max(1) as f32;
    let beta = 1.0 / (2.0 * mean_d2.max(1e-8));
    let (mut fg_model, mut bg_model): (Option<ColourModel>, Option<ColourModel>) = (None, None);
    for _ in 0..settings.iterations.max(1) {
        let of = |on: bool| -> Vec<[f32; 3]> {
            (0..n)
                .filter(|&i| fg[i] == on)
                .map(|i| g.colour[i])
                .collect()
        };
        let (fc, bc) = (of(true), of(false));
        fg_model = match &fg_model {
            Some(m) => m
                .refit(&fc)
                .or_else(|| ColourModel::fit(&fc, settings.components)),
            None => ColourModel::fit(&fc, settings.components),
        };
        bg_model = match &bg_model {
            Some(m) => m
                .refit(&bc)
                .or_else(|| ColourModel::fit(&bc, settings.components)),
            None => ColourModel::fit(&bc, settings.components),
        };
        let (Some(fm), Some(bm)) = (&fg_model, &bg_model) else {
            break;
        };
        let mut graph = FlowGraph::new(n, pairs.len());
        let unary: Vec<(f32, f32)> = g
            .colour
            .par_iter()
            .enumerate()
            .map(|(i, c)| match fixed[i] {
                1 => (HARD, 0.0),
                2 => (0.0, HARD),
                _ => {
                    let w = settings.prior_weight;
                    let mut on = fm.cost(c) - w * prior[i].ln();
                    let off = bm.cost(c) - w * (1.0 - prior[i]).ln();
                    if outside[i] {
                        on += settings.outside_cost;
                    }
                    // the source's arc is cut when the cell is background
                    (off, on)
                }
            })
            .collect();
        for (i, &(s, t)) in unary.iter().enumerate() {
            let m = s.min(t);
            graph.add_terminal(i, s - m, t - m);
        }
        for &(i, j, d2, diagonal) in &pairs {
            let mut c = settings.smoothness * (-beta * d2).exp();
            if diagonal {
                c *= std::f32::consts::FRAC_1_SQRT_2;
            }
            graph.add_edge(i as usize, j as usize, c, c);
        }
        graph.maxflow();
        let next: Vec<bool> = (0..n).map(|i| graph.is_source(i)).collect();
        let same = next == fg;
        fg = next;
        if same {
            break;
        }
    }
    fg
}

/// Each pair of 8-neighbour cells once: their indices, squared colour difference, and
/// whether they are diagonal.
fn neighbour_pairs(g: &Grid) -> Vec<(u32, u32, f32, bool)> {
    let mut out = Vec::with_capacity(4 * g.w * g.h);
    let d2 = |a: usize, b: usize| {
        let (p, q) = (g.colour[a], g.colour[b]);
        (0..3).map(|k| (p[k] - q[k]).powi(2)).sum::<f32>()
    };
    for y in 0..g.h {
        for x in 0..g.w {
            let i = y * g.w + x;
            let mut add =
                |j: usize, diagonal: bool| out.push((i as u32, j as u32, d2(i, j), diagonal));
            if x + 1 < g.w {
                add(i + 1, false);
            }
            if y + 1 < g.h {
                add(i + g.w, false);
                if x + 1 < g.w {
                    add(i + g.w + 1, true);
                }
                if x > 0 {
                    add(i + g.w - 1, true);
                }
            }
        }
    }
    out
}

/// The 8-connected parts of `fg` that hold an object point; else the one under the
/// bounds' centre; else the largest.
fn keep_part(g: &Grid, fg: &[bool], hints: &Hints) -> Vec<bool> {
    let mut label = vec![u32::MAX; fg.len()];
    let mut sizes = Vec::new();
    let mut stack = Vec::new();
    for start in 0..fg.len() {
        if !fg[start] || label[start] != u32::MAX {
            continue;
        }
        let id = sizes.len() as u32;
        let mut size = 0usize;
        label[start] = id;
        stack.push(start);
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y) = ((i % g.w) as i64, (i / g.w) as i64);
            for (dx, dy) in [
                (-1, -1),
                (0, -1),
                (1, -1),
                (-1, 0),
                (1, 0),
                (-1, 1),
                (0, 1),
                (1, 1),
            ] {
                let (nx, ny) = (x + dx, y + dy);
                if (0..g.w as i64).contains(&nx) && (0..g.h as i64).contains(&ny) {
                    let j = ny as usize * g.w + nx as usize;
                    if fg[j] && label[j] == u32::MAX {
                        label[j] = id;
                        stack.push(j);
                    }
                }
            }
        }
        sizes.push(size);
    }
    let label_at = |x: usize, y: usize| {
        let (cx, cy) = g.cell(x, y);
        label[cy * g.w + cx]
    };
    let mut keep = vec![false; sizes.len()];
    for p in hints.object {
        if let Some(k) = keep.get_mut(label_at(p[0], p[1]) as usize) {
            *k = true;
        }
    }
    if !keep.contains(&true) {
        let b = hints.bounds;
        let centre = label_at((b.x0 + b.x1) / 2, (b.y0 + b.y1) / 2) as usize;
        let largest = (0..sizes.len()).max_by_key(|&k| sizes[k]);
        if let Some(k) = keep.get_mut(centre).map(|_| centre).or(largest) {
            keep[k] = true;
        }
    }
    label
        .iter()
        .map(|&l| l != u32::MAX && keep[l as usize])
        .collect()
}

/// The kept cells at the photo's pixels: the guided filter's coefficients fitted on the
/// grid, applied to the photo's brightness, above one half; nothing outside the area (or
/// outside hard bounds).
fn upsample(photo: &Image, g: &Grid, kept: &[bool], hints: &Hints) -> Vec<bool> {
    let (w, h) = (photo.width, photo.height);
    let p: Vec<f32> = kept.iter().map(|&k| f32::from(u8::from(k))).collect();
    // 2 cells and a ridge of 1e-3 on display brightness: edges of a contrast above ~0.03
    // steer the mask, flatter ones leave it smooth
    let (a, b) = guided::coefficients(&g.luma, &p, g.w, g.h, 2, 1e-3);
    let clip = if hints.hard_bounds {
        hints.bounds
    } else {
        g.area
    };
    let mut out = vec![false; w * h];
    out.par_chunks_mut(w)
        .enumerate()
        .filter(|(y, _)| (clip.y0..clip.y1).contains(y))
        .for_each(|(y, row)| {
            let v = (y - g.area.y0) as f64 * g.scale + 0.5 * g.scale - 0.5;
            for (x, o) in row.iter_mut().enumerate().take(clip.x1).skip(clip.x0) {
                let u = (x - g.area.x0) as f64 * g.scale + 0.5 * g.scale - 0.5;
                let aa = crate::raster::bilinear_scalar(&a, g.w, g.h, u, v);
                let bb = crate::raster::bilinear_scalar(&b, g.w, g.h, u, v);
                let c = photo.pixels[y * w + x].map(display);
                *o = aa * luma(&c) + bb > 0.5;
            }
        });
    out
}

#[cfg(test)]
mod tests;
