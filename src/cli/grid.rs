//! `matedit grid`: every fit's (or photo's) shape and light with every other's material,
//! as one picture.

use std::path::PathBuf;

use matedit::edit::photo::{self, Object, PhotoOptions};
use matedit::edit::{dir, transfer};
use matedit::io::{self, Format};
use matedit::nets::Nets;
use matedit::{Accuracy, Device, Renderer};

use super::shared::{Failure, PointingArgs, PreviewArgs, runtime, with_progress};

/// Shown after the options by `matedit help grid`.
pub const EXAMPLES: &str = "\
Examples:
  matedit grid fits/jade fits/metal fits/clay -o grid.png
  matedit grid jade.jpg metal.png clay.exr -o grid.png     (photos: as `matedit edit`)
  matedit grid cup.jpg vase.jpg -o grid.png --box 1:40,30,300,280 --point 2:200,150

Row i keeps fit i's shape and light, column j brings fit j's material; the diagonal
shows the images fitted to. From photos, each is decomposed as `matedit edit` does (a
PNG's alpha is its mask, else the nets find the object), cell (i, j) is photo i edited
with photo j's refined material, and cells show the square around the object. --box,
--point and --not point at the object as for `matedit edit`, each value led by the
photo's number in the list (1: the first).";

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
    #[command(flatten)]
    pointing: PointingArgs,
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
    if !args.pointing.is_empty() {
        return Err(Failure::from(matedit::Error::Invalid(
            "--box, --point and --not: for photos, not fit folders".into(),
        )));
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
    let mut pointings = Vec::new();
    for (k, p) in args.fits.iter().enumerate() {
        let (img, mask) = super::edit::load_photo(p)?;
        pointings.push(
            args.pointing
                .pointing(Some(k + 1), img.width, img.height)
                .map_err(|f| Failure::from(matedit::Error::file(p, f.error.to_string())))?,
        );
        loaded.push((img, mask));
    }
    let nets = Nets::builtin()?.with_mirror(true);
    let renderer = Renderer::new(args.device)?;
    let options = PhotoOptions {
        steps: args.steps,
        ..PhotoOptions::default()
    };
    let mut parts = Vec::new();
    for (((img, mask), path), pointing) in loaded.iter().zip(&args.fits).zip(&pointings) {
        let object = match pointing {
            Some(p) => Object::Pointed(p),
            None => mask.as_deref().into(),
        };
        let d = with_progress("predicting and refining", || {
            photo::decompose(&renderer, &nets, img, object, &options, &mut |_| {})
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
