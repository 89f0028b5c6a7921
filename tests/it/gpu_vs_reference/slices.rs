//! Slices: the looped-over records of each gather pass split into independent partial sums
//! (the dispatch's y dimension), added in slice order by reduce_slices; and the dispatches
//! and timings that follow the plan.

use super::{compare_on, output_bits};
use crate::backends::sphere_scene;
use crate::common::{Rng, gpu, random_scene, scenes, upstream_for};
use matedit::gpu::Tiles;
use matedit::prepare::Prepared;
use matedit::{Backend, Batch, Camera, Convention, NormalMap, Scene, Wanted};

/// The scenes the slice tests run on: orthographic, perspective, a batch of 3, and a 20 x 20
/// sphere against 32 x 64 texels (slices that do not end on a tile).
fn slice_scenes() -> Vec<(String, Batch)> {
    let mut out = vec![
        ("64x128 equirect".to_string(), scenes::equirect_64x128()),
        ("batch of 3".to_string(), scenes::batch_of_3()),
        (
            "sphere 20".to_string(),
            Batch::single(sphere_scene(21, 32)).unwrap(),
        ),
    ];
    for (conv, batch) in scenes::perspective() {
        out.push((format!("perspective {conv:?}"), batch));
    }
    out
}

/// A renderer reading through `tiles` with `slices` slices; `None` without an adapter.
fn sliced(test: &str, tiles: Tiles, slices: u32) -> Option<matedit::gpu::GpuRenderer> {
    let g = gpu(test)?.with_tiles(tiles).expect("pipelines");
    Some(g.with_slices(slices))
}

#[test]
fn slices_forced_to_1_2_and_several() {
    // both ways of reading the looped-over records, whatever the adapter's default
    for tiles in [Tiles::Workgroup, Tiles::Uniform] {
        for s in [1, 2, 7] {
            let Some(g) = sliced("slices_forced_to_1_2_and_several", tiles, s) else {
                return;
            };
            for (name, batch) in slice_scenes() {
                compare_on(&g, &format!("{tiles:?}, {s} slices, {name}"), &batch);
            }
        }
    }
}

#[test]
fn batches_of_1_and_5_with_slices() {
    let mut rng = Rng::new(22);
    let five: Vec<Scene> = (0..5)
        .map(|_| {
            let mut s = random_scene(
                &mut rng,
                4,
                4,
                16,
                32,
                Convention::Equirect,
                Camera::Perspective { fov_y_deg: 45.0 },
            );
            s.normals = NormalMap::sphere(14);
            s
        })
        .collect();
    for (tiles, s) in [
        (Tiles::Workgroup, 1),
        (Tiles::Workgroup, 3),
        (Tiles::Uniform, 3),
    ] {
        let Some(g) = sliced("batches_of_1_and_5_with_slices", tiles, s) else {
            return;
        };
        compare_on(
            &g,
            &format!("batch of 1, {s} slices"),
            &Batch::single(five[0].clone()).unwrap(),
        );
        compare_on(
            &g,
            &format!("batch of 5, {s} slices"),
            &Batch::new(five.clone()).unwrap(),
        );
    }
}

#[test]
fn a_batch_is_one_dispatch_per_pass_with_each_scenes_own_sums() {
    // on workgroup tiles a batch's scenes go in z: one dispatch of each gather pass, and
    // each scene's outputs bit for bit what it gets alone with the same slice count (its
    // slices are as long; a scene with fewer leaves its last slices zero)
    let five: Vec<Scene> = (0..5)
        .map(|k| {
            let mut s = sphere_scene(23 + k as u64, 16);
            // foreground pixels differ: scene k loses its first 40 k pixels
            for n in s.normals.normals.iter_mut().take(40 * k) {
                *n = [0.0; 3];
            }
            s
        })
        .collect();
    let batch = Batch::new(five.clone()).unwrap();
    let test = "a_batch_is_one_dispatch_per_pass_with_each_scenes_own_sums";
    for s in [1, 3] {
        let Some(g) = sliced(test, Tiles::Workgroup, s) else {
            return;
        };
        let whole = output_bits(&g, &batch);
        let zs = |pass| {
            g.last_dispatches()
                .iter()
                .filter(|d| d.pass == pass)
                .map(|d| d.workgroups[2])
                .collect::<Vec<u32>>()
        };
        assert_eq!(zs(matedit::gpu::Pass::BackwardTexel), [5], "{s} slices");
        assert_eq!(zs(matedit::gpu::Pass::BackwardNormal), [5], "{s} slices");
        assert_eq!(zs(matedit::gpu::Pass::ReduceCtrl), [5], "{s} slices");
        g.render((&batch).into()).unwrap();
        assert_eq!(zs(matedit::gpu::Pass::Forward), [5], "{s} slices");
        // output_bits orders images, then gradients, scene by scene
        let up = upstream_for(&batch, 5);
        let mut alone: (Vec<u32>, Vec<u32>) = Default::default();
        for (b, scene) in five.iter().enumerate() {
            let one = Batch::single(scene.clone()).unwrap();
            let img = g.render((&one).into()).unwrap();
            let grad = g
                .backward((&one).into(), std::slice::from_ref(&up[b]), Wanted::ALL)
                .unwrap();
            alone
                .0
                .extend(img[0].pixels.iter().flatten().map(|x| x.to_bits()));
            alone.1.extend(
                grad[0]
                    .d_env
                    .iter()
                    .flatten()
                    .chain(grad[0].d_normals.iter().flatten())
                    .chain(grad[0].d_ctrl.iter())
                    .map(|x| x.to_bits()),
            );
        }
        let alone: Vec<u32> = alone.0.into_iter().chain(alone.1).collect();
        let first = whole.iter().zip(&alone).position(|(a, b)| a != b);
        assert!(
            whole.len() == alone.len() && first.is_none(),
            "{s} slices: the batch differs from its scenes alone, first at {first:?}"
        );
    }
}

