//! Where a scene's normals and material come from, as the command line's options and a
//! batch manifest's entries name them: one home for what [`super::manifest`] reads and the
//! command line's scene options give.

use std::path::PathBuf;

/// Largest image side accepted for a generated sphere.
pub const MAX_IMAGE_SIDE: usize = 8192;

/// Where a scene's normals come from.
#[derive(Clone, Debug, PartialEq)]
pub enum NormalsSource {
    /// A normal-map file (EXR, NPY or PNG).
    File(PathBuf),
    /// A unit sphere filling an N x N image.
    Sphere(usize),
}

/// Where a scene's material comes from.
#[derive(Clone, Debug, PartialEq)]
pub enum MaterialSource {
    /// A material JSON file.
    File(PathBuf),
    /// A built-in preset by name.
    Preset(String),
}
