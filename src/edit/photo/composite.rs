//! The edit: the object of a [`Decomposition`] rendered with another material, under the
//! refined light or another, at the photo's pixels, and put over the untouched photo with
//! the soft mask.

use super::Decomposition;
use crate::error::Result;
use crate::raster;
use crate::{Accuracy, Batch, Camera, EnvMap, Image, Material, NormalMap, Renderer, Scene};

impl Decomposition {
    /// `photo` (the photo decomposed, or one scaled alike with the decomposition) with the
    /// object made of `material`: rendered under `light` (`None`: the refined light) with
    /// `accuracy` ([`Accuracy::Exact`], or a preview through the levels of detail) and
    /// composited over the photo with the soft mask.
    pub fn edit(
        &self,
        renderer: &Renderer,
        photo: &Image,
        material: &Material,
        light: Option<&EnvMap>,
        accuracy: Accuracy,
    ) -> Result<Image> {
        let object = self.render_object(renderer, material, light, accuracy)?;
        Ok(composite(photo, &object, &self.alpha))
    }

    /// The object made of `material` under `light` (`None`: the refined light), rendered
    /// with `accuracy`, at the photo's pixels (black off the crop): the layer's part of
    /// [`Decomposition::edit`].
    pub fn render_object(
        &self,
        renderer: &Renderer,
        material: &Material,
        light: Option<&EnvMap>,
        accuracy: Accuracy,
    ) -> Result<Image> {
        let env = light.unwrap_or(&self.env);
        let img = render(renderer, &self.normals, env, material, accuracy)?;
        Ok(raster::uncrop(&img, self.crop, self.width, self.height))
    }

    /// The square of `image` (the photo's size) that the nets saw, black past its edges.
    pub fn crop_of(&self, image: &Image) -> Image {
        raster::crop(image, self.crop)
    }
}

/// `object` over `photo` with the soft mask `alpha`.
pub fn composite(photo: &Image, object: &Image, alpha: &[f32]) -> Image {
    let mut out = photo.clone();
    for ((o, p), &a) in out.pixels.iter_mut().zip(&object.pixels).zip(alpha) {
        for k in 0..3 {
            o[k] = (1.0 - a) * o[k] + a * p[k];
        }
    }
    out
}

/// `normals` made of `material` under `env`, seen orthographically, with `accuracy`.
pub(super) fn render(
    renderer: &Renderer,
    normals: &NormalMap,
    env: &EnvMap,
    material: &Material,
    accuracy: Accuracy,
) -> Result<Image> {
    let batch = Batch::single(Scene {
        normals: normals.clone(),
        env: env.clone(),
        material: material.clone(),
        camera: Camera::Orthographic,
    })?;
    Ok(match accuracy {
        Accuracy::Exact => renderer.render(&batch)?.remove(0),
        _ => renderer.render_with(&batch, &accuracy)?.0.remove(0),
    })
}
