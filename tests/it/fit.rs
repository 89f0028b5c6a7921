//! The fitter end to end: the shipped MERL presets re-fitted from the networks in the
//! repository, `matedit fit-brdf` on a MERL table written from a known BRDF and on the
//! NBRDF file, and its bad inputs (exit code 2, one line naming the file and the item, no
//! output left behind).

use std::path::Path;

use assert_cmd::cargo::cargo_bin_cmd;
use matedit::Material;
use matedit::brdf::{Isotropic, merl, nbrdf};
use matedit::fit_brdf::job::Bundle;
use matedit::fit_brdf::samples::{Grid, Tabulated};
use matedit::fit_brdf::{BrdfFitOptions, Lobes, fit, joint};
use matedit::material::idx;

const NBRDF: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/data/merl/merl_nbrdf.json");
const FITS: &str = include_str!("../../data/merl/fits.json");

fn matedit() -> assert_cmd::Command {
    cargo_bin_cmd!("matedit")
}

fn stderr(out: &std::process::Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The shipped control points are what the fitter makes from the shipped networks: a
/// few materials re-fitted (diffuse, glossy plastic, metal) match to 1e-6 relative (the
/// fit is deterministic; the slack is for a libm that rounds a last bit differently).
#[test]
fn shipped_fits_match_a_refit() {
    let bundle = Bundle::parse(FITS).expect("shipped fits parse");
    assert_eq!(bundle.materials.len(), 90);
    let nets = nbrdf::read(Path::new(NBRDF)).expect("shipped networks");
    for name in ["white-diffuse-bball", "red-specular-plastic", "alum-bronze"] {
        let net = nets.iter().find(|n| n.name == name).expect("network");
        let shipped = bundle
            .materials
            .iter()
            .find(|m| m.name == name)
            .expect("shipped fit");
        // the presets were made before the joint refinement and its broader judge, with
        // 5% slack for fewer lobes
        let options = BrdfFitOptions {
            joint: false,
            tolerance: 0.05,
            ..BrdfFitOptions::default()
        };
        let refit = fit(net, name, &options).expect("fit");
        assert_eq!(refit.best().lobes, shipped.lobes, "{name}");
        for (i, (a, b)) in refit
            .best()
            .material
            .ctrl
            .iter()
            .zip(&shipped.ctrl)
            .enumerate()
        {
            assert!(
                (a - b).abs() <= 1e-6 * b.abs().max(1e-3),
                "{name}: ctrl[{i}] refit {a}, shipped {b}"
            );
        }
    }
}

/// Every preset name lists first on its line, one per line, the default first.
#[test]
fn presets_list_the_merl_materials() {
    let out = matedit().arg("presets").output().expect("runs");
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    let names: Vec<&str> = text
        .lines()
        .map(|l| l.split_whitespace().next().unwrap_or(""))
        .collect();
    assert_eq!(names[0], matedit::presets::DEFAULT);
    for n in [
        "gold-metallic-paint",
        "alum-bronze",
        "yellow-plastic",
        "clay",
    ] {
        assert!(names.contains(&n), "{n} missing from `matedit presets`");
    }
    assert!(names.len() >= 95);
}

/// Lobes with negative scales (sheen, grazing rise) are subtracted from positive ones;
/// the sum must stay non-negative wherever an image can see it: at every (theta_h,
/// theta_d) where some phi_d puts both directions above the surface.
#[test]
fn shipped_presets_are_non_negative_where_seen() {
    let half_pi = std::f64::consts::FRAC_PI_2;
    let mut seen = Vec::new();
    for i in 0..=90 {
        for j in 0..=90 {
            let (th, td) = (i as f64 / 90.0 * half_pi, j as f64 / 90.0 * half_pi);
            let visible = (0..=36).any(|p| {
                let (w_i, w_o) = matedit::brdf::from_rusinkiewicz(th, td, p as f64 * 0.0872665);
                w_i[2] > 0.0 && w_o[2] > 0.0
            });
            if visible {
                seen.push((th, td));
            }
        }
    }
    let mut with_negative_lobes = 0;
    let mut worst = (0.0f64, "");
    for p in matedit::presets::all() {
        let m = p.material();
        if m.ctrl.iter().any(|&v| v < 0.0) {
            with_negative_lobes += 1;
        }
        let values: Vec<[f64; 3]> = seen.iter().map(|&(th, td)| m.eval(th, td, 0.0)).collect();
        let peak = values.iter().flatten().fold(0.0f64, |a, &v| a.max(v));
        let low = values.iter().flatten().fold(0.0f64, |a, &v| a.min(v));
        // the fitter keeps its samples (cell centres) >= 0; between them and at the
        // grid's edges a trace below 0 may remain
        assert!(
            low >= -1e-3 * peak,
            "{}: f down to {low} (peak {peak}) where seen",
            p.name
        );
        if low / peak < worst.0 {
            worst = (low / peak, p.name);
        }
    }
    eprintln!(
        "most negative where seen: {} at {:.2e} of its peak",
        worst.1, worst.0
    );
    // the fabrics and other materials brighter at grazing angles use them
    assert!(with_negative_lobes > 0);
}

/// A smooth analytic BRDF: a Lambertian base and a Phong-like lobe in theta_h whose
/// strength rises with theta_d, per channel.
struct Analytic;

impl Isotropic for Analytic {
    fn eval(&self, theta_h: f64, theta_d: f64, _phi_d: f64) -> [f64; 3] {
        let x = theta_h.cos();
        let spec = 2.0 * x.powf(80.0) * (1.0 + theta_d.sin().powi(4));
        [0.15 + spec, 0.09 + spec, 0.04 + spec]
    }
}

#[test]
fn fits_a_merl_table_from_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let table = dir.path().join("analytic.binary");
    merl::write(&table, [90, 45, 8], &Analytic).unwrap();
    let out_path = dir.path().join("fit.json");
    let out = matedit()
        .args(["fit-brdf", "--merl"])
        .arg(&table)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let m = matedit::io::json::read_material(&out_path).unwrap();
    assert_eq!(m.name, "analytic");
    assert!(stderr(&out).contains("analytic:"), "{}", stderr(&out));
    // The fit reproduces the table: the BRDF error of the written material is small.
    let error = matedit::fit_brdf::brdf_error(&m, &merl::read(&table).unwrap());
    assert!(error < 0.05, "BRDF error {error}");
}

