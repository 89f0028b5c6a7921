//! Fitting from files to files, as `matedit fit-brdf` does: BRDF sources (an NBRDF file
//! with one or more materials, a MERL `.binary` table), fits in parallel, and the outputs
//! (one material JSON, a folder of them, or one bundle file holding every fit, the format
//! of the shipped presets in `data/merl/fits.json`).

use std::path::{Path, PathBuf};

use rayon::prelude::*;

use super::{BrdfFitOptions, FittedBrdf, fit};
use crate::brdf::{Isotropic, merl, nbrdf};
use crate::error::{Error, Result};
use crate::io;
pub use crate::presets::{BUNDLE_FORMAT, Bundle, BundleEntry};

/// Where the BRDFs come from.
#[derive(Clone, Debug)]
pub enum BrdfSource {
    /// An NBRDF network file; `name` picks one material, `None` takes all.
    Nbrdf {
        /// The file.
        path: PathBuf,
        /// One material's name.
        name: Option<String>,
    },
    /// A MERL `.binary` table; the material is named after the file.
    Merl(PathBuf),
}

/// A named BRDF to fit.
pub struct Named {
    /// The material's name.
    pub name: String,
    /// The BRDF.
    pub brdf: Box<dyn Isotropic + Send>,
}

/// Loads the BRDFs of `source`.
pub fn load(source: &BrdfSource) -> Result<Vec<Named>> {
    match source {
        BrdfSource::Nbrdf { path, name } => {
            let nets = nbrdf::read(path)?;
            let nets: Vec<_> = match name {
                None => nets,
                Some(name) => {
                    let pick: Vec<_> = nets.iter().filter(|n| &n.name == name).cloned().collect();
                    if pick.is_empty() {
                        let names: Vec<&str> = nets.iter().map(|n| n.name.as_str()).collect();
                        return Err(Error::file(
                            path,
                            format!("no material '{name}'; the file has {}", names.join(", ")),
                        ));
                    }
                    pick
                }
            };
            Ok(nets
                .into_iter()
                .map(|n| Named {
                    name: n.name.clone(),
                    brdf: Box::new(n),
                })
                .collect())
        }
        BrdfSource::Merl(path) => {
            let table = merl::read(path)?;
            Ok(vec![Named {
                name: table.name.clone(),
                brdf: Box::new(table),
            }])
        }
    }
}

/// Fits every BRDF in parallel (each fit is deterministic, so the result does not depend
/// on the thread count); `done` is called after each.
pub fn fit_all(
    brdfs: &[Named],
    options: &BrdfFitOptions,
    done: &(dyn Fn() + Sync),
) -> Result<Vec<FittedBrdf>> {
    brdfs
        .par_iter()
        .map(|b| {
            let f = fit(b.brdf.as_ref(), &b.name, options);
            done();
            f
        })
        .collect()
}

/// One line describing a fit: lobes kept and the errors of each count tried.
pub fn describe(fitted: &FittedBrdf) -> String {
    let best = fitted.best();
    let tried: Vec<String> = fitted
        .fits
        .iter()
        .map(|f| {
            if f.image_error.is_nan() {
                format!("{}: {:.4}", f.lobes, f.error)
            } else {
                format!(
                    "{}: {:.4} / {:.2} dB",
                    f.lobes,
                    f.error,
                    psnr(f.image_error)
                )
            }
        })
        .collect();
    let judged = if best.image_error.is_nan() {
        String::new()
    } else {
        format!(", judge's PSNR {:.2} dB", psnr(best.image_error))
    };
    format!(
        "{} lobe{}, BRDF error {:.4} (floor {:.4}){judged} (by lobes {})",
        best.lobes,
        if best.lobes == 1 { "" } else { "s" },
        best.error,
        fitted.floor,
        tried.join(", ")
    )
}

/// PSNR of an RMSE-over-peak ratio.
fn psnr(ratio: f64) -> f64 {
    -20.0 * ratio.log10()
}

