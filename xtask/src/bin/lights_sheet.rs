//! Contact sheets of the procedural lights (`matedit::envgen`): each kind (rows: sun-sky,
//! overcast, studio, indoor) at several seeds (columns), tone-mapped, and a glossy and a
//! diffuse sphere rendered under each of the same maps.
//!
//! ```sh
//! cargo xtask lights_sheet                  # writes docs/environments/
//! cargo xtask lights_sheet -- --out DIR --seeds 6
//! ```
//!
//! sheet.png: 128 x 256 maps, Reinhard x / (1 + x) then sRGB. spheres.png: per map a
//! 96-pixel orthographic sphere of `red-specular-plastic` beside one of `clay`, rendered on
//! the fast CPU path from the map at 64 x 128, at exposure -1, Reinhard.
//!
//! It also prints the clear sky's sun-to-sky horizontal illuminance ratio over sun
//! elevation and turbidity, and the time to generate each kind at 64 x 128 and 256 x 512.

use std::path::PathBuf;

use std::time::Instant;

use matedit::envgen::sky::SunSky;
use matedit::envgen::{self, LightKind};
use matedit::io::png::{Preview, encode_preview};
use matedit::io::{Tonemap, write_atomic};
use matedit::{Batch, Camera, Device, Image, NormalMap, Renderer, Scene, presets};

const GAP: usize = 4;

fn main() {
    if let Err(e) = run() {
        eprintln!("lights_sheet: {e}");
        std::process::exit(1);
    }
}

fn arg(args: &[String], name: &str) -> Option<String> {
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1).cloned())
}

