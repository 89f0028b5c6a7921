//! The edges of the shaders' lobe branches (shaders/common.wgsl): 2^u - 1 by its polynomial
//! or by exp2, log2 x by its series or by log2, lobes skipped where x^m1 underflows in every
//! channel, the half vector's pad.

use super::compare_on;
use crate::common::{Rng, gpu};
use matedit::gpu::Tiles;
use matedit::prepare::Prepared;
use matedit::{Batch, Camera, Convention, EnvMap, Material, NormalMap, Scene, reference};

/// Unit normals at every elevation from facing away (z = -0.9) through grazing (z = +-1e-3,
/// 1e-4 ...) to facing the camera, at azimuths a golden angle apart. Not z = 0: against the
/// texel at w = (0, 0, -1) that puts n . w at 1e-16, on the horizon's kink, where the f32
/// or f64 rounding of w decides whether the pair is lit (dn jumps by L d_omega f w there).
/// Only those with z >= `z_min`.
fn grazing_normals(w: usize, h: usize, z_min: f64) -> NormalMap {
    let zs = [
        -0.9, -0.5, -0.1, -1e-3, -1e-4, 1e-4, 1e-3, 1e-2, 0.05, 0.2, 0.5, 0.8, 0.95, 0.999, 1.0,
    ];
    let zs: Vec<f64> = zs.into_iter().filter(|&z| z >= z_min).collect();
    let normals = (0..w * h)
        .map(|i| {
            let z = zs[i % zs.len()];
            let a = i as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            [r * a.cos(), r * a.sin(), z].map(|v| v as f32)
        })
        .collect();
    NormalMap::new(w, h, normals).unwrap()
}

/// A 9 x 18 equirect map: texel (4, 13) is at w = (0, 0, -1) = -w_p, where the orthographic
/// half vector is undefined.
fn edge_env(rng: &mut Rng) -> EnvMap {
    let texels = (0..9 * 18)
        .map(|_| [0; 3].map(|_: i32| rng.uniform(-1.0, 1.5).exp() as f32))
        .collect();
    EnvMap::new(9, 18, Convention::Equirect, texels).unwrap()
}

/// Lobe 0: scales about +-ln(2)/2 (negative in G), so that u = m0 log2(e) x^m1 is near the
/// 2^u - 1 branch point |u| = 1/2, with exponent 0.02 (R, G) and 0 (B: x^0 = 1 in an active
/// lobe, also at x = 0); lobe 1: scale 0 everywhere (only its scale's gradient); lobe 2:
/// scale 0 at four control points, exponents 1e4, 50 and 1.5. (An exponent below 1 is left
/// out: dn's m1 x^(m1 - 1) multiplies the f32 error of x near 0, about 1e-7 absolute, without
/// bound; with 0.5 here dn was 4e-4 of its max off the reference, with these shaders and
/// with those before them.)
fn branch_point_material() -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    let near_half = [0.30, 0.335, 0.345, 0.3466, 0.35, 0.40];
    for k in 0..3 {
        for j in 0..6 {
            let sign = if k == 1 { -1.0 } else { 1.0 };
            ctrl[matedit::material::idx(k, 0, 0, j)] = sign * near_half[j];
            ctrl[matedit::material::idx(k, 0, 1, j)] = [0.02, 0.02, 0.0][k];
            ctrl[matedit::material::idx(k, 1, 1, j)] = 30.0;
            ctrl[matedit::material::idx(k, 2, 0, j)] = [0.0, 0.0, 0.5, 1.0, 0.0, 0.0][j];
            ctrl[matedit::material::idx(k, 2, 1, j)] = [1e4, 50.0, 1.5][k];
        }
    }
    Material::new("branch point", &ctrl).unwrap()
}

/// Lobe 0: exponent 1e4 in every channel (skipped over most of the hemisphere); lobe 1:
/// exponents 5000, 1e4 and 100 (x^m1 underflows in some channels and not in others);
/// lobe 2: constant.
fn underflow_material() -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    for k in 0..3 {
        for j in 0..6 {
            ctrl[matedit::material::idx(k, 0, 0, j)] = 3.0;
            ctrl[matedit::material::idx(k, 0, 1, j)] = 1e4;
            ctrl[matedit::material::idx(k, 1, 0, j)] = [2.0, 1.0, 0.5][k];
            ctrl[matedit::material::idx(k, 1, 1, j)] = [5000.0, 1e4, 100.0][k];
            ctrl[matedit::material::idx(k, 2, 0, j)] = 0.2;
        }
    }
    Material::new("underflow", &ctrl).unwrap()
}

