//! The floor the object stands on: the plane through the object's lowest point, normal to
//! the world's up ([`up`]), textured ([`super::textures`]) and diffuse: its
//! radiance is albedo x E / pi with E the irradiance the sample's map gives the plane,
//! times the floor's visibility when shadows are on ([`super::shadow`]).
//!
//! A background pixel (not the object) whose camera ray meets the floor within
//! [`RADIUS`] of the object shows the floor (2 x 2 rays a pixel: the horizon and the
//! texture are antialiased); elsewhere it keeps the background. The floor is not the
//! object: the mask and the normals stay 0 there.

use std::path::Path;
use std::sync::Arc;

use rayon::prelude::*;
use serde::Deserialize;
use serde_json::{Value, json};
use sha2::Sha256;

use super::files::{files_of, hash_file};
use super::shadow::{self, Shadows};
use super::sources::{SampleNormals, Weighted, serde_message, weight_of};
use super::textures::{Kind, Texture, TileImage};
use crate::camera::Camera;
use crate::envmap::{Convention, EnvMap};
use crate::error::{Error, Result};
use crate::shapes::Geometry;
use crate::shapes::mesh::dot;
use crate::splitmix::SplitMix;

/// How far the floor reaches from the object, in the object's radii.
pub const RADIUS: f64 = 40.0;

/// Where a sample's floor comes from.
#[derive(Clone, Debug)]
pub enum FloorSource {
    /// No floor.
    None,
    /// A procedural texture drawn per sample.
    Procedural(Kind),
    /// Images, one picked per sample and tiled.
    Images(Vec<(String, Arc<TileImage>)>),
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFloor {
    none: Option<bool>,
    procedural: Option<String>,
    folder: Option<String>,
    file: Option<String>,
    weight: Option<f64>,
}

/// The spec's `floor` list, checked and loaded; errors name the item.
pub(super) fn floors(
    items: &[Value],
    normals: &[Weighted<SampleNormals>],
    camera: Camera,
    convention: Convention,
    base: &Path,
    hasher: &mut Sha256,
    err: &dyn Fn(String) -> Error,
) -> Result<Vec<Weighted<FloorSource>>> {
    if items.is_empty() {
        return Err(err(
            "floor: the list is empty; leave it out for no floor".into()
        ));
    }
    for (i, n) in normals.iter().enumerate() {
        if !matches!(
            n.source,
            SampleNormals::Shape(..) | SampleNormals::Meshes(..)
        ) {
            return Err(err(format!(
                "floor: normals[{i}] is not a shape or a mesh: a floor needs the object in 3D \
                 (normal maps have no depth); give {{\"shape\": ...}} or {{\"mesh\": ...}} \
                 sources only"
            )));
        }
    }
    if camera.is_orthographic() {
        return Err(err("floor: needs a perspective camera: give \"fov\"".into()));
    }
    if convention != Convention::Equirect {
        return Err(err("floor: needs the equirect convention".into()));
    }
    let mut out = Vec::new();
    for (i, item) in items.iter().enumerate() {
        let at = |m: String| err(format!("floor[{i}]: {m}"));
        if item.as_str() == Some("none") {
            out.push(Weighted {
                weight: 1.0,
                source: FloorSource::None,
            });
            continue;
        }
        let r: RawFloor =
            serde_json::from_value(item.clone()).map_err(|e| at(serde_message(&e)))?;
        let weight = weight_of(r.weight).map_err(at)?;
        let files = r.folder.is_some() || r.file.is_some();
        let source = match (r.procedural, files) {
            (None, false) if r.none == Some(true) => FloorSource::None,
            (Some(kind), false) if r.none.is_none() => {
                FloorSource::Procedural(Kind::parse(&kind).ok_or_else(|| {
                    at(format!(
                        "unknown procedural floor '{kind}': give \"wood\", \"tiles\" or \"cloth\""
                    ))
                })?)
            }
            (None, true) if r.none.is_none() => {
                let exts = ["png", "jpg", "jpeg", "exr", "npy"];
                let files = files_of(base, r.file, r.folder, &exts).map_err(at)?;
                let mut images = Vec::with_capacity(files.len());
                for f in files {
                    let bytes = crate::io::read_bytes(&f.path).map_err(|e| at(e.to_string()))?;
                    let image = crate::io::image_from_bytes(&f.path, &bytes)
                        .map_err(|e| at(e.to_string()))?;
                    hash_file(hasher, &f.label, &f.path).map_err(|e| at(e.to_string()))?;
                    images.push((f.label, Arc::new(TileImage::new(image))));
                }
                FloorSource::Images(images)
            }
            _ => {
                return Err(at(
                    "give exactly one of \"none\" ({\"none\": true}), {\"procedural\": KIND}, {\"folder\": PATH} or {\"file\": PATH}"
                        .into(),
                ));
            }
        };
        out.push(Weighted { weight, source });
    }
    Ok(out)
}

/// What the floor changes in a sample.
pub struct FloorDraw {
    /// The background with the floor drawn into it (`None`: black, no floor).
    pub background: Option<Vec<[f32; 3]>>,
    /// The factor on the object's rendered pixels (visibility), where shadows are on.
    pub shade: Option<Vec<f32>>,
    /// The floor's visibility at each pixel (1 off the floor), where shadows are on.
    pub floor_visibility: Option<Vec<f32>>,
    /// The factor on each other object's pixels ([`FloorScene::others`]), where shadows
    /// are on.
    pub others_shade: Vec<Vec<f32>>,
    /// What the sample records.
    pub params: Value,
}

/// Everything a sample's floor is drawn from.
pub struct FloorScene<'a> {
    /// The object as drawn.
    pub geometry: &'a Geometry,
    /// The sample's map, camera frame.
    pub env: &'a EnvMap,
    /// The camera.
    pub camera: Camera,
    /// Elevation, degrees.
    pub elevation: f64,
    /// Image (width, height).
    pub size: (usize, usize),
    /// Shadows on.
    pub shadows: bool,
    /// Other objects standing on the floor (clutter, [`super::clutter`]): the floor is
    /// not drawn where they are, and with shadows on they cast shadows as the object does
    /// and are shaded as it is.
    pub others: &'a [Geometry],
}

