//! The true edit (`"edit"` of a synth spec) and the last step of every sample.
//!
//! With `"edit": {"materials": [...]}` each sample is also rendered with a second
//! material drawn from those sources: the same normals, light, background and camera
//! (effects, noise field included), written as `edit.npy` with `edit_material.json`, the
//! ground truth an edit of `image.npy` is measured against. It costs a second render of
//! the object's pixels.
//!
//! The draws of the edit and of the camera effects ([`super::camera_effects`]) come from
//! generators of their own, derived from (seed, k): a spec without these keys draws, and
//! writes, exactly what it did before they existed.

use serde_json::json;

use super::draw::Sample;
use super::spec::Spec;
use super::{Engine, tar};
use crate::error::{Error, Result};
use crate::renderer::Renderer;
use crate::scene::{Batch, Image, Scene};

/// The members an edit adds to a sample, before the others (names sort so).
pub const EDIT_MEMBERS: [&str; 2] = ["edit.npy", "edit_material.json"];

impl Spec {
    /// The members of every sample, by suffix, in the order they are written.
    pub fn members(&self) -> Vec<&'static str> {
        let edit: &[&str] = if self.edit.is_some() {
            &EDIT_MEMBERS
        } else {
            &[]
        };
        edit.iter().chain(&tar::MEMBERS).copied().collect()
    }
}

impl Sample {
    /// Renders the sample's clutter (each object in its own material, under the sample's
    /// light) into its background, where each is seen: before [`Sample::compose`].
    /// Painting twice paints the same.
    pub fn paint_clutter(&mut self, renderer: &Renderer) -> Result<()> {
        if self.clutter.is_empty() {
            return Ok(());
        }
        let (w, h) = (self.scene.normals.width, self.scene.normals.height);
        let background = self.background.get_or_insert_with(|| vec![[0.0; 3]; w * h]);
        let (env, camera) = (&self.scene.env, self.scene.camera);
        super::clutter::paint(&self.clutter, env, camera, background, renderer)
            .map_err(|e| Error::Invalid(format!("sample {}: clutter: {e}", self.index)))
    }
}

/// A sample's members from the layer's render of its scene: the render over its
/// background, the edit rendered likewise, both developed by the camera effects.
pub(super) fn finish(sample: &mut Sample, render: Image, engine: &Engine) -> Result<tar::Members> {
    sample.paint_clutter(&engine.renderer)?;
    let mut images = vec![sample.compose(render)];
    if let Some(edit) = &sample.edit {
        let k = sample.index;
        let scene = Scene {
            material: edit.material.clone(),
            ..sample.scene.clone()
        };
        let batch = Batch::single(scene).map_err(|e| Error::Invalid(format!("sample {k}: {e}")))?;
        let render = engine
            .renderer
            .render(&batch)
            .map_err(|e| Error::Invalid(format!("sample {k}: edit: {e}")))?
            .remove(0);
        images.push(sample.compose(render));
    }
    if let Some(fx) = &sample.camera_effects {
        let (read, gain) = fx.develop(&mut images, sample.background.as_deref(), &sample.mask)?;
        let gain32 = gain as f32;
        for t in sample.scene.env.texels.iter_mut() {
            *t = t.map(|c| c * gain32);
        }
        if let Some(o) = sample.params["camera_effects"].as_object_mut() {
            o.insert("gain".into(), json!(gain));
            if fx.noise_level.is_some() {
                o.insert("read_noise_std".into(), json!(read));
            }
        }
    }
    let mut members = tar::members(sample, &images[0], &engine.label);
    if let (Some(edit), Some(image)) = (&sample.edit, images.get(1)) {
        let extra = [
            (
                EDIT_MEMBERS[0],
                crate::io::npy::encode_rgb(image.width, image.height, &image.pixels),
            ),
            (
                EDIT_MEMBERS[1],
                crate::io::json::encode_material(&edit.material, None),
            ),
        ];
        members.splice(0..0, extra);
    }
    Ok(members)
}
