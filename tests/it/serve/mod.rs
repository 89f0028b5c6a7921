//! `matedit serve` over real HTTP on an ephemeral loopback port: the page, an upload
//! followed to its decomposition by server-sent events, edits, the refusals (4xx with a
//! message, 413 past the limits), two clients at once, and 20 concurrent previews.
#![cfg(feature = "serve")]

mod clients;
mod page;
mod pointing;
mod refusals;
mod upload;

use crate::http;

use std::net::SocketAddr;

use http::request;

use matedit::serve::{self, Config};
use matedit::{Batch, Camera, Convention, Device, Image, NormalMap, Renderer, Scene};

pub(super) fn start(config: Config) -> serve::Handle {
    serve::start(config, "127.0.0.1:0").expect("the server starts")
}

pub(super) fn config() -> Config {
    Config {
        steps: 10,
        jobs: 2,
        device: Device::Cpu,
        ..Config::default()
    }
}

/// A `w` x `h` photo: a sphere of `material` under the built-in sky, centred, on a
/// vertical grey gradient; as PNG bytes with the sphere as alpha if `alpha`.
pub(super) fn photo(w: usize, h: usize, material: &str, alpha: bool) -> (Image, Vec<u8>) {
    let side = w.min(h) * 3 / 4;
    let r = Renderer::new(Device::Cpu).unwrap();
    let sphere = r
        .render(
            &Batch::single(Scene {
                normals: NormalMap::sphere(side),
                env: matedit::builtin_sky::procedural_env(16, 32, Convention::Equirect),
                material: matedit::presets::lookup(material).unwrap(),
                camera: Camera::Orthographic,
            })
            .unwrap(),
        )
        .unwrap()
        .remove(0);
    let inside = NormalMap::sphere(side);
    let (ox, oy) = ((w - side) / 2, (h - side) / 2);
    let mut img = Image::zeros(w, h);
    let mut mask = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let g = 0.1 + 0.3 * y as f32 / h as f32;
            img.pixels[y * w + x] = [g, g, g * 1.1];
            if (ox..ox + side).contains(&x) && (oy..oy + side).contains(&y) {
                let j = (y - oy) * side + (x - ox);
                if inside.normals[j] != [0.0; 3] {
                    img.pixels[y * w + x] = sphere.pixels[j];
                    mask[y * w + x] = true;
                }
            }
        }
    }
    let preview = matedit::io::Preview::default();
    let mut rgba = Vec::new();
    for (p, &m) in img.pixels.iter().zip(&mask) {
        rgba.extend(p.map(|v| matedit::io::png::display_value(v, &preview)));
        rgba.push(if m || !alpha { 255 } else { 0 });
    }
    let mut bytes = Vec::new();
    {
        let mut e = png::Encoder::new(&mut bytes, w as u32, h as u32);
        e.set_color(png::ColorType::Rgba);
        e.set_depth(png::BitDepth::Eight);
        e.write_header().unwrap().write_image_data(&rgba).unwrap();
    }
    (img, bytes)
}

/// 8-bit RGB(A) samples of a PNG: (width, height, channels, samples).
pub(super) fn decode_png(bytes: &[u8]) -> (usize, usize, usize, Vec<u8>) {
    let d = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut r = d.read_info().expect("a PNG");
    let mut buf = vec![0; r.output_buffer_size().unwrap()];
    let info = r.next_frame(&mut buf).unwrap();
    buf.truncate(info.buffer_size());
    (
        info.width as usize,
        info.height as usize,
        info.color_type.samples(),
        buf,
    )
}

/// Uploads `bytes` and follows the events to the end; returns the id and the events' names.
pub(super) fn upload_and_wait(addr: SocketAddr, bytes: &[u8]) -> (String, Vec<String>, String) {
    let r = request(
        addr,
        "POST",
        "/api/photos",
        &[("X-Filename", "sphere.png")],
        bytes,
    );
    assert_eq!(r.status, 202, "{}", r.text());
    let id = r.json()["id"].as_str().unwrap().to_string();
    assert_eq!(id.len(), 32);
    let (names, text) = follow(addr, &id);
    (id, names, text)
}

/// Follows a photo's events to the end; returns their names and the stream's text.
pub(super) fn follow(addr: SocketAddr, id: &str) -> (Vec<String>, String) {
    let ev = request(addr, "GET", &format!("/api/photos/{id}/events"), &[], b"");
    assert_eq!(ev.status, 200);
    assert_eq!(ev.header("content-type"), Some("text/event-stream"));
    let text = ev.text();
    let names: Vec<String> = text
        .lines()
        .filter_map(|l| {
            l.strip_prefix("event: ")
                .or_else(|| l.strip_prefix("event:"))
        })
        .map(|s| s.trim().to_string())
        .collect();
    (names, text)
}
