//! `matedit serve`: the material editor as a local web page (library: `matedit::serve`).

use std::path::PathBuf;

use matedit::Device;
use matedit::serve::{self, Config};

use super::shared::Failure;

/// Shown after the options by `matedit help serve`.
pub const EXAMPLES: &str = "\
Examples:
  matedit serve                                  (then open http://127.0.0.1:8000/)
  matedit serve --port 0                         (any free port; the line on stderr says which)
  matedit serve --host 0.0.0.0 --port 8080       (reachable from other machines: mind who can)

The page: drop a photo, watch the nets and the refinement find its shape, light and
material, pick a preset (or the material of another photo), turn and expose the light,
download the edit. Photos stay in memory (at most --max-photos, the oldest dropped);
stderr gets one line per request.";

/// The options of `matedit serve`.
#[derive(clap::Args)]
pub struct Args {
    /// The address to listen on (loopback: only this machine).
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// The port (0: any free one).
    #[arg(long, default_value_t = 8000)]
    port: u16,
    /// The largest upload, in megabytes (413 beyond).
    #[arg(long, value_name = "MB", default_value_t = 32)]
    max_upload_mb: usize,
    /// The largest photo, in megapixels (413 beyond).
    #[arg(long, value_name = "MP", default_value_t = 12.5)]
    max_megapixels: f64,
    /// Photos kept in memory; past this the oldest is dropped.
    #[arg(long, value_name = "N", default_value_t = Config::default().max_photos)]
    max_photos: usize,
    /// Photos decomposed at once (more wait their turn).
    #[arg(long, value_name = "N", default_value_t = Config::default().jobs)]
    jobs: usize,
    /// Refinement steps of material and light per photo.
    #[arg(long, value_name = "K", default_value_t = Config::default().steps)]
    steps: usize,
    /// Weights of the nets (default: the ones built in).
    #[arg(long, value_name = "FILE")]
    weights: Option<PathBuf>,
    /// Run the nets on each photo only, not also on its mirror image (as `edit --no-mirror`).
    #[arg(long)]
    no_mirror: bool,
    /// Backend, as for `render`.
    #[arg(long, value_name = "auto|gpu|cpu|reference", default_value = "auto")]
    device: Device,
}

/// Runs `matedit serve` until Ctrl-C.
pub fn run(args: &Args) -> Result<(), Failure> {
    if !(args.max_megapixels.is_finite() && args.max_megapixels > 0.0) {
        return Err(Failure::from(matedit::Error::Invalid(format!(
            "--max-megapixels {}: expected a positive number",
            args.max_megapixels
        ))));
    }
    let config = Config {
        max_upload_bytes: args.max_upload_mb.saturating_mul(1 << 20),
        max_pixels: (args.max_megapixels * 1e6) as usize,
        max_photos: args.max_photos,
        jobs: args.jobs,
        steps: args.steps,
        device: args.device,
        weights: args.weights.clone(),
        mirror: !args.no_mirror,
    };
    let host = if args.host.contains(':') && !args.host.starts_with('[') {
        format!("[{}]", args.host)
    } else {
        args.host.clone()
    };
    let handle = serve::start(config, &format!("{host}:{}", args.port))?;
    eprintln!("matedit: serving http://{}/", handle.addr);
    handle.wait();
    Ok(())
}