impl FloorSource {
    /// The floor of one sample over `background` (black where `None`), drawn from `rng`;
    /// for no floor, the background as it is.
    pub fn draw(
        &self,
        scene: &FloorScene,
        background: Option<Vec<[f32; 3]>>,
        rng: &mut SplitMix,
    ) -> FloorDraw {
        let (texture, record) = match self {
            FloorSource::None => {
                return FloorDraw {
                    background,
                    shade: None,
                    floor_visibility: None,
                    others_shade: Vec::new(),
                    params: json!("none"),
                };
            }
            FloorSource::Procedural(kind) => Texture::procedural(*kind, rng),
            FloorSource::Images(images) => {
                let (label, image) = &images[rng.below(images.len())];
                Texture::image(image.clone(), label, rng)
            }
        };
        draw_floor(scene, &texture, record, background)
    }
}

fn draw_floor(
    scene: &FloorScene,
    texture: &Texture,
    record: Value,
    background: Option<Vec<[f32; 3]>>,
) -> FloorDraw {
    let (w, h) = scene.size;
    let g = scene.geometry;
    let (ex, up, ez) = axes(scene.elevation);
    let verts = g.placed.positions.iter().map(|p| p.map(f64::from));
    let height = lowest(&g.placed, up);
    let n = g.placed.positions.len().max(1) as f64;
    let centre = verts.fold([0.0; 3], |a, p| {
        [a[0] + p[0] / n, a[1] + p[1] / n, a[2] + p[2] / n]
    });
    let e = shadow::irradiance(scene.env, up);
    let shadows = scene.shadows.then(|| {
        let meshes: Vec<_> = std::iter::once(g)
            .chain(scene.others)
            .map(|o| &o.placed)
            .collect();
        Shadows::of(&meshes, shadow::lights(scene.env, up))
    });
    let covered = |i: usize| g.mask[i] || scene.others.iter().any(|o| o.mask[i]);
    let tan = match scene.camera {
        Camera::Perspective { fov_y_deg } => (fov_y_deg.to_radians() / 2.0).tan(),
        Camera::Orthographic => 1.0,
    };
    let aspect = w as f64 / h as f64;
    let pixel = 2.0 * tan / h as f64;
    // a floor point and its footprint along the ray through (x, y) (pixel units), if the
    // ray meets the floor within the radius
    let hit = |x: f64, y: f64| -> Option<([f64; 3], f64)> {
        let d = [
            (x / w as f64 * 2.0 - 1.0) * tan * aspect,
            (1.0 - y / h as f64 * 2.0) * tan,
            -1.0,
        ];
        let along = dot(d, up);
        if along >= 0.0 || height >= 0.0 {
            return None;
        }
        let t = height / along;
        let p = d.map(|v| v * t);
        let off = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
        let planar = dot(off, off) - dot(off, up).powi(2);
        (planar < RADIUS * RADIUS).then(|| {
            let len = dot(d, d).sqrt();
            (p, t * len * pixel * 0.5 / (-along / len).max(0.02))
        })
    };
    let radiance = e.map(|v| v / std::f64::consts::PI);
    let mut bg = background.unwrap_or_else(|| vec![[0.0; 3]; w * h]);
    let rows: Vec<(Vec<[f32; 3]>, Vec<f32>)> = (0..h)
        .into_par_iter()
        .map(|y| {
            let mut out = bg[y * w..(y + 1) * w].to_vec();
            let mut vis_row = vec![1.0f32; w];
            for x in 0..w {
                if covered(y * w + x) {
                    continue;
                }
                let mut sum = [0.0f64; 3];
                let mut vis = None;
                for (fx, fy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let colour = match hit(x as f64 + fx, y as f64 + fy) {
                        Some((p, footprint)) => {
                            let v = *vis.get_or_insert_with(|| {
                                shadows
                                    .as_ref()
                                    .map_or(1.0, |s| s.visibility(p, up, 0.0, 1.5, 0.0))
                            });
                            let a = texture.albedo(dot(p, ex), dot(p, ez), footprint);
                            [0, 1, 2].map(|k| f64::from(a[k]) * radiance[k] * v)
                        }
                        None => out[x].map(f64::from),
                    };
                    for k in 0..3 {
                        sum[k] += colour[k] / 4.0;
                    }
                }
                out[x] = sum.map(|v| v as f32);
                vis_row[x] = vis.unwrap_or(1.0) as f32;
            }
            (out, vis_row)
        })
        .collect();
    let mut floor_vis = Vec::with_capacity(w * h);
    for (y, (row, vis)) in rows.into_iter().enumerate() {
        bg[y * w..(y + 1) * w].copy_from_slice(&row);
        floor_vis.extend(vis);
    }
    // what the object sees below the floor's horizon: the floor's mean radiance
    let m = texture.mean();
    let floor_lum =
        crate::envgen::colour::luminance([0, 1, 2].map(|k| f64::from(m[k]) * radiance[k]));
    let shade_of = |o: &Geometry, s: &Shadows| -> Vec<f32> {
        o.positions
            .par_iter()
            .zip(o.normals.normals.par_iter())
            .map(|(p, n)| {
                if *n == [0.0; 3] {
                    return 1.0;
                }
                let n = n.map(f64::from);
                s.visibility(*p, n, 0.03, 1.5, floor_lum) as f32
            })
            .collect()
    };
    let shade = shadows.as_ref().map(|s| shade_of(g, s));
    let others_shade = match &shadows {
        Some(s) => scene.others.iter().map(|o| shade_of(o, s)).collect(),
        None => Vec::new(),
    };
    let mut params = json!({ "texture": record, "irradiance": e, "height": height });
    if let Some(s) = &shadows {
        params["shadow_maps"] = json!(s.maps());
    }
    FloorDraw {
        background: Some(bg),
        floor_visibility: shadows.is_some().then_some(floor_vis),
        shade,
        others_shade,
        params,
    }
}

/// The height along `up` of `mesh`'s lowest vertex: where the floor under it lies.
pub fn lowest(mesh: &crate::shapes::Mesh, up: [f64; 3]) -> f64 {
    (mesh.positions.iter())
        .map(|p| dot(p.map(f64::from), up))
        .fold(f64::INFINITY, f64::min)
}

/// The world's x, up and z in the camera frame at `elevation` degrees: the floor's own
/// axes (x and z along it) and its normal.
pub fn axes(elevation: f64) -> ([f64; 3], [f64; 3], [f64; 3]) {
    let (s, c) = elevation.to_radians().sin_cos();
    ([1.0, 0.0, 0.0], up(elevation), [0.0, -s, c])
}

/// The world's up in the camera frame at `elevation` degrees: the floor's normal.
pub fn up(elevation: f64) -> [f64; 3] {
    let (s, c) = elevation.to_radians().sin_cos();
    [0.0, c, s]
}
