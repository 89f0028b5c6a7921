//! Fit folders: what `matedit fit` writes and what `transfer` and `grid` read.
//!
//! A folder holds `material.json` (the fitted material), `env.exr` (the light: fitted, or
//! the given map as it was used), `normals.npy` (the object's normals, 0 outside the
//! mask), `target.exr` (the image fitted to, 0 outside the mask), `render.exr` and
//! `render.png` (the fit rendered at the image's size), `compare.png` (the image and the
//! fit side by side), `loss.png` (the loss curve) and
//! `report.json` (`psnr`, `steps`, `seconds` and how the scene was set up).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::fit::{Fitted, render_one};
use super::inputs::Inputs;
use super::loss::psnr;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::io::{self, Preview};
use crate::{Camera, Image, Material, NormalMap, Renderer};

/// `report.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Report {
    /// PSNR of `render.exr` against the image over the mask, in dB (peak: the image's
    /// largest value there).
    pub psnr: f64,
    /// Adam steps taken.
    pub steps: usize,
    /// Seconds the fit took (not counting reading and writing files).
    pub seconds: f64,
    /// The last loss.
    pub loss: f64,
    /// The size the fit ran at, [width, height].
    pub work_size: [usize; 2],
    /// The image fitted to.
    pub image: String,
    /// "fitted HxW" or the map that was given.
    pub light: String,
    /// Texel convention of env.exr.
    pub convention: String,
    /// The camera's vertical field of view in degrees; absent for orthographic.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fov: Option<f64>,
    /// The material the fit started from.
    pub init: String,
    /// The backend.
    pub device: String,
}

/// A fit folder as read back.
#[derive(Clone, Debug)]
pub struct FitDir {
    /// The folder.
    pub path: PathBuf,
    /// Its material.
    pub material: Material,
    /// Its light.
    pub env: EnvMap,
    /// Its normals (0 outside the mask).
    pub normals: NormalMap,
    /// The image it was fitted to (0 outside the mask).
    pub target: Image,
    /// Its camera.
    pub camera: Camera,
    /// Its report.
    pub report: Report,
}

/// What a fit writes.
pub struct Output<'a> {
    /// The fitted material.
    pub material: &'a Material,
    /// The light.
    pub env: &'a EnvMap,
    /// Normals, 0 outside the mask.
    pub normals: &'a NormalMap,
    /// The image, 0 outside the mask.
    pub target: &'a Image,
    /// The fit rendered at the image's size.
    pub render: &'a Image,
    /// The loss per step.
    pub losses: &'a [f64],
    /// The report.
    pub report: &'a Report,
}

fn file_error(path: &Path, e: Error) -> Error {
    match e {
        Error::File { .. } => e,
        other => Error::file(path, other.to_string()),
    }
}

/// An error unless `dir` can become a fit folder: neither it nor a folder above it is a
/// file. Checked before minutes of fitting; the folder is created, with its parents, when
/// the fit is written.
pub fn check_folder(dir: &Path) -> Result<()> {
    match dir.ancestors().find(|p| p.exists() && !p.is_dir()) {
        Some(blocker) => Err(Error::file(
            dir,
            format!("{} is a file, not a folder", blocker.display()),
        )),
        None => Ok(()),
    }
}

/// A fit rendered at the image's full size and judged there.
pub struct Judged {
    /// The fitted material under the fitted (or given) light, at the image's size.
    pub render: Image,
    /// Its PSNR against the image over the mask (see [`psnr`]).
    pub psnr: f64,
}

/// Renders `fitted` on `inputs`' normals with `camera`, and its PSNR.
pub fn judge(
    renderer: &Renderer,
    inputs: &Inputs,
    fitted: &Fitted,
    camera: Camera,
) -> Result<Judged> {
    let render = render_one(renderer, inputs, &fitted.material, &fitted.env, camera)?;
    let psnr = psnr(&render, &inputs.target, &inputs.mask);
    Ok(Judged { render, psnr })
}

/// Writes the fit folder of `fitted` on `inputs` (see [`write()`]): normals and image kept
/// on the mask, 0 elsewhere.
pub fn write_fit(
    dir: &Path,
    inputs: &Inputs,
    fitted: &Fitted,
    judged: &Judged,
    report: &Report,
) -> Result<Vec<PathBuf>> {
    let masked = |v: &[[f32; 3]]| -> Vec<[f32; 3]> {
        v.iter()
            .zip(&inputs.mask)
            .map(|(p, &m)| if m { *p } else { [0.0; 3] })
            .collect()
    };
    let normals = NormalMap {
        normals: masked(&inputs.normals.normals),
        ..inputs.normals.clone()
    };
    let target = Image {
        pixels: masked(&inputs.target.pixels),
        ..inputs.target.clone()
    };
    write(
        dir,
        &Output {
            material: &fitted.material,
            env: &fitted.env,
            normals: &normals,
            target: &target,
            render: &judged.render,
            losses: &fitted.losses,
            report,
        },
    )
}

