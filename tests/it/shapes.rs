//! Shapes to normal maps (`matedit::shapes`): the rasteriser against an independent ray
//! caster and the analytic sphere, winding, facing the viewer, filling the frame, and
//! seeded shapes. Mesh files: tests/shapes_files.rs.

use matedit::shapes::{self, Mesh, Rotation, Shape, ShapeKind, View, tessellate};
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
        kind: ShapeKind::Sphere,
        seed: None,
    }
    .mesh(0);
    let cube = Shape {
        kind: ShapeKind::Box,
        seed: None,
    }
    .mesh(4);
    let blob = Shape {
        kind: ShapeKind::Blobby,
        seed: None,
    }
    .mesh(2);
    let torus = Shape {
        kind: ShapeKind::Torus,
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
        kind: ShapeKind::Sphere,
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

#[test]
fn seeded_shapes_are_deterministic_and_differ() {
    let view = View {
        rotation: Rotation::random(5),
        ..View::new(32, 32)
    };
    for (name, kind) in ShapeKind::ALL {
        let shape = Shape { kind, seed: None };
        let a = shape.mesh(1);
        assert_eq!(a, shape.mesh(1), "{name}");
        let (na, _) = shapes::render_normals(&a, &view).unwrap();
        assert_eq!(
            na,
            shapes::render_normals(&shape.mesh(1), &view).unwrap().0,
            "{name}"
        );
        if kind != ShapeKind::Sphere {
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
    for (name, kind) in ShapeKind::ALL {
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
        kind: ShapeKind::Blobby,
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
    // a mesh file without normals: its smooth normals come from its faces, whose windings
    // are made to agree first (else a rewound face's normal cancels its neighbours')
    let bare = |m: &Mesh| Mesh {
        normals: None,
        ..m.clone()
    };
    let view = View {
        rotation: Rotation::random(9),
        ..View::new(40, 40)
    };
    let a = shapes::render_normals(&bare(&mesh), &view).unwrap();
    let b = shapes::render_normals(&bare(&flipped), &view).unwrap();
    assert!(a == b, "smooth normals of a mesh without them");
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
