//! The quality of `matedit edit` on a held-out `matedit synth` folder (docs/edit.md).
//!
//!     cargo xtask edit_eval -- DATA [--limit N] [--steps K]
//!         [--normal-steps J] [--normal-smoothness S] [--normal-anchor A] [--weights W]
//!
//! For each sample: the photo I (image.npy) with its true mask is decomposed by the nets (the
//! built-in ones, or W) and refined with K steps (default 150); O' is the object rendered
//! with the next sample's material m_t under the refined light and the predicted normals;
//! O = R(n, m_t, L) is the true edit. Printed, as means over the samples (PSNR over the
//! object, peak = O's maximum there): O' from the predictions alone, O' after refinement,
//! I itself (the edit left undone), and O' with m_t taken from the next sample's photo,
//! decomposed and refined like the first (`--like`); O' after refinement times the ratio
//! of the photo's luminance to I''s (clamped to [1/4, 4]), and its square root (the photo's
//! detail carried over); and I' against I before and after refinement.

use std::path::{Path, PathBuf};
use std::time::Instant;

use matedit::edit::photo::{self, Object, PhotoOptions};
use matedit::edit::psnr;
use matedit::io::{json, npy};
use matedit::nets::Nets;
use matedit::synth::{self, tar};
use matedit::{
    Accuracy, Batch, Camera, Convention, Device, EnvMap, Image, NormalMap, Renderer, Scene,
};

struct Sample {
    image: Image,
    mask: Vec<bool>,
    normals: NormalMap,
    env: EnvMap,
    material: matedit::Material,
}

fn rgb(bytes: &[u8]) -> (usize, usize, Vec<[f32; 3]>) {
    let a = npy::parse(bytes).expect("an npy member");
    let (h, w) = (a.shape[0], a.shape[1]);
    let px = a
        .data
        .chunks_exact(3)
        .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32])
        .collect();
    (w, h, px)
}