/// Writes a fit folder (created if missing): every file or, on failure, none.
pub fn write(dir: &Path, out: &Output) -> Result<Vec<PathBuf>> {
    let created = io::create_dirs(dir)?;
    let result = write_files(dir, out);
    if result.is_err() {
        io::remove_created(&created);
    }
    result
}

fn write_files(dir: &Path, out: &Output) -> Result<Vec<PathBuf>> {
    let preview = Preview::default();
    let normals = Image {
        width: out.normals.width,
        height: out.normals.height,
        pixels: out.normals.normals.clone(),
    };
    let report = serde_json::to_vec_pretty(out.report)
        .map_err(|e| Error::file(dir.join("report.json"), e.to_string()))?;
    let files: Vec<(&str, Vec<u8>)> = vec![
        (
            "material.json",
            io::json::encode_material(out.material, Some("fitted by matedit fit")),
        ),
        (
            "env.exr",
            io::exr::encode_rgb(out.env.width, out.env.height, &out.env.texels)?,
        ),
        (
            "normals.npy",
            io::npy::encode_rgb(normals.width, normals.height, &normals.pixels),
        ),
        (
            "target.exr",
            io::exr::encode_rgb(out.target.width, out.target.height, &out.target.pixels)?,
        ),
        (
            "render.exr",
            io::exr::encode_rgb(out.render.width, out.render.height, &out.render.pixels)?,
        ),
        ("render.png", io::png::encode_preview(out.render, &preview)?),
        (
            "compare.png",
            side_by_side(&[out.target, out.render], &preview)?,
        ),
        ("loss.png", super::plot::loss_png(out.losses)?),
        ("report.json", report),
    ];
    let mut staged = Vec::new();
    for (name, bytes) in files {
        staged.push(io::stage(&dir.join(name), &bytes)?);
    }
    io::commit_all(staged)
}

/// Images of one size side by side, `GAP` pixels apart, as PNG bytes.
fn side_by_side(images: &[&Image], preview: &Preview) -> Result<Vec<u8>> {
    let (w, h) = (images[0].width, images[0].height);
    let total = images.len() * w + (images.len() - 1) * GAP;
    let mut rgb = vec![24u8; total * h * 3];
    for (n, image) in images.iter().enumerate() {
        for y in 0..h {
            for x in 0..w {
                let o = (y * total + n * (w + GAP) + x) * 3;
                for k in 0..3 {
                    rgb[o + k] = io::png::display_value(image.pixels[y * w + x][k], preview);
                }
            }
        }
    }
    io::png::encode_rgb8(total, h, &rgb)
}

/// Reads a fit folder written by [`write()`].
pub fn read(dir: &Path) -> Result<FitDir> {
    if !dir.is_dir() {
        return Err(Error::file(
            dir,
            "no such folder (a fit folder from `matedit fit`)",
        ));
    }
    let report_path = dir.join("report.json");
    let bytes = io::read_bytes(&report_path)?;
    let report: Report = serde_json::from_slice(&bytes)
        .map_err(|e| Error::file(&report_path, format!("not a fit report: {e}")))?;
    let convention: Convention = report
        .convention
        .parse()
        .map_err(|e: String| Error::file(&report_path, format!("'convention': {e}")))?;
    let camera = match report.fov {
        Some(fov_y_deg) => Camera::Perspective { fov_y_deg },
        None => Camera::Orthographic,
    };
    camera.validate().map_err(|e| file_error(&report_path, e))?;
    let material = io::json::read_material(&dir.join("material.json"))?;
    let env = io::load_env(&dir.join("env.exr"), convention)?.env;
    let normals = io::load_normals(&dir.join("normals.npy"))?;
    let target_path = dir.join("target.exr");
    let t = io::read_raster(&target_path, "an image")?;
    let target = Image {
        width: t.width,
        height: t.height,
        pixels: t.pixels.iter().map(|p| p.map(|v| v as f32)).collect(),
    };
    if (t.width, t.height) != (normals.width, normals.height) {
        return Err(Error::file(
            &target_path,
            format!(
                "size {}x{} differs from normals.npy's {}x{}",
                t.width, t.height, normals.width, normals.height
            ),
        ));
    }
    Ok(FitDir {
        path: dir.to_path_buf(),
        material,
        env,
        normals,
        target,
        camera,
        report,
    })
}

/// The material of a fit folder, or of a material file.
pub fn read_material(path: &Path) -> Result<Material> {
    if path.is_dir() {
        Ok(read(path)?.material)
    } else {
        io::load_material(path)
    }
}

/// Gap between images side by side and between grid cells, in pixels.
pub(super) const GAP: usize = 4;
