//! What the MERL examples (`merl_report`, `fit_cv`) share: the HDRIs they render under.

use std::path::{Path, PathBuf};

use matedit::io::resample::downsample;
use matedit::{Convention, EnvMap};

/// The `--env-size` value HxW.
pub fn env_size(v: &str) -> Result<(usize, usize), String> {
    let (h, w) = v.split_once('x').ok_or("--env-size is HxW")?;
    Ok((
        h.parse().map_err(|e| format!("--env-size: {e}"))?,
        w.parse().map_err(|e| format!("--env-size: {e}"))?,
    ))
}

/// The .exr maps of `dir`, resampled to `size` (rows, columns) and named by file stem,
/// in name order.
pub fn load_maps(dir: &Path, size: (usize, usize)) -> Result<Vec<(String, EnvMap)>, String> {
    let mut paths: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "exr"))
        .collect();
    paths.sort();
    if paths.is_empty() {
        return Err(format!("{}: no .exr maps", dir.display()));
    }
    paths
        .iter()
        .map(|p| {
            let loaded =
                matedit::io::load_env(p, Convention::Equirect).map_err(|e| e.to_string())?;
            let env = downsample(&loaded.env, size.0, size.1)?;
            let name = p
                .file_stem()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned();
            Ok((name, env))
        })
        .collect()
}
