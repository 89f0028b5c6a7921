//! `matedit grid`: every fit's shape and light with every fit's material, as one picture.

use std::path::PathBuf;

use matedit::edit::{dir, transfer};
use matedit::io::{self, Format};
use matedit::{Device, Renderer};

use super::shared::{Failure, PreviewArgs, runtime, with_progress};

/// Shown after the options by `matedit help grid`.
pub const EXAMPLES: &str = "\
Examples:
  matedit grid fits/jade fits/metal fits/clay -o grid.png

Row i keeps fit i's shape and light, column j brings fit j's material; the diagonal
shows the images fitted to.";

/// The options of `matedit grid`.
#[derive(clap::Args)]
pub struct Args {
    /// Fit folders from `matedit fit`, in the grid's order.
    #[arg(value_name = "DIR", required = true, num_args = 2..)]
    fits: Vec<PathBuf>,
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
