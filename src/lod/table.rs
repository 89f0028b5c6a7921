//! Normal tables: the layer at the nodes of a grid over the stereographic plane of normals,
//! interpolated per pixel with Catmull-Rom splines.
//!
//! (u, v) = (n.x, n.y) / (1 + n.z) maps the unit sphere (less -z) smoothly onto the plane,
//! the front hemisphere onto the unit disc, so a function that is smooth in the normal is
//! smooth on the grid: no seams to interpolate across.

use crate::prepare::{PixelRec, Prepared};

/// Unit normals only: |n|^2 - 1 must be below this for a pixel to be tabled (the layer
/// uses normals as given, and a table holds unit ones).
pub(crate) const UNIT_TOLERANCE: f64 = 1e-5;
/// Normals further behind than n.z = -0.6 (|(u, v)| > 2) are evaluated per pixel.
const MAX_RADIUS: f64 = 2.0;

/// The grid: R nodes per axis over [-extent, extent], one more on each side for the
/// stencils at the edges.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Grid {
    pub r: usize,
    pub extent: f64,
}

impl Grid {
    /// The grid of resolution `r` over the tabled pixels' footprint.
    pub fn new(r: usize, pixels: &[PixelRec]) -> Self {
        let extent = extent(pixels.iter().filter_map(stereo));
        Grid { r, extent }
    }

    /// Nodes per axis, margins included.
    pub fn side(&self) -> usize {
        self.r + 2
    }

    fn spacing(&self) -> f64 {
        2.0 * self.extent / (self.r - 1) as f64
    }

    /// The unit normal at node (i, j) (margins included: i = 0 is one step left of
    /// -extent).
    pub fn node_normal(&self, i: usize, j: usize) -> [f64; 3] {
        let h = self.spacing();
        let u = -self.extent + (i as f64 - 1.0) * h;
        let v = -self.extent + (j as f64 - 1.0) * h;
        let q = u * u + v * v;
        [
            2.0 * u / (1.0 + q),
            2.0 * v / (1.0 + q),
            (1.0 - q) / (1.0 + q),
        ]
    }

    /// A pixel's stencil (its first node and weights), or None if the pixel is left to
    /// per-pixel evaluation.
    fn place(&self, p: &PixelRec) -> Option<([usize; 2], [[f32; 4]; 2])> {
        let (u, v) = stereo(p)?;
        (u.abs() <= self.extent && v.abs() <= self.extent).then(|| self.stencil(u, v))
    }

    /// Flags the 16 nodes of the stencil whose first node is `at`.
    fn mark(&self, used: &mut [bool], [cu, cv]: [usize; 2]) {
        let side = self.side();
        for b in 0..4 {
            used[(cv + b) * side + cu..(cv + b) * side + cu + 4].fill(true);
        }
    }

    /// The first node of the stencil and the weights along each axis at (u, v).
    fn stencil(&self, u: f64, v: f64) -> ([usize; 2], [[f32; 4]; 2]) {
        let h = self.spacing();
        let axis = |x: f64| {
            let (c, t) = self.first(x, h);
            (c, catmull_rom(t - c as f64))
        };
        let (cu, wu) = axis(u);
        let (cv, wv) = axis(v);
        // node c - 1 of the grid is node c of the margined one
        ([cu, cv], [wu, wv])
    }

    /// Along one axis: the stencil's first node and the coordinate in node spacings `h`.
    fn first(&self, x: f64, h: f64) -> (usize, f64) {
        let t = (x + self.extent) / h;
        ((t.floor().max(0.0) as usize).min(self.r - 2), t)
    }
}

/// The tabled pixels' stereographic coordinates, to count the nodes of grids of several
/// resolutions over the same pixels (the choice's cost model) without making their tables.
pub(crate) struct Footprint {
    uv: Vec<(f64, f64)>,
    left: usize,
    extent: f64,
}

impl Footprint {
    pub fn new(pixels: &[PixelRec]) -> Self {
        let (mut uv, mut left) = (Vec::with_capacity(pixels.len()), 0);
        for p in pixels {
            match stereo(p) {
                Some(x) => uv.push(x),
                None => left += 1,
            }
        }
        let extent = extent(uv.iter().copied());
        Footprint { uv, left, extent }
    }

