//! Seeded procedural shapes for training data: a spec string names the kind and,
//! optionally, its seed (`blobby`, `torus:seed=3`); [`Shape::mesh`] draws the shape's
//! parameters from the seed through [`SplitMix`] and tessellates it. The same (kind, seed)
//! gives the same mesh, bit for bit, on every machine.

use std::f64::consts::PI;
use std::str::FromStr;

use super::mesh::{Mesh, V3, dot, scale, sub, widen};
use super::tessellate::{cuboid, cylinder, direction, prism, sphere_grid, torus_grid, tube};
use super::vessel::vessel;
use super::view::{Rotation, mat_vec};
use crate::splitmix::SplitMix;

/// The kinds of shape.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ShapeKind {
    /// The unit sphere (no random parameters).
    Sphere,
    /// A sphere whose radius is displaced by random real spherical harmonics of degree 1
    /// to 2-4 (as in the Blobby Shape Dataset).
    Blobby,
    /// A superquadric with random exponents (0.3 to 2) and axes.
    Superquadric,
    /// A torus with a random tube radius.
    Torus,
    /// A capsule (a cylinder with hemispherical ends) of random radius and length.
    Capsule,
    /// A box of random proportions: flat faces, sharp edges.
    Box,
    /// A cylinder of random proportions: flat caps with sharp rims.
    Cylinder,
    /// A thin plate or wing: a flattened ellipsoid with a random camber.
    Plate,
    /// A long slender limb: a tube bent along a curve, tapering, with rounded ends.
    Limb,
    /// A random star-shaped polygon extruded: flat faces, sharp edges.
    Extrusion,
    /// Two to four of the kinds above, each scaled, rotated and placed at random.
    Union,
    /// One of the kinds above but the sphere, drawn from the seed.
    Random,
    /// A vessel turned about +y (a cup or mug, bowl, vase, jar or bottle): a random smooth
    /// outer profile, open at the top with walls of a random thickness (half of those with
    /// a handle), or closed by a flat lid.
    /// Not among the kinds `union` and `random` draw, so their draws stay as they were.
    Vessel,
}

impl ShapeKind {
    /// Every kind, by its spec name.
    pub const ALL: [(&'static str, ShapeKind); 13] = [
        ("sphere", ShapeKind::Sphere),
        ("blobby", ShapeKind::Blobby),
        ("superquadric", ShapeKind::Superquadric),
        ("torus", ShapeKind::Torus),
        ("capsule", ShapeKind::Capsule),
        ("box", ShapeKind::Box),
        ("cylinder", ShapeKind::Cylinder),
        ("plate", ShapeKind::Plate),
        ("limb", ShapeKind::Limb),
        ("extrusion", ShapeKind::Extrusion),
        ("union", ShapeKind::Union),
        ("random", ShapeKind::Random),
        ("vessel", ShapeKind::Vessel),
    ];

    /// The spec name.
    pub fn name(self) -> &'static str {
        ShapeKind::ALL
            .iter()
            .find(|(_, k)| *k == self)
            .map_or("", |(n, _)| n)
    }
}

/// The kinds a union's parts and `random` draw from.
const PARTS: [ShapeKind; 9] = [
    ShapeKind::Blobby,
    ShapeKind::Superquadric,
    ShapeKind::Torus,
    ShapeKind::Capsule,
    ShapeKind::Box,
    ShapeKind::Cylinder,
    ShapeKind::Plate,
    ShapeKind::Limb,
    ShapeKind::Extrusion,
];

/// A procedural shape: a kind and, optionally, its own seed. Spec syntax:
/// `KIND[:seed=N]`, e.g. `blobby`, `union:seed=12`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    /// What is drawn.
    pub kind: ShapeKind,
    /// The spec's seed; it takes precedence over the seed given to [`Shape::mesh`].
    pub seed: Option<u64>,
}

impl FromStr for Shape {
    type Err = String;

    fn from_str(spec: &str) -> Result<Self, String> {
        let (name, options) = spec.split_once(':').unwrap_or((spec, ""));
        let names = || ShapeKind::ALL.map(|(n, _)| n).join(", ");
        let kind = ShapeKind::ALL
            .iter()
            .find(|(n, _)| *n == name.trim())
            .map(|&(_, k)| k)
            .ok_or_else(|| format!("shape '{spec}': unknown kind '{name}' (known: {})", names()))?;
        let mut seed = None;
        for option in options.split(',').filter(|o| !o.trim().is_empty()) {
            match option.split_once('=').map(|(k, v)| (k.trim(), v.trim())) {
                Some(("seed", v)) => {
                    seed = Some(v.parse::<u64>().map_err(|_| {
                        format!("shape '{spec}': seed '{v}' is not a whole number in 0..2^64")
                    })?);
                }
                _ => {
                    return Err(format!(
                        "shape '{spec}': unknown option '{option}' (known: seed=N)"
                    ));
                }
            }
        }
        Ok(Shape { kind, seed })
    }
}

impl std::fmt::Display for Shape {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.seed {
            Some(s) => write!(f, "{}:seed={s}", self.kind.name()),
            None => f.write_str(self.kind.name()),
        }
    }
}

