//! Normal tables: the layer at the nodes of a grid over the stereographic plane of normals,
//! interpolated per pixel from the 6 x 6 nodes around it (Lagrange interpolation of degree
//! 5 along each axis).
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

/// Nodes per axis of a pixel's stencil. In the lod bench's full default run, against
/// Catmull-Rom's 4 x 4 on the same 27 cases (the 256 and 512 scenes): table128's image error
/// 0.53 of it at the median (0.21 to 0.98), table256's 0.92 (0.14 to 1.02), never above 1.07;
/// the glossy gain most (`plastic-red` under `studio`, 512 sphere: table128 5.6e-3 against
/// 1.2e-3), and where the kinks of texels' horizons decide (`clay`) the two are level.
pub(crate) const TAPS: usize = 6;
/// Nodes of the stencil before the pixel's cell along an axis; the grid has as many more on
/// each side, for the stencils at the edges.
const MARGIN: usize = TAPS / 2 - 1;
/// Nodes per stencil.
pub(crate) const STENCIL: usize = TAPS * TAPS;

/// The grid: R nodes per axis over [-extent, extent], [`MARGIN`] more on each side for the
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
        self.r + 2 * MARGIN
    }

    fn spacing(&self) -> f64 {
        2.0 * self.extent / (self.r - 1) as f64
    }

    /// The unit normal at node (i, j) (margins included: i = 0 is [`MARGIN`] steps left of
    /// -extent).
    pub fn node_normal(&self, i: usize, j: usize) -> [f64; 3] {
        let h = self.spacing();
        let u = -self.extent + (i as f64 - MARGIN as f64) * h;
        let v = -self.extent + (j as f64 - MARGIN as f64) * h;
        let q = u * u + v * v;
        [
            2.0 * u / (1.0 + q),
            2.0 * v / (1.0 + q),
            (1.0 - q) / (1.0 + q),
        ]
    }

    /// A pixel's stencil (its first node and weights), or None if the pixel is left to
    /// per-pixel evaluation.
    fn place(&self, p: &PixelRec) -> Option<([usize; 2], [[f32; TAPS]; 2])> {
        let (u, v) = stereo(p)?;
        (u.abs() <= self.extent && v.abs() <= self.extent).then(|| self.stencil(u, v))
    }

    /// The first node of the stencil and the weights along each axis at (u, v).
    fn stencil(&self, u: f64, v: f64) -> ([usize; 2], [[f32; TAPS]; 2]) {
        let h = self.spacing();
        let axis = |x: f64| {
            let (c, t) = self.first(x, h);
            (c, lagrange(t - c as f64))
        };
        let (cu, wu) = axis(u);
        let (cv, wv) = axis(v);
        // node c - MARGIN of the grid is node c of the margined one
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
    /// stencil's first node, and a node is used where a flagged one is at most TAPS - 1
    /// before it along each axis (the stencil).
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
                *o = row[i.saturating_sub(TAPS - 1)..=i].iter().any(|&f| f);
            }
        }
        let mut used = 0;
        for j in 0..side {
            for i in 0..side {
                used += usize::from((j.saturating_sub(TAPS - 1)..=j).any(|b| rows[b * side + i]));
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

/// Lagrange weights of the [`TAPS`] nodes around a point a fraction `t` into its cell (the
/// nodes at -MARGIN, ..., TAPS - 1 - MARGIN): the polynomial of degree TAPS - 1 through
/// them. Exact for polynomials of that degree; continuous across cells, its derivative not.
fn lagrange(t: f64) -> [f32; TAPS] {
    let node = |i: usize| i as f64 - MARGIN as f64;
    std::array::from_fn(|i| {
        (0..TAPS)
            .filter(|&j| j != i)
            .map(|j| (t - node(j)) / (node(i) - node(j)))
            .product::<f64>() as f32
    })
}

/// One tabled pixel: where it goes, the slot in the node list of the first node of each of
/// its stencil's rows, and the weights along each axis (node (a, b) of the stencil weighs
/// `wu[a] * wv[b]`). The node list keeps the grid's order and holds every node of a
/// stencil, so a stencil's row is TAPS consecutive slots.
pub(crate) struct Cell {
    pub index: u32,
    pub rows: [u32; TAPS],
    pub wu: [f32; TAPS],
    pub wv: [f32; TAPS],
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
        let mut left = Vec::new();
        let mut stencils = Vec::with_capacity(pixels.len());
        for (k, p) in pixels.iter().enumerate() {
            match grid.place(p) {
                Some((at @ [cu, cv], [wu, wv])) => {
                    for b in 0..TAPS {
                        used[(cv + b) * side + cu..(cv + b) * side + cu + TAPS].fill(true);
                    }
                    stencils.push((p.index, at, wu, wv));
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
        let cells = stencils
            .into_iter()
            .map(|(index, [cu, cv], wu, wv)| Cell {
                index: index as u32,
                rows: std::array::from_fn(|b| slot[(cv + b) * side + cu]),
                wu,
                wv,
            })
            .collect();
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
            for (&at, &wv) in c.rows.iter().zip(&c.wv) {
                let row = &nodes[at as usize..at as usize + TAPS];
                let mut r = [0.0f32; 3];
                for (v, &wu) in row.iter().zip(&c.wu) {
                    for k in 0..3 {
                        r[k] += wu * v[k];
                    }
                }
                for k in 0..3 {
                    acc[k] += wv * r[k];
                }
            }
            for k in 0..3 {
                out[c.index as usize][k] += acc[k];
            }
        }
    }

    /// The interpolation's adjoint: per node, the sum of its weights times the upstream
    /// gradient `g` (image layout) over the pixels that use it.
    pub fn scatter(&self, g: &[[f32; 3]]) -> Vec<[f32; 3]> {
        let mut acc = vec![[0.0f64; 3]; self.normals.len()];
        for c in &self.cells {
            let gp = g[c.index as usize].map(f64::from);
            for (&at, &wv) in c.rows.iter().zip(&c.wv) {
                let row = &mut acc[at as usize..at as usize + TAPS];
                let gv = gp.map(|x| x * f64::from(wv));
                for (a, &wu) in row.iter_mut().zip(&c.wu) {
                    for k in 0..3 {
                        a[k] += f64::from(wu) * gv[k];
                    }
                }
            }
        }
        acc.iter().map(|a| a.map(|v| v as f32)).collect()
    }

    /// dLoss/dn of the tabled pixels, added to `out`: sum over channels of g_c times the
    /// interpolated dI_c/dn, from `jac`, the nodes' dI_c/dn.
    pub fn normal_gradients(&self, g: &[[f32; 3]], jac: &[[[f32; 3]; 3]], out: &mut [[f32; 3]]) {
        for c in &self.cells {
            let gp = g[c.index as usize];
            let mut acc = [0.0f32; 3];
            for (&at, &wv) in c.rows.iter().zip(&c.wv) {
                let row = &jac[at as usize..at as usize + TAPS];
                // the row's sum of wu_a dI_c/dn, contracted with g
                let mut r = [0.0f32; 3];
                for (j, &wu) in row.iter().zip(&c.wu) {
                    for ch in 0..3 {
                        let wg = wu * gp[ch];
                        for a in 0..3 {
                            r[a] += wg * j[ch][a];
                        }
                    }
                }
                for a in 0..3 {
                    acc[a] += wv * r[a];
                }
            }
            for a in 0..3 {
                out[c.index as usize][a] += acc[a];
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
