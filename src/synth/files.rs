//! The files and folders a spec names: resolved against the spec's folder, a folder's
//! files listed in name order, each file hashed into the spec's digest.

use std::path::{Path, PathBuf};

use sha2::{Digest, Sha256};

use crate::error::Result;

/// The files of `folder` with one of `exts` (lower case), sorted by name.
fn list_folder(folder: &Path, exts: &[&str]) -> std::result::Result<Vec<String>, String> {
    let entries = std::fs::read_dir(folder).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => format!("{}: no such folder", folder.display()),
        _ => format!("{}: cannot list the folder: {e}", folder.display()),
    })?;
    let mut names = Vec::new();
    for entry in entries {
        let entry = entry.map_err(|e| format!("{}: cannot list: {e}", folder.display()))?;
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let ext = Path::new(name)
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        if name.starts_with('.') || !ext.is_some_and(|e| exts.contains(&e.as_str())) {
            continue;
        }
        if entry.path().is_file() {
            names.push(name.to_string());
        }
    }
    names.sort();
    if names.is_empty() {
        return Err(format!(
            "{}: the folder has no .{} files",
            folder.display(),
            exts.join(" or .")
        ));
    }
    Ok(names)
}

/// A path as the spec gives it (labels) and as it resolves.
pub(super) struct Named {
    /// As the spec gives it.
    pub label: String,
    /// Resolved against the spec's folder.
    pub path: PathBuf,
}

/// The files an item names: `file` alone, or every matching file of `folder`.
pub(super) fn files_of(
    base: &Path,
    file: Option<String>,
    folder: Option<String>,
    exts: &[&str],
) -> std::result::Result<Vec<Named>, String> {
    let resolve = |p: &str| {
        let p = Path::new(p);
        if p.is_absolute() {
            p.to_path_buf()
        } else {
            base.join(p)
        }
    };
    match (file, folder) {
        (Some(f), None) => {
            let path = resolve(&f);
            if path.is_dir() {
                let names = list_folder(&path, exts)?;
                let label = f.trim_end_matches('/').to_string();
                return Ok(names
                    .into_iter()
                    .map(|n| Named {
                        label: format!("{label}/{n}"),
                        path: path.join(&n),
                    })
                    .collect());
            }
            if !path.exists() {
                return Err(format!("{}: no such file", path.display()));
            }
            Ok(vec![Named { label: f, path }])
        }
        (None, Some(d)) => {
            let path = resolve(&d);
            if path.exists() && !path.is_dir() {
                return Err(format!("{}: is a file, not a folder", path.display()));
            }
            let label = d.trim_end_matches('/').to_string();
            Ok(list_folder(&path, exts)?
                .into_iter()
                .map(|n| Named {
                    label: format!("{label}/{n}"),
                    path: path.join(&n),
                })
                .collect())
        }
        _ => Err("give \"file\" or \"folder\"".into()),
    }
}

/// Adds a file's label and content hash to the spec's digest.
pub(super) fn hash_file(hasher: &mut Sha256, label: &str, path: &Path) -> Result<()> {
    let bytes = crate::io::read_bytes(path)?;
    hasher.update(label.as_bytes());
    hasher.update([0]);
    hasher.update(Sha256::digest(&bytes));
    Ok(())
}