/// Uniform draws in a range.
struct Draw(SplitMix);

impl Draw {
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.0.uniform()
    }
    fn below(&mut self, n: usize) -> usize {
        self.0.below(n)
    }
}

impl Shape {
    /// The shape's mesh for `seed` (the spec's own seed, if it has one, instead), with
    /// vertex normals; sharp-edged kinds carry their own normals per face.
    pub fn mesh(&self, seed: u64) -> Mesh {
        make(self.kind, self.seed.unwrap_or(seed))
    }
}

fn make(kind: ShapeKind, seed: u64) -> Mesh {
    let mut d = Draw(SplitMix(seed));
    match kind {
        ShapeKind::Sphere => sphere_grid(48, 96, direction),
        ShapeKind::Blobby => blobby(&mut d),
        ShapeKind::Superquadric => superquadric(&mut d),
        ShapeKind::Torus => {
            let r = d.range(0.2, 0.5);
            torus_grid(48, 96, |u, v| {
                let (a, b) = (2.0 * PI * u, 2.0 * PI * v);
                let ring = 1.0 + r * b.cos();
                [ring * a.cos(), r * b.sin(), -ring * a.sin()]
            })
        }
        ShapeKind::Capsule => {
            let (r, h) = (d.range(0.25, 0.5), d.range(0.3, 1.0));
            tube(12, 16, 64, |t| [0.0, h - 2.0 * h * t, 0.0], |_| r)
        }
        ShapeKind::Box => cuboid([d.range(0.4, 1.0), d.range(0.4, 1.0), d.range(0.4, 1.0)]),
        ShapeKind::Cylinder => cylinder(d.range(0.3, 0.6), d.range(0.4, 1.2), 96),
        ShapeKind::Plate => {
            let (thick, width, camber) =
                (d.range(0.04, 0.12), d.range(0.35, 0.8), d.range(-0.3, 0.3));
            sphere_grid(48, 96, |t, p| {
                let v = direction(t, p);
                [v[0], thick * v[1] + camber * v[0] * v[0], width * v[2]]
            })
        }
        ShapeKind::Limb => {
            let (bend, r0) = (d.range(0.15, 0.7), d.range(0.08, 0.16));
            let taper = d.range(0.45, 1.0);
            // a quadratic Bezier from (-1, 0) over (0, 2 bend) to (1, 0)
            tube(
                10,
                64,
                48,
                move |t| [2.0 * t - 1.0, 4.0 * bend * t * (1.0 - t), 0.0],
                move |t| r0 * (1.0 + (taper - 1.0) * t),
            )
        }
        ShapeKind::Extrusion => {
            let k = 5 + d.below(8);
            let star: Vec<[f64; 2]> = (0..k)
                .map(|i| {
                    let a = 2.0 * PI * (i as f64 + d.range(-0.3, 0.3)) / k as f64;
                    let r = d.range(0.45, 1.0);
                    [r * a.cos(), r * a.sin()]
                })
                .collect();
            prism(&star, d.range(0.15, 0.6))
        }
        ShapeKind::Union => union(&mut d),
        ShapeKind::Random => make(PARTS[d.below(PARTS.len())], d.0.next_u64()),
        ShapeKind::Vessel => vessel(|lo, hi| d.range(lo, hi)),
    }
}

/// Real spherical harmonic Y_l^m (orthonormal on the sphere) at polar angle `theta`
/// (cos theta = `x`) and azimuth `phi`: sqrt 2 K cos(m phi) P_l^m for m > 0, sqrt 2 K
/// sin(|m| phi) P_l^|m| for m < 0, K P_l^0 for m = 0.
pub fn real_sh(l: usize, m: i64, x: f64, phi: f64) -> f64 {
    let am = m.unsigned_abs() as usize;
    // associated Legendre P_l^am(x) by the standard recurrence in l
    let s = (1.0 - x * x).max(0.0).sqrt();
    let mut pmm = 1.0;
    for k in 0..am {
        pmm *= -((2 * k + 1) as f64) * s;
    }
    let p = if l == am {
        pmm
    } else {
        let mut prev = pmm;
        let mut cur = x * (2 * am + 1) as f64 * pmm;
        for ll in am + 2..=l {
            let next =
                ((2 * ll - 1) as f64 * x * cur - (ll + am - 1) as f64 * prev) / (ll - am) as f64;
            prev = cur;
            cur = next;
        }
        cur
    };
    let ratio: f64 = ((l - am + 1)..=(l + am)).map(|k| k as f64).product();
    let k = ((2 * l + 1) as f64 / (4.0 * PI) / ratio).sqrt();
    match m {
        0 => k * p,
        m if m > 0 => 2f64.sqrt() * k * (am as f64 * phi).cos() * p,
        _ => 2f64.sqrt() * k * (am as f64 * phi).sin() * p,
    }
}

