//! `matedit presets`: the built-in materials, or one of them as a material JSON file.

use std::io::Write;

use matedit::{Error, io, presets};

use super::shared::Failure;

/// Shown after the options by `matedit help presets`.
pub const EXAMPLES: &str = "\
Examples:
  matedit presets
  matedit presets gold > gold.json     (then edit it and use --material gold.json)";

/// The options of `matedit presets`.
#[derive(clap::Args)]
pub struct Args {
    /// Print this preset's material JSON instead of the list.
    name: Option<String>,
}

/// Runs `matedit presets`.
pub fn run(args: &Args) -> Result<(), Failure> {
    match args.name.as_deref() {
        None => {
            let width = presets::names().iter().map(|n| n.len()).max().unwrap_or(0);
            // A closed pipe (`matedit presets | head`) ends the list quietly.
            let mut out = std::io::stdout().lock();
            for p in presets::all() {
                if writeln!(out, "{:<width$}  {}", p.name, p.description).is_err() {
                    break;
                }
            }
        }
        Some(name) => {
            let Some(p) = presets::all().iter().find(|p| p.name == name) else {
                return Err(Error::Invalid(format!(
                    "unknown preset '{name}'; the presets are {}",
                    presets::names().join(", ")
                ))
                .into());
            };
            let bytes = io::json::encode_material(&p.material(), Some(&p.description));
            print!("{}", String::from_utf8_lossy(&bytes));
        }
    }
    Ok(())
}
