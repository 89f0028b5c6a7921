//! A vessel turned about +y, the kind `vessel` of the procedural shapes: a cup, bowl,
//! vase, jar or bottle, with a random smooth outer profile, open at the top with walls of
//! a random thickness (half of them with a handle) or closed by a flat lid, as a ring of
//! vertices per point of the profile between two poles on the axis.

use std::f64::consts::PI;

use super::mesh::Mesh;
use super::tessellate::{lathe, tube};

/// A vessel from the draws of `range(lo, hi)` (uniform in [lo, hi)). Its profile runs
/// (radius, height) from the lathe's top pole to its bottom one, the poles left out: for
/// an open vessel from the middle of its inner floor out and up the inner wall, over a
/// round lip and down the outer wall, then in across the base; for a closed one across
/// the lid, down the wall, across the base. The solid stays on one side of the walk, so
/// the rings' triangles face out of it everywhere, into the opening too.
pub(super) fn vessel(mut range: impl FnMut(f64, f64) -> f64) -> Mesh {
    const ROWS: usize = 64;
    const DISC: usize = 8;
    let h = range(0.4, 1.1);
    let base = range(0.35, 0.8);
    // the outer radius along the height t in [0, 1]: the base radius times three waves of
    // falling amplitude (a belly, a neck, a flare), at least 30 % of it
    let waves: Vec<(f64, f64)> = (1..=3)
        .map(|j| (range(-0.35, 0.35) / j as f64, range(0.0, 2.0 * PI)))
        .collect();
    let outer = move |t: f64| {
        let w: f64 = (1..=3)
            .zip(&waves)
            .map(|(j, &(c, p))| c * (j as f64 * PI * t + p).cos())
            .sum();
        base * (1.0 + w).max(0.3)
    };
    let y = |t: f64| -h + 2.0 * h * t;
    let mut profile: Vec<[f64; 2]> = Vec::new();
    let mut handle = None;
    let top = if range(0.0, 1.0) < 0.5 {
        let wall = range(0.03, 0.08);
        let floor = -h + range(0.06, 0.18);
        let t0 = (floor + h) / (2.0 * h);
        let inner = |t: f64| (outer(t) - wall).max(0.02);
        profile.extend((1..=DISC).map(|i| [inner(t0) * i as f64 / DISC as f64, floor]));
        profile.extend((1..=ROWS).map(|i| {
            let t = t0 + (1.0 - t0) * i as f64 / ROWS as f64;
            [inner(t), y(t)]
        }));
        let (ri, ro) = (inner(1.0), outer(1.0));
        let (c, r) = ((ri + ro) / 2.0, (ro - ri) / 2.0);
        profile.extend((1..DISC).map(|i| {
            let a = PI * i as f64 / DISC as f64;
            [c - r * a.cos(), h + r * a.sin()]
        }));
        if range(0.0, 1.0) < 0.5 {
            // a cup's handle: a round bar along a cubic Bezier out from the outer wall
            // and back, in the x-y plane; its rounded ends sink into the wall by half the
            // bar's radius, less than the wall is thick, so they stay out of the opening
            let bar = wall * range(0.8, 1.6);
            let (upper, lower) = (range(0.6, 0.9), range(0.15, 0.45));
            let widest = (0..=32)
                .map(|i| outer(lower + (upper - lower) * i as f64 / 32.0))
                .fold(0.0, f64::max);
            let out = widest + range(0.2, 0.45);
            let p = [
                [outer(upper) + 0.5 * bar, y(upper)],
                [out, y(upper)],
                [out, y(lower)],
                [outer(lower) + 0.5 * bar, y(lower)],
            ];
            let bezier = move |s: f64| {
                let w = [
                    (1.0 - s).powi(3),
                    3.0 * (1.0 - s).powi(2) * s,
                    3.0 * (1.0 - s) * s * s,
                    s.powi(3),
                ];
                let at = |k: usize| (0..4).map(|j| w[j] * p[j][k]).sum::<f64>();
                [at(0), at(1), 0.0]
            };
            handle = Some(tube(6, 48, 24, bezier, |_| bar));
        }
        floor
    } else {
        profile.extend((1..DISC).map(|i| [outer(1.0) * i as f64 / DISC as f64, h]));
        h
    };
    profile.extend((0..=ROWS).rev().map(|i| {
        let t = i as f64 / ROWS as f64;
        [outer(t), y(t)]
    }));
    profile.extend(
        (1..DISC)
            .rev()
            .map(|i| [outer(0.0) * i as f64 / DISC as f64, -h]),
    );
    let mut m = lathe(top, &profile, -h, 96);
    if let Some(handle) = handle {
        m.append(&handle);
    }
    m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shapes::mesh::{cross, dot, widen};
    use crate::splitmix::SplitMix;

    #[test]
    fn vessels_face_out_of_their_walls_open_or_closed() {
        let (mut open, mut closed, mut handles) = (0, 0, 0);
        for seed in 0..64 {
            let mut r = SplitMix(seed);
            let m = vessel(|lo, hi| lo + (hi - lo) * r.uniform());
            assert_eq!(m.validate(), Ok(()), "seed {seed}");
            // every ring's triangles agree with their neighbours' windings
            assert!(m.winding_signs().iter().all(|&s| s == 1.0), "seed {seed}");
            let n = m.normals.as_ref().unwrap();
            // the first pole: the middle of an open vessel's inner floor, below the rim,
            // or of a closed one's lid, at the top; either faces up, out of the solid
            assert!(
                n[0][1] > 0.99,
                "seed {seed}: first pole's normal {:?}",
                n[0]
            );
            let (_, hi) = m.bounds();
            if f64::from(m.positions[0][1]) < hi[1] - 0.01 {
                open += 1;
            } else {
                closed += 1;
            }
            // the body has 2 poles and rings of 96 vertices; a handle adds a tube's
            handles += usize::from((m.positions.len() - 2) % 96 != 0);
            // facing out of the solid: the triangles enclose a positive signed volume
            let volume: f64 = m
                .triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| widen(m.positions[v as usize]));
                    dot(a, cross(b, c)) / 6.0
                })
                .sum();
            assert!(volume > 0.01, "seed {seed}: signed volume {volume}");
        }
        assert!(
            open >= 16 && closed >= 16 && handles >= 6 && handles < open,
            "{open} open ({handles} with a handle), {closed} closed of 64"
        );
    }
}