/// Tiles `cells` (rows of equally sized images) into one image with gaps between them.
fn tile(cells: &[Vec<Image>]) -> Image {
    let (ch, cw) = (cells[0][0].height, cells[0][0].width);
    let cols = cells[0].len();
    let width = cols * cw + (cols + 1) * GAP;
    let height = cells.len() * ch + (cells.len() + 1) * GAP;
    let mut pixels = vec![[0.0f32; 3]; width * height];
    for (i, row) in cells.iter().enumerate() {
        for (j, cell) in row.iter().enumerate() {
            let (y0, x0) = (GAP + i * (ch + GAP), GAP + j * (cw + GAP));
            for r in 0..ch {
                let dst = (y0 + r) * width + x0;
                pixels[dst..dst + cw].copy_from_slice(&cell.pixels[r * cw..(r + 1) * cw]);
            }
        }
    }
    Image {
        width,
        height,
        pixels,
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().collect();
    let out = PathBuf::from(arg(&args, "--out").unwrap_or_else(|| "docs/environments".into()));
    let seeds: u64 = arg(&args, "--seeds").map_or(Ok(4), |s| s.parse().map_err(|_| "--seeds N"))?;
    std::fs::create_dir_all(&out).map_err(|e| format!("{}: {e}", out.display()))?;
    let renderer = Renderer::new(Device::Cpu).map_err(|e| e.to_string())?;
    let materials = ["red-specular-plastic", "clay"]
        .map(|n| presets::lookup(n).ok_or(format!("no preset {n}")));
    let [glossy, diffuse] = materials;
    let (glossy, diffuse) = (glossy?, diffuse?);

    let mut maps = Vec::new();
    let mut spheres = Vec::new();
    for kind in LightKind::ALL {
        let mut map_row = Vec::new();
        let mut sphere_row = Vec::new();
        for seed in 0..seeds {
            let env = envgen::generate(kind, seed, 128, 256).map_err(|e| e.to_string())?;
            eprintln!("{kind} seed {seed}: {}", envgen::Params::draw(kind, seed));
            map_row.push(Image {
                width: env.width,
                height: env.height,
                pixels: env.texels.clone(),
            });
            let small = envgen::generate(kind, seed, 64, 128).map_err(|e| e.to_string())?;
            let scenes = [&glossy, &diffuse].map(|m| Scene {
                normals: NormalMap::sphere(96),
                env: small.clone(),
                material: m.clone(),
                camera: Camera::Orthographic,
            });
            let batch = Batch::new(scenes.to_vec()).map_err(|e| e.to_string())?;
            let images = renderer.render(&batch).map_err(|e| e.to_string())?;
            // the two spheres side by side as one cell
            let mut pair = vec![[0.0f32; 3]; 96 * 192];
            for r in 0..96 {
                for (k, img) in images.iter().enumerate() {
                    pair[r * 192 + k * 96..r * 192 + (k + 1) * 96]
                        .copy_from_slice(&img.pixels[r * 96..(r + 1) * 96]);
                }
            }
            sphere_row.push(Image {
                width: 192,
                height: 96,
                pixels: pair,
            });
        }
        maps.push(map_row);
        spheres.push(sphere_row);
    }
    let write = |name: &str, image: &Image, exposure: f32| -> Result<(), String> {
        let preview = Preview {
            exposure,
            tonemap: Tonemap::Reinhard,
        };
        let bytes = encode_preview(image, &preview).map_err(|e| e.to_string())?;
        let path = out.join(name);
        write_atomic(&path, &bytes).map_err(|e| e.to_string())?;
        eprintln!(
            "wrote {} ({}x{})",
            path.display(),
            image.width,
            image.height
        );
        Ok(())
    };
    sun_to_sky_table()?;
    builtin_sun_to_sky();
    timings()?;
    write("sheet.png", &tile(&maps), 0.0)?;
    write("spheres.png", &tile(&spheres), -1.0)?;
    Ok(())
}

/// The sun's horizontal illuminance over the sky's, as a Markdown table.
fn sun_to_sky_table() -> Result<(), String> {
    let turbidities = [2.0, 3.0, 5.0, 10.0];
    println!("| sun elevation | T = 2 | T = 3 | T = 5 | T = 10 |");
    println!("| ---: | ---: | ---: | ---: | ---: |");
    for elevation in [2.0, 5.0, 15.0, 30.0, 45.0, 60.0, 90.0] {
        let mut row = format!("| {elevation} |");
        for turbidity in turbidities {
            let sky = SunSky {
                elevation,
                azimuth: 0.0,
                turbidity,
                ground: [0.2; 3],
                sun: true,
            };
            let r = sky.model().map_err(|e| e.to_string())?.sun_to_sky();
            row += &format!(" {r:.2} |");
        }
        println!("{row}");
    }
    Ok(())
}

/// The same ratio for the built-in sky (`defaults`), from its constants: the sun's
/// luminance times its solid angle and cosine over the sky's horizontal illuminance (a
/// midpoint quadrature).
fn builtin_sun_to_sky() {
    use matedit::builtin_sky::{SUN_DIR, SUN_RADIANCE, SUN_RADIUS, sky_radiance};
    use matedit::envgen::colour::luminance;
    use std::f64::consts::PI;
    let omega = 2.0 * PI * (1.0 - SUN_RADIUS.cos());
    let sun = luminance(SUN_RADIANCE) * omega * SUN_DIR[1];
    let (nt, np) = (256, 512);
    let mut sky = 0.0;
    for i in 0..nt {
        let theta = (i as f64 + 0.5) / nt as f64 * PI / 2.0;
        let d = theta.sin() * theta.cos() * (PI / 2.0 / nt as f64) * (2.0 * PI / np as f64);
        for j in 0..np {
            let phi = (j as f64 + 0.5) / np as f64 * 2.0 * PI;
            let w = [
                phi.cos() * theta.sin(),
                theta.cos(),
                phi.sin() * theta.sin(),
            ];
            sky += luminance(sky_radiance(w)) * d;
        }
    }
    println!(
        "built-in sky: sun-to-sky {:.2} (sun {sun:.3}, sky {sky:.3})",
        sun / sky
    );
}

/// Seconds to generate each kind (seed 0), one run each.
fn timings() -> Result<(), String> {
    println!("| kind | 64 x 128 | 256 x 512 |");
    println!("| --- | ---: | ---: |");
    for kind in LightKind::ALL {
        let mut row = format!("| {kind} |");
        for (h, w) in [(64, 128), (256, 512)] {
            let start = Instant::now();
            envgen::generate(kind, 0, h, w).map_err(|e| e.to_string())?;
            row += &format!(" {:.3} |", start.elapsed().as_secs_f64());
        }
        println!("{row}");
    }
    Ok(())
}
