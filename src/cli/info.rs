//! `matedit info`: what an input file holds (format, size, channels, value range, NaN and
//! negative counts) and whether matedit can use it as normals, environment, material,
//! upstream gradient or batch manifest.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use matedit::envmap::MAX_RADIANCE;
use matedit::error::{Error, Result};
use matedit::io::resample::EnvSize;
use matedit::io::{self, Format, Raster};
use matedit::scene::BACKGROUND_EPS;

use super::shared::Failure;

/// Shown after the options by `matedit help info`.
pub const EXAMPLES: &str = "\
Examples:
  matedit info sky.exr
  matedit info normals.npy
  matedit info material.json";

/// The options of `matedit info`.
#[derive(clap::Args)]
pub struct Args {
    /// An .exr, .npy, .png or .json file.
    file: PathBuf,
}

/// Runs `matedit info`.
pub fn run(args: &Args) -> Result<(), Failure> {
    print!("{}", describe(&args.file)?);
    Ok(())
}

/// Statistics of a 3-channel raster.
#[derive(Clone, Debug, Default, PartialEq)]
struct Stats {
    /// Per channel (min, max) over finite values; `None` if a channel has none.
    range: [Option<(f64, f64)>; 3],
    /// NaN values.
    nan: usize,
    /// Infinite values.
    inf: usize,
    /// Negative values.
    negative: usize,
    /// Values above [`MAX_RADIANCE`].
    huge: usize,
    /// Pixels with |v| < 1e-6 (background as normals).
    near_zero: usize,
    /// (min, max) of |v| over the other finite pixels.
    length: Option<(f64, f64)>,
    /// The first non-finite pixel, (column, row).
    first_bad: Option<(usize, usize)>,
}

/// Computes [`Stats`] of a raster.
fn stats(r: &Raster) -> Stats {
    let mut s = Stats::default();
    let widen = |o: &mut Option<(f64, f64)>, v: f64| {
        *o = Some(match *o {
            None => (v, v),
            Some((a, b)) => (a.min(v), b.max(v)),
        })
    };
    for (i, p) in r.pixels.iter().enumerate() {
        let mut finite = true;
        for (c, &v) in p.iter().enumerate() {
            if v.is_nan() {
                s.nan += 1;
                finite = false;
            } else if v.is_infinite() {
                s.inf += 1;
                finite = false;
            } else {
                widen(&mut s.range[c], v);
                if v < 0.0 {
                    s.negative += 1;
                }
                if v > MAX_RADIANCE as f64 {
                    s.huge += 1;
                }
            }
        }
        if !finite {
            s.first_bad.get_or_insert((i % r.width, i / r.width));
            continue;
        }
        let len = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        if len < BACKGROUND_EPS {
            s.near_zero += 1;
        } else {
            widen(&mut s.length, len);
        }
    }
    s
}

fn range_str(r: Option<(f64, f64)>) -> String {
    match r {
        Some((a, b)) => format!("{a:.6} .. {b:.6}"),
        None => "no finite values".into(),
    }
}

fn usable(out: &mut String, what: &str, verdict: std::result::Result<String, String>) {
    let (yes, text) = match verdict {
        Ok(t) => ("yes", t),
        Err(t) => ("no", t),
    };
    let _ = writeln!(
        out,
        "  {what:<10}{yes}{}{text}",
        if text.is_empty() { "" } else { ": " }
    );
}

