//! Every buffer bound to a pass meets the shader's minimum binding size for any input, and
//! the inputs that bind the smallest buffers give the reference's answers on every tile
//! kind and plan. A binding's minimum is what naga lays out for its variable (a runtime
//! array's element stride, a fixed array's or struct's span): the host never binds a
//! buffer smaller than [`matedit::gpu::MIN_BYTES`], so every minimum must fit in it.

use crate::common;

use common::{Rng, assert_close, gpu, random_material, random_scene};
use matedit::gpu::{GpuRenderer, MIN_BYTES, Pass, Tiles};
use matedit::prepare::Prepared;
use matedit::reference;
use matedit::{
    Backend, Batch, Camera, Convention, EnvMap, Image, NormalMap, Scene, Wanted, material::idx,
};

/// The smallest size wgpu accepts for a buffer bound to `var`: the span of its type, or
/// for a runtime-sized array (or a struct ending in one) the size with one element.
fn min_binding_size(
    m: &naga::Module,
    layouter: &naga::proc::Layouter,
    var: &naga::GlobalVariable,
) -> u32 {
    match &m.types[var.ty].inner {
        naga::TypeInner::Array {
            size: naga::ArraySize::Dynamic,
            stride,
            ..
        } => *stride,
        naga::TypeInner::Struct { members, span } => match members.last() {
            Some(last) => match &m.types[last.ty].inner {
                naga::TypeInner::Array {
                    size: naga::ArraySize::Dynamic,
                    stride,
                    ..
                } => last.offset + stride,
                _ => *span,
            },
            None => *span,
        },
        _ => layouter[var.ty].size,
    }
}

#[test]
fn every_binding_fits_the_smallest_buffer() {
    for pass in Pass::ALL {
        for tiles in [Tiles::Workgroup, Tiles::Uniform] {
            let src = pass.source(tiles);
            let m = naga::front::wgsl::parse_str(&src).expect("parses");
            let mut layouter = naga::proc::Layouter::default();
            layouter.update(m.to_ctx()).expect("layout");
            let mut bound = 0;
            for (_, var) in m.global_variables.iter() {
                let Some(binding) = &var.binding else {
                    continue;
                };
                bound += 1;
                let min = min_binding_size(&m, &layouter, var) as u64;
                // the params (binding 0: one Params per scene, at least one) and uniform
                // chunks are bound at their full size
                let full = binding.binding == 0 || var.space == naga::AddressSpace::Uniform;
                assert!(
                    full || min <= MIN_BYTES,
                    "{} ({tiles:?}): {:?} needs {min} bytes > MIN_BYTES {MIN_BYTES}",
                    pass.name(),
                    var.name
                );
            }
            assert!(bound >= 3, "{}: {bound} bindings", pass.name());
        }
    }
}

/// The renderer on every tile kind, and with the large-GPU plan (many slices; a batch in
/// one dispatch).
fn renderers(test: &str) -> Vec<(String, GpuRenderer)> {
    let mut out = Vec::new();
    for tiles in [Tiles::Workgroup, Tiles::Uniform] {
        let Some(g) = gpu(test) else { return out };
        out.push((
            format!("{tiles:?}"),
            g.with_tiles(tiles).expect("pipelines"),
        ));
    }
    if let Some(g) = gpu(test) {
        let large = matedit::gpu::Planner::large_gpu();
        let g = g.with_tiles(large.tiles).expect("pipelines").with_slices(7);
        out.push(("Workgroup, 7 slices".into(), g));
    }
    out
}

fn flat(v: &[[f32; 3]]) -> Vec<f64> {
    v.iter().flatten().map(|&x| x as f64).collect()
}

fn flat64(v: &[[f64; 3]]) -> Vec<f64> {
    v.iter().flatten().copied().collect()
}

/// Checks the forward and the backward of `scenes` (one batch) on every renderer against
/// the reference, with upstream gradients `up`.
fn check(test: &str, scenes: Vec<Scene>, up: Vec<Image>) {
    check_on(test, &renderers(test), scenes, up);
}

