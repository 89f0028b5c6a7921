//! Clutter (`"clutter"` of a synth spec): other shapes and meshes standing on the floor
//! beside and behind the object, each with its own material, lit by the sample's map.
//!
//! Each object is a shape or a mesh of the clutter's `normals` sources, upright (turned
//! about the world's up by a uniform yaw), scaled so that its bounding sphere has a radius
//! drawn from `size` (in the object's radii: the object's bounding sphere has radius 1),
//! and set on the floor beside or behind the object: its footprint's centre at an angle
//! within 90 degrees of the direction from the camera to the object, its footprint (the
//! circle around its vertices on the floor) a gap of [`GAP`] radii from the object's and
//! from the other objects'. A placement whose bounding sphere is not wholly in front of
//! the camera or whose centre is outside the frame is drawn again, up to [`TRIES`] times,
//! then the object is left out.
//!
//! The objects are rasterised like the object and depth-tested against it and each other
//! pixel by pixel; what is nearest is seen. A point on an object above the floor is nearer
//! along its ray than the floor, so the floor never hides one. Clutter is not the object:
//! the mask and normals are the object's where the object is seen (0 where clutter hides
//! it). The objects' renders ([`paint`]) go into the background, under the camera effects
//! as the floor does; the true edit changes the object's material only.

use std::borrow::Cow;

use serde::Deserialize;
use serde_json::{Value, json};
use sha2::Sha256;

use super::draws::{draw_material, pick};
use super::floor;
use super::sources::{self, MaterialItem, SampleNormals, Weighted, serde_message};
use super::world::SampleView;
use crate::camera::Camera;
use crate::envmap::EnvMap;
use crate::error::{Error, Result};
use crate::material::Material;
use crate::renderer::Renderer;
use crate::scene::{Batch, NormalMap, Scene};
use crate::shapes::mesh::{V3, dot};
use crate::shapes::view::mat_vec;
use crate::shapes::{Geometry, Mesh, Rotation, View};
use crate::splitmix::SplitMix;

/// Most objects a sample's clutter may hold.
pub const MAX_COUNT: usize = 8;
/// Objects per sample when the spec does not say.
pub const DEFAULT_COUNT: [usize; 2] = [1, 3];
/// Bounding-sphere radii when the spec does not say, in the object's radii.
pub const DEFAULT_SIZE: [f64; 2] = [0.3, 0.8];
/// Largest radius `size` may give.
pub const MAX_SIZE: f64 = 2.0;
/// The gap between footprints, in the object's radii: uniform in this range from the
/// object's, at least the low end between two clutter objects.
pub const GAP: [f64; 2] = [0.05, 1.0];
/// Placements drawn for one object before it is left out.
pub const TRIES: usize = 12;

/// The clutter of a spec: how many objects, how large, drawn from which sources.
#[derive(Clone, Debug)]
pub struct Clutter {
    /// Objects per sample, uniform in [lo, hi].
    pub count: [usize; 2],
    /// Bounding-sphere radius, uniform, in the object's radii.
    pub size: [f64; 2],
    /// Shapes and meshes (their `views` are not used: clutter stands upright).
    pub normals: Vec<Weighted<SampleNormals>>,
    /// Materials.
    pub materials: Vec<Weighted<MaterialItem>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawClutter {
    count: Option<Value>,
    size: Option<Value>,
    normals: Option<Vec<Value>>,
    materials: Option<Vec<Value>>,
}

/// The spec's own sources, the clutter's defaults, and what checking its own needs.
pub(super) struct Defaults<'a> {
    pub normals: &'a [Weighted<SampleNormals>],
    pub materials: &'a [Weighted<MaterialItem>],
    pub image_size: (usize, usize),
    pub has_floor: bool,
}

fn pair(v: &Value) -> Option<[f64; 2]> {
    match v.as_array().map(Vec::as_slice) {
        Some([a, b]) => Some([a.as_f64()?, b.as_f64()?]),
        _ => v.as_f64().map(|x| [x, x]),
    }
}