/// The bundle of `fits` made from `source`.
pub fn bundle(source: &str, fits: &[FittedBrdf]) -> Bundle {
    let mut materials: Vec<BundleEntry> = fits
        .iter()
        .map(|f| BundleEntry {
            name: f.best().material.name.clone(),
            lobes: f.best().lobes,
            brdf_error: f.fits.iter().map(|f| f.error).collect(),
            image_error: f
                .fits
                .iter()
                .map(|f| f.image_error)
                .filter(|e| !e.is_nan())
                .collect(),
            ctrl: f.best().material.ctrl.to_vec(),
        })
        .collect();
    materials.sort_by(|a, b| a.name.cmp(&b.name));
    Bundle {
        format: BUNDLE_FORMAT.into(),
        source: source.into(),
        materials,
    }
}

/// Where `matedit fit-brdf` writes: `output` is one material's file when it ends in
/// `.json`, else a folder of NAME.json files; `bundle` is one file with every fit.
#[derive(Clone, Copy, Debug, Default)]
pub struct Outputs<'a> {
    /// A material file or a folder.
    pub output: Option<&'a Path>,
    /// A bundle file.
    pub bundle: Option<&'a Path>,
}

impl Outputs<'_> {
    /// `output`, if it is one material's file.
    pub fn file(&self) -> Option<&Path> {
        self.output.filter(|o| {
            o.extension()
                .is_some_and(|e| e.eq_ignore_ascii_case("json"))
        })
    }

    /// Checked before anything is read: the bundle's folder exists.
    pub fn check_bundle(&self) -> Result<()> {
        match self.bundle {
            Some(b) => io::check_parent(b),
            None => Ok(()),
        }
    }

    /// Checked before minutes of fitting `count` materials from `source`: a material file
    /// takes one, in a folder that exists.
    pub fn check_file(&self, source: &str, count: usize) -> Result<()> {
        let Some(o) = self.file() else {
            return Ok(());
        };
        if count > 1 {
            return Err(Error::Invalid(format!(
                "-o {}: {source} holds {count} materials; give a folder for one NAME.json each, or pick one with --name",
                o.display(),
            )));
        }
        io::check_parent(o)
    }

    /// Writes the fits made from `source`: the material file and the bundle together (both
    /// or neither), then the folder; the paths written.
    pub fn write(&self, fits: &[FittedBrdf], source: &str) -> Result<Vec<PathBuf>> {
        let mut staged = Vec::new();
        if let (Some(o), Some(f)) = (self.file(), fits.first()) {
            let bytes =
                io::json::encode_material(&f.best().material, Some(&description(f, source)));
            staged.push(io::stage(o, &bytes)?);
        }
        if let Some(b) = self.bundle {
            staged.push(io::stage(b, &bundle(source, fits).encode())?);
        }
        let mut written = io::commit_all(staged)?;
        if let (Some(dir), None) = (self.output, self.file()) {
            written.extend(write_folder(dir, fits, source)?);
        }
        Ok(written)
    }
}

/// Writes each fit's material as NAME.json into `dir` (created if missing), all or none.
pub fn write_folder(dir: &Path, fits: &[FittedBrdf], source: &str) -> Result<Vec<PathBuf>> {
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::file(dir, format!("cannot create the folder: {e}")))?;
    let mut staged = Vec::with_capacity(fits.len());
    for f in fits {
        let m = &f.best().material;
        let path = dir.join(format!("{}.json", m.name));
        let bytes = io::json::encode_material(m, Some(&description(f, source)));
        staged.push(io::stage(&path, &bytes)?);
    }
    io::commit_all(staged)
}

/// The description written into a fitted material's file.
pub fn description(f: &FittedBrdf, source: &str) -> String {
    format!("fitted by matedit fit-brdf to {source}: {}", describe(f))
}
