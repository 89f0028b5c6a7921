//! The edit: the object of a [`Decomposition`] rendered with another material, under the
//! refined light or another, and put over the untouched photo with the soft mask.
//!
//! The layer renders the object at most [`RENDER_SIZE`] pixels a side; the photo gives
//! the rest. At each of the object's pixels, with R the render of the refined
//! decomposition (what the model explains of the photo P) and R' the render with the new
//! material, channel by channel, the edit is R' (Y' C^s)^detail, where Y = Y(P) / Y(R) is
//! the ratio of luminances, C = (P / R) / Y the ratio's colour (P and R offset by a small
//! epsilon), s in [0, 1] says how close R' is to R (1 where they are the same, 0 from
//! [`SAME_SHADING`] apart), and Y' = min(Y, [`MAX_RATIO`])^(1 - s) Y^s: a spot brighter
//! than the model explains (a highlight it missed) goes with the old material. With `detail` = 1
//! (the default) the photo's own detail in brightness (small shadows, occlusion, texture,
//! geometry finer than the nets see, the photo's full resolution) multiplies the new
//! material's shading; its colour detail, which is mostly what the model gets wrong of the
//! old material's colour, goes with the old material, so it is kept only as far as the
//! new material shades like the old: the photo's own material gives the photo back. With
//! `detail` = 0 the edit is the render alone. R and R' are brought to the photo's pixels
//! bilinearly from the object's render pixels only, so the outline does not darken.

use rayon::prelude::*;

use super::Decomposition;
use crate::continuous_light::{self, Integration};
use crate::error::Result;
use crate::raster::{self, Columns};
use crate::{Accuracy, Batch, Camera, EnvMap, Image, Material, NormalMap, Renderer, Scene};

/// The most pixels a side the object is rendered at for an edit: the photo's own detail
/// gives the rest. On the photo set's edits 128 gave the gains of 192 (docs/edit.md,
/// "Speed") at less than half the cost of the two renders.
pub const RENDER_SIZE: usize = 128;
/// The largest ratio of the photo to the refined render an edit carries over: brighter
/// spots than that (a highlight the model missed) belong to the old material.
pub const MAX_RATIO: f32 = 4.0;
/// How far apart (relative) the new material's shading may be from the old before none
/// of the photo's colour detail is kept.
pub const SAME_SHADING: f32 = 0.25;
/// The epsilon of the ratio, as a fraction of the refined render's mean over the object.
const EPSILON: f32 = 0.02;
/// Relative error allowed of the continuous light in edits: sharp lobes (chrome, gold)
/// integrate each texel of the light over its patch of directions instead of showing it
/// as a point.
pub const LIGHT_TOLERANCE: f64 = 0.02;
/// The continuous light takes its sub-texels from the light upsampled this many times.
const LIGHT_DETAIL: usize = 4;

impl Decomposition {
    /// `photo` (the photo decomposed, or one scaled alike with the decomposition) with the
    /// object made of `material`: rendered under `light` (`None`: the refined light) with
    /// `accuracy` ([`Accuracy::Exact`], sharp lobes under the continuous light; or a
    /// preview through the levels of detail, under the layer's point lights), with
    /// the photo's detail carried over as `self.detail` says, and composited over the
    /// photo with the soft mask.
    pub fn edit(
        &self,
        renderer: &Renderer,
        photo: &Image,
        material: &Material,
        light: Option<&EnvMap>,
        accuracy: Accuracy,
    ) -> Result<Image> {
        let new = self.render_new(renderer, material, light, accuracy)?;
        Ok(self.transfer(photo, &new))
    }

    /// The object made of `material` under `light` (`None`: the refined light), rendered
    /// with `accuracy`, at the photo's pixels (black off the object): the layer's part of
    /// [`Decomposition::edit`], without the photo's detail.
    pub fn render_object(
        &self,
        renderer: &Renderer,
        material: &Material,
        light: Option<&EnvMap>,
        accuracy: Accuracy,
    ) -> Result<Image> {
        let new = self.render_new(renderer, material, light, accuracy)?;
        let mut out = Image::zeros(self.width, self.height);
        let s = self.render_normals.width;
        let f = s as f64 / self.crop.size as f64;
        for (i, o) in out.pixels.iter_mut().enumerate() {
            if let Some((sx, sy)) = self.render_coords(i, f) {
                *o = on_object(&new.pixels, &self.coverage, s, sx, sy).unwrap_or([0.0; 3]);
            }
        }
        Ok(out)
    }

