//! Shadows from the environment: the object's contact shadow on the floor and its ambient
//! occlusion, as the weighted fraction of a set of light directions that the object does
//! not block.
//!
//! The map is grouped into a coarse grid of cells ([`GRID`]); each cell above the floor
//! becomes one direction (the radiance-weighted mean direction of its texels, so that a
//! sun stays where it is) with its power (luminance times solid angle). For each direction
//! the object's mesh is rasterised as an orthographic depth map ([`ShadowMap`]); a point is
//! lit from a direction where no part of the object lies between it and the light. The
//! layer itself has no visibility: the object's pixels are multiplied by the ratio of the
//! light that reaches them unblocked (weighted by n . d) to all of it, an approximation.

use crate::envgen::colour::luminance;
use crate::envmap::EnvMap;
use crate::shapes::Mesh;
use crate::shapes::mesh::{V3, cross, dot, unit};

/// Rows and columns of the grid of directions over the map (the cells above the floor,
/// about half of them, are the directions).
pub const GRID: (usize, usize) = (8, 16);
/// Texels of a shadow map on its longer side.
const MAP: usize = 96;

/// One direction towards the light: unit, and its power (luminance x solid angle).
#[derive(Clone, Copy, Debug)]
pub struct ShadowLight {
    /// Unit direction towards the light, camera frame.
    pub dir: V3,
    /// Luminance times solid angle of its cell.
    pub power: f64,
    /// Its cell's solid angle.
    pub solid_angle: f64,
    /// Above the floor (else the floor hides it).
    pub above: bool,
}

/// The directions of `env`'s cells: those above the plane with normal `up` that carry
/// light, and every one below it (where the floor is seen instead).
pub fn lights(env: &EnvMap, up: V3) -> Vec<ShadowLight> {
    let (gr, gc) = GRID;
    let mut sums = vec![([0.0f64; 3], 0.0f64, 0.0f64); gr * gc];
    for r in 0..env.height {
        for c in 0..env.width {
            let (d, d_omega) = env.convention.texel(r, c, env.height, env.width);
            let p = luminance(env.texels[r * env.width + c].map(f64::from)) * d_omega;
            let cell = &mut sums[(r * gr / env.height) * gc + c * gc / env.width];
            for k in 0..3 {
                cell.0[k] += p * d[k];
            }
            cell.1 += p;
            cell.2 += d_omega;
            if p == 0.0 {
                // a dark cell keeps a direction: its texels' mean
                for k in 0..3 {
                    cell.0[k] += 1e-300 * d[k];
                }
            }
        }
    }
    let total: f64 = sums.iter().map(|s| s.1).sum();
    sums.into_iter()
        .filter_map(|(d, p, solid_angle)| {
            let dir = unit(d)?;
            let above = dot(dir, up) > 0.0;
            (!above || p > 1e-5 * total).then_some(ShadowLight {
                dir,
                power: p,
                solid_angle,
                above,
            })
        })
        .collect()
}

/// The irradiance (RGB) that `env` gives a surface with normal `n`: the cosine-weighted
/// sum over the texels above it, with their solid angles.
pub fn irradiance(env: &EnvMap, n: V3) -> [f64; 3] {
    let mut e = [0.0; 3];
    for r in 0..env.height {
        for c in 0..env.width {
            let (d, d_omega) = env.convention.texel(r, c, env.height, env.width);
            let cos = dot(d, n);
            if cos > 0.0 {
                let t = env.texels[r * env.width + c];
                for k in 0..3 {
                    e[k] += f64::from(t[k]) * cos * d_omega;
                }
            }
        }
    }
    e
}

/// The object's depth along a light direction on an orthographic grid across it.
#[derive(Clone, Debug)]
pub struct ShadowMap {
    u: V3,
    v: V3,
    d: V3,
    lo: [f64; 2],
    cell: f64,
    n: usize,
    /// Largest p . d (nearest the light) per texel; -inf where the object is not.
    depth: Vec<f64>,
}

