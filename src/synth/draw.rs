//! The pure function from (spec, sample index) to a sample: every draw from the sample's
//! own generator, so that sample k depends on the spec, its seed and k alone.

use serde_json::{Value, json};

use super::augment::Views;
use super::camera_effects::EffectDraws;
use super::clutter::{Clutter, ClutterLayer};
use super::draws::{draw_material, merge, pick};
use super::floor::FloorSource;
use super::sources::SampleNormals;
use super::spec::Spec;
use super::world::{SampleView, World};
use crate::camera::Camera;
use crate::error::{Error, Result};
use crate::material::Material;
use crate::scene::{NormalMap, Scene};
use crate::shapes::Geometry;
use crate::splitmix::SplitMix;

/// Mixed into a sample's generator for its camera effects' draws.
const CAMERA_EFFECTS_STREAM: u64 = 0x63616d_6572615f;
/// Mixed into a sample's generator for its edit material's draws.
const EDIT_STREAM: u64 = 0x65646974_5f6d6174;

/// A sample's edit: the second material and what made it.
#[derive(Clone, Debug)]
pub struct EditDraw {
    /// The material the edit renders the object in.
    pub material: Material,
    /// What the sample's params record: the item and its draws.
    pub record: Value,
}

/// A sample's inputs and the parameters that made it.
#[derive(Clone, Debug)]
pub struct Sample {
    /// Its index in the dataset.
    pub index: u64,
    /// What is rendered.
    pub scene: Scene,
    /// Where the object is: the pixels whose normal is not the background's zero.
    pub mask: Vec<bool>,
    /// What is seen elsewhere (`None`: black).
    pub background: Option<Vec<[f32; 3]>>,
    /// A factor on the object's rendered pixels: its visibility, where shadows are on.
    pub shade: Option<Vec<f32>>,
    /// The floor's visibility at each pixel (1 off the floor), where shadows are on.
    pub floor_visibility: Option<Vec<f32>>,
    /// The other objects on the floor, where the spec has clutter: rendered into the
    /// background by [`Sample::paint_clutter`].
    pub clutter: Vec<ClutterLayer>,
    /// The draws: sources, rotation, mixing weights, seed and index (JSON).
    pub params: Value,
    /// The camera effects' draws, if the spec asks for them.
    pub camera_effects: Option<super::camera_effects::EffectDraws>,
    /// The edit's material, if the spec asks for one.
    pub edit: Option<EditDraw>,
}

impl SplitMix {
    /// The generator of sample `k` under `seed`: independent of every other sample's.
    pub fn for_sample(seed: u64, k: u64) -> Self {
        let a = SplitMix(seed).next_u64();
        let b = SplitMix(k ^ 0x5851_f42d_4c95_7f2d).next_u64();
        SplitMix(a ^ b.rotate_left(17))
    }
}

