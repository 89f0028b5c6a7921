//! Mesh files (`matedit::shapes::load_mesh`): the test writes one small mesh in every
//! format (OBJ, ASCII and binary PLY, ASCII and binary STL, OFF; with the `gltf` feature
//! glTF with a buffer file and with a data URI, GLB) and requires the same pixels; normals
//! in files are used; bad files give one-line errors naming the file and the element.

use std::path::Path;

use matedit::shapes::{self, Mesh, Rotation, View, tessellate};

fn norm(a: [f64; 3]) -> [f64; 3] {
    let l = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    a.map(|c| c / l)
}

/// A small lumpy closed mesh (170 triangles), without normals.
fn small_mesh() -> Mesh {
    let mut m = tessellate::sphere_grid(8, 12, |t, p| {
        let r = 1.0 + 0.2 * (3.0 * p).sin() * t.sin();
        tessellate::direction(t, p).map(|c| c * r)
    });
    m.normals = None;
    m
}

fn obj_text(m: &Mesh, normals: bool) -> String {
    let mut s = String::from("# a small test mesh\n");
    for p in &m.positions {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    if normals {
        for n in m.normals.as_ref().unwrap() {
            s += &format!("vn {} {} {}\n", n[0], n[1], n[2]);
        }
    }
    for t in &m.triangles {
        let [a, b, c] = t.map(|v| v + 1);
        s += &if normals {
            format!("f {a}//{a} {b}//{b} {c}//{c}\n")
        } else {
            format!("f {a} {b} {c}\n")
        };
    }
    s
}

/// "x y z" lines, then "3 a b c" lines: the body of ASCII PLY and OFF files.
fn vertex_and_face_lines(m: &Mesh) -> String {
    let mut s = String::new();
    for p in &m.positions {
        s += &format!("{} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &m.triangles {
        s += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    s
}

fn ply_ascii(m: &Mesh) -> String {
    let mut s = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    );
    s += &vertex_and_face_lines(m);
    s
}

fn ply_binary(m: &Mesh) -> Vec<u8> {
    let mut b = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\nproperty float y\n\
         property float z\nelement face {}\nproperty list uchar uint vertex_indices\nend_header\n",
        m.positions.len(),
        m.triangles.len()
    )
    .into_bytes();
    for p in &m.positions {
        p.iter().for_each(|c| b.extend_from_slice(&c.to_le_bytes()));
    }
    for t in &m.triangles {
        b.push(3);
        t.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    b
}

fn stl_binary(m: &Mesh) -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&(m.triangles.len() as u32).to_le_bytes());
    for t in &m.triangles {
        b.extend_from_slice(&[0u8; 12]);
        for &v in t {
            m.positions[v as usize]
                .iter()
                .for_each(|c| b.extend_from_slice(&c.to_le_bytes()));
        }
        b.extend_from_slice(&[0, 0]);
    }
    b
}

fn stl_ascii(m: &Mesh) -> String {
    let mut s = String::from("solid test\n");
    for t in &m.triangles {
        s += "facet normal 0 0 0\nouter loop\n";
        for &v in t {
            let p = m.positions[v as usize];
            s += &format!("vertex {} {} {}\n", p[0], p[1], p[2]);
        }
        s += "endloop\nendfacet\n";
    }
    s + "endsolid test\n"
}

fn off_text(m: &Mesh) -> String {
    let mut s = format!(
        "OFF\n# comment\n{} {} 0\n",
        m.positions.len(),
        m.triangles.len()
    );
    s += &vertex_and_face_lines(m);
    s
}

fn base64(bytes: &[u8]) -> String {
    const A: &[u8; 64] = b"ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    let mut s = String::new();
    for c in bytes.chunks(3) {
        let n = (c[0] as u32) << 16
            | (*c.get(1).unwrap_or(&0) as u32) << 8
            | *c.get(2).unwrap_or(&0) as u32;
        for k in 0..4 {
            s.push(if k <= c.len() {
                A[(n >> (18 - 6 * k)) as usize & 63] as char
            } else {
                '='
            });
        }
    }
    s
}