impl ShadowMap {
    /// Rasterises `mesh` (camera space) along `d` (unit, towards the light).
    pub fn new(mesh: &Mesh, d: V3) -> ShadowMap {
        let helper = if d[0].abs() < 0.9 {
            [1.0, 0.0, 0.0]
        } else {
            [0.0, 1.0, 0.0]
        };
        let u = unit(cross(helper, d)).unwrap_or([1.0, 0.0, 0.0]);
        let v = cross(d, u);
        let proj: Vec<V3> = mesh
            .positions
            .iter()
            .map(|p| {
                let p = p.map(f64::from);
                [dot(p, u), dot(p, v), dot(p, d)]
            })
            .collect();
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for p in &proj {
            for k in 0..2 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let n = MAP;
        let cell = ((hi[0] - lo[0]).max(hi[1] - lo[1]) / (n - 2) as f64).max(1e-9);
        let lo = [lo[0] - cell, lo[1] - cell];
        let mut depth = vec![f64::NEG_INFINITY; n * n];
        for tri in &mesh.triangles {
            let [a, b, c] = tri.map(|i| proj[i as usize]);
            let to = |p: V3| [(p[0] - lo[0]) / cell, (p[1] - lo[1]) / cell, p[2]];
            let (a, b, c) = (to(a), to(b), to(c));
            let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
            if area == 0.0 || !area.is_finite() {
                continue;
            }
            let x0 = (a[0].min(b[0]).min(c[0]) - 0.5).ceil().max(0.0) as usize;
            let x1 = ((a[0].max(b[0]).max(c[0]) - 0.5).floor().min(n as f64 - 1.0)) as isize;
            let y0 = (a[1].min(b[1]).min(c[1]) - 0.5).ceil().max(0.0) as usize;
            let y1 = ((a[1].max(b[1]).max(c[1]) - 0.5).floor().min(n as f64 - 1.0)) as isize;
            for y in y0 as isize..=y1 {
                for x in x0 as isize..=x1 {
                    let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                    let w0 = ((b[0] - px) * (c[1] - py) - (b[1] - py) * (c[0] - px)) / area;
                    let w1 = ((c[0] - px) * (a[1] - py) - (c[1] - py) * (a[0] - px)) / area;
                    let w2 = 1.0 - w0 - w1;
                    if w0 < 0.0 || w1 < 0.0 || w2 < 0.0 {
                        continue;
                    }
                    let z = w0 * a[2] + w1 * b[2] + w2 * c[2];
                    let i = y as usize * n + x as usize;
                    if z > depth[i] {
                        depth[i] = z;
                    }
                }
            }
        }
        ShadowMap {
            u,
            v,
            d,
            lo,
            cell,
            n,
            depth,
        }
    }

    /// How lit `p` is from this direction, in [0, 1]: the share of the four nearest
    /// texels (weighted bilinearly) where nothing lies more than `bias` texels nearer the
    /// light.
    pub fn lit(&self, p: V3, bias: f64) -> f64 {
        let x = (dot(p, self.u) - self.lo[0]) / self.cell - 0.5;
        let y = (dot(p, self.v) - self.lo[1]) / self.cell - 0.5;
        let z = dot(p, self.d) + bias * self.cell;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let mut lit = 0.0;
        for (dx, dy, w) in [
            (0, 0, (1.0 - fx) * (1.0 - fy)),
            (1, 0, fx * (1.0 - fy)),
            (0, 1, (1.0 - fx) * fy),
            (1, 1, fx * fy),
        ] {
            let (i, j) = (x0 as isize + dx, y0 as isize + dy);
            let n = self.n as isize;
            let blocked =
                i >= 0 && j >= 0 && i < n && j < n && self.depth[(j * n + i) as usize] > z;
            if !blocked {
                lit += w;
            }
        }
        lit
    }
}

/// The shadow maps of placed meshes along each light above the floor.
pub struct Shadows {
    lights: Vec<ShadowLight>,
    /// Per light: one map per mesh (`None` below the floor).
    maps: Vec<Option<Vec<ShadowMap>>>,
}

impl Shadows {
    /// The maps of `mesh` (camera space) for `lights`.
    pub fn new(mesh: &Mesh, lights: Vec<ShadowLight>) -> Shadows {
        Shadows::of(&[mesh], lights)
    }