impl Spec {
    /// Sample `k`'s scene and the parameters that made it: a pure function of the spec,
    /// its seed and `k`.
    pub fn sample(&self, k: u64) -> Result<Sample> {
        if k >= self.count {
            return Err(Error::Invalid(format!(
                "sample {k}: the spec has {} samples",
                self.count
            )));
        }
        let mut rng = SplitMix::for_sample(self.seed, k);
        let (w, h) = self.image_size;
        // the photo-like options draw from a stream of their own: without them, a spec
        // draws what it always drew
        let mut wrng = World::rng(self.seed, k);
        let sv = self.world.draw_view(self.camera, &mut wrng);
        let mut geometry = None;

        let ni = pick(&mut rng, &self.normals);
        let (mut normals, nparams) = match &self.normals[ni].source {
            SampleNormals::Sphere(m) => (m.clone(), json!({ "sphere": w })),
            SampleNormals::Bumpy => {
                let seed = rng.next_u64();
                (
                    NormalMap::bumpy(w, h, seed),
                    json!({ "bumpy": [h, w], "bumpy_seed": seed }),
                )
            }
            SampleNormals::Shape(shape, views) => {
                let seed = rng.next_u64();
                let (m, rotation, g) = self.draw_mesh(&shape.mesh(seed), views, &mut rng, sv)?;
                geometry = g;
                let p = json!({
                    "shape": shape.to_string(),
                    "shape_seed": seed,
                    "rotation": [rotation.yaw, rotation.pitch, rotation.roll],
                });
                (m, p)
            }
            SampleNormals::Meshes(meshes, views) => {
                let (label, mesh) = &meshes[rng.below(meshes.len())];
                let (m, rotation, g) = self.draw_mesh(mesh, views, &mut rng, sv)?;
                geometry = g;
                let p = json!({
                    "mesh": label,
                    "rotation": [rotation.yaw, rotation.pitch, rotation.roll],
                });
                (m, p)
            }
            SampleNormals::Files(maps) => {
                let (label, m) = &maps[rng.below(maps.len())];
                (m.clone(), json!({ "file": label }))
            }
        };

        let ei = pick(&mut rng, &self.envs);
        let src = &self.envs[ei].source;
        let (env, mut eparams) = match src.procedural {
            Some(kind) => {
                let seed = rng.next_u64();
                let drawn = crate::envgen::Params::draw(kind, seed);
                let (eh, ew) = self.env_size;
                let p =
                    json!({ "procedural": kind.name(), "seed": seed, "params": drawn.to_string() });
                (drawn.env(eh, ew)?, p)
            }
            None => {
                let (label, map) = &src.maps[rng.below(src.maps.len())];
                (map.clone(), json!({ "file": label }))
            }
        };
        let (env, changes) = src.augment.apply(env, &mut rng)?;
        merge(&mut eparams, changes);
        let env = if sv.elevation != 0.0 {
            super::world::tilt(&env, sv.elevation)?
        } else {
            env
        };

        let (mi, material, mparams) = draw_material(&mut rng, &self.materials)?;

        let mut mask: Vec<bool> = normals.normals.iter().map(|n| *n != [0.0f32; 3]).collect();
        let bi = pick(&mut rng, &self.backgrounds);
        let (background, bparams) =
            self.backgrounds[bi]
                .source
                .draw(&env, sv.camera, self.image_size, &mut rng);
        let (mut clutter, mut cparams) = (Vec::new(), None);
        let (background, shade, floor_visibility, fparams) = match (&self.world.floors, &geometry) {
            (Some(floors), Some(g)) => {
                let fi = pick(&mut wrng, floors);
                // clutter stands on a floor: none where the sample draws no floor
                let others = match (&self.clutter, &floors[fi].source) {
                    (Some(c), FloorSource::Procedural(_) | FloorSource::Images(_)) => {
                        let mut crng = Clutter::rng(self.seed, k);
                        Some(c.draw(g, sv, self.image_size, &mut crng)?)
                    }
                    _ => None,
                };
                let scene = super::floor::FloorScene {
                    geometry: g,
                    env: &env,
                    camera: sv.camera,
                    elevation: sv.elevation,
                    size: self.image_size,
                    shadows: self.world.shadows,
                    others: others.as_ref().map_or(&[], |c| c.geometries.as_slice()),
                };
                let d = floors[fi].source.draw(&scene, background, &mut wrng);
                if let Some(c) = others {
                    let (layers, p) = c.resolve(g, &mut normals, &mut mask, d.others_shade)?;
                    (clutter, cparams) = (layers, Some(p));
                }
                let p = json!({ "item": fi, "floor": d.params });
                (d.background, d.shade, d.floor_visibility, Some(p))
            }
            _ => (background, None, None, None),
        };
        let mut params = json!({
            "index": k,
            "seed": self.seed,
            "normals": nparams,
            "normals_item": ni,
            "env": eparams,
            "env_item": ei,
            "material": mparams,
            "material_item": mi,
            "background": bparams,
            "background_item": bi,
            "image_size": [h, w],
            "env_size": [self.env_size.0, self.env_size.1],
            "convention": self.convention.name(),
            "fov": match sv.camera {
                Camera::Perspective { fov_y_deg } => json!(fov_y_deg),
                Camera::Orthographic => Value::Null,
            },
        });
        // from generators of their own: a spec without these keys draws what it did
        let (camera_effects, edit) = self.draw_extras(k, &mut params)?;
        if self.world.elevation.is_some() {
            params["elevation"] = json!(sv.elevation);
        }
        if let Some(mut p) = fparams {
            p["margin"] = json!(sv.margin);
            params["floor"] = p;
        }
        if self.clutter.is_some() {
            params["clutter"] = cparams.unwrap_or_else(|| json!({ "drawn": 0, "objects": [] }));
        }
        Ok(Sample {
            index: k,
            mask,
            background,
            camera_effects,
            edit,
            shade,
            floor_visibility,
            clutter,
            scene: Scene {
                normals,
                env,
                material,
                camera: sv.camera,
            },
            params,
        })
    }
}

