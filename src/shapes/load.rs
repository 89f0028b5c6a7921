//! Mesh files, known by their extension: OBJ (tobj), PLY (ply-rs-bw, ASCII or binary),
//! STL (stl_io, ASCII or binary), OFF (parsed here) and, with the `gltf` feature, glTF
//! 2.0 (`.gltf` with its buffers, `.glb`). Polygons are split into triangle fans. Every
//! error is one line that names the file and the element: `bunny.obj: line 57: face 12:
//! vertex index 900 out of range (812 vertices)`. Faces and vertices count from 0, lines
//! from 1; indices are as the file writes them (OBJ's from 1).

use std::collections::HashMap;
use std::io::Cursor;
use std::path::Path;

use super::mesh::{Mesh, fan};
use crate::error::{Error, Result};

/// The extensions [`load_mesh`] reads.
pub const EXTENSIONS: [&str; 6] = ["obj", "ply", "stl", "off", "gltf", "glb"];

/// Loads a triangle mesh from an OBJ, PLY, STL, OFF, glTF or GLB file (by extension),
/// checked as [`Mesh::validate`] says.
pub fn load_mesh(path: &Path) -> Result<Mesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !EXTENSIONS.contains(&ext.as_str()) {
        return Err(Error::file(
            path,
            "a mesh must be a .obj, .ply, .stl, .off, .gltf or .glb file (known by its extension)",
        ));
    }
    let bytes = crate::io::read_bytes(path)?;
    mesh_from_bytes(path, &ext, &bytes)
}

/// [`load_mesh`] on a file's bytes; `ext` (lower case, no dot) says the format and `path`
/// names the file in errors (and, for glTF, where its buffer files are).
pub fn mesh_from_bytes(path: &Path, ext: &str, bytes: &[u8]) -> Result<Mesh> {
    let mesh = match ext {
        "obj" => obj(bytes),
        "ply" => super::ply::read(bytes),
        "stl" => stl(bytes),
        "off" => off(bytes),
        _ => gltf(path, bytes),
    }
    .map_err(|m| Error::file(path, m))?;
    mesh.validate().map_err(|m| Error::file(path, m))?;
    Ok(mesh)
}

#[cfg(feature = "gltf")]
fn gltf(path: &Path, bytes: &[u8]) -> std::result::Result<Mesh, String> {
    super::gltf::read(path, bytes)
}

#[cfg(not(feature = "gltf"))]
fn gltf(_: &Path, _: &[u8]) -> std::result::Result<Mesh, String> {
    Err("glTF meshes need matedit built with `--features gltf`".into())
}

fn one_line(s: impl ToString) -> String {
    s.to_string()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

fn obj(bytes: &[u8]) -> std::result::Result<Mesh, String> {
    let options = tobj::LoadOptions {
        single_index: true,
        triangulate: true,
        ignore_points: true,
        ignore_lines: true,
    };
    // materials do not matter here: no .mtl file is read
    let (models, _) = tobj::load_obj_buf(&mut Cursor::new(bytes), &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| obj_problem(bytes).unwrap_or_else(|| format!("not a readable OBJ file: {e}")))?;
    let mut mesh = Mesh::default();
    for model in &models {
        let m = &model.mesh;
        let positions: Vec<[f32; 3]> = m
            .positions
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let normals = (m.normals.len() == m.positions.len()).then(|| {
            m.normals
                .chunks_exact(3)
                .map(|c| [c[0], c[1], c[2]])
                .collect()
        });
        let triangles = m
            .indices
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        mesh.append(&Mesh {
            positions,
            normals,
            triangles,
        });
    }
    Ok(mesh)
}

/// What tobj refused, found again line by line so that the message can say where: a
/// number that does not parse, or a face's vertex index out of range.
fn obj_problem(bytes: &[u8]) -> Option<String> {
    let text = String::from_utf8_lossy(bytes);
    let total = text
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count();
    let (mut seen, mut faces) = (0usize, 0usize);
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let at = format!("line {}", n + 1);
        match words.next() {
            Some(key @ ("v" | "vn" | "vt")) => {
                let what = match key {
                    "v" => format!("vertex {seen}"),
                    "vn" => "normal".to_string(),
                    _ => "texture coordinate".to_string(),
                };
                for w in words.by_ref().take(if key == "vt" { 2 } else { 3 }) {
                    if w.parse::<f32>().is_err() {
                        return Some(format!("{at}: {what}: '{w}' is not a number"));
                    }
                }
                seen += usize::from(key == "v");
            }
            Some("f") => {
                for w in words {
                    let first = w.split('/').next().unwrap_or("");
                    let Ok(i) = first.parse::<i64>() else {
                        return Some(format!("{at}: face {faces}: '{w}' is not a vertex index"));
                    };
                    // negative indices count back from the vertices read so far
                    let resolved = if i < 0 { seen as i64 + i } else { i - 1 };
                    if i == 0 || resolved < 0 || resolved >= total as i64 {
                        return Some(format!(
                            "{at}: face {faces}: vertex index {i} out of range ({total} vertices)"
                        ));
                    }
                }
                faces += 1;
            }
            _ => {}
        }
    }
    None
}