/// The same lobes in the three channels (a grey material: the passes compute each lobe once
/// for the three channels): a sharp lobe (exponent 1e4), a lobe with scales about ln(2)/2
/// and exponent 0.02 (near the 2^u - 1 branch point) and a broad one.
fn grey_material() -> Material {
    let mut ctrl = [0.0; matedit::N_PARAMS];
    let near_half = [0.30, 0.335, 0.345, 0.3466, 0.35, 0.40];
    for k in 0..3 {
        for j in 0..6 {
            ctrl[matedit::material::idx(k, 0, 0, j)] = 3.0;
            ctrl[matedit::material::idx(k, 0, 1, j)] = 1e4;
            ctrl[matedit::material::idx(k, 1, 0, j)] = near_half[j];
            ctrl[matedit::material::idx(k, 1, 1, j)] = 0.02;
            ctrl[matedit::material::idx(k, 2, 0, j)] = 0.5;
            ctrl[matedit::material::idx(k, 2, 1, j)] = 8.0;
        }
    }
    Material::new("grey", &ctrl).unwrap()
}

/// Over the lit pairs (n . w > 0) of an orthographic scene: how many have u = m0 log2(e)
/// x^m1 of lobe 0 in some channel within 10% below and above |u| = 1/2, how many have an
/// undefined half vector, and how many have lobe 1's x^m1 underflowing (m1 log2 x < -150)
/// in some channel but not in all.
fn edge_coverage(scene: &Scene) -> ([usize; 2], usize, usize) {
    let prep = Prepared::new(scene);
    let (mut near, mut no_half, mut some_underflow) = ([0; 2], 0, 0);
    for &i in &prep.lit {
        let t = &prep.texels[i];
        for p in &prep.pixels {
            if matedit::prepare::dot(p.n, t.w) <= 0.0 {
                continue;
            }
            no_half += usize::from(t.h == [0.0; 3]);
            let (x, lnx) = reference::common::lobe_x(t.h, p.n, p.nn_m1);
            for k in 0..3 {
                let coef = |s: usize, tt: usize| t.coef[(k * 3 + s) * 2 + tt];
                let pw = reference::common::lobe_pow(x, lnx, coef(0, 1));
                let u = (coef(0, 0) * std::f64::consts::LOG2_E * pw).abs();
                if (0.45..0.5).contains(&u) {
                    near[0] += 1;
                } else if (0.5..0.55).contains(&u) {
                    near[1] += 1;
                }
            }
            let under =
                |k: usize| t.coef[(k * 3 + 1) * 2 + 1] * lnx / std::f64::consts::LN_2 < -150.0;
            let n_under = (0..3).filter(|&k| under(k)).count();
            some_underflow += usize::from(x > 0.0 && n_under > 0 && n_under < 3);
        }
    }
    (near, no_half, some_underflow)
}

/// Both sides of each branch, and the edge cases around them, against the reference on both
/// cameras and both tile kinds: 2^u - 1 on both sides of |u| = 1/2, lobes with zero scales,
/// exponents up to 1e4 that underflow in some channels only, grey lobes (computed once for
/// the three channels), normals facing away and grazing, and a texel with an undefined half
/// vector. The perspective camera gets only normals facing it (z >= 0.2): its half vector
/// is computed in f32 from w + w_p, whose length 2 n . w_p is small where h is near a normal
/// facing away or grazing, and there the 1e4 lobe's dn was 7e-3 of its max off the
/// reference, with these shaders and with those before them.
#[test]
fn lobe_branches_at_their_edges() {
    let mut rng = Rng::new(28);
    for (camera, z_min) in [
        (Camera::Orthographic, -1.0),
        (Camera::Perspective { fov_y_deg: 50.0 }, 0.2),
    ] {
        let scenes: Vec<Scene> = [
            branch_point_material(),
            underflow_material(),
            grey_material(),
        ]
        .into_iter()
        .map(|material| Scene {
            normals: grazing_normals(24, 24, z_min),
            env: edge_env(&mut rng),
            material,
            camera,
        })
        .collect();
        if camera == Camera::Orthographic {
            let (near, no_half, _) = edge_coverage(&scenes[0]);
            assert!(
                near[0] > 0 && near[1] > 0,
                "lobe 0's |u| within 10% of 1/2: {near:?} pairs below and above"
            );
            assert!(no_half > 0, "no lit pair with an undefined half vector");
            let (_, _, some_underflow) = edge_coverage(&scenes[1]);
            assert!(
                some_underflow > 0,
                "no pair where lobe 1 underflows in some channels only"
            );
        }
        // both tile kinds: the branches are taken on workgroup tiles (GPUs) only
        let batch = Batch::new(scenes).unwrap();
        for tiles in [Tiles::Workgroup, Tiles::Uniform] {
            let test =
                format!("lobe branches {camera:?} {tiles:?} (branch point, underflow, grey)");
            let Some(g) = gpu(&test) else { return };
            compare_on(&g.with_tiles(tiles).expect("pipelines"), &test, &batch);
        }
    }
}
