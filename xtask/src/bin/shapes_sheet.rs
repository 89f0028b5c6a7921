//! The contact sheet of procedural shapes in docs/shapes.md: each kind (columns: sphere,
//! blobby, superquadric, torus, capsule, box, cylinder, plate, limb, extrusion, union,
//! vessel)
//! for seeds 1, 2 and 3 (rows), each seed's random rotation, orthographic, smooth normals,
//! shown as (n + 1) / 2 on grey.
//!
//! `cargo xtask shapes_sheet -- [OUT] [TILE]` writes OUT (default
//! docs/shapes/sheet.png) with TILE x TILE pixels per shape (default 96).

use std::path::PathBuf;

use matedit::io;
use matedit::shapes::{self, Rotation, Shape, ShapeKind, View};

const SEEDS: [u64; 3] = [1, 2, 3];

fn main() -> matedit::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "docs/shapes/sheet.png".into()),
    );
    let tile: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(96);
    let kinds: Vec<ShapeKind> = ShapeKind::ALL
        .iter()
        .map(|&(_, k)| k)
        .filter(|&k| k != ShapeKind::Random)
        .collect();
    let (w, h) = (kinds.len() * tile, SEEDS.len() * tile);
    let mut rgb = vec![48u8; w * h * 3];
    for (col, &kind) in kinds.iter().enumerate() {
        for (row, &seed) in SEEDS.iter().enumerate() {
            let mesh = Shape { kind, seed: None }.mesh(seed);
            let view = View {
                rotation: Rotation::random(seed),
                ..View::new(tile, tile)
            };
            let (map, mask) = shapes::render_normals(&mesh, &view)?;
            for (i, n) in map.normals.iter().enumerate() {
                if !mask[i] {
                    continue;
                }
                let (x, y) = (col * tile + i % tile, row * tile + i / tile);
                let px = &mut rgb[(y * w + x) * 3..][..3];
                for c in 0..3 {
                    px[c] = ((n[c] + 1.0) / 2.0 * 255.0).round() as u8;
                }
            }
        }
    }
    io::write_atomic(&out, &io::png::encode_rgb8(w, h, &rgb)?)?;
    println!("wrote {} ({w} x {h})", out.display());
    Ok(())
}