fn stl(bytes: &[u8]) -> std::result::Result<Mesh, String> {
    let mut cursor = Cursor::new(bytes);
    let reader = stl_io::create_stl_reader(&mut cursor)
        .map_err(|e| format!("not a readable STL file: {}", one_line(e)))?;
    // corners with the same bits are one vertex, so that smooth normals can be averaged
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut mesh = Mesh::default();
    for (f, t) in reader.enumerate() {
        let t = t.map_err(|e| format!("face {f}: cannot read: {}", one_line(e)))?;
        let tri = t.vertices.map(|v| {
            let next = mesh.positions.len() as u32;
            *index.entry(v.0.map(f32::to_bits)).or_insert_with(|| {
                mesh.positions.push(v.0);
                next
            })
        });
        mesh.triangles.push(tri);
    }
    Ok(mesh)
}

/// OFF: an optional `OFF` (or `COFF`, `NOFF`, `CNOFF`) line, then "vertices faces edges",
/// a line per vertex (x y z, then a normal for N, colours ignored) and a line per face
/// (k, then k vertex indices, colours ignored). `#` starts a comment.
fn off(bytes: &[u8]) -> std::result::Result<Mesh, String> {
    let text = std::str::from_utf8(bytes)
        .map_err(|_| "not a text OFF file (binary OFF is not read)".to_string())?;
    let mut lines = text
        .lines()
        .enumerate()
        .map(|(n, l)| (n + 1, l.split('#').next().unwrap_or("").trim()))
        .filter(|(_, l)| !l.is_empty());
    let (mut n, mut line) = lines.next().ok_or("the file is empty")?;
    let mut normals = false;
    let first = line.split_whitespace().next().unwrap_or("");
    if let Some(flags) = first.strip_suffix("OFF") {
        if !flags.chars().all(|c| "CN".contains(c)) {
            return Err(format!(
                "line {n}: '{first}' is not a header this reader knows (OFF, COFF, NOFF, CNOFF)"
            ));
        }
        normals = flags.contains('N');
        line = line[first.len()..].trim();
        if line.is_empty() {
            (n, line) = lines.next().ok_or("the file ends after its header")?;
        }
    }
    let counts: Vec<usize> = line
        .split_whitespace()
        .take(2)
        .map(|w| w.parse::<usize>())
        .collect::<std::result::Result<_, _>>()
        .map_err(|_| format!("line {n}: '{line}' is not 'vertices faces edges'"))?;
    let [nv, nf] = counts[..] else {
        return Err(format!("line {n}: '{line}' is not 'vertices faces edges'"));
    };
    let mut mesh = Mesh::default();
    let mut vertex_normals = Vec::new();
    for v in 0..nv {
        let (n, line) = lines
            .next()
            .ok_or_else(|| format!("the header says {nv} vertices; the file ends after {v}"))?;
        let count = if normals { 6 } else { 3 };
        let at = format!("line {n}: vertex {v}");
        let vals: Vec<f64> = numbers(&at, line.split_whitespace(), count, "numbers")?;
        mesh.positions
            .push([vals[0], vals[1], vals[2]].map(|c| c as f32));
        if normals {
            vertex_normals.push([vals[3], vals[4], vals[5]].map(|c| c as f32));
        }
    }
    for f in 0..nf {
        let (n, line) = lines
            .next()
            .ok_or_else(|| format!("the header says {nf} faces; the file ends after {f}"))?;
        let mut words = line.split_whitespace();
        let k: usize = words.next().and_then(|w| w.parse().ok()).ok_or_else(|| {
            format!("line {n}: face {f}: '{line}' does not start with a vertex count")
        })?;
        let at = format!("line {n}: face {f}");
        let indices: Vec<i64> = numbers(&at, words, k, "vertex indices")?;
        fan(f, &indices, nv, &mut mesh.triangles).map_err(|m| format!("line {n}: {m}"))?;
    }
    mesh.normals = normals.then_some(vertex_normals);
    Ok(mesh)
}

/// The first `count` words as numbers; `at` and `noun` name them in errors.
fn numbers<'a, T: std::str::FromStr>(
    at: &str,
    words: impl Iterator<Item = &'a str>,
    count: usize,
    noun: &str,
) -> std::result::Result<Vec<T>, String> {
    let values: Vec<T> = words
        .take(count)
        .map(|w| {
            w.parse::<T>()
                .map_err(|_| format!("{at}: '{w}' is not a number"))
        })
        .collect::<std::result::Result<_, _>>()?;
    if values.len() < count {
        return Err(format!(
            "{at}: {count} {noun} needed, {} given",
            values.len()
        ));
    }
    Ok(values)
}
