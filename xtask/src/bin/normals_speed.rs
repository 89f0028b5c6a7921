//! How long `shapes::render_normals` takes on a 100k-triangle mesh at 512 x 512, how long
//! its smooth normals take where a file has none, and how long loading that mesh from an
//! OBJ file takes: the figures in docs/shapes.md.
//!
//! `cargo xtask normals_speed -- [SIZE] [REPS]`: a lumpy sphere of
//! 160 rings x 320 segments (101,760 triangles), a random rotation; orthographic and
//! perspective (fov 40), smooth and flat; the median of REPS (default 7) calls after a
//! warm-up, with rayon's threads (RAYON_NUM_THREADS, else one per core).

use std::time::Instant;

use matedit::Camera;
use matedit::shapes::{self, Mesh, Rotation, View, tessellate};

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    f();
    median(
        (0..reps)
            .map(|_| {
                let t = Instant::now();
                f();
                t.elapsed().as_secs_f64()
            })
            .collect(),
    )
}

fn obj(m: &Mesh) -> String {
    let mut s = String::new();
    for p in &m.positions {
        s += &format!("v {} {} {}\n", p[0], p[1], p[2]);
    }
    for t in &m.triangles {
        s += &format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

fn main() -> matedit::Result<()> {
    let mut args = std::env::args().skip(1);
    let size: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(512);
    let reps: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(7);
    let mesh = tessellate::sphere_grid(160, 320, |t, p| {
        let r = 1.0 + 0.15 * (5.0 * p).sin() * (3.0 * t).sin() + 0.05 * (17.0 * p + 11.0 * t).cos();
        tessellate::direction(t, p).map(|c| c * r)
    });
    println!(
        "mesh: {} triangles, {} vertices; image {size} x {size}; {} threads; median of {reps}",
        mesh.triangles.len(),
        mesh.positions.len(),
        rayon::current_num_threads()
    );
    for (name, camera) in [
        ("orthographic", Camera::Orthographic),
        ("perspective 40", Camera::Perspective { fov_y_deg: 40.0 }),
    ] {
        for flat in [false, true] {
            let view = View {
                camera,
                flat,
                rotation: Rotation::random(1),
                ..View::new(size, size)
            };
            let mut covered = 0;
            let s = time(reps, || {
                let (_, mask) = shapes::render_normals(&mesh, &view).expect("renders");
                covered = mask.iter().filter(|&&m| m).count();
            });
            let shading = if flat { "flat" } else { "smooth" };
            println!(
                "render_normals {name}, {shading}: {:.1} ms ({covered} pixels on the object)",
                s * 1e3
            );
        }
    }
    // what a mesh file without normals adds: its windings checked (and made to agree
    // where they do not) and its vertex normals summed
    let mut shuffled = mesh.clone();
    for t in shuffled.triangles.iter_mut().step_by(2) {
        t.swap(1, 2);
    }
    for (name, m) in [
        ("agreeing windings", &mesh),
        ("every other face rewound", &shuffled),
    ] {
        let s = time(reps, || {
            std::hint::black_box(m.smooth_normals());
        });
        println!("smooth_normals, {name}: {:.1} ms", s * 1e3);
    }
    let dir = tempfile::tempdir().map_err(|e| matedit::Error::Invalid(e.to_string()))?;
    let path = dir.path().join("mesh.obj");
    std::fs::write(&path, obj(&mesh)).map_err(|e| matedit::Error::Invalid(e.to_string()))?;
    let s = time(reps, || {
        shapes::load_mesh(&path).expect("loads");
    });
    println!(
        "load_mesh OBJ ({} MB): {:.1} ms",
        std::fs::metadata(&path).map_or(0, |m| m.len()) / 1_000_000,
        s * 1e3
    );
    Ok(())
}
