//! `matedit fit-brdf`: the DSBRDF fitted to measured BRDFs (a MERL table or NBRDF
//! networks).

use std::path::PathBuf;
use std::time::Instant;

use matedit::fit_brdf::job::{self, BrdfSource};
use matedit::fit_brdf::{BrdfFitOptions, Lobes};

use super::shared::{Failure, progress_bar, runtime};

/// Shown after the options by `matedit help fit-brdf`.
pub const EXAMPLES: &str = "\
Examples:
  matedit fit-brdf --merl gold-metallic-paint.binary -o gold.json
  matedit fit-brdf --nbrdf data/merl/merl_nbrdf.json --name alum-bronze -o alum.json --lobes 2
  matedit fit-brdf --nbrdf data/merl/merl_nbrdf.json -o fits/
  matedit fit-brdf --nbrdf data/merl/merl_nbrdf.json --bundle data/merl/fits.json

Fits the 108 control points to the BRDF over (theta_h, theta_d); phi_d, which the
DSBRDF cannot represent, is averaged with the weights cos theta_i cos theta_o. With
--lobes auto (the default) 1, 2 and 3 lobes are fitted and the fewest whose image error
(under the fitter's built-in lights) is within --tolerance of the best's is kept; unused
lobes have m0 = 0.
--bundle writes every fit into one file, the format of the shipped presets.";

/// The options of `matedit fit-brdf`.
#[derive(clap::Args)]
pub struct Args {
    /// An NBRDF network file (one or more materials), e.g. data/merl/merl_nbrdf.json.
    #[arg(
        long,
        value_name = "FILE",
        required_unless_present = "merl",
        conflicts_with = "merl"
    )]
    nbrdf: Option<PathBuf>,
    /// The material of the NBRDF file to fit [default: all of them].
    #[arg(long, value_name = "NAME", requires = "nbrdf", conflicts_with = "merl")]
    name: Option<String>,
    /// A MERL measured BRDF table (.binary).
    #[arg(long, value_name = "FILE")]
    merl: Option<PathBuf>,
    /// Output: a material .json for one material, a folder (one NAME.json each) for several.
    #[arg(short, long, value_name = "OUT", required_unless_present = "bundle")]
    output: Option<PathBuf>,
    /// Also (or only) write every fit into this one .json file, the presets' format.
    #[arg(long, value_name = "FILE")]
    bundle: Option<PathBuf>,
    /// Lobes to fit: 1, 2, 3 or auto.
    #[arg(long, value_name = "N", default_value = "auto", value_parser = parse_lobes)]
    lobes: Lobes,
    /// With --lobes auto: the relative slack over the best image error allowed to fewer lobes.
    #[arg(long, value_name = "REL", default_value_t = 0.0, value_parser = parse_tolerance_slack)]
    tolerance: f64,
    /// Leave out the joint least-squares refinement of the judge's pick (the fitter the
    /// shipped presets were made with, with --tolerance 0.05).
    #[arg(long)]
    no_joint: bool,
}

fn parse_lobes(v: &str) -> Result<Lobes, String> {
    match v {
        "auto" => Ok(Lobes::Auto),
        "1" | "2" | "3" => Ok(Lobes::Fixed(v.parse().expect("a digit"))),
        _ => Err(format!("'{v}' is not 1, 2, 3 or auto")),
    }
}

fn parse_tolerance_slack(v: &str) -> Result<f64, String> {
    match v.parse::<f64>() {
        Ok(t) if t.is_finite() && t >= 0.0 => Ok(t),
        _ => Err(format!("'{v}' is not a number >= 0")),
    }
}

/// Runs `matedit fit-brdf`.
pub fn run(args: &Args) -> Result<(), Failure> {
    let (source, label) = match (&args.nbrdf, &args.merl) {
        (Some(path), _) => (
            BrdfSource::Nbrdf {
                path: path.clone(),
                name: args.name.clone(),
            },
            path.display().to_string(),
        ),
        (None, Some(path)) => (BrdfSource::Merl(path.clone()), path.display().to_string()),
        (None, None) => unreachable!("clap requires --nbrdf or --merl"),
    };
    // Outputs are checked before minutes of fitting.
    let outputs = job::Outputs {
        output: args.output.as_deref(),
        bundle: args.bundle.as_deref(),
    };
    outputs.check_bundle()?;
    let brdfs = job::load(&source)?;
    outputs.check_file(&label, brdfs.len())?;
    let options = BrdfFitOptions {
        lobes: args.lobes,
        tolerance: args.tolerance,
        joint: !args.no_joint,
        ..Default::default()
    };
    let bar = progress_bar(
        brdfs.len() as u64,
        "fitting {bar:30} {pos}/{len} {elapsed} (eta {eta})",
    );
    let start = Instant::now();
    let fits = job::fit_all(&brdfs, &options, &|| {
        if let Some(b) = &bar {
            b.inc(1);
        }
    })?;
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    for f in &fits {
        eprintln!("matedit: {}: {}", f.best().material.name, job::describe(f));
    }
    eprintln!(
        "matedit: fitted {} material{} in {:.1} s on {} thread{}",
        fits.len(),
        if fits.len() == 1 { "" } else { "s" },
        start.elapsed().as_secs_f64(),
        rayon::current_num_threads(),
        if rayon::current_num_threads() == 1 {
            ""
        } else {
            "s"
        }
    );
    let written = outputs.write(&fits, &label).map_err(runtime)?;
    if written.len() <= 3 {
        for p in &written {
            eprintln!("matedit: wrote {}", p.display());
        }
    } else {
        eprintln!("matedit: wrote {} files", written.len());
    }
    Ok(())
}