/// [`check`] on the given renderers.
fn check_on(test: &str, renderers: &[(String, GpuRenderer)], scenes: Vec<Scene>, up: Vec<Image>) {
    let batch = Batch::new(scenes).expect("batch");
    for (name, g) in renderers {
        let images = g
            .render((&batch).into())
            .unwrap_or_else(|e| panic!("{test} {name}: forward: {e}"));
        let grads = g
            .backward((&batch).into(), &up, Wanted::ALL)
            .unwrap_or_else(|e| panic!("{test} {name}: backward: {e}"));
        for (b, s) in batch.scenes().iter().enumerate() {
            let prep = Prepared::new(s);
            let want = reference::forward(&prep);
            let what = format!("{test} {name} scene {b}");
            assert_close(
                &format!("{what} image"),
                &flat(&images[b].pixels),
                &flat64(&want),
                1e-5,
                1e-4,
            );
            let up64: Vec<[f64; 3]> = up[b].pixels.iter().map(|p| p.map(|v| v as f64)).collect();
            let gw = reference::backward(&prep, &up64);
            assert_close(
                &format!("{what} d_env"),
                &flat(&grads[b].d_env),
                &flat64(&gw.d_env),
                1e-5,
                1e-4,
            );
            assert_close(
                &format!("{what} d_normals"),
                &flat(&grads[b].d_normals),
                &flat64(&gw.d_normals),
                1e-5,
                1e-4,
            );
            let dc: Vec<f64> = grads[b].d_ctrl.iter().map(|&v| v as f64).collect();
            assert_close(&format!("{what} d_ctrl"), &dc, &gw.d_ctrl, 1e-5, 1e-4);
        }
    }
}

fn ones(s: &Scene) -> Image {
    let (w, h) = (s.normals.width, s.normals.height);
    Image {
        width: w,
        height: h,
        pixels: vec![[1.0, 0.5, -0.25]; w * h],
    }
}

fn zeros(s: &Scene) -> Image {
    Image {
        width: s.normals.width,
        height: s.normals.height,
        pixels: vec![[0.0; 3]; s.normals.width * s.normals.height],
    }
}

fn scene(seed: u64, camera: Camera) -> Scene {
    random_scene(
        &mut Rng::new(seed),
        9,
        7,
        6,
        12,
        Convention::Equirect,
        camera,
    )
}

const CAMERAS: [Camera; 2] = [
    Camera::Orthographic,
    Camera::Perspective { fov_y_deg: 40.0 },
];

#[test]
fn no_foreground_pixels() {
    for camera in CAMERAS {
        let mut s = scene(1, camera);
        s.normals = NormalMap::new(9, 7, vec![[0.0; 3]; 63]).unwrap();
        let up = vec![ones(&s)];
        check("no_foreground_pixels", vec![s], up);
    }
}

#[test]
fn one_pixel() {
    for camera in CAMERAS {
        let mut s = scene(2, camera);
        s.normals = NormalMap::new(1, 1, vec![[0.2, 0.1, 0.97]]).unwrap();
        let up = vec![ones(&s)];
        check("one_pixel", vec![s], up);
    }
}

#[test]
fn no_lit_texel_and_one_lit_texel() {
    for camera in CAMERAS {
        let mut s = scene(3, camera);
        let mut texels = vec![[0.0f32; 3]; 6 * 12];
        s.env = EnvMap::new(6, 12, Convention::Equirect, texels.clone()).unwrap();
        let dark = s.clone();
        texels[2 * 12 + 5] = [2.0, 1.0, 0.5];
        s.env = EnvMap::new(6, 12, Convention::Equirect, texels).unwrap();
        let (u0, u1) = (ones(&dark), ones(&s));
        check("no_lit_texel", vec![dark], vec![u0]);
        check("one_lit_texel", vec![s], vec![u1]);
    }
}

#[test]
fn no_upstream_gradient() {
    for camera in CAMERAS {
        let s = scene(4, camera);
        let up = vec![zeros(&s)];
        check("no_upstream_gradient", vec![s], up);
    }
}

#[test]
fn only_constant_lobes_and_no_lobes() {
    for camera in CAMERAS {
        let mut s = scene(5, camera);
        let mut ctrl = [0.0; 108];
        for k in 0..3 {
            for j in 0..6 {
                ctrl[idx(k, 1, 0, j)] = 0.3;
            }
        }
        s.material = matedit::Material::new("constant", &ctrl).unwrap();
        let mut none = s.clone();
        none.material = matedit::Material::new("black", &[0.0; 108]).unwrap();
        let (u0, u1) = (ones(&s), ones(&none));
        check("only_constant_lobes", vec![s], vec![u0]);
        check("no_lobes", vec![none], vec![u1]);
    }
}

#[test]
fn batches_holding_empty_scenes() {
    for camera in CAMERAS {
        let full = scene(6, camera);
        let mut empty = scene(7, camera);
        empty.normals = NormalMap::new(9, 7, vec![[0.0; 3]; 63]).unwrap();
        let mut dark = scene(8, camera);
        dark.env = EnvMap::new(6, 12, Convention::Equirect, vec![[0.0; 3]; 72]).unwrap();
        let mut other = scene(9, camera);
        other.material = random_material(&mut Rng::new(10), (0.1, 1.0), (2.0, 30.0));
        let scenes = vec![empty, full, dark, other];
        let mut up: Vec<Image> = scenes.iter().map(ones).collect();
        up[3] = zeros(&scenes[3]);
        check("batches_holding_empty_scenes", scenes, up);
    }
}

