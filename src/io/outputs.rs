//! What `render` and `grad` write for a batch: one image per scene, or one folder of
//! gradient files per scene, at the outputs the batch names (in scene order). Outputs are checked before any work, and a batch is written
//! whole or not at all: every file is staged before any is put in place, and on a failure
//! the files already in place and the folders this call created are removed.

use std::path::{Path, PathBuf};

use super::png::Preview;
use super::write::{
    Staged, check_output, check_parent, commit_all, create_dirs, encode_image, remove_created,
    stage,
};
use super::{Format, json, npy};
use crate::error::{Error, Result};
use crate::scene::{Batch, Gradients, Image, Wanted};

/// An error unless every output is an image file (.exr, .npy or .png) that can be
/// written.
pub fn check_images(outputs: &[PathBuf]) -> Result<()> {
    for output in outputs {
        check_output(output, &[Format::Exr, Format::Npy, Format::Png])?;
    }
    Ok(())
}

/// Writes scene i's image to `outputs[i]` (the format by its extension, PNG through
/// `preview`); the paths written.
pub fn write_images(
    outputs: &[PathBuf],
    images: &[Image],
    preview: &Preview,
) -> Result<Vec<PathBuf>> {
    let mut staged = Vec::with_capacity(images.len());
    for (output, image) in outputs.iter().zip(images) {
        let bytes = encode_image(output, image, preview)?;
        staged.push(stage(output, &bytes)?);
    }
    commit_all(staged)
}

/// An error unless every folder can be one: one already, or a new one in a
/// folder that exists.
pub fn check_gradient_folders(folders: &[PathBuf]) -> Result<()> {
    for dir in folders {
        check_folder(dir)?;
    }
    Ok(())
}

fn check_folder(dir: &Path) -> Result<()> {
    if dir.exists() && !dir.is_dir() {
        return Err(Error::file(dir, "exists and is not a folder"));
    }
    if !dir.exists() {
        check_parent(dir)?;
    }
    Ok(())
}

/// Writes scene i's gradients that `wanted` names into `folders[i]` (created if missing):
/// `d_env.npy`, `d_normals.npy`, `d_material.json`; the paths written.
pub fn write_gradients(
    folders: &[PathBuf],
    batch: &Batch,
    grads: &[Gradients],
    wanted: Wanted,
) -> Result<Vec<PathBuf>> {
    let mut created = Vec::new();
    let result = stage_gradients(folders, batch, grads, wanted, &mut created).and_then(commit_all);
    if result.is_err() {
        remove_created(&created);
    }
    result
}

fn stage_gradients(
    folders: &[PathBuf],
    batch: &Batch,
    grads: &[Gradients],
    wanted: Wanted,
    created: &mut Vec<PathBuf>,
) -> Result<Vec<Staged>> {
    let mut staged = Vec::new();
    for ((dir, scene), g) in folders.iter().zip(batch.scenes()).zip(grads) {
        created.extend(create_dirs(dir)?);
        let env = &scene.env;
        let n = &scene.normals;
        let mut files = Vec::new();
        if wanted.env {
            let bytes = npy::encode_rgb(env.width, env.height, &g.d_env);
            files.push(("d_env.npy", bytes));
        }
        if wanted.normals {
            let bytes = npy::encode_rgb(n.width, n.height, &g.d_normals);
            files.push(("d_normals.npy", bytes));
        }
        if wanted.ctrl {
            files.push(("d_material.json", json::encode_gradient(&g.d_ctrl)));
        }
        for (name, bytes) in &files {
            staged.push(stage(&dir.join(name), bytes)?);
        }
    }
    Ok(staged)
}
