//! The surfaces the procedural shapes are made of, as triangle meshes with normals: closed
//! rings of vertices between two poles (sphere-like surfaces and rounded tubes), rings
//! wrapped both ways (tori), and solids with sharp creases (prisms, boxes, cylinders)
//! whose faces carry their own vertices and flat normals.
//!
//! Triangles are wound counter-clockwise seen from outside; smooth surfaces get
//! area-weighted vertex normals ([`Mesh::smooth_normals`]).

use std::f64::consts::PI;

use super::mesh::{Mesh, V3, add, cross, scale, sub, unit};

fn f32s(v: V3) -> [f32; 3] {
    v.map(|c| c as f32)
}

fn with_smooth_normals(mut m: Mesh) -> Mesh {
    m.normals = Some(m.smooth_normals());
    m
}

/// A closed surface: pole `top`, rings of equal length (each ordered by increasing
/// angle about the axis from `top` to `bottom`, counter-clockwise seen from `top`), pole
/// `bottom`.
pub fn closed_rings(top: V3, rings: &[Vec<V3>], bottom: V3) -> Mesh {
    let cols = rings.first().map_or(0, Vec::len);
    let mut m = Mesh::default();
    m.positions.push(f32s(top));
    for ring in rings {
        m.positions.extend(ring.iter().map(|&p| f32s(p)));
    }
    let b = m.positions.len() as u32;
    m.positions.push(f32s(bottom));
    let at = |r: usize, i: usize| (1 + r * cols + i % cols) as u32;
    for i in 0..cols {
        m.triangles.push([0, at(0, i), at(0, i + 1)]);
        for r in 0..rings.len() - 1 {
            m.triangles.push([at(r, i), at(r + 1, i + 1), at(r, i + 1)]);
            m.triangles.push([at(r, i), at(r + 1, i), at(r + 1, i + 1)]);
        }
        let last = rings.len() - 1;
        m.triangles.push([b, at(last, i + 1), at(last, i)]);
    }
    with_smooth_normals(m)
}

/// A surface of revolution about +y: `profile`'s (radius, height) points, each turned into
/// a ring of `cols` points, between the poles at heights `top` and `bottom` on the axis.
pub fn lathe(top: f64, profile: &[[f64; 2]], bottom: f64, cols: usize) -> Mesh {
    let rings: Vec<Vec<V3>> = profile
        .iter()
        .map(|&[r, y]| {
            (0..cols)
                .map(|k| {
                    let phi = 2.0 * PI * k as f64 / cols as f64;
                    [r * phi.cos(), y, -r * phi.sin()]
                })
                .collect()
        })
        .collect();
    closed_rings([0.0, top, 0.0], &rings, [0.0, bottom, 0.0])
}

/// A sphere-like surface: `f(theta, phi)` on `rows` - 1 rings of `cols` points, theta
/// (from +y) in (0, pi), phi in [0, 2 pi) (see [`direction`]); the poles are f(0, 0) and
/// f(pi, 0).
pub fn sphere_grid(rows: usize, cols: usize, f: impl Fn(f64, f64) -> V3) -> Mesh {
    let rings: Vec<Vec<V3>> = (1..rows)
        .map(|r| {
            let theta = PI * r as f64 / rows as f64;
            (0..cols)
                .map(|i| f(theta, 2.0 * PI * i as f64 / cols as f64))
                .collect()
        })
        .collect();
    closed_rings(f(0.0, 0.0), &rings, f(PI, 0.0))
}

/// The unit direction at (theta, phi): theta from +y, phi from +x towards -z, so that
/// the rings run counter-clockwise seen from +y.
pub fn direction(theta: f64, phi: f64) -> V3 {
    [
        theta.sin() * phi.cos(),
        theta.cos(),
        -theta.sin() * phi.sin(),
    ]
}

/// A surface wrapped both ways (a torus): `f(u, v)` for u, v in [0, 1) on a `rows` x
/// `cols` grid.
pub fn torus_grid(rows: usize, cols: usize, f: impl Fn(f64, f64) -> V3) -> Mesh {
    let mut m = Mesh::default();
    for r in 0..rows {
        for i in 0..cols {
            m.positions
                .push(f32s(f(r as f64 / rows as f64, i as f64 / cols as f64)));
        }
    }
    let at = |r: usize, i: usize| ((r % rows) * cols + i % cols) as u32;
    for r in 0..rows {
        for i in 0..cols {
            m.triangles.push([at(r, i), at(r + 1, i + 1), at(r, i + 1)]);
            m.triangles.push([at(r, i), at(r + 1, i), at(r + 1, i + 1)]);
        }
    }
    with_smooth_normals(m)
}

