//! The fit-quality report of the MERL presets: every material fitted with 1, 2 and 3
//! lobes, each fit rendered on a sphere under each HDRI with the fast CPU path, against
//! the same sphere rendered with the measured BRDF itself (the NBRDF network, summed over
//! the same texels in f64 by `matedit::brdf::render::render_measured`, which shares no
//! code with the layer). Writes docs/materials.md and docs/materials/contact.png.
//!
//! ```text
//! cargo xtask merl_report -- [--envmaps DIR] [--out docs]
//!     [--sphere 64] [--env-size 64x128] [--only a,b]
//! ```

#[path = "../common/maps.rs"]
mod maps;

use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use matedit::brdf::nbrdf::{self, Nbrdf};
use matedit::brdf::render::render_measured;
use matedit::fit_brdf::{BrdfFitOptions, FittedBrdf, fit};
use matedit::{Batch, Camera, Device, Image, NormalMap, Renderer, Scene};
use plotters::prelude::*;
use plotters::style::FontStyle;
use rayon::prelude::*;

struct Args {
    nbrdf: PathBuf,
    envmaps: PathBuf,
    out: PathBuf,
    sphere: usize,
    env_size: (usize, usize),
    only: Option<Vec<String>>,
}

fn args() -> Result<Args, String> {
    let mut a = Args {
        nbrdf: "data/merl/merl_nbrdf.json".into(),
        envmaps: "../shared/data/envmaps".into(),
        out: "docs".into(),
        sphere: 64,
        env_size: (64, 128),
        only: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(flag) = it.next() {
        let mut value = || it.next().ok_or(format!("{flag} needs a value"));
        match flag.as_str() {
            "--nbrdf" => a.nbrdf = value()?.into(),
            "--envmaps" => a.envmaps = value()?.into(),
            "--out" => a.out = value()?.into(),
            "--sphere" => a.sphere = value()?.parse().map_err(|e| format!("--sphere: {e}"))?,
            "--env-size" => a.env_size = maps::env_size(&value()?)?,
            "--only" => a.only = Some(value()?.split(',').map(String::from).collect()),
            other => return Err(format!("unknown option {other}")),
        }
    }
    Ok(a)
}

/// Image errors over the sphere's pixels (background left out): relative RMSE and PSNR
/// with the measured image's largest value as the peak.
fn errors(fitted: &Image, measured: &Image, mask: &[bool]) -> (f64, f64) {
    let (mut se, mut ss, mut n, mut peak) = (0.0, 0.0, 0usize, 0.0f64);
    for ((a, b), &m) in fitted.pixels.iter().zip(&measured.pixels).zip(mask) {
        if !m {
            continue;
        }
        for k in 0..3 {
            let (a, b) = (f64::from(a[k]), f64::from(b[k]));
            se += (a - b) * (a - b);
            ss += b * b;
            peak = peak.max(b);
            n += 1;
        }
    }
    let rmse = (se / ss.max(1e-300)).sqrt();
    let psnr = 10.0 * (peak * peak / (se / n as f64).max(1e-300)).log10();
    (rmse, psnr)
}

/// One material's results: per lobe count (1, 2, 3), per env map, (relative RMSE, PSNR).
struct Row {
    name: String,
    fitted: FittedBrdf,
    seconds: f64,
    by_lobes: Vec<Vec<(f64, f64)>>,
    /// The contact sheet's pair: fitted (chosen) and measured, under the first map.
    pair: (Image, Image),
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

fn min(v: &[f64]) -> f64 {
    v.iter().copied().fold(f64::INFINITY, f64::min)
}

fn mean(v: &[f64]) -> f64 {
    v.iter().sum::<f64>() / v.len() as f64
}

fn main() {
    if let Err(e) = run() {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}

fn run() -> Result<(), String> {
    let a = args()?;
    let mut nets: Vec<Nbrdf> = nbrdf::read(&a.nbrdf).map_err(|e| e.to_string())?;
    if let Some(only) = &a.only {
        nets.retain(|n| only.contains(&n.name));
    }
    let envs = maps::load_maps(&a.envmaps, a.env_size)?;
    let normals = NormalMap::sphere(a.sphere);
    let mask: Vec<bool> = normals.normals.iter().map(|n| n[2] > 0.0).collect();
    let renderer = Renderer::new(Device::Cpu).map_err(|e| e.to_string())?;

    // Fits first (timed on their own, all cores), then the renders.
    let start = Instant::now();
    let fits: Vec<(FittedBrdf, f64)> = nets
        .par_iter()
        .map(|n| {
            let t = Instant::now();
            let f = fit(n, &n.name, &BrdfFitOptions::default()).map_err(|e| e.to_string())?;
            Ok((f, t.elapsed().as_secs_f64()))
        })
        .collect::<Result<_, String>>()?;
    let fit_seconds = start.elapsed().as_secs_f64();
    eprintln!(
        "fitted {} materials in {fit_seconds:.1} s on {} threads",
        nets.len(),
        rayon::current_num_threads()
    );
    let render_start = Instant::now();
    let mut rows = Vec::with_capacity(nets.len());
    for (net, (fitted, seconds)) in nets.iter().zip(fits) {
        let mut by_lobes = vec![Vec::new(); fitted.fits.len()];
        let mut pair = None;
        for (ei, (_, env)) in envs.iter().enumerate() {
            let measured = render_measured(net, &normals, env, Camera::Orthographic)
                .map_err(|e| e.to_string())?;
            let scenes: Vec<Scene> = fitted
                .fits
                .iter()
                .map(|f| Scene {
                    normals: normals.clone(),
                    env: env.clone(),
                    material: f.material.clone(),
                    camera: Camera::Orthographic,
                })
                .collect();
            let images = renderer
                .render(&Batch::new(scenes).map_err(|e| e.to_string())?)
                .map_err(|e| e.to_string())?;
            for (l, img) in images.iter().enumerate() {
                by_lobes[l].push(errors(img, &measured, &mask));
            }
            if ei == 0 {
                pair = Some((images[fitted.chosen].clone(), measured));
            }
        }
        eprintln!(
            "{:28} lobes {}, PSNR {:.1} dB (mean over maps)",
            net.name,
            fitted.best().lobes,
            mean(
                &by_lobes[fitted.chosen]
                    .iter()
                    .map(|e| e.1)
                    .collect::<Vec<_>>()
            )
        );
        rows.push(Row {
            name: net.name.clone(),
            fitted,
            seconds,
            by_lobes,
            pair: pair.expect("one map at least"),
        });
    }
    eprintln!("rendered in {:.1} s", render_start.elapsed().as_secs_f64());

    let env_names: Vec<&str> = envs.iter().map(|(n, _)| n.as_str()).collect();
    let md = report(&a, &rows, &env_names, fit_seconds);
    print!("{}", summary(&rows, &env_names));
    let png = contact_sheet(&rows, env_names[0])?;
    let dir = a.out.join("materials");
    std::fs::create_dir_all(&dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    matedit::io::write_atomic(&dir.join("contact.png"), &png).map_err(|e| e.to_string())?;
    matedit::io::write_atomic(&a.out.join("materials.md"), md.as_bytes())
        .map_err(|e| e.to_string())?;
    eprintln!(
        "wrote {} and {}",
        a.out.join("materials.md").display(),
        dir.join("contact.png").display()
    );
    Ok(())
}

/// PSNR of a row's fit `l` (index) per map.
fn psnrs(row: &Row, l: usize) -> Vec<f64> {
    row.by_lobes[l].iter().map(|e| e.1).collect()
}

/// The summary table: median and worst over materials of each material's mean PSNR over
/// the maps, and of the single worst map, for 1, 2, 3 lobes and the chosen count; then
/// per map.
fn summary(rows: &[Row], envs: &[&str]) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "| fit | median PSNR (mean over maps) | worst PSNR (mean over maps) | median PSNR (worst map) | worst PSNR (worst map) | median rel. RMSE |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|");
    let counts = rows.iter().map(|r| r.fitted.fits.len()).min().unwrap_or(0);
    let mut lines: Vec<(String, Vec<usize>)> = (0..counts)
        .map(|l| {
            (
                format!("{} lobe{}", l + 1, if l == 0 { "" } else { "s" }),
                vec![l; rows.len()],
            )
        })
        .collect();
    lines.push((
        "chosen".into(),
        rows.iter().map(|r| r.fitted.chosen).collect(),
    ));
    for (label, pick) in &lines {
        let means: Vec<f64> = rows
            .iter()
            .zip(pick)
            .map(|(r, &l)| mean(&psnrs(r, l)))
            .collect();
        let worsts: Vec<f64> = rows
            .iter()
            .zip(pick)
            .map(|(r, &l)| min(&psnrs(r, l)))
            .collect();
        let rmse: Vec<f64> = rows
            .iter()
            .zip(pick)
            .map(|(r, &l)| mean(&r.by_lobes[l].iter().map(|e| e.0).collect::<Vec<_>>()))
            .collect();
        let _ = writeln!(
            s,
            "| {label} | {:.1} dB | {:.1} dB | {:.1} dB | {:.1} dB | {:.2}% |",
            median(means.clone()),
            min(&means),
            median(worsts.clone()),
            min(&worsts),
            100.0 * median(rmse)
        );
    }
    let _ = writeln!(s);
    let _ = writeln!(s, "Chosen fits, per map:");
    let _ = writeln!(s);
    let _ = writeln!(s, "| map | median PSNR | worst PSNR | worst material |");
    let _ = writeln!(s, "|---|---|---|---|");
    for (e, env) in envs.iter().enumerate() {
        let v: Vec<(f64, &str)> = rows
            .iter()
            .map(|r| (r.by_lobes[r.fitted.chosen][e].1, r.name.as_str()))
            .collect();
        let worst = v
            .iter()
            .copied()
            .min_by(|a, b| a.0.total_cmp(&b.0))
            .unwrap_or((0.0, ""));
        let _ = writeln!(
            s,
            "| {env} | {:.1} dB | {:.1} dB | {} |",
            median(v.iter().map(|x| x.0).collect()),
            worst.0,
            worst.1
        );
    }
    s
}

fn report(a: &Args, rows: &[Row], envs: &[&str], fit_seconds: f64) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# The MERL presets: how well each fits\n");
    let _ = writeln!(
        s,
        "Measured with `cargo xtask merl_report -- --envmaps {} --sphere {} --env-size {}x{}`.\n",
        a.envmaps.display(),
        a.sphere,
        a.env_size.0,
        a.env_size.1
    );
    let _ = writeln!(
        s,
        "Each material of `data/merl/merl_nbrdf.json` is fitted with 1, 2 and 3 lobes \
         (`matedit::fit_brdf::fit`, defaults); the preset keeps the fewest lobes whose BRDF error is \
         within 5% of the 3-lobe fit's. Each fit is rendered on a {0} x {0} sphere \
         (orthographic) under each HDRI ({1}, resampled to {2} x {3}) with the fast CPU path, \
         and compared with the same sphere rendered with the measured BRDF itself: the network \
         evaluated at every (pixel, texel) pair and summed in f64 \
         (`matedit::brdf::render::render_measured`, which shares no code with the layer).\n",
        a.sphere,
        envs.join(", "),
        a.env_size.0,
        a.env_size.1
    );
    let _ = writeln!(
        s,
        "- **BRDF error**: relative RMSE of the fit against the measured BRDF over pairs of \
         directions in the upper hemisphere, weighted by cos theta_i cos theta_o (phi_d included, \
         which the DSBRDF cannot represent). **floor**: the smallest BRDF error any DSBRDF can \
         reach, that of the BRDF averaged over phi_d with the same weights: the share of the \
         material that depends on phi_d.\n\
         - **Image error**: over the sphere's pixels and channels (background left out): relative \
         RMSE, and PSNR = 10 log10(peak^2 / MSE) with the measured image's largest value as the \
         peak.\n\
         - Fitting all {} materials took {:.1} s on {} threads.\n",
        rows.len(),
        fit_seconds,
        rayon::current_num_threads()
    );
    let _ = writeln!(s, "## Summary\n");
    s += &summary(rows, envs);
    let _ = writeln!(s);
    let mut order: Vec<&Row> = rows.iter().collect();
    order.sort_by(|a, b| {
        mean(&psnrs(a, a.fitted.chosen)).total_cmp(&mean(&psnrs(b, b.fitted.chosen)))
    });
    let _ = writeln!(
        s,
        "Worst three (chosen fit, mean PSNR over maps): {}.\n",
        order
            .iter()
            .take(3)
            .map(|r| format!("`{}` {:.1} dB", r.name, mean(&psnrs(r, r.fitted.chosen))))
            .collect::<Vec<_>>()
            .join(", ")
    );
    let _ = writeln!(s, "## Every material\n");
    let _ = writeln!(
        s,
        "PSNR by lobe count is the mean over the maps; the chosen fit's PSNR is given per map.\n"
    );
    let mut head =
        "| material | lobes | BRDF error 1 / 2 / 3 | floor | PSNR 1 / 2 / 3 |".to_string();
    for e in envs {
        head += &format!(" {e} |");
    }
    head += " rel. RMSE | fit time |";
    let _ = writeln!(s, "{head}");
    let _ = writeln!(s, "|{}", "---|".repeat(7 + envs.len()));
    for r in rows {
        let errs: Vec<String> = r
            .fitted
            .fits
            .iter()
            .map(|f| format!("{:.3}", f.error))
            .collect();
        let ps: Vec<String> = (0..r.fitted.fits.len())
            .map(|l| format!("{:.1}", mean(&psnrs(r, l))))
            .collect();
        let mut line = format!(
            "| {} | {} | {} | {:.3} | {} |",
            r.name,
            r.fitted.best().lobes,
            errs.join(" / "),
            r.fitted.floor,
            ps.join(" / ")
        );
        for p in psnrs(r, r.fitted.chosen) {
            line += &format!(" {p:.1} |");
        }
        let rmse = mean(
            &r.by_lobes[r.fitted.chosen]
                .iter()
                .map(|e| e.0)
                .collect::<Vec<_>>(),
        );
        line += &format!(" {:.2}% | {:.2} s |", 100.0 * rmse, r.seconds);
        let _ = writeln!(s, "{line}");
    }
    let _ = writeln!(
        s,
        "\n![Each material: fitted (left) and measured (right) under {}](materials/contact.png)",
        envs[0]
    );
    s
}

/// Tone mapping for the sheet: exposure from the measured image's 99th percentile, then
/// clamp and sRGB.
fn tone(img: &Image, scale: f32) -> Vec<[u8; 3]> {
    img.pixels
        .iter()
        .map(|p| {
            p.map(|v| {
                (matedit::io::png::srgb_encode((v * scale).clamp(0.0, 1.0)) * 255.0).round() as u8
            })
        })
        .collect()
}

fn contact_sheet(rows: &[Row], env: &str) -> Result<Vec<u8>, String> {
    plotters::style::register_font(
        "sans-serif",
        FontStyle::Normal,
        epaint_default_fonts::HACK_REGULAR,
    )
    .map_err(|_| "the embedded font cannot be read".to_string())?;
    let n = rows[0].pair.0.width;
    let (cols, cell_w, cell_h) = (6usize, 2 * n + 12, n + 16);
    let sheet_rows = rows.len().div_ceil(cols);
    let (w, h) = (cols * cell_w + 8, sheet_rows * cell_h + 24);
    let mut buf = vec![0u8; w * h * 3];
    {
        let root = BitMapBackend::with_buffer(&mut buf, (w as u32, h as u32)).into_drawing_area();
        root.fill(&RGBColor(24, 24, 24))
            .map_err(|e| e.to_string())?;
        let style = ("sans-serif", 11)
            .into_font()
            .color(&RGBColor(220, 220, 220));
        root.draw_text(
            &format!("fitted (left) and measured (right), under {env}"),
            &style,
            (6, 4),
        )
        .map_err(|e| e.to_string())?;
        for (i, r) in rows.iter().enumerate() {
            let (x0, y0) = ((i % cols) * cell_w + 6, (i / cols) * cell_h + 22);
            let (fitted, measured) = &r.pair;
            let mut vals: Vec<f32> = measured
                .pixels
                .iter()
                .map(|p| p[0].max(p[1]).max(p[2]))
                .filter(|&v| v > 0.0)
                .collect();
            vals.sort_by(f32::total_cmp);
            let p99 = vals
                .get(vals.len() * 99 / 100)
                .copied()
                .unwrap_or(1.0)
                .max(1e-6);
            for (side, img) in [fitted, measured].iter().enumerate() {
                let px = tone(img, 1.0 / p99);
                for (j, c) in px.iter().enumerate() {
                    let (x, y) = (x0 + side * n + (j % n), y0 + j / n);
                    root.draw_pixel((x as i32, y as i32), &RGBColor(c[0], c[1], c[2]))
                        .map_err(|e| e.to_string())?;
                }
            }
            root.draw_text(&r.name, &style, (x0 as i32, (y0 + n + 1) as i32))
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    matedit::io::png::encode_rgb8(w, h, &buf).map_err(|e| e.to_string())
}
