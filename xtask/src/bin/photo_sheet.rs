//! The contact sheet of real photographs in docs/edit.md and the README: for each photo of
//! tests/data/photos (with the box around its object from boxes.json), one row of
//! photo | mask | gold | white paint | its own material, each edit made as `matedit edit
//! PHOTO --box ... --material NAME` makes it (the built-in nets, the default refinement),
//! and the cup's gold edit alone beside the photo for the README.
//!
//! `cargo xtask photo_sheet -- [OUT_DIR] [ROW_HEIGHT]` writes OUT_DIR/photos.png and
//! OUT_DIR/coffee_gold.png (default docs/edit, rows 180 pixels high), and prints each
//! photo's stage times.

use std::path::{Path, PathBuf};

use matedit::edit::photo::{self, PhotoOptions, Pointing};
use matedit::io::{self, Preview};
use matedit::nets::Nets;
use matedit::segment::Rect;
use matedit::{Accuracy, Device, Image, Renderer};

const PHOTOS: [&str; 3] = ["coffee.jpg", "flower.jpg", "rocket.jpg"];
const GAP: usize = 4;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let out = PathBuf::from(args.next().unwrap_or_else(|| "docs/edit".into()));
    let row_h: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(180);
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/photos");
    let boxes: serde_json::Value = serde_json::from_slice(&std::fs::read(dir.join("boxes.json"))?)?;
    let renderer = Renderer::new(Device::Cpu)?;
    let nets = Nets::builtin()?;
    let gold = matedit::presets::lookup("gold").ok_or("no gold")?;
    let paint = matedit::presets::lookup("white-paint").ok_or("no white-paint")?;
    let mut rows = Vec::new();
    for name in PHOTOS {
        let photo = io::load_image(&dir.join(name))?;
        let b: Vec<usize> = boxes[name]["box"]
            .as_array()
            .ok_or("boxes.json: no box")?
            .iter()
            .map(|v| v.as_u64().unwrap_or(0) as usize)
            .collect();
        let pointing = Pointing {
            bounds: Some(Rect {
                x0: b[0],
                y0: b[1],
                x1: b[2],
                y1: b[3],
            }),
            ..Pointing::default()
        };
        let d = photo::decompose(
            &renderer,
            &nets,
            &photo,
            &pointing,
            &PhotoOptions::default(),
            &mut |_| {},
        )?;
        let mask = Image {
            width: d.width,
            height: d.height,
            pixels: d
                .mask
                .iter()
                .map(|&m| [f32::from(u8::from(m)); 3])
                .collect(),
        };
        let mut tiles = vec![photo.clone(), mask];
        for m in [&gold, &paint, &d.material] {
            tiles.push(d.edit(&renderer, &photo, m, None, Accuracy::Exact)?);
        }
        println!("{name}: {:?}", d.stages);
        if name == "coffee.jpg" {
            let pair = [&tiles[0], &tiles[2]].map(|t| scaled(t, 2 * row_h));
            let strip = hstack(&pair);
            io::write_atomic(
                &out.join("coffee_gold.png"),
                &io::png::encode_preview(&strip, &Preview::default())?,
            )?;
        }
        rows.push(hstack(
            &tiles.iter().map(|t| scaled(t, row_h)).collect::<Vec<_>>(),
        ));
    }
    let sheet = vstack(&rows);
    io::write_atomic(
        &out.join("photos.png"),
        &io::png::encode_preview(&sheet, &Preview::default())?,
    )?;
    println!(
        "wrote {} ({} x {})",
        out.join("photos.png").display(),
        sheet.width,
        sheet.height
    );
    Ok(())
}

/// `img` box-filtered to `h` rows, its width in proportion.
fn scaled(img: &Image, h: usize) -> Image {
    let w = (img.width * h).div_ceil(img.height);
    matedit::raster::resize(img, w, h)
}

/// Images side by side with gaps, on black.
fn hstack(tiles: &[Image]) -> Image {
    let h = tiles.iter().map(|t| t.height).max().unwrap_or(0);
    let w = tiles.iter().map(|t| t.width).sum::<usize>() + GAP * tiles.len().saturating_sub(1);
    let mut out = Image::zeros(w, h);
    let mut x0 = 0;
    for t in tiles {
        for y in 0..t.height {
            for x in 0..t.width {
                out.pixels[y * w + x0 + x] = t.pixels[y * t.width + x];
            }
        }
        x0 += t.width + GAP;
    }
    out
}

/// Images one above the other with gaps, left-aligned, on black.
fn vstack(rows: &[Image]) -> Image {
    let w = rows.iter().map(|t| t.width).max().unwrap_or(0);
    let h = rows.iter().map(|t| t.height).sum::<usize>() + GAP * rows.len().saturating_sub(1);
    let mut out = Image::zeros(w, h);
    let mut y0 = 0;
    for t in rows {
        for y in 0..t.height {
            for x in 0..t.width {
                out.pixels[(y0 + y) * w + x] = t.pixels[y * t.width + x];
            }
        }
        y0 += t.height + GAP;
    }
    out
}
