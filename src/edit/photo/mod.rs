//! A material edit of an object in a photo (`matedit edit`; the paper's "approach with
//! post-optimization"): the nets ([`crate::nets`]) predict the object's mask, normals,
//! light and material on a square crop around the object; a fit through the layer
//! ([`super::fit`]) refines the material and the light from those predictions until the
//! layer re-renders the photo, and, if asked, the normals with those fixed
//! (`refine_normals`, an experiment: docs/edit.md); the object is then rendered with
//! another material under the refined light and normals, at the photo's resolution, and
//! composited over the untouched background with a soft mask. Normals or a light known
//! otherwise ([`PhotoOptions::normals`], [`PhotoOptions::env`]) take the nets' place: a
//! known light is neither refined nor blurred, and only the material is refined under it.
//!
//! The crop: the square around the mask's bounding box with the margin the nets were
//! trained with (the object fills the frame but 5% on each side), padded with black where
//! it leaves the photo, box-filtered to the nets' input size. Without a mask, passes on the
//! whole photo (padded to a square) find the object: the first on the photo normalised by
//! its mean, each next on the photo normalised by the mean over the mask found before (as
//! the nets were trained); the last pass's mask probability, bilinear at the photo's
//! pixels, above one half; refused when no single object stands out
//! ([`check::single_object`]). Pointed at ([`Pointing`]: a box, points on the object and
//! off it), a cut with the nets' mask for a prior finds it ([`pointing`](mod@pointing)).
//! The soft mask of the composite is the
//! mask averaged over each pixel's 3 x 3 neighbourhood.
//!
//! Files: [`check`] (the photos and masks taken), [`decompose`](mod@decompose) (nets and
//! refinement: a photo to its [`Decomposition`]), `crop.rs` (the square around the
//! object, and values carried between it and the photo), `refine.rs` (the normals'
//! refinement), [`composite`](mod@composite) (the edit: the object re-rendered and put
//! over the photo).

pub mod check;
pub mod composite;
mod crop;
pub mod decompose;
pub mod light;
pub mod pointing;
mod refine;

pub use crate::raster::Crop;
pub use check::{
    MAX_PIXELS, MAX_SIDE, MIN_OBJECT_PIXELS, MIN_SIDE, check_mask, check_photo, single_object,
};
pub use composite::{LIGHT_TOLERANCE, MAX_RATIO, RENDER_SIZE, composite};
pub use decompose::decompose;
pub use pointing::{Pointing, segment_object};

use crate::{EnvMap, Image, Material, NormalMap};

/// The default of [`PhotoOptions::work_pixels`].
pub const WORK_PIXELS: usize = 2048;

/// Refinement steps where the normals and the light are both known
/// ([`PhotoOptions::normals`], [`PhotoOptions::env`]): only the material moves, with nothing
/// wrong in them for it to absorb, and it goes on coming closer where 20 steps (the
/// default, chosen with the nets' normals and light) stop early for that reason
/// (docs/edit.md, "What each guess costs").
pub const KNOWN_STEPS: usize = 100;

/// The refinement's steps where none are asked for: [`KNOWN_STEPS`] where the normals and
/// the light are both known, else [`PhotoOptions::default`]'s.
pub fn default_steps(normals_known: bool, light_known: bool) -> usize {
    if normals_known && light_known {
        KNOWN_STEPS
    } else {
        PhotoOptions::default().steps
    }
}

/// How to edit.
#[derive(Clone, Debug)]
pub struct PhotoOptions {
    /// Refinement steps of material and light (0: the predictions as they are; 20 by
    /// default, [`KNOWN_STEPS`] suits known normals and light).
    pub steps: usize,
    /// Refinement steps of the normals after them, material and light fixed (0: none, the
    /// default: an experiment, docs/edit.md).
    pub normal_steps: usize,
    /// Weight of the normals' smoothness prior (the mean squared difference between
    /// neighbouring normals on the object).
    pub normal_smoothness: f64,
    /// Weight of the normals' anchor to the nets' (the mean squared difference between a
    /// refined normal and the predicted one over the object).
    pub normal_anchor: f64,
    /// The refinement runs on the crop box-filtered by a whole factor to at most this many
    /// pixels a side (0: no bound) ...
    pub work_size: usize,
    /// ... and at most this many pixels on the object (0: no bound), down to the nets'
    /// size a side: it fits a light and a material, which a photo's full resolution does
    /// not tell better, and each step costs in proportion to these pixels.
    pub work_pixels: usize,
    /// The nets' input size (square; a multiple of 2^(levels - 1)); 0 (the default): the
    /// size they were trained at ([`Nets::image_size`](crate::nets::Nets::image_size)).
    pub net_size: usize,
    /// How much of the photo's own detail an edit keeps, in [0, 1]: 1 (the default) the
    /// photo with the shading changed from the old material to the new (the photo itself
    /// when the material is the photo's own), 0 the re-rendered object alone
    /// ([`composite`](mod@composite)).
    pub detail: f32,
    /// The predicted light takes the background's mean radiance before the refinement, or
    /// on black a grey card's exposure ([`light`]); false keeps the nets' level.
    pub background_light: bool,
    /// The object's normals, known (camera frame, the photo's size), in place of the nets':
    /// from a depth camera or another estimator. A pixel on the object without one (zero)
    /// takes the nets'.
    pub normals: Option<NormalMap>,
    /// The light, known (a lat-long map in the photo's linear units, whose size the nets'
    /// light size divides), in place of the nets': brought to their size, neither matched to
    /// the background, refined nor blurred (its detail is real); only the material is
    /// refined.
    pub env: Option<EnvMap>,
}

