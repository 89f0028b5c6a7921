//! PLY meshes (ASCII, binary little- or big-endian) through ply-rs-bw: the `vertex`
//! element's x, y, z (and nx, ny, nz when all three are there), the `face` element's
//! `vertex_indices` (or `vertex_index`) lists, split into triangle fans.

use std::io::Cursor;

use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{DefaultElement, Property};

use super::mesh::{Mesh, fan};

/// A scalar property as f64, or `None` for a list.
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v.into(),
        Property::UChar(v) => v.into(),
        Property::Short(v) => v.into(),
        Property::UShort(v) => v.into(),
        Property::Int(v) => v.into(),
        Property::UInt(v) => v.into(),
        Property::Float(v) => v.into(),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// A list property's values as i64 (integer lists only).
fn index_list(p: &Property) -> Option<Vec<i64>> {
    fn all<T: Copy + Into<i64>>(v: &[T]) -> Vec<i64> {
        v.iter().map(|&x| x.into()).collect()
    }
    Some(match p {
        Property::ListChar(v) => all(v),
        Property::ListUChar(v) => all(v),
        Property::ListShort(v) => all(v),
        Property::ListUShort(v) => all(v),
        Property::ListInt(v) => all(v),
        Property::ListUInt(v) => all(v),
        _ => return None,
    })
}

/// Reads a PLY mesh from a file's bytes.
pub(crate) fn read(bytes: &[u8]) -> Result<Mesh, String> {
    let ply = Parser::<DefaultElement>::new()
        .read_ply(&mut Cursor::new(bytes))
        .map_err(|e| {
            let msg = e.to_string();
            format!(
                "not a readable PLY file: {}",
                msg.split_whitespace().collect::<Vec<_>>().join(" ")
            )
        })?;
    let vertices = ply
        .payload
        .get("vertex")
        .ok_or("the file has no 'vertex' element")?;
    let faces = ply
        .payload
        .get("face")
        .ok_or("the file has no 'face' element")?;
    let mut mesh = Mesh::default();
    let has_normals = vertices
        .first()
        .is_some_and(|v| ["nx", "ny", "nz"].iter().all(|k| v.contains_key(*k)));
    let mut normals = Vec::new();
    let coords = |v: &DefaultElement, i: usize, keys: [&str; 3]| {
        let mut out = [0.0f32; 3];
        for (k, key) in keys.iter().enumerate() {
            let p = v
                .get(*key)
                .ok_or_else(|| format!("vertex {i}: no property '{key}'"))?;
            out[k] = scalar(p).ok_or_else(|| format!("vertex {i}: '{key}' is a list"))? as f32;
        }
        Ok::<_, String>(out)
    };
    for (i, v) in vertices.iter().enumerate() {
        mesh.positions.push(coords(v, i, ["x", "y", "z"])?);
        if has_normals {
            normals.push(coords(v, i, ["nx", "ny", "nz"])?);
        }
    }
    for (f, face) in faces.iter().enumerate() {
        let list = face
            .get("vertex_indices")
            .or_else(|| face.get("vertex_index"))
            .ok_or_else(|| format!("face {f}: no property 'vertex_indices'"))?;
        let indices = index_list(list)
            .ok_or_else(|| format!("face {f}: 'vertex_indices' is not a list of integers"))?;
        fan(f, &indices, mesh.positions.len(), &mut mesh.triangles)?;
    }
    mesh.normals = has_normals.then_some(normals);
    Ok(mesh)
}