    /// R': the object in `material` under `light` (`None`: the refined light) at the
    /// render's size, as edits show it.
    fn render_new(
        &self,
        renderer: &Renderer,
        material: &Material,
        light: Option<&EnvMap>,
        accuracy: Accuracy,
    ) -> Result<Image> {
        let env = light.unwrap_or(&self.env);
        // a preview (through the levels of detail) under the layer's point lights, as
        // its reference ([`Decomposition::set_render_normals`])
        let continuous = accuracy == Accuracy::Exact;
        render(
            renderer,
            &self.render_normals,
            env,
            material,
            accuracy,
            continuous,
        )
    }

    /// Sets the normals edits render (over the crop, any size; zero off the object) and the
    /// fraction of each of their pixels on the object, and renders the refined
    /// decomposition on them (the reference the photo's detail is measured against). With
    /// `preview`, for a decomposition that only previews (edits with an approximate
    /// [`Accuracy`]), the reference renders as previews do, under the layer's point
    /// lights, without the continuous light's cost (most of a preview's time:
    /// docs/edit.md, "Speed").
    pub fn set_render_normals(
        &mut self,
        renderer: &Renderer,
        normals: NormalMap,
        coverage: Vec<f32>,
        preview: bool,
    ) -> Result<()> {
        self.reference = render(
            renderer,
            &normals,
            &self.env,
            &self.material,
            Accuracy::Exact,
            !preview,
        )?;
        self.render_normals = normals;
        self.coverage = coverage;
        Ok(())
    }

    /// The square of `image` (the photo's size) that the nets saw, black past its edges.
    pub fn crop_of(&self, image: &Image) -> Image {
        raster::crop(image, self.crop)
    }

    /// Pixel `i` of the photo in the render's texel-centre coordinates, if it is inside
    /// the crop and the soft mask touches it.
    fn render_coords(&self, i: usize, f: f64) -> Option<(f64, f64)> {
        if self.alpha[i] <= 0.0 {
            return None;
        }
        let u = ((i % self.width) as i64 - self.crop.x0) as f64 + 0.5;
        let v = ((i / self.width) as i64 - self.crop.y0) as f64 + 0.5;
        let size = self.crop.size as f64;
        (u >= 0.0 && v >= 0.0 && u < size && v < size).then_some((u * f - 0.5, v * f - 0.5))
    }

    /// The photo with the object's pixels made R' (Y' C^s)^detail and put over it with
    /// the soft mask (`new`: R', at the render's size).
    fn transfer(&self, photo: &Image, new: &Image) -> Image {
        let s = self.render_normals.width;
        let f = s as f64 / self.crop.size as f64;
        let (on, sum) = self
            .reference
            .pixels
            .iter()
            .zip(&self.coverage)
            .filter(|(_, c)| **c > 0.0)
            .fold((0usize, 0.0f64), |(n, t), (p, _)| {
                (
                    n + 1,
                    t + p.iter().map(|&v| f64::from(v)).sum::<f64>() / 3.0,
                )
            });
        let eps = (EPSILON as f64 * sum / on.max(1) as f64).max(1e-6) as f32;
        let detail = self.detail.clamp(0.0, 1.0);
        let mut out = photo.clone();
        out.pixels
            .par_chunks_mut(self.width)
            .enumerate()
            .for_each(|(y, row)| {
                for (x, o) in row.iter_mut().enumerate() {
                    let i = y * self.width + x;
                    let Some((sx, sy)) = self.render_coords(i, f) else {
                        continue;
                    };
                    let (Some(r1), Some(r0)) = (
                        on_object(&new.pixels, &self.coverage, s, sx, sy),
                        on_object(&self.reference.pixels, &self.coverage, s, sx, sy),
                    ) else {
                        continue;
                    };
                    let a = self.alpha[i];
                    let p = *o;
                    let y = (luminance(p) + eps) / (luminance(r0) + eps);
                    // how close the new shading is to the old: 1 the same, 0 from
                    // SAME_SHADING apart (relative, summed over the channels)
                    let apart: f32 = (0..3).map(|k| (r1[k] - r0[k]).abs()).sum::<f32>()
                        / (0..3).map(|k| r0[k] + eps).sum::<f32>();
                    let same = (1.0 - apart / SAME_SHADING).max(0.0);
                    // the brightness ratio clamped as far as the material changes
                    let y_kept = match same {
                        0.0 => y.min(MAX_RATIO),
                        1.0 => y,
                        s => y.min(MAX_RATIO).powf(1.0 - s) * y.powf(s),
                    };
                    for k in 0..3 {
                        let colour = ((p[k] + eps) / (r0[k] + eps)) / y;
                        let kept = match same {
                            0.0 => y_kept,
                            1.0 => y_kept * colour,
                            s => y_kept * colour.powf(s),
                        };
                        let gain = if detail == 1.0 {
                            kept
                        } else {
                            kept.powf(detail)
                        };
                        let value = (r1[k] + eps) * gain - eps;
                        o[k] = (1.0 - a) * p[k] + a * value.max(0.0);
                    }
                }
            });
        out
    }
}

