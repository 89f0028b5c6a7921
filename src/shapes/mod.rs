//! Shapes for the layer: triangle meshes (from files, or generated from a seeded
//! [`Shape`]) rasterised to per-pixel camera-space normals and a mask.
//!
//! ```
//! use matedit::shapes::{self, Shape, View};
//! let mesh = "torus:seed=3".parse::<Shape>()?.mesh(0);
//! let (normals, mask) = shapes::render_normals(&mesh, &View::new(64, 64))?;
//! assert_eq!(normals.normals.len(), mask.len());
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```
//!
//! The image is the layer's frame (x right, y up, z towards the viewer, row 0 at the
//! top). The object is rotated about the centre of its bounding box ([`Rotation`]), then
//! centred and scaled (orthographic) or moved in front of the pinhole (perspective) so that
//! it fills the frame but for a margin ([`View`]). Background pixels get the normal
//! [0, 0, 0] and mask `false`; every foreground normal has unit length and faces the
//! viewer (n . w_p >= 0; n.z >= 0 when orthographic). docs/shapes.md has the commands,
//! the formats and the shapes.
//!
//! Files: [`mesh`] (the mesh type, its checks and vertex normals); [`view`](mod@view)
//! (camera, rotation, placement); `raster.rs` (the z-buffer); [`load`] (mesh files: OBJ,
//! PLY, STL, OFF, glTF with the `gltf` feature) with `ply.rs` and `gltf.rs`; [`procedural`] (the shapes) on
//! [`tessellate`] (the surfaces they are made of).

pub mod load;
pub mod mesh;
pub mod procedural;
mod raster;
pub mod tessellate;
mod vessel;
pub mod view;

#[cfg(feature = "gltf")]
mod gltf;
mod ply;

use rayon::prelude::*;

use crate::error::Result;
use crate::normals::loader_stable_unit;
use crate::scene::NormalMap;

pub use load::load_mesh;
pub use mesh::{Mesh, check_crease};
pub use procedural::{Shape, ShapeKind};
pub use view::{DEFAULT_MARGIN, Rotation, View};

/// `mesh` as `view`'s camera sees it: positions rotated and fitted to the frame (camera
/// space: x right, y up, z towards the viewer; the pinhole at the origin), normals rotated
/// and normalised (the mesh's own, or area-weighted ones). What [`render_normals`] draws.
pub fn camera_space(mesh: &Mesh, view: &View) -> Result<Mesh> {
    mesh.validate().map_err(crate::error::Error::Invalid)?;
    view.validate()?;
    let placed = view::place(mesh, view)?;
    let f32s = |v: &[f64; 3]| v.map(|c| c as f32);
    Ok(Mesh {
        positions: placed.positions.iter().map(f32s).collect(),
        normals: Some(placed.normals.iter().map(f32s).collect()),
        triangles: mesh.triangles.clone(),
    })
}

/// What [`render_geometry`] draws: the normals and mask of [`render_normals`], each
/// covered pixel's camera-space point, and the placed mesh ([`camera_space`]).
#[derive(Clone, Debug)]
pub struct Geometry {
    /// The normals, as [`render_normals`] gives them.
    pub normals: NormalMap,
    /// The pixels the mesh covers.
    pub mask: Vec<bool>,
    /// The camera-space point seen at each pixel ([0, 0, 0] where the mask is unset).
    pub positions: Vec<[f64; 3]>,
    /// The mesh in camera space.
    pub placed: Mesh,
}

/// [`render_normals`] with each pixel's camera-space point and the placed mesh: what the
/// floors and shadows of `matedit synth` need. The normals and mask are the same bits.
pub fn render_geometry(mesh: &Mesh, view: &View) -> Result<Geometry> {
    mesh.validate().map_err(crate::error::Error::Invalid)?;
    view.validate()?;
    let placed = view::place(mesh, view)?;
    geometry(&mesh.triangles, &placed, view)
}

/// [`render_geometry`] of a mesh already in camera space (as [`camera_space`] gives one, or
/// placed by the caller): rasterised where it is, with its vertex normals (its own, or
/// area-weighted ones), through `view`'s camera and size; its rotation and margin are not
/// used. What `matedit synth` draws the other objects on a floor with.
pub fn render_in_camera_space(mesh: &Mesh, view: &View) -> Result<Geometry> {
    mesh.validate().map_err(crate::error::Error::Invalid)?;
    view.validate()?;
    let placed = view::Placed {
        positions: mesh.positions.iter().map(|&p| mesh::widen(p)).collect(),
        normals: (mesh.vertex_normals().iter())
            .map(|&n| mesh::unit(mesh::widen(n)).unwrap_or([0.0; 3]))
            .collect(),
    };
    geometry(&mesh.triangles, &placed, view)
}

/// The geometry of `triangles` over the `placed` vertices.
fn geometry(triangles: &[[u32; 3]], placed: &view::Placed, view: &View) -> Result<Geometry> {
    let ids = raster::visible(triangles, placed, view);
    let w = view.width;
    let (normals, positions): (Vec<[f32; 3]>, Vec<[f64; 3]>) = ids
        .par_iter()
        .enumerate()
        .map(|(i, &t)| {
            if t == u32::MAX {
                return ([0.0; 3], [0.0; 3]);
            }
            let tri = triangles[t as usize];
            let n = raster::normal_at(tri, placed, view, i % w, i / w)
                .map_or([0.0; 3], loader_stable_unit);
            let p = raster::position_at(tri, placed, view, i % w, i / w).unwrap_or([0.0; 3]);
            if n == [0.0; 3] {
                ([0.0; 3], [0.0; 3])
            } else {
                (n, p)
            }
        })
        .unzip();
    let mask = normals.iter().map(|n| *n != [0.0; 3]).collect();
    let f32s = |v: &[f64; 3]| v.map(|c| c as f32);
    let placed_mesh = Mesh {
        positions: placed.positions.iter().map(f32s).collect(),
        normals: Some(placed.normals.iter().map(f32s).collect()),
        triangles: triangles.to_vec(),
    };
    Ok(Geometry {
        normals: NormalMap::new(view.width, view.height, normals)?,
        mask,
        positions,
        placed: placed_mesh,
    })
}

/// The camera-space normals of `mesh` seen through `view`, and the mask of pixels it
/// covers (rows first). Smooth normals interpolate the vertex normals (the mesh's own, or
/// area-weighted ones where it has none) with perspective-correct weights and normalise
/// them; `view.flat` gives each triangle's face normal instead. Each normal is stored so
/// that the file loaders' normalisation gives it back bit for bit.
pub fn render_normals(mesh: &Mesh, view: &View) -> Result<(NormalMap, Vec<bool>)> {
    mesh.validate().map_err(crate::error::Error::Invalid)?;
    view.validate()?;
    let placed = view::place(mesh, view)?;
    let ids = raster::visible(&mesh.triangles, &placed, view);
    let w = view.width;
    let normals: Vec<[f32; 3]> = ids
        .par_iter()
        .enumerate()
        .map(|(i, &t)| {
            if t == u32::MAX {
                return [0.0; 3];
            }
            let tri = mesh.triangles[t as usize];
            raster::normal_at(tri, &placed, view, i % w, i / w).map_or([0.0; 3], loader_stable_unit)
        })
        .collect();
    let mask = normals.iter().map(|n| *n != [0.0; 3]).collect();
    let map = NormalMap::new(view.width, view.height, normals)?;
    Ok((map, mask))
}