    /// The maps of several meshes (camera space) for `lights`: each mesh has its own map
    /// along each light (a map across them all would spread its texels over the gaps),
    /// and a point is lit from a light where none of them blocks it.
    pub fn of(meshes: &[&Mesh], lights: Vec<ShadowLight>) -> Shadows {
        use rayon::prelude::*;
        let maps = lights
            .par_iter()
            .map(|l| {
                l.above.then(|| {
                    meshes
                        .iter()
                        .map(|m| ShadowMap::new(m, l.dir))
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        Shadows { lights, maps }
    }

    /// Directions with shadow maps (those above the floor).
    pub fn maps(&self) -> usize {
        self.maps.iter().flatten().count()
    }

    /// The visibility of point `p` whose surface has normal `n`: the light reaching it
    /// (the lights' power times n . d; a light below the floor replaced by the floor's
    /// luminance `floor` over its cell), over all the map gives it; 1 where no light
    /// reaches the normal, at most 1. A point on the object is moved off its surface
    /// along `n` by `offset` first.
    pub fn visibility(&self, p: V3, n: V3, offset: f64, bias: f64, floor: f64) -> f64 {
        let p = [0, 1, 2].map(|k| p[k] + offset * n[k]);
        let (mut lit, mut all) = (0.0, 0.0);
        for (l, m) in self.lights.iter().zip(&self.maps) {
            let w = l.power * dot(n, l.dir);
            if w <= 0.0 {
                continue;
            }
            all += w;
            lit += match m {
                // one mesh: its map's value, the bits of a single map
                Some(m) => w * m.iter().map(|m| m.lit(p, bias)).product::<f64>(),
                None => floor * l.solid_angle * dot(n, l.dir),
            };
        }
        if all > 0.0 {
            (lit / all).clamp(0.0, 1.0)
        } else {
            1.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::envmap::Convention;

    #[test]
    fn a_cube_shades_the_floor_under_it_not_far_away() {
        let mesh = crate::shapes::tessellate::cuboid([0.5, 0.5, 0.5]);
        let env = EnvMap::constant(16, 32, Convention::Equirect, [1.0; 3]).unwrap();
        let up = [0.0, 1.0, 0.0];
        let lights = lights(&env, up);
        assert_eq!(lights.len(), 128);
        let s = Shadows::new(&mesh, lights);
        let under = s.visibility([0.0, -0.5, 0.0], up, 0.0, 1.5, 0.0);
        let edge = s.visibility([0.6, -0.5, 0.0], up, 0.0, 1.5, 0.0);
        let far = s.visibility([8.0, -0.5, 0.0], up, 0.0, 1.5, 0.0);
        assert!(under < 0.05, "{under}");
        assert!(under < edge && edge < far, "{under} {edge} {far}");
        assert!(far > 0.95 && far <= 1.0, "{far}");
        // the top of the cube sees the whole sky
        let top = s.visibility([0.0, 0.5, 0.0], up, 0.02, 1.5, 0.0);
        assert!(top > 0.98, "{top}");
        assert_eq!(s.maps(), 64);
        // a side sees half the floor (dark here): about 1/2 to 3/4
        let side = s.visibility([0.5, 0.0, 0.0], [1.0, 0.0, 0.0], 0.02, 1.5, 0.0);
        assert!((0.4..0.8).contains(&side), "{side}");
        // irradiance of a constant sky of 1 on a plane: pi
        let e = irradiance(&env, up);
        // (within 1%: the midpoint rule over 8 rows of the hemisphere)
        assert!((e[0] / std::f64::consts::PI - 1.0).abs() < 0.01, "{e:?}");
    }
}