impl Default for PhotoOptions {
    fn default() -> Self {
        PhotoOptions {
            steps: 20,
            normal_steps: 0,
            normal_smoothness: 0.05,
            normal_anchor: 0.0,
            work_size: 128,
            work_pixels: WORK_PIXELS,
            net_size: 0,
            detail: 1.0,
            background_light: true,
            normals: None,
            env: None,
        }
    }
}

/// What the nets and the refinement made of a photo.
#[derive(Clone, Debug)]
pub struct Decomposition {
    /// The photo's columns.
    pub width: usize,
    /// The photo's rows.
    pub height: usize,
    /// The crop the nets saw.
    pub crop: Crop,
    /// The object's normals at the crop's pixels (crop.size square; zero off the object).
    pub normals: NormalMap,
    /// The object at the photo's pixels.
    pub mask: Vec<bool>,
    /// The soft mask at the photo's pixels, in [0, 1].
    pub alpha: Vec<f32>,
    /// The nets' material.
    pub predicted_material: Material,
    /// The nets' light, in the photo's units.
    pub predicted_env: EnvMap,
    /// The refined material (the prediction without refinement).
    pub material: Material,
    /// The light edits render under: the refined light (the prediction without
    /// refinement) blurred by [`light::EDIT_LIGHT_BLUR`] ([`light::blur`]), or the known
    /// light ([`PhotoOptions::env`]) as it was given.
    pub env: EnvMap,
    /// PSNR (dB) of I' = R(n', m', L') against the photo over the object, with the
    /// predictions and after refinement (with the refined light before its blur), at the
    /// refinement's working size.
    pub psnr_predicted: f64,
    /// As `psnr_predicted`, after refinement.
    pub psnr_refined: f64,
    /// The refinement's loss per step (material and light).
    pub losses: Vec<f64>,
    /// The normals' refinement's loss (data term and smoothness prior) at its start and
    /// after each step taken (empty without it).
    pub normal_losses: Vec<f64>,
    /// The factors the predicted light was scaled by per channel to take the background's
    /// level (or the grey card's) in grey (ones where it was not, or where the light was
    /// given: [`light`]).
    pub light_factors: light::Factors,
    /// The object's normals at the size edits render at (at most [`RENDER_SIZE`] a side,
    /// over the crop).
    pub render_normals: NormalMap,
    /// The fraction of each of `render_normals`' pixels on the object.
    pub coverage: Vec<f32>,
    /// The refined decomposition rendered at `render_normals`' pixels: what the model
    /// explains of the photo.
    pub reference: Image,
    /// How much of the photo's detail edits keep ([`PhotoOptions::detail`]).
    pub detail: f32,
    /// Seconds per stage: "segment" (when pointed at), "predict", "refine", "reference".
    pub stages: Vec<(&'static str, f64)>,
}

/// A stage of [`decompose`], for a progress display.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    /// Cutting out the object pointed at.
    Segment,
    /// Finding the object: pass `pass` of `passes` of the normals net on the whole photo.
    Mask { pass: usize, passes: usize },
    /// The nets on the crop around the object.
    Predict,
    /// Refining material and light: `step` of `steps` done.
    Refine { step: usize, steps: usize },
    /// Refining the normals: `step` of `steps` done.
    Normals { step: usize, steps: usize },
}

/// Where the object is: found by the nets, given as a mask, or pointed at.
#[derive(Clone, Copy, Debug)]
pub enum Object<'a> {
    /// The nets find it (refused when no single object stands out).
    Find,
    /// The object's pixels (row-major, the photo's size).
    Mask(&'a [bool]),
    /// A box and points, cut out with the nets' mask for a prior.
    Pointed(&'a Pointing),
}

impl<'a> From<Option<&'a [bool]>> for Object<'a> {
    fn from(mask: Option<&'a [bool]>) -> Self {
        mask.map_or(Object::Find, Object::Mask)
    }
}

impl<'a> From<&'a Pointing> for Object<'a> {
    fn from(p: &'a Pointing) -> Self {
        Object::Pointed(p)
    }
}