impl Clutter {
    /// The spec's `clutter` object, checked and its sources loaded (hashed into the
    /// digest); errors name `clutter.KEY`.
    pub(super) fn parse(
        v: &Value,
        defaults: Defaults,
        base: &std::path::Path,
        hasher: &mut Sha256,
        err: &dyn Fn(String) -> Error,
    ) -> Result<Clutter> {
        let raw: RawClutter = serde_path_to_error::deserialize(v.clone()).map_err(|e| {
            let (at, m) = (e.path().to_string(), serde_message(e.inner()));
            err(if at == "." {
                format!("clutter: {m}")
            } else {
                format!("clutter.{at}: {m}")
            })
        })?;
        if !defaults.has_floor {
            return Err(err(
                "clutter: needs a \"floor\" (clutter stands on it)".into()
            ));
        }
        let count = match &raw.count {
            None => DEFAULT_COUNT,
            Some(c) => match pair(c) {
                Some([lo, hi])
                    if lo.fract() == 0.0
                        && hi.fract() == 0.0
                        && lo >= 0.0
                        && lo <= hi
                        && hi <= MAX_COUNT as f64 =>
                {
                    [lo as usize, hi as usize]
                }
                _ => {
                    return Err(err(format!(
                        "clutter.count: {c}: expected a whole number or [LO, HI] with 0 <= LO <= HI <= {MAX_COUNT}"
                    )));
                }
            },
        };
        let size = match &raw.size {
            None => DEFAULT_SIZE,
            Some(s) => match pair(s) {
                Some([lo, hi]) if lo > 0.0 && lo <= hi && hi <= MAX_SIZE => [lo, hi],
                _ => {
                    return Err(err(format!(
                        "clutter.size: {s}: expected [LO, HI] radii with 0 < LO <= HI <= {MAX_SIZE}"
                    )));
                }
            },
        };
        let at = |m: String| err(format!("clutter.{m}"));
        let normals = match &raw.normals {
            None => defaults.normals.to_vec(),
            Some(items) if items.is_empty() => {
                return Err(at(
                    "normals: the list is empty; leave it out for the spec's own".into(),
                ));
            }
            Some(items) => {
                let n = sources::normals(items, defaults.image_size, base, hasher, &at)?;
                for (i, item) in n.iter().enumerate() {
                    if !matches!(
                        item.source,
                        SampleNormals::Shape(..) | SampleNormals::Meshes(..)
                    ) {
                        return Err(at(format!(
                            "normals[{i}]: not a shape or a mesh: clutter stands on the floor in 3D; give {{\"shape\": ...}} or {{\"mesh\": ...}}"
                        )));
                    }
                }
                n
            }
        };
        let materials = match &raw.materials {
            None => defaults.materials.to_vec(),
            Some(items) if items.is_empty() => {
                return Err(at(
                    "materials: the list is empty; leave it out for the spec's own".into(),
                ));
            }
            Some(items) => sources::materials(items, base, hasher, &at)?,
        };
        Ok(Clutter {
            count,
            size,
            normals,
            materials,
        })
    }

    /// The generator of sample `k`'s clutter: a stream apart from every other.
    pub fn rng(seed: u64, k: u64) -> SplitMix {
        SplitMix::for_sample(seed ^ 0x2f4d_1c7b_93e8_a605, k.rotate_left(29))
    }
}

/// An object's footprint on the floor: its vertices' centre and radius in the floor's
/// (x, z) coordinates, and its lowest height.
struct Footprint {
    centre: [f64; 2],
    radius: f64,
    lowest: f64,
}

fn footprint(points: &[[f32; 3]], axes: (V3, V3, V3)) -> Footprint {
    let (ex, up, ez) = axes;
    let (mut lo, mut hi, mut lowest) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2], f64::INFINITY);
    for p in points {
        let p = p.map(f64::from);
        let q = [dot(p, ex), dot(p, ez)];
        for k in 0..2 {
            lo[k] = lo[k].min(q[k]);
            hi[k] = hi[k].max(q[k]);
        }
        lowest = lowest.min(dot(p, up));
    }
    let centre = [(lo[0] + hi[0]) / 2.0, (lo[1] + hi[1]) / 2.0];
    let radius = (points.iter())
        .map(|p| {
            let p = p.map(f64::from);
            (dot(p, ex) - centre[0]).hypot(dot(p, ez) - centre[1])
        })
        .fold(0.0, f64::max);
    Footprint {
        centre,
        radius,
        lowest,
    }
}

/// One object of a sample's clutter, as drawn: its render's inputs (the normals where it
/// is seen), and the factor on its pixels where shadows are on.
#[derive(Clone, Debug)]
pub struct ClutterLayer {
    /// Its normals where it is seen, 0 elsewhere.
    pub normals: NormalMap,
    /// Its material.
    pub material: Material,
    /// Its visibility where shadows are on.
    pub shade: Option<Vec<f32>>,
}

/// A sample's clutter, placed and rasterised.
pub struct ClutterDraw {
    /// Each object's geometry, all it covers (the floor's [`floor::FloorScene::others`]).
    pub geometries: Vec<Geometry>,
    /// Each object's material.
    pub materials: Vec<Material>,
    /// What the sample records.
    pub params: Value,
}

