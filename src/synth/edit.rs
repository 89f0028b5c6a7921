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

use serde::Deserialize;
use serde_json::{Value, json};
use sha2::Sha256;

use super::camera_effects::Drawn;
use super::draw::Sample;
use super::sources::{MaterialItem, Weighted, serde_message};
use super::spec::Spec;
use super::{Engine, tar};
use crate::error::{Error, Result};
use crate::material::Material;
use crate::scene::{Batch, Image, Scene};
use crate::splitmix::SplitMix;

/// Mixed into a sample's generator for its camera effects' draws.
const CAMERA_EFFECTS_STREAM: u64 = 0x63616d_6572615f;
/// Mixed into a sample's generator for its edit material's draws.
const EDIT_STREAM: u64 = 0x65646974_5f6d6174;

/// The members an edit adds to a sample, before the others (names sort so).
pub const EDIT_MEMBERS: [&str; 2] = ["edit.npy", "edit_material.json"];

/// A sample's edit: the second material and what made it.
#[derive(Clone, Debug)]
pub struct EditDraw {
    /// The material the edit renders the object in.
    pub material: Material,
    /// What the sample's params record: the item and its draws.
    pub record: Value,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawEdit {
    materials: Vec<Value>,
}

/// The spec's `edit` object: its material sources, loaded and hashed into the digest;
/// errors name `edit.materials[i]`.
pub(super) fn materials(
    v: &Value,
    base: &std::path::Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<MaterialItem>>> {
    let raw: RawEdit = serde_path_to_error::deserialize(v.clone()).map_err(|e| {
        let at = e.path().to_string();
        let m = serde_message(e.inner());
        err(if at == "." {
            format!("edit: {m}")
        } else {
            format!("edit.{at}: {m}")
        })
    })?;
    if raw.materials.is_empty() {
        return Err(err(
            "edit.materials: the list is empty; give at least one".into()
        ));
    }
    super::sources::materials(&raw.materials, base, hasher, &|m| err(format!("edit.{m}")))
}

/// Sample `k`'s generator for one of the extra streams.
fn stream(seed: u64, k: u64, constant: u64) -> SplitMix {
    let mut s = SplitMix::for_sample(seed, k);
    SplitMix(SplitMix(s.next_u64() ^ constant).next_u64())
}

impl Spec {
    /// Sample `k`'s camera effects and edit material, each from its own generator, and
    /// their records added to `params` (nothing when the spec has neither key).
    pub(super) fn draw_extras(
        &self,
        k: u64,
        params: &mut Value,
    ) -> Result<(Option<Drawn>, Option<EditDraw>)> {
        let effects = self
            .camera_effects
            .as_ref()
            .map(|fx| fx.draw(&mut stream(self.seed, k, CAMERA_EFFECTS_STREAM)));
        let edit = match &self.edit {
            None => None,
            Some(items) => {
                let mut rng = stream(self.seed, k, EDIT_STREAM);
                let (item, material, record) = super::draw::draw_material(&mut rng, items)?;
                Some(EditDraw {
                    material,
                    record: json!({ "material": record, "material_item": item }),
                })
            }
        };
        if let Some(o) = params.as_object_mut() {
            if let Some(d) = &effects {
                o.insert("camera_effects".into(), d.record());
            }
            if let Some(e) = &edit {
                o.insert("edit".into(), e.record.clone());
            }
        }
        Ok((effects, edit))
    }

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

/// A sample's members from the layer's render of its scene: the render over its
/// background, the edit rendered likewise, both developed by the camera effects.
pub(super) fn finish(sample: &mut Sample, render: Image, engine: &Engine) -> Result<tar::Members> {
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