/// A tube with rounded ends around a centreline in the x-y plane: `centre(t)` for t in
/// [0, 1], radius `radius(t)`, hemispherical caps at both ends. `cap_rows` rings per cap,
/// `body_rows` along the line, `cols` around it.
pub fn tube(
    cap_rows: usize,
    body_rows: usize,
    cols: usize,
    centre: impl Fn(f64) -> V3,
    radius: impl Fn(f64) -> f64,
) -> Mesh {
    let dt = 1e-4;
    let frame = |t: f64| {
        let t0 = (t - dt).max(0.0);
        let t1 = (t + dt).min(1.0);
        let tangent = unit(sub(centre(t1), centre(t0))).unwrap_or([1.0, 0.0, 0.0]);
        // in the plane: the tangent turned by 90 degrees; out of it: +z
        let normal = [-tangent[1], tangent[0], 0.0];
        (tangent, normal, [0.0, 0.0, 1.0])
    };
    let ring = |c: V3, tangent: V3, n: V3, b: V3, along: f64, r: f64| -> Vec<V3> {
        // counter-clockwise seen from the start of the line
        (0..cols)
            .map(|i| {
                let phi = 2.0 * PI * i as f64 / cols as f64;
                let around = add(scale(n, phi.cos()), scale(b, -phi.sin()));
                add(add(c, scale(tangent, along)), scale(around, r))
            })
            .collect()
    };
    let mut rings = Vec::new();
    let (t0, n0, b0) = frame(0.0);
    let r0 = radius(0.0);
    for k in 1..=cap_rows {
        let a = PI / 2.0 * k as f64 / cap_rows as f64;
        rings.push(ring(centre(0.0), t0, n0, b0, -r0 * a.cos(), r0 * a.sin()));
    }
    for k in 1..body_rows {
        let t = k as f64 / body_rows as f64;
        let (tn, nn, bn) = frame(t);
        rings.push(ring(centre(t), tn, nn, bn, 0.0, radius(t)));
    }
    let (t1, n1, b1) = frame(1.0);
    let r1 = radius(1.0);
    for k in (1..=cap_rows).rev() {
        let a = PI / 2.0 * k as f64 / cap_rows as f64;
        rings.push(ring(centre(1.0), t1, n1, b1, r1 * a.cos(), r1 * a.sin()));
    }
    let top = add(centre(0.0), scale(t0, -r0));
    let bottom = add(centre(1.0), scale(t1, r1));
    closed_rings(top, &rings, bottom)
}

/// Appends a flat polygon (a fan from its first corner) with its own vertices and
/// normal.
fn flat_face(m: &mut Mesh, corners: &[V3]) {
    let normal = unit(cross(
        sub(corners[1], corners[0]),
        sub(corners[2], corners[0]),
    ))
    .unwrap_or([0.0, 0.0, 1.0]);
    let first = m.positions.len() as u32;
    m.positions.extend(corners.iter().map(|&p| f32s(p)));
    if let Some(n) = &mut m.normals {
        n.extend(corners.iter().map(|_| f32s(normal)));
    }
    for k in 1..corners.len() as u32 - 1 {
        m.triangles.push([first, first + k, first + k + 1]);
    }
}

/// A prism: `polygon` (counter-clockwise in x-y, star-shaped about the origin) extruded
/// from z = -`half_depth` to +`half_depth`; flat caps (fans from the origin) and a flat
/// face per edge.
pub fn prism(polygon: &[[f64; 2]], half_depth: f64) -> Mesh {
    let mut m = Mesh {
        normals: Some(Vec::new()),
        ..Mesh::default()
    };
    let at = |p: [f64; 2], z: f64| [p[0], p[1], z];
    // caps as fans from the centre, so that a star-shaped polygon is covered exactly
    let k = polygon.len();
    for i in 0..k {
        let (p, q) = (polygon[i], polygon[(i + 1) % k]);
        flat_face(
            &mut m,
            &[[0.0, 0.0, half_depth], at(p, half_depth), at(q, half_depth)],
        );
        flat_face(
            &mut m,
            &[
                [0.0, 0.0, -half_depth],
                at(q, -half_depth),
                at(p, -half_depth),
            ],
        );
        flat_face(
            &mut m,
            &[
                at(p, -half_depth),
                at(q, -half_depth),
                at(q, half_depth),
                at(p, half_depth),
            ],
        );
    }
    m
}