fn describe_raster(out: &mut String, r: &Raster, png: bool) {
    let s = stats(r);
    if !png {
        let _ = writeln!(out, "size: {} wide x {} high", r.width, r.height);
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let _ = writeln!(out, "channel {name}: {}", range_str(s.range[c]));
        }
        let _ = writeln!(
            out,
            "NaN values: {}, infinite values: {}, negative values: {}",
            s.nan, s.inf, s.negative
        );
    }
    let bad = s
        .first_bad
        .map(|(x, y)| format!("pixel ({x}, {y}) is not finite"));
    let _ = writeln!(out, "usable as:");

    // normals
    let normals = match &bad {
        Some(b) => Err(b.clone()),
        None => {
            let outside = s
                .range
                .iter()
                .flatten()
                .any(|&(lo, hi)| lo < -1.001 || hi > 1.001);
            let lengths = match s.length {
                _ if outside => "values outside [-1, 1], so probably not a normal map \
                                 (it would be normalised)"
                    .to_string(),
                Some((a, b)) if (a - 1.0).abs() < 1e-3 && (b - 1.0).abs() < 1e-3 => {
                    "unit length".to_string()
                }
                Some((a, b)) => format!("lengths {a:.4} .. {b:.4}, will be normalised"),
                None => "every pixel is background".into(),
            };
            let bg = if png {
                "background where alpha = 0 or R = G = B = 0".to_string()
            } else {
                format!("{} background pixels (|n| < 1e-6)", s.near_zero)
            };
            Ok(format!("{lengths}; {bg}; renders {}x{}", r.width, r.height))
        }
    };
    usable(out, "normals", normals);

    // environment
    let env = if png {
        Err("8-bit PNG is not HDR; environment maps are EXR or NPY".to_string())
    } else if let Some(b) = &bad {
        Err(b.clone())
    } else if s.huge > 0 {
        Err(format!("{} values above {MAX_RADIANCE}", s.huge))
    } else {
        let mut t = String::new();
        if s.negative > 0 {
            let _ = write!(t, "{} negative values will be clamped to 0; ", s.negative);
        }
        let EnvSize::Size { height, width } = EnvSize::default() else {
            unreachable!("the default env size is a size")
        };
        if r.height.is_multiple_of(height) && r.width.is_multiple_of(width) {
            let _ = write!(
                t,
                "--env-size {height}x{width} (the default) fits ({}x{} texels averaged into \
                 one), or --env-size full",
                r.height / height,
                r.width / width
            );
        } else {
            let _ = write!(
                t,
                "the default --env-size {height}x{width} does not divide {}x{} (rows x \
                 columns): use --env-size full or a divisor of each side",
                r.height, r.width
            );
        }
        if r.width != 2 * r.height {
            let _ = write!(t, "; note: not 2:1 like a lat-long map");
        }
        Ok(t)
    };
    usable(out, "env", env);

    // upstream
    let upstream = if png {
        Err("8-bit PNG cannot hold gradients; use EXR or NPY".to_string())
    } else if let Some(b) = &bad {
        Err(b.clone())
    } else {
        Ok(format!("for a {}x{} render", r.width, r.height))
    };
    usable(out, "upstream", upstream);
    usable(out, "material", Err("not a JSON file".into()));
}

