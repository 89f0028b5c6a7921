//! The contact sheet of synthesised samples in the README and docs/synth.md: the samples of
//! a `matedit synth` spec (default docs/synth/sheet.json: procedural shapes and a few bumpy
//! surfaces under the four kinds of procedural light, random perturbed MERL materials,
//! perspective, the map behind the object), each made as `matedit synth` makes it (the
//! render over its background), scaled so that its 98th-percentile object pixel shows at
//! 0.8, then clamped and sRGB-encoded.
//!
//! `cargo xtask synth_sheet -- [SPEC] [OUT] [COLUMNS]` writes OUT
//! (default docs/synth/sheet.png), COLUMNS samples a row (default 8).

use std::path::PathBuf;

use matedit::io::png::{Preview, encode_preview};
use matedit::synth::Spec;
use matedit::{Batch, Device, Image, Renderer};

fn main() -> matedit::Result<()> {
    let mut args = std::env::args().skip(1);
    let spec_path = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "docs/synth/sheet.json".into()),
    );
    let out = PathBuf::from(args.next().unwrap_or_else(|| "docs/synth/sheet.png".into()));
    let cols: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(8);
    let spec = Spec::load(&spec_path)?;
    let renderer = Renderer::new(Device::Cpu)?;
    let (w, h) = spec.image_size;
    let rows = (spec.count as usize).div_ceil(cols);
    let mut sheet = Image {
        width: cols * w,
        height: rows * h,
        pixels: vec![[0.0; 3]; cols * w * rows * h],
    };
    for k in 0..spec.count {
        let mut sample = spec.sample(k)?;
        sample.paint_clutter(&renderer)?;
        let render = renderer
            .render(&Batch::single(sample.scene.clone())?)?
            .remove(0);
        let image = sample.compose(render);
        let fg = &sample.mask;
        let mut values: Vec<f32> = image
            .pixels
            .iter()
            .zip(fg)
            .filter(|(_, f)| **f)
            .map(|(p, _)| p[0].max(p[1]).max(p[2]))
            .collect();
        values.sort_by(f32::total_cmp);
        let top = values.get(values.len() * 98 / 100).copied().unwrap_or(1.0);
        let scale = if top > 0.0 { 0.8 / top } else { 1.0 };
        let (x0, y0) = ((k as usize % cols) * w, (k as usize / cols) * h);
        for y in 0..h {
            for x in 0..w {
                let p = image.pixels[y * w + x];
                sheet.pixels[(y0 + y) * sheet.width + x0 + x] = p.map(|v| v * scale);
            }
        }
    }
    let png = encode_preview(&sheet, &Preview::default())?;
    std::fs::write(&out, png).map_err(|e| matedit::Error::file(&out, e.to_string()))?;
    eprintln!("wrote {} ({} samples)", out.display(), spec.count);
    Ok(())
}