impl Clutter {
    /// The clutter around `main` (the object as drawn, standing on its floor), drawn from
    /// `rng`.
    pub fn draw(
        &self,
        main: &Geometry,
        sv: SampleView,
        size: (usize, usize),
        rng: &mut SplitMix,
    ) -> Result<ClutterDraw> {
        let axes = floor::axes(sv.elevation);
        let (ex, up, ez) = axes;
        let height = floor::lowest(&main.placed, up);
        let m = footprint(&main.placed.positions, axes);
        // towards the object, seen from the camera (the origin), along the floor
        let len = m.centre[0].hypot(m.centre[1]);
        let f = if len > 1e-9 {
            [m.centre[0] / len, m.centre[1] / len]
        } else {
            [0.0, -1.0]
        };
        let side = [-f[1], f[0]];
        let n = self.count[0] + rng.below(self.count[1] - self.count[0] + 1);
        let mut placed: Vec<([f64; 2], f64)> = Vec::new();
        let (mut geometries, mut materials, mut records) = (Vec::new(), Vec::new(), Vec::new());
        let view = View {
            camera: sv.camera,
            ..View::new(size.0, size.1)
        };
        for _ in 0..n {
            let ni = pick(rng, &self.normals);
            let (mesh, mut record) = match &self.normals[ni].source {
                SampleNormals::Shape(shape, _) => {
                    let seed = rng.next_u64();
                    let p = json!({ "shape": shape.to_string(), "shape_seed": seed });
                    (Cow::Owned(shape.mesh(seed)), p)
                }
                SampleNormals::Meshes(meshes, _) => {
                    let (label, mesh) = &meshes[rng.below(meshes.len())];
                    (Cow::Borrowed(mesh), json!({ "mesh": label }))
                }
                _ => {
                    return Err(Error::Invalid(
                        "clutter: a source is not a shape or a mesh".into(),
                    ));
                }
            };
            let yaw = 360.0 * rng.uniform();
            let radius = self.size[0] + (self.size[1] - self.size[0]) * rng.uniform();
            let (mi, material, mparams) = draw_material(rng, &self.materials)?;
            let Some(model) = upright(&mesh, yaw, sv.elevation, radius) else {
                continue;
            };
            let fp = footprint(&model.positions, axes);
            let mut found = None;
            for _ in 0..TRIES {
                let phi = (2.0 * rng.uniform() - 1.0) * std::f64::consts::FRAC_PI_2;
                let gap = GAP[0] + (GAP[1] - GAP[0]) * rng.uniform();
                let d = m.radius + fp.radius + gap;
                let (s, c) = phi.sin_cos();
                let at = [0, 1].map(|k| m.centre[k] + d * (c * f[k] + s * side[k]));
                let apart = placed
                    .iter()
                    .all(|(o, r)| (at[0] - o[0]).hypot(at[1] - o[1]) >= r + fp.radius + GAP[0]);
                let (du, dv, dh) = (
                    at[0] - fp.centre[0],
                    at[1] - fp.centre[1],
                    height - fp.lowest,
                );
                let t: V3 = [0, 1, 2].map(|k| du * ex[k] + dh * up[k] + dv * ez[k]);
                if apart && in_view(t, radius, sv.camera, size) {
                    found = Some((t, at, phi.to_degrees(), d));
                    break;
                }
            }
            let Some((t, at, angle, distance)) = found else {
                continue;
            };
            placed.push((at, fp.radius));
            let moved = model.transformed(|p| [p[0] + t[0], p[1] + t[1], p[2] + t[2]], |n| n);
            geometries.push(crate::shapes::render_in_camera_space(&moved, &view)?);
            materials.push(material);
            let o = json!({
                "normals_item": ni, "material": mparams, "material_item": mi,
                "radius": radius, "yaw": yaw, "angle": angle, "distance": distance,
            });
            super::draws::merge(&mut record, o);
            records.push(record);
        }
        Ok(ClutterDraw {
            geometries,
            materials,
            params: json!({ "drawn": n, "objects": records }),
        })
    }
}

