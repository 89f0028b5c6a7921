//! Output: checks before any work (a known extension, a folder to write into), images
//! encoded by their extension, and atomic writes: bytes staged in a temporary file beside
//! their destination and renamed into place, a batch committed whole or not at all, and
//! the folders a failed run created taken back.

use std::path::{Path, PathBuf};

use super::png::Preview;
use super::{Format, exr, format_of, npy, png};
use crate::envmap::EnvMap;
use crate::error::{Error, Result};
use crate::scene::{Image, NormalMap};

/// Checks before any work is done that an output can be written to `path`: a known
/// extension among `allowed` and an existing folder to put it in.
pub fn check_output(path: &Path, allowed: &[Format]) -> Result<Format> {
    let format = format_of(path, "the output", allowed)?;
    if path.is_dir() {
        return Err(Error::file(path, "is a folder; give a file name"));
    }
    check_parent(path)?;
    Ok(format)
}

/// Checks that the folder that will hold `path` exists.
pub fn check_parent(path: &Path) -> Result<()> {
    let parent = parent_dir(path);
    if !parent.is_dir() {
        return Err(Error::file(
            path,
            format!("folder {} does not exist", parent.display()),
        ));
    }
    Ok(())
}

fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// Encodes a rendered image for `path` by its extension: `.exr` (linear float32 RGB),
/// `.npy` (float32, H x W x 3) or `.png` (8-bit sRGB preview under `preview`).
pub fn encode_image(path: &Path, image: &Image, preview: &Preview) -> Result<Vec<u8>> {
    match format_of(path, "the output", &[Format::Exr, Format::Npy, Format::Png])? {
        Format::Exr => exr::encode_rgb(image.width, image.height, &image.pixels),
        Format::Npy => Ok(npy::encode_rgb(image.width, image.height, &image.pixels)),
        _ => png::encode_preview(image, preview),
    }
}

/// Writes an environment map to `path` atomically, encoded by its extension as
/// [`encode_image`] does (a `.png` is a preview under `preview`).
pub fn write_env(path: &Path, env: &EnvMap, preview: &Preview) -> Result<()> {
    let image = Image {
        width: env.width,
        height: env.height,
        pixels: env.texels.clone(),
    };
    write_atomic(path, &encode_image(path, &image, preview)?)
}

/// Encodes a normal map for `path` by its extension: `.exr` (float32 RGB = n.x, n.y, n.z),
/// `.npy` (float32, H x W x 3) or `.png` (8-bit RGBA, alpha 255 where `mask` is set; see
/// [`png::encode_normals`]). Background pixels are [0, 0, 0] in all three.
pub fn encode_normals(path: &Path, map: &NormalMap, mask: &[bool]) -> Result<Vec<u8>> {
    match format_of(path, "the output", &[Format::Exr, Format::Npy, Format::Png])? {
        Format::Exr => exr::encode_rgb(map.width, map.height, &map.normals),
        Format::Npy => Ok(npy::encode_rgb(map.width, map.height, &map.normals)),
        _ => png::encode_normals(map, mask),
    }
}

/// Encodes a mask for `path` by its extension: `.png` (8-bit grey, 255 inside), `.npy`
/// (float32, H x W, 1 inside) or `.exr` (RGB, 1 inside); what [`super::load_mask`] reads.
pub fn encode_mask(path: &Path, width: usize, height: usize, mask: &[bool]) -> Result<Vec<u8>> {
    let one = |m: &bool| if *m { 1.0f32 } else { 0.0 };
    match format_of(path, "the mask", &[Format::Exr, Format::Npy, Format::Png])? {
        Format::Exr => {
            let rgb: Vec<[f32; 3]> = mask.iter().map(|m| [one(m); 3]).collect();
            exr::encode_rgb(width, height, &rgb)
        }
        Format::Npy => Ok(npy::encode_f32(
            &[height, width],
            &mask.iter().map(one).collect::<Vec<_>>(),
        )),
        _ => png::encode_mask(width, height, mask),
    }
}

/// Bytes written to a temporary file beside their destination, not yet in place.
#[derive(Debug)]
pub struct Staged {
    file: tempfile::NamedTempFile,
    path: PathBuf,
}

impl Staged {
    /// Moves the file into place (an atomic rename on the same file system).
    pub fn commit(self) -> Result<PathBuf> {
        let path = self.path;
        self.file
            .persist(&path)
            .map_err(|e| Error::file(&path, format!("cannot write: {}", e.error)))?;
        Ok(path)
    }

    /// The destination.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// Writes `bytes` to a temporary file `.NAME.XXXX.tmp` in `path`'s folder (NAME: the
/// destination's file name, so that what a killed run left can be found);
/// [`Staged::commit`] puts it in place. Dropping the [`Staged`] removes the temporary file.
pub fn stage(path: &Path, bytes: &[u8]) -> Result<Staged> {
    use std::io::Write;
    let dir = parent_dir(path);
    let fail = |e: std::io::Error| Error::file(path, format!("cannot write: {e}"));
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy())
        .unwrap_or_default();
    let prefix = format!(".{name}.");
    let mut builder = tempfile::Builder::new();
    builder.prefix(&prefix).suffix(".tmp");
    #[cfg(unix)]
    {
        // temporary files are private (0600); an output is an ordinary file: 0666 less
        // the user's umask, applied by the system when the file is created
        use std::os::unix::fs::PermissionsExt;
        builder.permissions(std::fs::Permissions::from_mode(0o666));
    }
    let mut file = builder.tempfile_in(dir).map_err(fail)?;
    file.write_all(bytes).map_err(fail)?;
    file.as_file().sync_all().map_err(fail)?;
    Ok(Staged {
        file,
        path: path.to_path_buf(),
    })
}

/// Writes `bytes` to `path` atomically: all of it or, on failure, nothing.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    stage(path, bytes)?.commit().map(|_| ())
}

/// Creates `dir` and its missing parents; returns the folders it created, outermost
/// first, so that a failed run can take them back with [`remove_created`].
pub fn create_dirs(dir: &Path) -> Result<Vec<PathBuf>> {
    let missing: Vec<PathBuf> = dir
        .ancestors()
        .take_while(|p| !p.as_os_str().is_empty() && !p.exists())
        .map(Path::to_path_buf)
        .collect();
    std::fs::create_dir_all(dir)
        .map_err(|e| Error::file(dir, format!("cannot create the folder: {e}")))?;
    Ok(missing.into_iter().rev().collect())
}

/// Removes folders made by [`create_dirs`], innermost first, where they are still empty.
pub fn remove_created(dirs: &[PathBuf]) {
    for d in dirs.iter().rev() {
        let _ = std::fs::remove_dir(d);
    }
}

/// Puts staged files in place. On a failure, removes those already put in place by this
/// call, so that a batch is written whole or not at all (as far as the file system allows).
pub fn commit_all(staged: Vec<Staged>) -> Result<Vec<PathBuf>> {
    let mut done = Vec::new();
    for s in staged {
        match s.commit() {
            Ok(p) => done.push(p),
            Err(e) => {
                for p in &done {
                    let _ = std::fs::remove_file(p);
                }
                return Err(e);
            }
        }
    }
    Ok(done)
}