impl Spec {
    /// `mesh`'s normals at the image size under the sample's camera, turned by a
    /// rotation of `views` drawn from `rng` and pitched by the sample's elevation; with a
    /// floor, its geometry too.
    fn draw_mesh(
        &self,
        mesh: &crate::shapes::Mesh,
        views: &Views,
        rng: &mut SplitMix,
        sv: SampleView,
    ) -> Result<(NormalMap, crate::shapes::Rotation, Option<Geometry>)> {
        let rotation = views.draw(rng);
        let (w, h) = self.image_size;
        let view = crate::shapes::View {
            camera: sv.camera,
            rotation: super::world::pitched(rotation, sv.elevation),
            margin: sv.margin,
            ..crate::shapes::View::new(w, h)
        };
        if self.world.floors.is_some() {
            let g = crate::shapes::render_geometry(mesh, &view)?;
            return Ok((g.normals.clone(), rotation, Some(g)));
        }
        Ok((
            crate::shapes::render_normals(mesh, &view)?.0,
            rotation,
            None,
        ))
    }
}

impl Sample {
    /// The sample's image from the layer's render of its scene: the render where the mask
    /// is set, the background elsewhere (the render itself when the background is black).
    pub fn compose(&self, mut render: crate::scene::Image) -> crate::scene::Image {
        if let Some(shade) = &self.shade {
            for ((p, s), m) in render.pixels.iter_mut().zip(shade).zip(&self.mask) {
                if *m {
                    *p = p.map(|v| v * s);
                }
            }
        }
        if let Some(bg) = &self.background {
            for ((p, b), m) in render.pixels.iter_mut().zip(bg).zip(&self.mask) {
                if !m {
                    *p = *b;
                }
            }
        }
        render
    }
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
    ) -> Result<(Option<EffectDraws>, Option<EditDraw>)> {
        let effects = self
            .camera_effects
            .as_ref()
            .map(|fx| fx.draw(&mut stream(self.seed, k, CAMERA_EFFECTS_STREAM)));
        let edit = match &self.edit {
            None => None,
            Some(items) => {
                let mut rng = stream(self.seed, k, EDIT_STREAM);
                let (item, material, record) = draw_material(&mut rng, items)?;
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
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn draws_are_per_sample() {
        let a: Vec<u64> = (0..4)
            .map(|k| SplitMix::for_sample(7, k).next_u64())
            .collect();
        let b: Vec<u64> = (0..4)
            .map(|k| SplitMix::for_sample(7, k).next_u64())
            .collect();
        assert_eq!(a, b);
        assert_ne!(a[0], a[1]);
        assert_ne!(
            SplitMix::for_sample(7, 0).next_u64(),
            SplitMix::for_sample(8, 0).next_u64()
        );
        let mut r = SplitMix(1);
        assert!((0..1000).all(|_| r.below(5) < 5));
    }
}