fn blobby(d: &mut Draw) -> Mesh {
    let degree = 2 + d.below(3);
    // amplitudes fall with the degree, so that low orders shape the blob and higher ones
    // add lumps
    let mut terms = Vec::new();
    for l in 1..=degree {
        for m in -(l as i64)..=(l as i64) {
            terms.push((l, m, d.range(-1.0, 1.0) * 1.1 / l as f64));
        }
    }
    sphere_grid(64, 128, |theta, phi| {
        let r: f64 = 1.0
            + terms
                .iter()
                .map(|&(l, m, c)| c * real_sh(l, m, theta.cos(), phi))
                .sum::<f64>();
        scale(direction(theta, phi), r.max(0.25))
    })
}

fn superquadric(d: &mut Draw) -> Mesh {
    let (e1, e2) = (d.range(0.3, 2.0), d.range(0.3, 2.0));
    let axes = [1.0, d.range(0.5, 1.0), d.range(0.5, 1.0)];
    let pow = |c: f64, e: f64| c.signum() * c.abs().powf(e);
    sphere_grid(64, 128, |theta, phi| {
        // theta from the +y pole; phi about y
        let (st, ct) = (theta.sin(), theta.cos());
        [
            axes[0] * pow(st, e1) * pow(phi.cos(), e2),
            axes[1] * pow(ct, e1),
            -axes[2] * pow(st, e1) * pow(phi.sin(), e2),
        ]
    })
}

/// Centres `m` on its bounding box and scales it into the unit ball.
fn unit_ball(m: &Mesh) -> Mesh {
    let (lo, hi) = m.bounds();
    let c = scale([lo[0] + hi[0], lo[1] + hi[1], lo[2] + hi[2]], 0.5);
    let r = m
        .positions
        .iter()
        .map(|&p| {
            let v = sub(widen(p), c);
            dot(v, v).sqrt()
        })
        .fold(0.0, f64::max);
    m.transformed(|p| scale(sub(p, c), 1.0 / r), |n| n)
}

fn union(d: &mut Draw) -> Mesh {
    let parts = 2 + d.below(3);
    let mut out = Mesh::default();
    for _ in 0..parts {
        let kind = PARTS[d.below(PARTS.len())];
        let seed = d.0.next_u64();
        let size = d.range(0.45, 0.75);
        let offset: V3 = loop {
            let o = [d.range(-1.0, 1.0), d.range(-1.0, 1.0), d.range(-1.0, 1.0)];
            if dot(o, o) <= 1.0 {
                break scale(o, 0.5);
            }
        };
        let r = Rotation::random(seed).matrix();
        let part = unit_ball(&make(kind, seed)).transformed(
            |p| super::mesh::add(scale(mat_vec(&r, p), size), offset),
            |n| mat_vec(&r, n),
        );
        out.append(&part);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn specs_parse_and_print() {
        let s: Shape = "torus:seed=3".parse().unwrap();
        assert_eq!((s.kind, s.seed), (ShapeKind::Torus, Some(3)));
        assert_eq!(s.to_string(), "torus:seed=3");
        assert_eq!("union".parse::<Shape>().unwrap().seed, None);
        let e = "blobbi".parse::<Shape>().unwrap_err();
        assert!(
            e.starts_with("shape 'blobbi': unknown kind 'blobbi' (known: sphere, blobby"),
            "{e}"
        );
        let e = "box:sed=1".parse::<Shape>().unwrap_err();
        assert_eq!(
            e,
            "shape 'box:sed=1': unknown option 'sed=1' (known: seed=N)"
        );
        assert!("box:seed=-1".parse::<Shape>().is_err());
    }

    #[test]
    fn real_sh_are_orthonormal() {
        // the Gram matrix of degrees 0 to 4 by the midpoint rule over the sphere
        let (nt, np) = (200, 400);
        let all: Vec<(usize, i64)> = (0..=4)
            .flat_map(|l| (-(l as i64)..=l as i64).map(move |m| (l, m)))
            .collect();
        let mut gram = vec![0.0; all.len() * all.len()];
        for i in 0..nt {
            let t = PI * (i as f64 + 0.5) / nt as f64;
            let w = t.sin() * PI / nt as f64 * 2.0 * PI / np as f64;
            for j in 0..np {
                let p = 2.0 * PI * (j as f64 + 0.5) / np as f64;
                let y: Vec<f64> = all
                    .iter()
                    .map(|&(l, m)| real_sh(l, m, t.cos(), p))
                    .collect();
                for a in 0..all.len() {
                    for b in 0..all.len() {
                        gram[a * all.len() + b] += w * y[a] * y[b];
                    }
                }
            }
        }
        for a in 0..all.len() {
            for b in 0..all.len() {
                let want = if a == b { 1.0 } else { 0.0 };
                let got = gram[a * all.len() + b];
                assert!(
                    (got - want).abs() < 1e-3,
                    "<Y{:?}, Y{:?}> = {got}",
                    all[a],
                    all[b]
                );
            }
        }
    }

    #[test]
    fn every_kind_makes_a_valid_mesh() {
        for (name, kind) in ShapeKind::ALL {
            for seed in 0..3 {
                let m = make(kind, seed);
                assert_eq!(m.validate(), Ok(()), "{name} seed {seed}");
                assert!(
                    m.normals
                        .as_ref()
                        .is_some_and(|n| n.len() == m.positions.len()),
                    "{name}"
                );
            }
        }
    }
}