fn read(data: &Path, limit: usize) -> Vec<Sample> {
    let mut out = Vec::new();
    for path in synth::data_files(data).expect("a synth folder") {
        if path.extension().is_some_and(|e| e != "tar") {
            continue;
        }
        let members = tar::decode(&std::fs::read(&path).unwrap()).unwrap();
        let mut keys: Vec<&str> = members
            .iter()
            .map(|(n, _)| n.split('.').next().unwrap())
            .collect();
        keys.dedup();
        for key in keys {
            let get = |suffix: &str| {
                let name = format!("{key}.{suffix}");
                &members.iter().find(|(n, _)| *n == name).unwrap().1
            };
            let (w, h, image) = rgb(get("image.npy"));
            let (_, _, normals) = rgb(get("normals.npy"));
            let (ew, eh, texels) = rgb(get("env.npy"));
            let mask = npy::parse(get("mask.npy"))
                .unwrap()
                .data
                .iter()
                .map(|&m| m > 0.5)
                .collect();
            out.push(Sample {
                image: Image {
                    width: w,
                    height: h,
                    pixels: image,
                },
                mask,
                normals: NormalMap::new(w, h, normals).unwrap(),
                env: EnvMap::new(eh, ew, Convention::Equirect, texels).unwrap(),
                material: json::parse_material(Path::new(key), get("material.json")).unwrap(),
            });
            if out.len() == limit {
                return out;
            }
        }
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let flag = |name: &str| {
        args.iter()
            .position(|a| a == name)
            .map(|i| args[i + 1].clone())
    };
    let data = PathBuf::from(
        args.first()
            .expect("usage: edit_eval DATA [--limit N] [--steps K] [--weights W]"),
    );
    let limit: usize = flag("--limit").map_or(64, |v| v.parse().unwrap());
    let steps: usize =
        flag("--steps").map_or(PhotoOptions::default().steps, |v| v.parse().unwrap());
    let nets = match flag("--weights") {
        Some(w) => Nets::load(Path::new(&w)).unwrap(),
        None => Nets::builtin().unwrap(),
    };
    let renderer = Renderer::new(Device::Cpu).unwrap();
    let samples = read(&data, limit);
    let n = samples.len();
    let normal_steps: usize = flag("--normal-steps").map_or(0, |v| v.parse().unwrap());
    let defaults = PhotoOptions::default();
    let normal_smoothness: f64 =
        flag("--normal-smoothness").map_or(defaults.normal_smoothness, |v| v.parse().unwrap());
    let normal_anchor: f64 =
        flag("--normal-anchor").map_or(defaults.normal_anchor, |v| v.parse().unwrap());
    let options = |steps| PhotoOptions {
        steps,
        normal_steps,
        normal_smoothness,
        normal_anchor,
        ..PhotoOptions::default()
    };
    let t = Instant::now();
    let predicted: Vec<_> = samples
        .iter()
        .map(|s| {
            photo::decompose(
                &renderer,
                &nets,
                &s.image,
                Object::Mask(&s.mask),
                &options(0),
                &mut |_| {},
            )
            .unwrap()
        })
        .collect();
    let predict_s = t.elapsed().as_secs_f64() / n as f64;
    let t = Instant::now();
    let refined: Vec<_> = samples
        .iter()
        .map(|s| {
            photo::decompose(
                &renderer,
                &nets,
                &s.image,
                Object::Mask(&s.mask),
                &options(steps),
                &mut |_| {},
            )
            .unwrap()
        })
        .collect();
    let refine_s = t.elapsed().as_secs_f64() / n as f64;
    let (mut rows, mut i_pred, mut i_ref) = (vec![[0.0f64; 6]; n], 0.0, 0.0);
    for (i, s) in samples.iter().enumerate() {
        let next = (i + 1) % n;
        let m_t = &samples[next].material;
        let truth = Batch::single(Scene {
            normals: s.normals.clone(),
            env: s.env.clone(),
            material: m_t.clone(),
            camera: Camera::Orthographic,
        })
        .unwrap();
        let o = renderer.render(&truth).unwrap().remove(0);
        let o_pred = predicted[i]
            .render_object(&renderer, m_t, None, Accuracy::Exact)
            .unwrap();
        let o_ref = refined[i]
            .render_object(&renderer, m_t, None, Accuracy::Exact)
            .unwrap();
        let o_like = refined[i]
            .render_object(&renderer, &refined[next].material, None, Accuracy::Exact)
            .unwrap();
        let i_ref_img = refined[i]
            .render_object(&renderer, &refined[i].material, None, Accuracy::Exact)
            .unwrap();
        // the photo's detail carried over: O' times (lum I / lum I')^power on the object
        let detail = |o_new: &Image, power: f32| -> Image {
            let mut out = o_new.clone();
            for (j, p) in out.pixels.iter_mut().enumerate() {
                let (a, b) = (s.image.pixels[j], i_ref_img.pixels[j]);
                let (la, lb) = (a[0] + a[1] + a[2], b[0] + b[1] + b[2]);
                if s.mask[j] && lb > 1e-6 {
                    let r = (la / lb).clamp(0.25, 4.0).powf(power);
                    *p = p.map(|v| v * r);
                }
            }
            out
        };
        rows[i] = [
            psnr(&o_pred, &o, &s.mask),
            psnr(&o_ref, &o, &s.mask),
            psnr(&s.image, &o, &s.mask),
            psnr(&o_like, &o, &s.mask),
            psnr(&detail(&o_ref, 1.0), &o, &s.mask),
            psnr(&detail(&o_ref, 0.5), &o, &s.mask),
        ];
        i_pred += refined[i].psnr_predicted / n as f64;
        i_ref += refined[i].psnr_refined / n as f64;
    }
    let mean = |k: usize| rows.iter().map(|r| r[k]).sum::<f64>() / n as f64;
    let median = |k: usize| {
        let mut v: Vec<f64> = rows.iter().map(|r| r[k]).collect();
        v.sort_by(f64::total_cmp);
        v[n / 2]
    };
    println!(
        "{n} samples of {}, {steps} refinement steps, {normal_steps} of the normals (smoothness {normal_smoothness}, anchor {normal_anchor})",
        data.display()
    );
    println!(
        "{:44} {:>8} {:>8}",
        "PSNR (dB) over the object, against O", "mean", "median"
    );
    for (k, name) in [
        "O' from the predictions alone",
        "O' after refinement",
        "I (the edit left undone)",
        "O' with m_t from the next photo (--like)",
        "O' refined x (lum I / lum I')",
        "O' refined x (lum I / lum I')^0.5",
    ]
    .iter()
    .enumerate()
    {
        println!("{name:44} {:8.2} {:8.2}", mean(k), median(k));
    }
    println!("I' against I: {i_pred:.2} dB predicted, {i_ref:.2} dB refined (means)");
    println!("seconds per sample: predict {predict_s:.3}, predict + refine {refine_s:.3}");
}