    /// How many nodes the table of resolution `r` over these pixels has ([`Grid::new`]'s
    /// extent), and how many pixels it leaves to per-pixel evaluation: each pixel flags its
    /// stencil's first node, and a node is used where a flagged one is at most 3 before it
    /// along each axis (the 4 x 4 stencil).
    pub fn count(&self, r: usize) -> (usize, usize) {
        let grid = Grid {
            r,
            extent: self.extent,
        };
        let (side, h) = (grid.side(), grid.spacing());
        let mut first = vec![false; side * side];
        for &(u, v) in &self.uv {
            let (cu, cv) = (grid.first(u, h).0, grid.first(v, h).0);
            first[cv * side + cu] = true;
        }
        let mut rows = vec![false; side * side];
        for (row, out) in first.chunks(side).zip(rows.chunks_mut(side)) {
            for (i, o) in out.iter_mut().enumerate() {
                *o = row[i.saturating_sub(3)..=i].iter().any(|&f| f);
            }
        }
        let mut used = 0;
        for j in 0..side {
            for i in 0..side {
                used += usize::from((j.saturating_sub(3)..=j).any(|b| rows[b * side + i]));
            }
        }
        (used, self.left)
    }
}

/// The grid's half-width over stereographic coordinates: their largest |u| or |v|.
fn extent(uv: impl Iterator<Item = (f64, f64)>) -> f64 {
    uv.fold(1e-3f64, |m, (u, v)| m.max(u.abs()).max(v.abs()))
}

/// The pixel's stereographic coordinates, if it can be tabled.
fn stereo(p: &PixelRec) -> Option<(f64, f64)> {
    let n = p.n;
    if p.nn_m1.abs() > UNIT_TOLERANCE || n[2] <= -0.6 {
        return None;
    }
    let (u, v) = (n[0] / (1.0 + n[2]), n[1] / (1.0 + n[2]));
    (u * u + v * v <= MAX_RADIUS * MAX_RADIUS).then_some((u, v))
}

/// Catmull-Rom weights of the 4 nodes around a point a fraction `t` into its cell.
fn catmull_rom(t: f64) -> [f32; 4] {
    let (t2, t3) = (t * t, t * t * t);
    [
        0.5 * (-t3 + 2.0 * t2 - t),
        0.5 * (3.0 * t3 - 5.0 * t2 + 2.0),
        0.5 * (-3.0 * t3 + 4.0 * t2 + t),
        0.5 * (t3 - t2),
    ]
    .map(|w| w as f32)
}

/// One tabled pixel: where it goes, its 16 nodes (slots in the node list) and weights.
pub(crate) struct Cell {
    pub index: usize,
    pub slots: [u32; 16],
    pub weights: [f32; 16],
}

/// A table over some pixels: the nodes they need, and per pixel its stencil.
pub(crate) struct Table {
    /// The nodes' unit normals, in grid order.
    pub normals: Vec<[f64; 3]>,
    /// The tabled pixels.
    pub cells: Vec<Cell>,
    /// Positions (in the pixel list given) of the pixels left to per-pixel evaluation.
    pub left: Vec<usize>,
}

impl Table {
    /// The table of `grid` that `pixels` need.
    pub fn new(grid: &Grid, pixels: &[PixelRec]) -> Self {
        let side = grid.side();
        let mut used = vec![false; side * side];
        let mut cells = Vec::with_capacity(pixels.len());
        let mut left = Vec::new();
        let mut stencils = Vec::with_capacity(pixels.len());
        for (k, p) in pixels.iter().enumerate() {
            match grid.place(p) {
                Some((at, [wu, wv])) => {
                    grid.mark(&mut used, at);
                    stencils.push((p.index, at[0], at[1], wu, wv));
                }
                None => left.push(k),
            }
        }
        let mut slot = vec![u32::MAX; side * side];
        let mut normals = Vec::new();
        for j in 0..side {
            for i in 0..side {
                if used[j * side + i] {
                    slot[j * side + i] = normals.len() as u32;
                    normals.push(grid.node_normal(i, j));
                }
            }
        }
        for (index, cu, cv, wu, wv) in stencils {
            let mut c = Cell {
                index,
                slots: [0; 16],
                weights: [0.0; 16],
            };
            for b in 0..4 {
                for a in 0..4 {
                    c.slots[b * 4 + a] = slot[(cv + b) * side + cu + a];
                    c.weights[b * 4 + a] = wu[a] * wv[b];
                }
            }
            cells.push(c);
        }
        Table {
            normals,
            cells,
            left,
        }
    }

