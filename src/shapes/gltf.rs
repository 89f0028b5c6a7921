//! glTF 2.0 meshes (`.gltf` JSON or `.glb` binary) through the gltf crate without its
//! importer: buffers come from the GLB's binary chunk, base64 `data:` URIs or files beside
//! the `.gltf`. Every triangle primitive of the default scene (else the first; else every
//! mesh) is taken with its nodes' transforms, positions and normals in the scene's frame.

use std::path::Path;

use glam::{Mat3, Mat4, Vec3};

use super::mesh::Mesh;

/// Nodes nested deeper than this are refused (a cycle in a malformed file).
const MAX_DEPTH: usize = 64;

/// Reads a glTF or GLB mesh from a file's bytes; `path` locates buffer files.
pub(crate) fn read(path: &Path, bytes: &[u8]) -> Result<Mesh, String> {
    let gltf = gltf::Gltf::from_slice(bytes)
        .map_err(|e| format!("not a readable glTF file: {}", flat(e)))?;
    let mut buffers = Vec::new();
    for buffer in gltf.buffers() {
        let i = buffer.index();
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => gltf
                .blob
                .clone()
                .ok_or_else(|| format!("buffer {i}: the file has no binary chunk"))?,
            gltf::buffer::Source::Uri(uri) => {
                buffer_uri(path, uri).map_err(|m| format!("buffer {i}: {m}"))?
            }
        };
        if data.len() < buffer.length() {
            return Err(format!(
                "buffer {i}: {} bytes, the file says {}",
                data.len(),
                buffer.length()
            ));
        }
        buffers.push(data);
    }
    let mut mesh = Mesh::default();
    let mut add = |m: gltf::Mesh, transform: Mat4| primitives(&m, transform, &buffers, &mut mesh);
    let scene = gltf.default_scene().or_else(|| gltf.scenes().next());
    match scene {
        Some(scene) => {
            for node in scene.nodes() {
                walk(node, Mat4::IDENTITY, 0, &mut add)?;
            }
        }
        None => {
            for m in gltf.meshes() {
                add(m, Mat4::IDENTITY)?;
            }
        }
    }
    Ok(mesh)
}

fn flat(e: impl ToString) -> String {
    e.to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

fn walk(
    node: gltf::Node,
    parent: Mat4,
    depth: usize,
    add: &mut impl FnMut(gltf::Mesh, Mat4) -> Result<(), String>,
) -> Result<(), String> {
    if depth > MAX_DEPTH {
        return Err(format!(
            "node {}: nodes nested more than {MAX_DEPTH} deep",
            node.index()
        ));
    }
    let transform = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
    if let Some(m) = node.mesh() {
        add(m, transform)?;
    }
    for child in node.children() {
        walk(child, transform, depth + 1, add)?;
    }
    Ok(())
}

/// Appends the triangle primitives of `m`, transformed, to `out`.
fn primitives(
    m: &gltf::Mesh,
    transform: Mat4,
    buffers: &[Vec<u8>],
    out: &mut Mesh,
) -> Result<(), String> {
    let normal_matrix = Mat3::from_mat4(transform).inverse().transpose();
    for p in m.primitives() {
        let at = format!("mesh {} primitive {}", m.index(), p.index());
        if p.mode() != gltf::mesh::Mode::Triangles {
            continue;
        }
        let reader = p.reader(|b| buffers.get(b.index()).map(Vec::as_slice));
        let positions: Vec<[f32; 3]> = reader
            .read_positions()
            .ok_or_else(|| format!("{at}: no readable POSITION accessor"))?
            .map(|v| transform.transform_point3(Vec3::from(v)).to_array())
            .collect();
        let normals = reader.read_normals().map(|ns| {
            ns.map(|n| (normal_matrix * Vec3::from(n)).to_array())
                .collect::<Vec<_>>()
        });
        let normals = normals.filter(|n| n.len() == positions.len());
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..positions.len() as u32).collect(),
        };
        if !indices.len().is_multiple_of(3) {
            return Err(format!(
                "{at}: {} indices, not a whole number of triangles",
                indices.len()
            ));
        }
        let n = positions.len();
        if let Some(bad) = indices.iter().position(|&i| i as usize >= n) {
            return Err(format!(
                "{at}: face {}: vertex index {} out of range ({n} vertices)",
                bad / 3,
                indices[bad]
            ));
        }
        let triangles = indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        out.append(&Mesh {
            positions,
            normals,
            triangles,
        });
    }
    Ok(())
}

/// A buffer's bytes from its URI: a base64 `data:` URI, or a file relative to the glTF.
fn buffer_uri(path: &Path, uri: &str) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (head, data) = rest.split_once(',').ok_or("a data: URI without a comma")?;
        if !head.ends_with(";base64") {
            return Err("a data: URI that is not base64".into());
        }
        return base64(data).ok_or_else(|| "a data: URI whose base64 does not decode".into());
    }
    if uri.contains("://") {
        return Err(format!("'{uri}' is not a local file"));
    }
    let file = path.parent().unwrap_or(Path::new(".")).join(uri);
    std::fs::read(&file).map_err(|e| format!("cannot read {}: {e}", file.display()))
}

/// Standard base64 (padding optional, no whitespace).
fn base64(s: &str) -> Option<Vec<u8>> {
    let value = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let s = s.trim_end_matches('=').as_bytes();
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    for chunk in s.chunks(4) {
        if chunk.len() == 1 {
            return None;
        }
        let mut acc = 0u32;
        for (k, &c) in chunk.iter().enumerate() {
            acc |= value(c)? << (18 - 6 * k);
        }
        out.extend_from_slice(&acc.to_be_bytes()[1..chunk.len()]);
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    #[test]
    fn base64_decodes() {
        assert_eq!(super::base64("TWFu").as_deref(), Some(&b"Man"[..]));
        assert_eq!(super::base64("TWE=").as_deref(), Some(&b"Ma"[..]));
        assert_eq!(super::base64("TQ==").as_deref(), Some(&b"M"[..]));
        assert_eq!(super::base64("T"), None);
        assert_eq!(super::base64("T!=="), None);
    }
}