/// `mesh` centred on its bounding box, turned by `yaw` about the world's up, pitched by
/// the elevation as the world is, and scaled so that its bounding sphere has `radius`;
/// `None` for a mesh with no extent.
fn upright(mesh: &Mesh, yaw: f64, elevation: f64, radius: f64) -> Option<Mesh> {
    let r = Rotation {
        yaw,
        pitch: elevation,
        roll: 0.0,
    }
    .matrix();
    let (lo, hi) = mesh.bounds();
    let c = [0, 1, 2].map(|k| (lo[k] + hi[k]) / 2.0);
    let extent = (mesh.triangles.iter().flatten())
        .map(|&v| {
            let p = mesh.positions[v as usize].map(f64::from);
            let d = [p[0] - c[0], p[1] - c[1], p[2] - c[2]];
            dot(d, d).sqrt()
        })
        .fold(0.0, f64::max);
    if !(extent.is_finite() && extent > 0.0) {
        return None;
    }
    let s = radius / extent;
    let normals = mesh.vertex_normals();
    let turned = Mesh {
        normals: Some(normals),
        ..mesh.clone()
    };
    Some(turned.transformed(
        |p| mat_vec(&r, [p[0] - c[0], p[1] - c[1], p[2] - c[2]]).map(|v| v * s),
        |n| mat_vec(&r, n),
    ))
}

/// Whether a bounding sphere at `centre` (camera space) of `radius` lies wholly in front
/// of the camera, its centre within the frame.
fn in_view(centre: V3, radius: f64, camera: Camera, (w, h): (usize, usize)) -> bool {
    let Camera::Perspective { fov_y_deg } = camera else {
        return false;
    };
    let depth = -centre[2];
    let tan = (fov_y_deg.to_radians() / 2.0).tan();
    let aspect = w as f64 / h as f64;
    depth > radius + 0.05
        && (centre[0] / depth).abs() < tan * aspect
        && (centre[1] / depth).abs() < tan
}

impl ClutterDraw {
    /// The depth test: hides the object's pixels where an object of the clutter is nearer
    /// (zero normal, mask unset) and gives each object its layer, its normals where it is
    /// the nearest; `shades`, the floor's factors on each object's pixels, where shadows
    /// are on. Returns the layers and what the sample records (each object's `pixels`
    /// seen added).
    pub fn resolve(
        self,
        main: &Geometry,
        normals: &mut NormalMap,
        mask: &mut [bool],
        shades: Vec<Vec<f32>>,
    ) -> Result<(Vec<ClutterLayer>, Value)> {
        let objects = &self.geometries;
        let mut seen: Vec<Vec<[f32; 3]>> = vec![vec![[0.0; 3]; mask.len()]; objects.len()];
        for i in 0..mask.len() {
            let mut best = (f64::INFINITY, None);
            if main.mask[i] {
                best = (-main.positions[i][2], None);
            }
            for (j, o) in objects.iter().enumerate() {
                if o.mask[i] && -o.positions[i][2] < best.0 {
                    best = (-o.positions[i][2], Some(j));
                }
            }
            if let (_, Some(j)) = best {
                seen[j][i] = objects[j].normals.normals[i];
                normals.normals[i] = [0.0; 3];
                mask[i] = false;
            }
        }
        let mut params = self.params;
        let records = params["objects"].as_array_mut();
        for (r, n) in records.into_iter().flatten().zip(&seen) {
            r["pixels"] = json!(n.iter().filter(|v| **v != [0.0; 3]).count());
        }
        let mut shades = shades.into_iter();
        let (w, h) = (normals.width, normals.height);
        let layers = (seen.into_iter().zip(self.materials))
            .map(|(n, material)| {
                Ok(ClutterLayer {
                    normals: NormalMap::new(w, h, n)?,
                    material,
                    shade: shades.next(),
                })
            })
            .collect::<Result<_>>()?;
        Ok((layers, params))
    }
}

/// Renders `layers` under `env` through `camera` with `renderer` and writes each where it
/// is seen into `background` (times its shade).
pub fn paint(
    layers: &[ClutterLayer],
    env: &EnvMap,
    camera: Camera,
    background: &mut [[f32; 3]],
    renderer: &Renderer,
) -> Result<()> {
    if layers.is_empty() {
        return Ok(());
    }
    let scenes = (layers.iter())
        .map(|l| Scene {
            normals: l.normals.clone(),
            env: env.clone(),
            material: l.material.clone(),
            camera,
        })
        .collect();
    let renders = renderer.render(&Batch::new(scenes)?)?;
    for (l, r) in layers.iter().zip(renders) {
        for (i, n) in l.normals.normals.iter().enumerate() {
            if *n != [0.0; 3] {
                let s = l.shade.as_ref().map_or(1.0, |s| s[i]);
                background[i] = r.pixels[i].map(|v| v * s);
            }
        }
    }
    Ok(())
}