#[test]
fn fits_one_nbrdf_material_and_writes_a_bundle() {
    let dir = tempfile::tempdir().unwrap();
    let bundle = dir.path().join("one.json");
    let out = matedit()
        .args([
            "fit-brdf",
            "--nbrdf",
            NBRDF,
            "--name",
            "gold-paint",
            "--lobes",
            "2",
        ])
        .arg("--bundle")
        .arg(&bundle)
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", stderr(&out));
    let b = Bundle::parse(&std::fs::read_to_string(&bundle).unwrap()).unwrap();
    assert_eq!(b.materials.len(), 1);
    assert_eq!(b.materials[0].lobes, 2);
    let m: &Material = &b.materials()[0];
    let lobe2_scales = (0..3).flat_map(|k| (0..6).map(move |j| ((k * 3 + 2) * 2) * 6 + j));
    assert!(lobe2_scales.map(|i| m.ctrl[i]).all(|v| v == 0.0));
    // Same numbers as the library.
    let net = nbrdf::read(Path::new(NBRDF)).unwrap();
    let net = net.iter().find(|n| n.name == "gold-paint").unwrap();
    let lib = fit(
        net,
        "gold-paint",
        &BrdfFitOptions {
            lobes: Lobes::Fixed(2),
            ..BrdfFitOptions::default()
        },
    )
    .unwrap();
    assert_eq!(lib.best().material.ctrl.to_vec(), b.materials[0].ctrl);
}