/// A box with half-sizes `h`, centred at the origin, a flat face per side.
pub fn cuboid(h: V3) -> Mesh {
    let square = [[-1.0, -1.0], [1.0, -1.0], [1.0, 1.0], [-1.0, 1.0]];
    let mut m = prism(&square, 1.0);
    for p in &mut m.positions {
        *p = [0, 1, 2].map(|k| p[k] * h[k] as f32);
    }
    m
}

/// A cylinder of `radius` along y from -`half_height` to +`half_height`: a smooth side
/// (`cols` segments) and two flat caps, each with its own vertices.
pub fn cylinder(radius: f64, half_height: f64, cols: usize) -> Mesh {
    let mut m = Mesh {
        normals: Some(Vec::new()),
        ..Mesh::default()
    };
    let rim = |i: usize, y: f64| {
        let phi = 2.0 * PI * i as f64 / cols as f64;
        [radius * phi.cos(), y, -radius * phi.sin()]
    };
    let top: Vec<V3> = (0..cols).map(|i| rim(i, half_height)).collect();
    let mut bottom: Vec<V3> = (0..cols).map(|i| rim(i, -half_height)).collect();
    flat_face(&mut m, &top);
    bottom.reverse();
    flat_face(&mut m, &bottom);
    let side = m.positions.len() as u32;
    for i in 0..cols {
        for y in [half_height, -half_height] {
            let p = rim(i, y);
            m.positions.push(f32s(p));
            if let Some(n) = &mut m.normals {
                n.push(f32s([p[0] / radius, 0.0, p[2] / radius]));
            }
        }
    }
    let at = |i: usize, lower: u32| side + 2 * (i % cols) as u32 + lower;
    for i in 0..cols {
        m.triangles.push([at(i, 0), at(i, 1), at(i + 1, 1)]);
        m.triangles.push([at(i, 0), at(i + 1, 1), at(i + 1, 0)]);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::super::mesh::{dot, widen};
    use super::*;

    /// Every face normal of a closed, origin-centred convex solid points away from the
    /// origin, and so does every vertex normal.
    fn assert_outward(m: &Mesh, name: &str) {
        m.validate().unwrap();
        let normals = m.normals.as_ref().expect("normals");
        for (f, t) in m.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| widen(m.positions[v as usize]));
            let n = cross(sub(b, a), sub(c, a));
            let centre = scale(add(add(a, b), c), 1.0 / 3.0);
            assert!(dot(n, centre) > 0.0, "{name}: face {f} is wound inwards");
            for &v in t {
                let p = widen(m.positions[v as usize]);
                let vn = widen(normals[v as usize]);
                assert!(
                    dot(vn, p) > 0.0,
                    "{name}: vertex {v} normal {vn:?} at {p:?}"
                );
            }
        }
    }

    #[test]
    fn solids_are_wound_outwards() {
        assert_outward(&sphere_grid(8, 12, direction), "sphere");
        assert_outward(&cuboid([1.0, 0.5, 0.25]), "box");
        assert_outward(&cylinder(0.5, 1.0, 16), "cylinder");
        let star: Vec<[f64; 2]> = (0..7)
            .map(|i| {
                let a = 2.0 * PI * i as f64 / 7.0;
                let r = if i % 2 == 0 { 1.0 } else { 0.6 };
                [r * a.cos(), r * a.sin()]
            })
            .collect();
        let m = prism(&star, 0.3);
        m.validate().unwrap();
        let capsule = tube(6, 8, 16, |t| [2.0 * t - 1.0, 0.0, 0.0], |_| 0.4);
        assert_outward(&capsule, "capsule");
        // a torus about y: outwards is away from the nearest point of its core circle
        let torus = torus_grid(12, 24, |u, v| {
            let (a, b) = (2.0 * PI * u, 2.0 * PI * v);
            let ring = 1.0 + 0.3 * b.cos();
            [ring * a.cos(), 0.3 * b.sin(), -ring * a.sin()]
        });
        for (f, t) in torus.triangles.iter().enumerate() {
            let [a, b, c] = t.map(|v| widen(torus.positions[v as usize]));
            let n = cross(sub(b, a), sub(c, a));
            let centre = scale(add(add(a, b), c), 1.0 / 3.0);
            let core = unit([centre[0], 0.0, centre[2]]).unwrap();
            assert!(
                dot(n, sub(centre, core)) > 0.0,
                "torus: face {f} is wound inwards"
            );
        }
    }
}