/// Rec. 709 luminance of a linear RGB value.
fn luminance(c: [f32; 3]) -> f32 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Bilinear lookup at (x, y) in an `s` x `s` render, from the pixels on the object only
/// (`coverage` > 0); `None` where none of the four is.
fn on_object(px: &[[f32; 3]], coverage: &[f32], s: usize, x: f64, y: f64) -> Option<[f32; 3]> {
    let (x, y) = (x.clamp(0.0, (s - 1) as f64), y.clamp(0.0, (s - 1) as f64));
    let (x0, y0) = (x.floor() as usize, y.floor() as usize);
    let (x1, y1) = ((x0 + 1).min(s - 1), (y0 + 1).min(s - 1));
    let (fx, fy) = ((x - x0 as f64) as f32, (y - y0 as f64) as f32);
    let mut sum = [0.0f32; 3];
    let mut weight = 0.0f32;
    for (xx, yy, w) in [
        (x0, y0, (1.0 - fx) * (1.0 - fy)),
        (x1, y0, fx * (1.0 - fy)),
        (x0, y1, (1.0 - fx) * fy),
        (x1, y1, fx * fy),
    ] {
        let i = yy * s + xx;
        if coverage[i] > 0.0 && w > 0.0 {
            for k in 0..3 {
                sum[k] += w * px[i][k];
            }
            weight += w;
        }
    }
    (weight > 0.0).then(|| sum.map(|v| v / weight))
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

/// `normals` made of `material` under `env`, seen orthographically, with `accuracy`; with
/// `continuous`, a sharp lobe under the continuous light (equirect maps:
/// [`LIGHT_TOLERANCE`]), as edits show it.
pub(super) fn render(
    renderer: &Renderer,
    normals: &NormalMap,
    env: &EnvMap,
    material: &Material,
    accuracy: Accuracy,
    continuous: bool,
) -> Result<Image> {
    let batch = Batch::single(Scene {
        normals: normals.clone(),
        env: env.clone(),
        material: material.clone(),
        camera: Camera::Orthographic,
    })?;
    if continuous && env.convention == crate::Convention::Equirect {
        let details = [Some(upsampled(env, LIGHT_DETAIL))];
        let light = Integration::Tolerance(LIGHT_TOLERANCE);
        return Ok(
            continuous_light::render(renderer, &batch, &accuracy, light, &details)?
                .0
                .remove(0),
        );
    }
    Ok(match accuracy {
        Accuracy::Exact => renderer.render(&batch)?.remove(0),
        _ => renderer.render_with(&batch, &accuracy)?.0.remove(0),
    })
}

/// `env` bilinearly upsampled `factor` times in rows and columns (columns wrapping).
fn upsampled(env: &EnvMap, factor: usize) -> EnvMap {
    let (h, w) = (env.height * factor, env.width * factor);
    let f = factor as f64;
    let texels = (0..h * w)
        .map(|i| {
            let (r, c) = (i / w, i % w);
            let (x, y) = ((c as f64 + 0.5) / f - 0.5, (r as f64 + 0.5) / f - 0.5);
            raster::bilinear(&env.texels, env.width, env.height, x, y, Columns::Wrap)
        })
        .collect();
    EnvMap {
        height: h,
        width: w,
        convention: env.convention,
        texels,
    }
}
