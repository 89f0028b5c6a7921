//! `matedit grid`: every fit's (or photo's) shape and light with every other's material,
//! as one picture.

use std::path::PathBuf;

use matedit::edit::photo::{self, PhotoOptions};
use matedit::edit::{dir, transfer};
use matedit::io::{self, Format};
use matedit::nets::Nets;
use matedit::{Accuracy, Device, Renderer};

use super::shared::{Failure, PreviewArgs, runtime, with_progress};

/// Shown after the options by `matedit help grid`.
pub const EXAMPLES: &str = "\
Examples:
  matedit grid fits/jade fits/metal fits/clay -o grid.png
  matedit grid jade.jpg metal.png clay.exr -o grid.png     (photos: as `matedit edit`)

Row i keeps fit i's shape and light, column j brings fit j's material; the diagonal
shows the images fitted to. From photos, each is decomposed as `matedit edit` does (a
PNG's alpha is its mask, else the nets find the object), cell (i, j) is photo i edited
with photo j's refined material, and cells show the square around the object.";

/// The options of `matedit grid`.
#[derive(clap::Args)]
pub struct Args {
    /// Fit folders from `matedit fit`, or photos (JPEG, PNG, EXR, NPY), in the grid's order.
    #[arg(value_name = "DIR|PHOTO", required = true, num_args = 2..)]
    fits: Vec<PathBuf>,
    /// Refinement steps per photo (photos only).
    #[arg(long, value_name = "K", default_value_t = PhotoOptions::default().steps)]
    steps: usize,
    /// Output picture (.png).
    #[arg(short, long, value_name = "FILE")]
    output: PathBuf,
    /// Pixels per cell side.
    #[arg(long, value_name = "N", default_value_t = 128, value_parser = clap::value_parser!(u32).range(8..=2048))]
    cell: u32,
    #[command(flatten)]
    preview: PreviewArgs,
    /// Backend, as for `render`.
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
}

/// Runs `matedit grid`.
pub fn run(args: &Args) -> Result<(), Failure> {
    io::check_output(&args.output, &[Format::Png])?;
    if args.fits.iter().all(|p| p.is_file()) {
        return photos(args);
    }
    let fits = args
        .fits
        .iter()
        .map(|p| dir::read(p))
        .collect::<Result<Vec<_>, _>>()?;
    let renderer = Renderer::new(args.device)?;
    let preview = args.preview.preview();
    let (w, h, rgb) = with_progress("rendering the grid", || {
        transfer::grid(&renderer, &fits, args.cell as usize, &preview)
    })?;
    let bytes = io::png::encode_rgb8(w, h, &rgb)?;
    io::write_atomic(&args.output, &bytes).map_err(runtime)?;
    eprintln!(
        "matedit: wrote {} ({}x{} cells)",
        args.output.display(),
        fits.len(),
        fits.len()
    );
    Ok(())
}

/// The grid of photos: each decomposed, then edited with every other's material.
fn photos(args: &Args) -> Result<(), Failure> {
    let mut loaded = Vec::new();
    for p in &args.fits {
        loaded.push(super::edit::load_photo(p)?);
    }
    let nets = Nets::builtin()?;
    let renderer = Renderer::new(args.device)?;
    let options = PhotoOptions {
        steps: args.steps,
        ..PhotoOptions::default()
    };
    let mut parts = Vec::new();
    for ((img, mask), path) in loaded.iter().zip(&args.fits) {
        let d = with_progress("predicting and refining", || {
            photo::decompose(
                &renderer,
                &nets,
                img,
                mask.as_deref(),
                &options,
                &mut |_| {},
            )
        })
        .map_err(|e| Failure::from(matedit::Error::file(path, e.to_string())))?;
        parts.push(d);
    }
    let preview = args.preview.preview();
    let (w, h, rgb) = transfer::grid_of(parts.len(), args.cell as usize, &preview, |i, j| {
        let (img, d) = (&loaded[i].0, &parts[i]);
        let cell = if i == j {
            img.clone()
        } else {
            d.edit(&renderer, img, &parts[j].material, None, Accuracy::Exact)?
        };
        Ok(d.crop_of(&cell))
    })?;
    let bytes = io::png::encode_rgb8(w, h, &rgb)?;
    io::write_atomic(&args.output, &bytes).map_err(runtime)?;
    eprintln!(
        "matedit: wrote {} ({}x{} photos)",
        args.output.display(),
        parts.len(),
        parts.len()
    );
    Ok(())
}