/// glTF JSON for one triangle primitive whose buffer (positions, then u32 indices) is at
/// `uri` (None: the GLB's binary chunk).
fn gltf_json(m: &Mesh, uri: Option<&str>, len: usize) -> String {
    let (lo, hi) = m.bounds();
    let pos_len = m.positions.len() * 12;
    let uri = uri.map_or(String::new(), |u| format!("\"uri\": \"{u}\", "));
    format!(
        r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}], "nodes": [{{"mesh": 0}}],
 "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}, "indices": 1}}]}}],
 "buffers": [{{{uri}"byteLength": {len}}}],
 "bufferViews": [{{"buffer": 0, "byteOffset": 0, "byteLength": {pos_len}}}, {{"buffer": 0, "byteOffset": {pos_len}, "byteLength": {}}}],
 "accessors": [{{"bufferView": 0, "componentType": 5126, "count": {}, "type": "VEC3", "min": [{}, {}, {}], "max": [{}, {}, {}]}},
  {{"bufferView": 1, "componentType": 5125, "count": {}, "type": "SCALAR"}}]}}"#,
        m.triangles.len() * 12,
        m.positions.len(),
        lo[0] as f32,
        lo[1] as f32,
        lo[2] as f32,
        hi[0] as f32,
        hi[1] as f32,
        hi[2] as f32,
        m.triangles.len() * 3
    )
}

fn gltf_buffer(m: &Mesh) -> Vec<u8> {
    let mut b = Vec::new();
    for p in &m.positions {
        p.iter().for_each(|c| b.extend_from_slice(&c.to_le_bytes()));
    }
    for t in &m.triangles {
        t.iter().for_each(|v| b.extend_from_slice(&v.to_le_bytes()));
    }
    b
}

fn glb(m: &Mesh) -> Vec<u8> {
    let bin = gltf_buffer(m);
    let mut json = gltf_json(m, None, bin.len()).into_bytes();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut b = Vec::new();
    b.extend_from_slice(b"glTF");
    b.extend_from_slice(&2u32.to_le_bytes());
    b.extend_from_slice(&(total as u32).to_le_bytes());
    b.extend_from_slice(&(json.len() as u32).to_le_bytes());
    b.extend_from_slice(b"JSON");
    b.extend_from_slice(&json);
    b.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    b.extend_from_slice(b"BIN\0");
    b.extend_from_slice(&bin);
    b
}

/// `m` in every format, by file name; writes the glTF's buffer file `mesh.bin` into `dir`.
fn format_files(m: &Mesh, dir: &Path) -> Vec<(&'static str, Vec<u8>)> {
    let buffer = gltf_buffer(m);
    std::fs::write(dir.join("mesh.bin"), &buffer).unwrap();
    let data_uri = format!("data:application/octet-stream;base64,{}", base64(&buffer));
    let mut files = vec![
        ("mesh.obj", obj_text(m, false).into_bytes()),
        ("ascii.ply", ply_ascii(m).into_bytes()),
        ("binary.ply", ply_binary(m)),
        ("binary.stl", stl_binary(m)),
        ("ascii.stl", stl_ascii(m).into_bytes()),
        ("mesh.off", off_text(m).into_bytes()),
    ];
    let gltf = [
        (
            "file.gltf",
            gltf_json(m, Some("mesh.bin"), buffer.len()).into_bytes(),
        ),
        (
            "embedded.gltf",
            gltf_json(m, Some(&data_uri), buffer.len()).into_bytes(),
        ),
        ("mesh.glb", glb(m)),
    ];
    if cfg!(feature = "gltf") {
        files.extend(gltf);
    }
    files
}

#[test]
fn every_format_loads_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let m = small_mesh();
    let files = format_files(&m, dir.path());
    for flat in [false, true] {
        let view = View {
            flat,
            rotation: Rotation {
                yaw: 20.0,
                pitch: 30.0,
                roll: 0.0,
            },
            ..View::new(48, 40)
        };
        let want = shapes::render_normals(&m, &view).unwrap();
        for (name, bytes) in &files {
            let path = dir.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            let loaded = shapes::load_mesh(&path).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(loaded.triangles.len(), m.triangles.len(), "{name}");
            // the same positions and triangles give the same pixels, bit for bit
            let got = shapes::render_normals(&loaded, &view).unwrap();
            assert!(got == want, "{name} (flat: {flat}) renders differently");
        }
    }
}

#[test]
fn normals_in_files_are_used() {
    let dir = tempfile::tempdir().unwrap();
    let mut m = small_mesh();
    // normals that are not the area-weighted ones: pointing away from (-0.3, 0, 0)
    m.normals = Some(
        m.positions
            .iter()
            .map(|p| norm([p[0] as f64 + 0.3, p[1] as f64, p[2] as f64]).map(|c| c as f32))
            .collect(),
    );
    let path = dir.path().join("n.obj");
    std::fs::write(&path, obj_text(&m, true)).unwrap();
    let loaded = shapes::load_mesh(&path).unwrap();
    let view = View::new(32, 32);
    let want = shapes::render_normals(&m, &view).unwrap();
    assert!(shapes::render_normals(&loaded, &view).unwrap() == want);
    m.normals = None;
    assert!(shapes::render_normals(&m, &view).unwrap() != want);
}

