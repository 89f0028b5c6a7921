//! Shapes to normal maps (`matedit::shapes`): the rasteriser against an independent ray
//! caster and the analytic sphere, every mesh format on the same mesh, one-line errors for
//! bad files, and seeded shapes.

use std::path::Path;

use matedit::shapes::{self, Kind, Mesh, Rotation, Shape, View, tessellate};
use matedit::{Camera, NormalMap};

type V3 = [f64; 3];

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn dot(a: V3, b: V3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn cross(a: V3, b: V3) -> V3 {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
fn norm(a: V3) -> V3 {
    let l = dot(a, a).sqrt();
    [a[0] / l, a[1] / l, a[2] / l]
}

/// Möller-Trumbore: (t, u, v) of the ray's hit on triangle (a, b, c), if any.
fn intersect(o: V3, d: V3, a: V3, b: V3, c: V3) -> Option<(f64, f64, f64)> {
    let (e1, e2) = (sub(b, a), sub(c, a));
    let p = cross(d, e2);
    let det = dot(e1, p);
    if det.abs() < 1e-14 {
        return None;
    }
    let s = sub(o, a);
    let u = dot(s, p) / det;
    let q = cross(s, e1);
    let v = dot(d, q) / det;
    let t = dot(e2, q) / det;
    (u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0).then_some((t, u, v))
}

/// Casts a ray through every pixel centre against every triangle of the camera-space
/// mesh: the nearest hit's normal (vertex normals weighted by the hit's barycentric
/// coordinates, or the face normal when flat), turned to the viewer by the documented
/// rules. `None` where the ray misses.
fn ray_cast(cam: &Mesh, view: &View) -> Vec<Option<V3>> {
    let (w, h) = (view.width, view.height);
    let aspect = w as f64 / h as f64;
    let pos: Vec<V3> = cam.positions.iter().map(|p| p.map(f64::from)).collect();
    let nrm: Vec<V3> = cam
        .normals
        .as_ref()
        .unwrap()
        .iter()
        .map(|p| p.map(f64::from))
        .collect();
    let mut out = Vec::with_capacity(w * h);
    for py in 0..h {
        for px in 0..w {
            let wp = view.camera.view_dir(px, py, w, h);
            let (o, d) = match view.camera {
                Camera::Orthographic => {
                    let x = ((px as f64 + 0.5) / w as f64 * 2.0 - 1.0) * aspect;
                    let y = 1.0 - (py as f64 + 0.5) / h as f64 * 2.0;
                    ([x, y, 1e3], [0.0, 0.0, -1.0])
                }
                Camera::Perspective { .. } => ([0.0; 3], [-wp[0], -wp[1], -wp[2]]),
            };
            let mut best: Option<(f64, usize, f64, f64)> = None;
            for (t_i, tri) in cam.triangles.iter().enumerate() {
                let [a, b, c] = tri.map(|v| pos[v as usize]);
                if let Some((t, u, v)) = intersect(o, d, a, b, c)
                    && best.is_none_or(|bst| t < bst.0)
                {
                    best = Some((t, t_i, u, v));
                }
            }
            out.push(best.map(|(_, t_i, u, v)| {
                let tri = cam.triangles[t_i];
                let [a, b, c] = tri.map(|v| pos[v as usize]);
                let mut face = norm(cross(sub(b, a), sub(c, a)));
                if dot(face, wp) < 0.0 {
                    face = face.map(|x| -x);
                }
                if view.flat {
                    return face;
                }
                let wts = [1.0 - u - v, u, v];
                let mut n = [0.0; 3];
                for k in 0..3 {
                    for c in 0..3 {
                        n[c] += wts[k] * nrm[tri[k] as usize][c];
                    }
                }
                let mut n = norm(n);
                if dot(n, face) < 0.0 {
                    n = n.map(|x| -x);
                }
                let along = dot(n, wp);
                if along < 0.0 {
                    n = norm(sub(n, wp.map(|x| x * along)));
                }
                n
            }));
        }
    }
    out
}

/// Pixels whose 3 x 3 neighbourhood is all foreground in `mask`.
fn interior(mask: &[bool], w: usize, h: usize) -> Vec<usize> {
    let mut out = Vec::new();
    for y in 1..h.saturating_sub(1) {
        for x in 1..w.saturating_sub(1) {
            if (0..9).all(|k| mask[(y + k / 3 - 1) * w + x + k % 3 - 1]) {
                out.push(y * w + x);
            }
        }
    }
    out
}

fn angle_deg(a: [f32; 3], b: V3) -> f64 {
    let a = a.map(f64::from);
    (dot(a, b) / (dot(a, a) * dot(b, b)).sqrt())
        .clamp(-1.0, 1.0)
        .acos()
        .to_degrees()
}

/// The rasteriser's normals against the ray caster's at interior pixels: every angle
/// within 0.5 degrees (both interpolate the same vertex normals at the same point; only
/// f32 rounding of the camera-space mesh separates them). Returns the largest angle.
fn check_against_rays(mesh: &Mesh, view: &View, what: &str) -> f64 {
    let (map, mask) = shapes::render_normals(mesh, view).unwrap();
    let rays = ray_cast(&shapes::camera_space(mesh, view).unwrap(), view);
    let inside = interior(&mask, view.width, view.height);
    assert!(
        inside.len() > view.width * view.height / 10,
        "{what}: {} interior pixels",
        inside.len()
    );
    let mut worst = 0.0f64;
    for &i in &inside {
        let n = rays[i].unwrap_or_else(|| panic!("{what}: pixel {i}: the ray misses"));
        let a = angle_deg(map.normals[i], n);
        assert!(
            a < 0.5,
            "{what}: pixel ({}, {}): {:?} vs ray {n:?}: {a} degrees",
            i % view.width,
            i / view.width,
            map.normals[i]
        );
        worst = worst.max(a);
    }
    // and the masks agree wherever the ray caster is sure (away from the silhouette)
    for (i, r) in rays.iter().enumerate() {
        if r.is_none() {
            assert!(!inside.contains(&i), "{what}: pixel {i}");
        }
    }
    worst
}

fn views() -> Vec<(String, View)> {
    let mut out = Vec::new();
    for (cam_name, camera) in [
        ("orthographic", Camera::Orthographic),
        ("perspective 50", Camera::Perspective { fov_y_deg: 50.0 }),
    ] {
        for flat in [false, true] {
            let view = View {
                camera,
                flat,
                rotation: Rotation {
                    yaw: 30.0,
                    pitch: -20.0,
                    roll: 10.0,
                },
                ..View::new(40, 32)
            };
            out.push((
                format!("{cam_name}, {}", if flat { "flat" } else { "smooth" }),
                view,
            ));
        }
    }
    out
}

#[test]
fn normals_agree_with_a_ray_caster() {
    let sphere = Shape {
        kind: Kind::Sphere,
        seed: None,
    }
    .mesh(0);
    let cube = Shape {
        kind: Kind::Box,
        seed: None,
    }
    .mesh(4);
    let blob = Shape {
        kind: Kind::Blobby,
        seed: None,
    }
    .mesh(2);
    let torus = Shape {
        kind: Kind::Torus,
        seed: None,
    }
    .mesh(1);
    for (name, mesh) in [
        ("sphere", &sphere),
        ("box", &cube),
        ("blobby", &blob),
        ("torus", &torus),
    ] {
        for (v_name, view) in views() {
            let worst = check_against_rays(mesh, &view, &format!("{name}, {v_name}"));
            eprintln!("{name}, {v_name}: largest angle {worst:.2e} degrees");
        }
    }
}

#[test]
fn a_sphere_mesh_matches_the_analytic_sphere() {
    let n = 96;
    let mesh = Shape {
        kind: Kind::Sphere,
        seed: None,
    }
    .mesh(0);
    let view = View {
        margin: 0.0,
        ..View::new(n, n)
    };
    let (map, mask) = shapes::render_normals(&mesh, &view).unwrap();
    let exact = NormalMap::sphere(n);
    let mut worst = 0.0f64;
    for i in interior(&mask, n, n) {
        let e = exact.normals[i].map(f64::from);
        // where the true normal is within 60 degrees of the view: the tessellation (96
        // segments around, 48 rings) is at most 3.75 degrees per edge, and smooth normals
        // follow the sphere to within a fraction of that
        if e[2] > 0.5 {
            worst = worst.max(angle_deg(map.normals[i], e));
        }
        assert!(
            !exact.is_background(i),
            "pixel {i} is inside the mesh and outside the disc"
        );
    }
    eprintln!("largest angle to the analytic sphere: {worst:.3} degrees");
    assert!(worst < 0.5, "{worst} degrees");
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

#[test]
fn every_format_loads_the_same_mesh() {
    let dir = tempfile::tempdir().unwrap();
    let m = small_mesh();
    let buffer = gltf_buffer(&m);
    std::fs::write(dir.path().join("mesh.bin"), &buffer).unwrap();
    let data_uri = format!("data:application/octet-stream;base64,{}", base64(&buffer));
    let files: Vec<(&str, Vec<u8>)> = vec![
        ("mesh.obj", obj_text(&m, false).into_bytes()),
        ("ascii.ply", ply_ascii(&m).into_bytes()),
        ("binary.ply", ply_binary(&m)),
        ("binary.stl", stl_binary(&m)),
        ("ascii.stl", stl_ascii(&m).into_bytes()),
        ("mesh.off", off_text(&m).into_bytes()),
        (
            "file.gltf",
            gltf_json(&m, Some("mesh.bin"), buffer.len()).into_bytes(),
        ),
        (
            "embedded.gltf",
            gltf_json(&m, Some(&data_uri), buffer.len()).into_bytes(),
        ),
        ("mesh.glb", glb(&m)),
    ];
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
    assert!(load_error("bad.gltf", b"{\"asset\": 3}").starts_with("not a readable glTF file"));
    assert!(load_error("mesh.xyz", b"").contains(".obj, .ply, .stl, .off, .gltf or .glb"));
    let e = shapes::load_mesh(Path::new("/no/such/mesh.obj"))
        .unwrap_err()
        .to_string();
    assert_eq!(e, "/no/such/mesh.obj: no such file");
}

#[test]
fn seeded_shapes_are_deterministic_and_differ() {
    let view = View {
        rotation: Rotation::random(5),
        ..View::new(32, 32)
    };
    for (name, kind) in Kind::ALL {
        let shape = Shape { kind, seed: None };
        let a = shape.mesh(1);
        assert_eq!(a, shape.mesh(1), "{name}");
        let (na, _) = shapes::render_normals(&a, &view).unwrap();
        assert_eq!(
            na,
            shapes::render_normals(&shape.mesh(1), &view).unwrap().0,
            "{name}"
        );
        if kind != Kind::Sphere {
            assert_ne!(a, shape.mesh(2), "{name}: seeds 1 and 2 give the same mesh");
            assert_ne!(
                na,
                shapes::render_normals(&shape.mesh(2), &view).unwrap().0,
                "{name}"
            );
        }
        // the spec's own seed wins over the argument
        let fixed = Shape {
            kind,
            seed: Some(1),
        };
        assert_eq!(fixed.mesh(7), a, "{name}");
    }
    assert_ne!(Rotation::random(1), Rotation::random(2));
}

#[test]
fn normals_face_the_viewer_and_fill_the_frame() {
    for (name, kind) in Kind::ALL {
        for camera in [
            Camera::Orthographic,
            Camera::Perspective { fov_y_deg: 60.0 },
        ] {
            let view = View {
                camera,
                rotation: Rotation::random(3),
                ..View::new(64, 48)
            };
            let (map, mask) =
                shapes::render_normals(&Shape { kind, seed: None }.mesh(3), &view).unwrap();
            let (mut x0, mut x1, mut y0, mut y1) = (usize::MAX, 0, usize::MAX, 0);
            for (i, n) in map.normals.iter().enumerate() {
                let (x, y) = (i % 64, i / 64);
                if !mask[i] {
                    assert_eq!(*n, [0.0; 3], "{name}: background pixel {i}");
                    continue;
                }
                let w = camera.view_dir(x, y, 64, 48);
                let n = n.map(f64::from);
                assert!(
                    (dot(n, n) - 1.0).abs() < 1e-6,
                    "{name}: pixel {i}: |n|^2 = {}",
                    dot(n, n)
                );
                assert!(
                    dot(n, w) >= -1e-7,
                    "{name}: pixel {i}: n {n:?} faces away from {w:?}"
                );
                (x0, x1, y0, y1) = (x0.min(x), x1.max(x), y0.min(y), y1.max(y));
            }
            // the margin is 5% of the half-size on each side: about 1 pixel of 24 and of 32;
            // the object touches the margin on at least one axis
            let (span_x, span_y) = (x1 + 1 - x0, y1 + 1 - y0);
            assert!(
                span_x <= 64 && span_y <= 48 && x0 >= 1 && y0 >= 1 && x1 <= 62 && y1 <= 46,
                "{name}: {x0}..{x1} x {y0}..{y1}"
            );
            assert!(
                span_x >= 58 || span_y >= 43,
                "{name} {camera:?}: spans {span_x} x {span_y}"
            );
        }
    }
}

#[test]
fn winding_does_not_matter() {
    // every other triangle wound the other way: the same pixels, smooth (the vertex normals
    // the shape carries) and flat; an open bowl (the lower half of a sphere) seen from
    // above shows its inside, with normals facing the viewer
    let mesh = Shape {
        kind: Kind::Blobby,
        seed: None,
    }
    .mesh(4);
    let mut flipped = mesh.clone();
    for t in flipped.triangles.iter_mut().step_by(2) {
        t.swap(1, 2);
    }
    for flat in [false, true] {
        for camera in [
            Camera::Orthographic,
            Camera::Perspective { fov_y_deg: 45.0 },
        ] {
            let view = View {
                flat,
                camera,
                rotation: Rotation::random(9),
                ..View::new(40, 40)
            };
            let a = shapes::render_normals(&mesh, &view).unwrap();
            let b = shapes::render_normals(&flipped, &view).unwrap();
            assert!(a == b, "flat {flat}, {camera:?}");
        }
    }
    let mut bowl = tessellate::sphere_grid(16, 32, tessellate::direction);
    let n_top = bowl.positions.len();
    bowl.triangles
        .retain(|t| t.iter().all(|&v| bowl.positions[v as usize][1] <= 1e-6));
    assert!(bowl.triangles.len() < n_top * 2);
    let view = View {
        rotation: Rotation {
            yaw: 0.0,
            pitch: 60.0,
            roll: 0.0,
        },
        ..View::new(32, 32)
    };
    let (map, mask) = shapes::render_normals(&bowl, &view).unwrap();
    let centre = map.normals[16 * 32 + 16].map(f64::from);
    assert!(mask[16 * 32 + 16]);
    // looking into the bowl: the centre pixel sees the far inside wall, whose outward
    // normal points away from the viewer; the inside's normal faces it
    assert!(centre[2] > 0.9, "{centre:?}");
    for (i, n) in map.normals.iter().enumerate() {
        assert!(!mask[i] || n[2] >= 0.0, "pixel {i}: {n:?}");
    }
}