/// A renderer keeps its buffers between calls: whatever a larger or different call left in
/// them must not reach the next call's answers.
#[test]
fn a_kept_renderer_answers_each_call_afresh() {
    let test = "a_kept_renderer_answers_each_call_afresh";
    let kept = renderers(test);
    let sized = |seed, w, h, hl, wl, convention| {
        random_scene(
            &mut Rng::new(seed),
            w,
            h,
            hl,
            wl,
            convention,
            Camera::Orthographic,
        )
    };
    let big = sized(11, 24, 20, 32, 64, Convention::Equirect);
    let mut empty = scene(12, Camera::Orthographic);
    empty.normals = NormalMap::new(9, 7, vec![[0.0; 3]; 63]).unwrap();
    let mut dark = sized(18, 24, 20, 32, 64, Convention::Equirect);
    dark.env = EnvMap::new(32, 64, Convention::Equirect, vec![[0.0; 3]; 32 * 64]).unwrap();
    let calls = vec![
        vec![big.clone()],
        vec![sized(13, 4, 4, 1, 2, Convention::Paper)],
        vec![sized(14, 4, 4, 2, 4, Convention::Equirect)],
        vec![sized(15, 24, 20, 32, 64, Convention::Equirect), big.clone()],
        vec![empty],
        vec![big.clone()],
        vec![dark.clone()],
        vec![sized(16, 1, 1, 1, 2, Convention::Equirect)],
        vec![big.clone(), dark],
        vec![big],
        vec![scene(17, Camera::Perspective { fov_y_deg: 40.0 })],
    ];
    for (k, scenes) in calls.into_iter().enumerate() {
        let up = scenes.iter().map(ones).collect();
        check_on(&format!("{test} call {k}"), &kept, scenes, up);
    }
}

/// Prepared scenes of one call may differ in their texel counts (the parts of a level of
/// detail: a culled map, blocks of texels): on workgroup tiles they go in one dispatch,
/// and each scene's dLoss/dctrl sums its own texels' shares.
#[test]
fn prepared_scenes_with_different_texel_counts() {
    let test = "prepared_scenes_with_different_texel_counts";
    let scenes: Vec<Scene> = [(6, 12), (2, 4), (4, 8), (1, 2)]
        .iter()
        .enumerate()
        .map(|(k, &(hl, wl))| {
            let c = Convention::Equirect;
            random_scene(
                &mut Rng::new(40 + k as u64),
                9,
                7,
                hl,
                wl,
                c,
                Camera::Orthographic,
            )
        })
        .collect();
    let preps: Vec<Prepared> = scenes.iter().map(Prepared::new).collect();
    let up: Vec<Image> = scenes.iter().map(ones).collect();
    for (name, g) in renderers(test) {
        let grads = g
            .backward((&preps).into(), &up, Wanted::ALL)
            .unwrap_or_else(|e| panic!("{test} {name}: {e}"));
        for (b, (prep, u)) in preps.iter().zip(&up).enumerate() {
            let up64: Vec<[f64; 3]> = u.pixels.iter().map(|p| p.map(f64::from)).collect();
            let want = reference::backward(prep, &up64);
            let dc: Vec<f64> = grads[b].d_ctrl.iter().map(|&v| v as f64).collect();
            let what = format!("{test} {name} scene {b}");
            assert_close(&format!("{what} d_ctrl"), &dc, &want.d_ctrl, 1e-5, 1e-4);
            assert_close(
                &format!("{what} d_env"),
                &flat(&grads[b].d_env),
                &flat64(&want.d_env),
                1e-5,
                1e-4,
            );
        }
    }
}

/// Renderers share the process's device: one opened for the first renderer, none for
/// renderers made later, one after another or from several threads at once.
#[test]
fn renderers_share_one_device() {
    let Some(_first) = common::gpu("renderers_share_one_device") else {
        return;
    };
    let opened = matedit::gpu::GpuContext::devices_opened();
    let threads: Vec<_> = (0..4)
        .map(|_| std::thread::spawn(|| matedit::gpu::GpuRenderer::new().map(drop)))
        .collect();
    for t in threads {
        t.join().expect("no panic").expect("a renderer");
    }
    for _ in 0..3 {
        drop(matedit::gpu::GpuRenderer::new().expect("a renderer"));
    }
    assert_eq!(matedit::gpu::GpuContext::devices_opened(), opened);
}