    /// The nodes as the pixels of a scene with `base`'s lights, in one row.
    pub fn nodes_scene(&self, base: &Prepared) -> Prepared {
        let pixels = self
            .normals
            .iter()
            .enumerate()
            .map(|(i, &n)| PixelRec::new(i, n, [0.0, 0.0, 1.0]))
            .collect();
        base.with_pixels(self.normals.len(), 1, pixels)
    }

    /// Adds the interpolated node values `nodes` to `out` (image layout).
    pub fn interpolate(&self, nodes: &[[f32; 3]], out: &mut [[f32; 3]]) {
        for c in &self.cells {
            let mut acc = [0.0f32; 3];
            for (&s, &w) in c.slots.iter().zip(&c.weights) {
                let v = nodes[s as usize];
                for k in 0..3 {
                    acc[k] += w * v[k];
                }
            }
            for k in 0..3 {
                out[c.index][k] += acc[k];
            }
        }
    }

    /// The interpolation's adjoint: per node, the sum of its weights times the upstream
    /// gradient `g` (image layout) over the pixels that use it.
    pub fn scatter(&self, g: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let mut acc = vec![[0.0f64; 3]; self.normals.len()];
        for c in &self.cells {
            let gp = g[c.index].map(f64::from);
            for (&s, &w) in c.slots.iter().zip(&c.weights) {
                let a = &mut acc[s as usize];
                for k in 0..3 {
                    a[k] += f64::from(w) * gp[k];
                }
            }
        }
        acc.iter().map(|a| a.map(|v| v as f32)).collect()
    }

    /// dLoss/dn of the tabled pixels, added to `out`: sum over channels of g_c times the
    /// interpolated dI_c/dn, from `jac`, the nodes' dI_c/dn.
    pub fn normal_gradients(&self, g: &[[f32; 3]], jac: &[[[f32; 3]; 3]], out: &mut [[f32; 3]]) {
        for c in &self.cells {
            let gp = g[c.index];
            let mut acc = [0.0f32; 3];
            for (&s, &w) in c.slots.iter().zip(&c.weights) {
                let s = s as usize;
                for ch in 0..3 {
                    let j = jac[s][ch];
                    let wg = w * gp[ch];
                    for a in 0..3 {
                        acc[a] += wg * j[a];
                    }
                }
            }
            for a in 0..3 {
                out[c.index][a] += acc[a];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn footprint_counts_as_the_tables_do() {
        // normals over the front hemisphere and some behind it (left per pixel), a few
        // not unit length
        let mut z = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            z ^= z << 13;
            z ^= z >> 7;
            z ^= z << 17;
            (z >> 11) as f64 / (1u64 << 53) as f64
        };
        let pixels: Vec<PixelRec> = (0..5000)
            .map(|i| {
                let (a, b) = (next() * std::f64::consts::TAU, next() * 2.0 - 1.0);
                let s = (1.0 - b * b).sqrt();
                let n = [s * a.cos(), s * a.sin(), b * 0.9 + 0.1];
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let k = if i % 97 == 0 { 1.1 } else { 1.0 / l };
                PixelRec::new(i, n.map(|x| x * k), [0.0, 0.0, 1.0])
            })
            .collect();
        let fp = Footprint::new(&pixels);
        for r in [4, 16, 32, 96, 256] {
            let table = Table::new(&Grid::new(r, &pixels), &pixels);
            let counted = (table.normals.len(), table.left.len());
            assert_eq!(fp.count(r), counted, "r = {r}");
            assert!(counted.0 > 0 && counted.1 > 0);
        }
    }
}