#[test]
fn slices_under_forced_caps() {
    // bindings of 64 pixels (per-pixel partial sums: at most 3 slices; shares: 1 slice)
    // and of 2 workgroups of shares (2 texel slices); 2 and 3 workgroups per dimension
    // (more ranges, and reductions that go on in y)
    let batch = Batch::single(sphere_scene(18, 16)).unwrap();
    let caps: [(Option<u64>, Option<u32>); 4] = [
        (Some(64 * 48), None),
        (Some(2 * 64 * 432), None),
        (None, Some(2)),
        (Some(64 * 48), Some(3)),
    ];
    for (bytes, groups) in caps {
        for slices in [2, 5] {
            let Some(mut g) = sliced("slices_under_forced_caps", Tiles::Workgroup, slices) else {
                return;
            };
            if let Some(b) = bytes {
                g = g.with_binding_cap(b);
            }
            if let Some(n) = groups {
                g = g.with_workgroup_cap(n);
            }
            compare_on(
                &g,
                &format!("cap {bytes:?} bytes, {groups:?} groups, {slices} slices"),
                &batch,
            );
        }
    }
}

#[test]
fn sliced_sums_are_deterministic() {
    // two runs with the same slice count give the same bits; so do slice counts whose
    // slices are the same (the same slice length in every pass: e.g. 120 pixels in 12 or
    // 13 slices are 12 slices of 10; the pair is searched for), because each slice sums its records in order and
    // reduce_slices adds the slices in order
    let Some(g) = gpu("sliced_sums_are_deterministic") else {
        return;
    };
    let batch = scenes::equirect_64x128();
    let prep = Prepared::new(&batch.scenes()[0]);
    let (np, nl, nt) = (prep.pixels.len(), prep.lit.len(), prep.texels.len());
    let test = "sliced_sums_are_deterministic";
    let same = |a: &[u32], b: &[u32], what: &str| {
        let first = a.iter().zip(b).position(|(x, y)| x != y);
        assert!(
            a.len() == b.len() && first.is_none(),
            "{what}: outputs differ, first at {first:?}"
        );
    };
    for tiles in [Tiles::Workgroup, Tiles::Uniform] {
        let mut planner = g.planner().clone();
        planner.tiles = tiles;
        let shapes = |s: u32| {
            let p = planner.clone().with_slices(s);
            (
                p.gather(matedit::gpu::Pass::Forward, np, nl),
                p.gather(matedit::gpu::Pass::BackwardTexel, nt, np),
            )
        };
        let pair = (2..400)
            .find(|&s| shapes(s) == shapes(s + 1) && shapes(s).0.slices > 1)
            .expect("two slice counts with the same slices");
        let bits = |s| output_bits(&sliced(test, tiles, s).unwrap(), &batch);
        let a = bits(pair);
        same(
            &a,
            &bits(pair),
            &format!("{tiles:?}: two runs, {pair} slices"),
        );
        same(
            &a,
            &bits(pair + 1),
            &format!(
                "{tiles:?}: {pair} and {} slices (the same slices)",
                pair + 1
            ),
        );
    }
    if g.planner().software {
        // the automatic count on a software adapter is 1 (on the tile kind it uses:
        // MATEDIT_GPU_TILES may have changed it)
        let one = output_bits(&sliced(test, g.planner().tiles, 1).unwrap(), &batch);
        same(&output_bits(&g, &batch), &one, "automatic and 1 slice");
    }
}

#[test]
fn dispatches_follow_the_plan_and_passes_are_timed() {
    let Some(g) = sliced(
        "dispatches_follow_the_plan_and_passes_are_timed",
        Tiles::Workgroup,
        3,
    ) else {
        return;
    };
    let batch = scenes::equirect_64x128();
    let prep = Prepared::new(&batch.scenes()[0]);
    let (np, nl, nt) = (prep.pixels.len(), prep.lit.len(), prep.texels.len());
    g.render((&batch).into()).unwrap();
    assert_eq!(g.last_dispatches(), g.planner().forward(np, nl));
    let timed = g.context().timestamps;
    let t = g.last_timings();
    if timed {
        let names: Vec<&str> = t.iter().map(|t| t.pass).collect();
        assert_eq!(names, ["forward", "reduce_slices"]);
        assert_eq!(t[0].pairs, (np * nl) as u64);
        assert!(t.iter().all(|t| t.seconds > 0.0), "{t:?}");
    } else {
        assert!(t.is_empty());
    }
    let up = upstream_for(&batch, 3);
    let active = prep
        .pixels
        .iter()
        .filter(|p| up[0].pixels[p.index].iter().any(|&v| v != 0.0))
        .count();
    g.backward((&batch).into(), &up, Wanted::ALL).unwrap();
    assert_eq!(
        g.last_dispatches(),
        g.planner().backward(np, nl, nt, active)
    );
    if timed {
        let names: Vec<&str> = g.last_timings().iter().map(|t| t.pass).collect();
        assert_eq!(
            names,
            [
                "backward_texel",
                "reduce_slices",
                "reduce_ctrl",
                "backward_normal"
            ]
        );
    }
}