/// `load_mesh`'s error for a file `name` holding `text`.
fn load_error(name: &str, text: &[u8]) -> String {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(name);
    std::fs::write(&path, text).unwrap();
    let e = shapes::load_mesh(&path).expect_err(name).to_string();
    assert!(!e.contains('\n'), "{name}: not one line: {e}");
    let shown = path.display().to_string();
    e.strip_prefix(&format!("{shown}: "))
        .unwrap_or_else(|| panic!("{name}: no file name: {e}"))
        .to_string()
}

#[test]
fn bad_files_give_one_line_errors() {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    assert_eq!(
        load_error("bunny.obj", format!("{tri}f 1 2 3\nf 1 2 900\n").as_bytes()),
        "line 5: face 1: vertex index 900 out of range (3 vertices)"
    );
    assert_eq!(
        load_error("bad.obj", format!("{tri}v 1 x 2\nf 1 2 3\n").as_bytes()),
        "line 4: vertex 3: 'x' is not a number"
    );
    assert_eq!(
        load_error("nan.obj", b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n"),
        "face 0: vertex 1: coordinate y is NaN"
    );
    assert_eq!(
        load_error("empty.obj", tri.as_bytes()),
        "the mesh has no triangles"
    );
    assert!(load_error("flat.obj", b"v 1 1 1\nv 1 1 1\nv 1 1 1\nf 1 2 3\n").contains("no extent"));
    assert_eq!(
        load_error("bad.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n"),
        "line 6: face 0: vertex index 7 out of range (3 vertices)"
    );
    assert_eq!(
        load_error("short.off", b"OFF\n3 1 0\n0 0 0\n1 0 0\n"),
        "the header says 3 vertices; the file ends after 2"
    );
    let ply = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0\n1 0 0\n0 1 0\n3 0 1 5\n";
    assert_eq!(
        load_error("bad.ply", ply.as_bytes()),
        "face 0: vertex index 5 out of range (3 vertices)"
    );
    assert!(load_error("garbage.ply", b"not a ply").starts_with("not a readable PLY file"));
    // a binary STL that promises 2 triangles and holds 1
    let mut stl = stl_binary(&small_mesh());
    stl.truncate(84 + 50);
    stl[80..84].copy_from_slice(&2u32.to_le_bytes());
    assert!(load_error("cut.stl", &stl).starts_with("face 1: cannot read"));
    let gltf = load_error("bad.gltf", b"{\"asset\": 3}");
    if cfg!(feature = "gltf") {
        assert!(gltf.starts_with("not a readable glTF file"), "{gltf}");
    } else {
        assert_eq!(
            gltf,
            "glTF meshes need matedit built with `--features gltf`"
        );
    }
    assert!(load_error("mesh.xyz", b"").contains(".obj, .ply, .stl, .off, .gltf or .glb"));
    let e = shapes::load_mesh(Path::new("/no/such/mesh.obj"))
        .unwrap_err()
        .to_string();
    assert_eq!(e, "/no/such/mesh.obj: no such file");
}

#[test]
fn corrupted_files_never_panic() {
    // every format's file, cut short at many lengths and with bytes overwritten at random:
    // each load returns a mesh or an error, and an error is one line naming the file
    let dir = tempfile::tempdir().unwrap();
    let files = format_files(&small_mesh(), dir.path());
    let mut rng = matedit::splitmix::SplitMix(11);
    for (name, bytes) in &files {
        let path = dir.path().join(name);
        for trial in 0..120 {
            let mut b = bytes.clone();
            if trial % 2 == 0 {
                b.truncate(rng.below(b.len()));
            } else {
                for _ in 0..1 + rng.below(4) {
                    let at = rng.below(b.len());
                    b[at] = rng.next_u64() as u8;
                }
            }
            std::fs::write(&path, &b).unwrap();
            if let Err(e) = shapes::load_mesh(&path) {
                let e = e.to_string();
                assert!(
                    !e.contains('\n') && e.starts_with(&path.display().to_string()),
                    "{name}: {e}"
                );
            }
        }
    }
}
