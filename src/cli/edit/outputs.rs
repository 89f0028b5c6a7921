//! `matedit edit`'s output files but the report: the edit in the photo's kind, the
//! normals, mask, light, material, a sphere of it and the comparison strip.

use std::path::Path;

use matedit::edit::photo::Decomposition;
use matedit::io::{self, Format, Preview};
use matedit::{Convention, Device, Image, Material, NormalMap, Renderer};

use crate::cli::shared::{Failure, runtime};

/// Every output file but the report of the edit of the photo at `photo_path`, encoded.
pub(super) fn encode_outputs(
    photo_path: &Path,
    kind: Format,
    photo: &Image,
    edit: &Image,
    d: &Decomposition,
    material: &Material,
) -> Result<Vec<(String, Vec<u8>)>, Failure> {
    let preview = Preview::default();
    let crop_mask: Vec<bool> = d.normals.normals.iter().map(|n| n != &[0.0; 3]).collect();
    // the edit's encoding runs on one thread; the sphere, the comparison strip, the normals
    // and the mask beside it
    let (edit_file, others) = rayon::join(
        || -> Result<_, Failure> {
            Ok(match kind {
                Format::Jpeg => ("edit.jpg", encode_jpeg(edit)?),
                Format::Png => ("edit.png", io::png::encode_preview(edit, &preview)?),
                _ => (
                    "edit.exr",
                    io::exr::encode_rgb(edit.width, edit.height, &edit.pixels)?,
                ),
            })
        },
        || -> Result<_, Failure> {
            let sky = matedit::builtin_sky::procedural_env(32, 64, Convention::Equirect);
            let renderer = Renderer::new(Device::Cpu)?;
            let sphere = renderer
                .render(&matedit::Batch::single(matedit::Scene {
                    normals: NormalMap::sphere(128),
                    env: sky,
                    material: d.material.clone(),
                    camera: matedit::Camera::Orthographic,
                })?)?
                .remove(0);
            let compare = compare_strip(photo, edit, &d.normals, &crop_mask, &sphere, &preview)?;
            let normals = io::png::encode_normals(&d.normals, &crop_mask)?;
            let mask = io::png::encode_mask(d.width, d.height, &d.mask)?;
            Ok((sphere, compare, normals, mask))
        },
    );
    let (edit_file, (sphere, compare, normals, mask)) = (edit_file?, others?);
    let description = format!(
        "the material of matedit edit {} ({})",
        photo_path.display(),
        material.name
    );
    Ok(vec![
        (edit_file.0.to_string(), edit_file.1),
        ("normals.png".into(), normals),
        ("mask.png".into(), mask),
        (
            "light.exr".into(),
            io::exr::encode_rgb(d.env.width, d.env.height, &d.env.texels)?,
        ),
        (
            "material.json".into(),
            io::json::encode_material(&d.material, Some(&description)),
        ),
        (
            "sphere.png".into(),
            io::png::encode_preview(&sphere, &preview)?,
        ),
        ("compare.png".into(), compare),
    ])
}

fn encode_jpeg(image: &Image) -> Result<Vec<u8>, Failure> {
    let preview = Preview::default();
    let rgb = io::png::display_bytes(image, &preview);
    let mut out = Vec::new();
    jpeg_encoder::Encoder::new(&mut out, 92)
        .encode(
            &rgb,
            image.width as u16,
            image.height as u16,
            jpeg_encoder::ColorType::Rgb,
        )
        .map_err(|e| {
            runtime(matedit::Error::Invalid(format!(
                "encoding the edit as JPEG: {e}"
            )))
        })?;
    Ok(out)
}

/// photo | edit | normals | sphere, each scaled to 256 rows, on a dark background.
fn compare_strip(
    photo: &Image,
    edit: &Image,
    normals: &NormalMap,
    mask: &[bool],
    sphere: &Image,
    preview: &Preview,
) -> matedit::Result<Vec<u8>> {
    const H: usize = 256;
    const GAP: usize = 8;
    let pw = (photo.width * H / photo.height).max(1);
    let normal_rgb = Image {
        width: normals.width,
        height: normals.height,
        // shown as (n + 1) / 2, already display values: undo the sRGB curve of the preview
        pixels: normals
            .normals
            .iter()
            .zip(mask)
            .map(|(n, &m)| {
                if m {
                    n.map(|v| io::png::srgb_decode((v + 1.0) / 2.0))
                } else {
                    [0.0; 3]
                }
            })
            .collect(),
    };
    let tiles = [
        matedit::raster::resize(photo, pw, H),
        matedit::raster::resize(edit, pw, H),
        matedit::raster::resize(&normal_rgb, H, H),
        matedit::raster::resize(sphere, H, H),
    ];
    let width = tiles.iter().map(|t| t.width).sum::<usize>() + GAP * (tiles.len() + 1);
    let height = H + 2 * GAP;
    let mut rgb = vec![24u8; width * height * 3];
    let mut ox = GAP;
    for t in &tiles {
        for y in 0..t.height {
            for x in 0..t.width {
                let o = ((GAP + y) * width + ox + x) * 3;
                for k in 0..3 {
                    rgb[o + k] = io::png::display_value(t.pixels[y * t.width + x][k], preview);
                }
            }
        }
        ox += t.width + GAP;
    }
    io::png::encode_rgb8(width, height, &rgb)
}