#[test]
fn bad_inputs_fail_with_one_line_and_no_output() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.json");
    // Several materials into one .json file.
    let out = matedit()
        .args(["fit-brdf", "--nbrdf", NBRDF, "-o"])
        .arg(&out_path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("90 materials"), "{}", stderr(&out));
    // An unknown material.
    let out = matedit()
        .args(["fit-brdf", "--nbrdf", NBRDF, "--name", "unobtainium", "-o"])
        .arg(&out_path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(stderr(&out).contains("unobtainium"), "{}", stderr(&out));
    // A truncated MERL table.
    let bad = dir.path().join("bad.binary");
    std::fs::write(&bad, [90u8, 0, 0, 0, 90, 0, 0, 0]).unwrap();
    let out = matedit()
        .args(["fit-brdf", "--merl"])
        .arg(&bad)
        .arg("-o")
        .arg(&out_path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let e = stderr(&out);
    assert!(e.contains("bad.binary") && e.lines().count() == 1, "{e}");
    assert!(!e.contains("panick"), "{e}");
    // A lobe count the DSBRDF does not have.
    let out = matedit()
        .args(["fit-brdf", "--nbrdf", NBRDF, "--lobes", "4", "-o"])
        .arg(&out_path)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(!out_path.exists());
}

/// A DSBRDF whose glossy lobe's scale changes sign across theta_d (below 0 at normal
/// incidence, rising towards grazing) over a constant lobe that keeps it positive: the
/// lobe-per-sign log-parameters of the staged fit cannot take it, free scales can.
fn sign_changing() -> Material {
    let mut ctrl = [0.0; 108];
    let glossy = [-0.3, -0.15, 0.1, 0.4, 0.8, 1.2];
    for k in 0..3 {
        for j in 0..6 {
            ctrl[idx(k, 0, 0, j)] = [0.5, 0.4, 0.35][k];
            ctrl[idx(k, 1, 0, j)] = glossy[j];
            ctrl[idx(k, 1, 1, j)] = 80.0;
        }
    }
    Material::new("truth", &ctrl).unwrap()
}

/// The joint refinement only takes steps that lower its cost, the cosine-weighted squared
/// BRDF error: started from the staged fit (no refinement), its BRDF error is never
/// higher, here on the analytic BRDF and on the sign-changing DSBRDF, which it must
/// recover far better than its start.
#[test]
fn joint_refinement_lowers_the_brdf_error_of_its_start() {
    let staged = BrdfFitOptions {
        lobes: Lobes::Fixed(2),
        joint: false,
        ..BrdfFitOptions::default()
    };
    let truth = sign_changing();
    let brdfs: [(&dyn Isotropic, &str); 2] = [(&Analytic, "analytic"), (&truth, "sign-changing")];
    for (brdf, name) in brdfs {
        let table = Tabulated::new(brdf, Grid::default());
        let start = fit(brdf, name, &staged).unwrap().best().material.clone();
        let refined = joint::refine(&table.plane(), &start, 2, joint::REFINE_STEPS).unwrap();
        let (before, after) = (table.error(&start), table.error(&refined));
        eprintln!("{name}: BRDF error {before:.5} staged, {after:.5} refined");
        assert!(
            after <= before * (1.0 + 1e-9),
            "{name}: {before} -> {after}"
        );
        if name == "sign-changing" {
            assert!(
                after < 0.2 * before && after < 0.01,
                "{name}: {before} -> {after}"
            );
        }
    }
}

/// The default fit (staged, refined, judged under suns and broad lights) renders the
/// sign-changing DSBRDF closer than the staged fit alone, in the judge's own measure.
#[test]
fn default_fit_recovers_sign_changing_scales() {
    let truth = sign_changing();
    let staged = fit(
        &truth,
        "t",
        &BrdfFitOptions {
            lobes: Lobes::Fixed(2),
            joint: false,
            ..BrdfFitOptions::default()
        },
    )
    .unwrap();
    let full = fit(
        &truth,
        "t",
        &BrdfFitOptions {
            lobes: Lobes::Fixed(2),
            ..BrdfFitOptions::default()
        },
    )
    .unwrap();
    let judge = matedit::fit_brdf::judge::Judge::broad(&truth).unwrap();
    let (a, b) = (
        judge.error(&staged.best().material),
        judge.error(&full.best().material),
    );
    eprintln!("image error: staged {a:.2e}, default {b:.2e}");
    assert!(b < 0.5 * a, "staged {a}, default {b}");
    assert!(full.best().error < 0.01, "BRDF error {}", full.best().error);
}