/// A multi-line, human-readable report on `path`. Errors only where the file cannot be
/// read or its format is unknown; what makes it unusable is part of the report.
fn describe(path: &Path) -> Result<String> {
    let mut out = String::new();
    let _ = writeln!(out, "file: {}", path.display());
    let format = io::format_of(
        path,
        "the file",
        &[
            Format::Exr,
            Format::Npy,
            Format::Png,
            Format::Json,
            Format::Jpeg,
        ],
    )?;
    // Fail early, and with the plain message, for a missing or unreadable file.
    let bytes = io::read_bytes(path)?;
    match format {
        Format::Exr => {
            match io::exr::read_info(path) {
                Ok(layers) => {
                    let _ = writeln!(out, "format: OpenEXR, {} layer(s)", layers.len());
                    for (i, l) in layers.iter().enumerate() {
                        let chans: Vec<String> = l
                            .channels
                            .iter()
                            .map(|(n, t)| format!("{n} ({t})"))
                            .collect();
                        let _ = writeln!(
                            out,
                            "layer {i}{}: {} wide x {} high, {} compression{}, channels {}",
                            l.name
                                .as_ref()
                                .map(|n| format!(" '{n}'"))
                                .unwrap_or_default(),
                            l.width,
                            l.height,
                            l.compression,
                            if l.deep { ", deep data" } else { "" },
                            chans.join(", ")
                        );
                    }
                }
                Err(e) => return Ok(unusable(out, e)),
            }
            match io::exr::read_rgb(path) {
                Ok(r) => describe_raster(&mut out, &r, false),
                Err(e) => return Ok(unusable(out, e)),
            }
        }
        Format::Npy => {
            let a = match io::npy::parse(&bytes) {
                Ok(a) => a,
                Err(m) => return Ok(unusable(out, Error::file(path, m))),
            };
            let _ = writeln!(
                out,
                "format: NumPy array, {}, shape {}",
                a.dtype.name(),
                io::npy::shape_str(&a.shape)
            );
            match io::npy_raster(path, a) {
                Ok(r) => describe_raster(&mut out, &r, false),
                Err(e) => return Ok(unusable(out, e)),
            }
        }
        Format::Png => match io::png::decode(path) {
            Ok(d) => {
                let kind = ["grey", "grey + alpha", "RGB", "RGBA"]
                    .get(d.channels.saturating_sub(1))
                    .copied()
                    .unwrap_or("?");
                let _ = writeln!(out, "format: PNG, {}-bit {kind}", d.bit_depth);
                if d.channels < 3 {
                    return Ok(unusable(
                        out,
                        Error::file(path, "a greyscale PNG holds no normals"),
                    ));
                }
                let _ = writeln!(out, "size: {} wide x {} high", d.width, d.height);
                for (c, name) in ["R", "G", "B", "A"]
                    .iter()
                    .enumerate()
                    .take(d.channels.max(3))
                {
                    let vals = d.samples.iter().skip(c).step_by(d.channels);
                    let (lo, hi) = vals.fold((u16::MAX, 0), |(a, b), &v| (a.min(v), b.max(v)));
                    let _ = writeln!(out, "channel {name}: {lo} .. {hi}");
                }
                if d.channels == 4 {
                    let clear = d
                        .samples
                        .iter()
                        .skip(3)
                        .step_by(4)
                        .filter(|&&a| a == 0)
                        .count();
                    let _ = writeln!(out, "transparent pixels (alpha 0): {clear}");
                }
                let (width, height, raw) = io::png::normals_of(path, &d)?;
                describe_raster(
                    &mut out,
                    &Raster {
                        width,
                        height,
                        pixels: raw,
                    },
                    true,
                );
            }
            Err(e) => return Ok(unusable(out, e)),
        },
        Format::Json => describe_json(&mut out, path, &bytes),
        Format::Jpeg => match io::image_from_bytes(path, &bytes) {
            Ok(image) => {
                let _ = writeln!(out, "format: JPEG, 8-bit sRGB");
                let _ = writeln!(out, "size: {} x {} (W x H)", image.width, image.height);
                let _ = writeln!(out, "usable as: an image to fit to or edit, a background");
            }
            Err(e) => return Ok(unusable(out, e)),
        },
    }
    Ok(out)
}

fn unusable(mut out: String, e: Error) -> String {
    let _ = writeln!(out, "cannot be used: {}", file_message(&e));
    out
}

fn describe_json(out: &mut String, path: &Path, bytes: &[u8]) {
    let value: serde_json::Value = match serde_json::from_slice(bytes) {
        Ok(v) => v,
        Err(e) => {
            let e = matedit::error::one_line(&e.to_string()).into_owned();
            let _ = writeln!(out, "format: JSON (invalid)\ncannot be used: {e}");
            return;
        }
    };
    if value.get("scenes").is_some() {
        let _ = writeln!(out, "format: JSON batch manifest");
        match io::manifest::read(path, None) {
            Ok(m) => {
                let _ = writeln!(out, "scenes: {}", m.scenes.len());
                for (i, s) in m.scenes.iter().enumerate() {
                    let _ = writeln!(out, "  scene {i}: output {}", s.output.display());
                }
                let _ = writeln!(
                    out,
                    "usable as:\n  manifest  yes: matedit render --batch {}",
                    path.display()
                );
            }
            Err(e) => {
                let _ = writeln!(out, "usable as:\n  manifest  no: {}", file_message(&e));
            }
        }
        return;
    }
    let _ = writeln!(out, "format: JSON");
    match io::json::read_material(path) {
        Ok(m) => {
            let _ = writeln!(
                out,
                "material: '{}', {} control points",
                m.name,
                m.ctrl.len()
            );
            for (t, what) in [(0, "scale m0"), (1, "exponent m1")] {
                let vals = m
                    .ctrl
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| (i / matedit::spline::N_CTRL_POINTS) % 2 == t)
                    .map(|(_, &v)| v);
                let (lo, hi) = vals.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
                    (a.min(v), b.max(v))
                });
                let _ = writeln!(out, "{what}: {lo} .. {hi}");
            }
            let _ = writeln!(out, "usable as:\n  material  yes");
        }
        Err(e) => {
            let _ = writeln!(out, "usable as:\n  material  no: {}", file_message(&e));
        }
    }
}

fn file_message(e: &Error) -> String {
    match e {
        Error::File { message, .. } => matedit::error::one_line(message).into_owned(),
        other => other.to_string(),
    }
}
