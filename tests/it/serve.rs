//! `matedit serve` over real HTTP on an ephemeral loopback port: the page, an upload
//! followed to its decomposition by server-sent events, edits, the refusals (4xx with a
//! message, 413 past the limits), two clients at once, and 20 concurrent previews.
#![cfg(feature = "serve")]

use crate::http;

use std::net::SocketAddr;
use std::time::Instant;

use http::{Reply, post_edit, request};

use matedit::serve::{self, Config};
use matedit::{Batch, Camera, Convention, Device, Image, NormalMap, Renderer, Scene};

fn start(config: Config) -> serve::Handle {
    serve::start(config, "127.0.0.1:0").expect("the server starts")
}

fn config() -> Config {
    Config {
        steps: 10,
        jobs: 2,
        device: Device::Cpu,
        ..Config::default()
    }
}

/// A `w` x `h` photo: a sphere of `material` under the built-in sky, centred, on a
/// vertical grey gradient; as PNG bytes with the sphere as alpha if `alpha`.
fn photo(w: usize, h: usize, material: &str, alpha: bool) -> (Image, Vec<u8>) {
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
fn decode_png(bytes: &[u8]) -> (usize, usize, usize, Vec<u8>) {
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
fn upload_and_wait(addr: SocketAddr, bytes: &[u8]) -> (String, Vec<String>, String) {
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
    (id, names, text)
}

#[test]
fn the_page_and_its_parts_load() {
    let server = start(config());
    let r = request(server.addr, "GET", "/", &[], b"");
    assert_eq!(r.status, 200);
    assert!(r.header("content-type").unwrap().starts_with("text/html"));
    assert!(r.text().contains("page.js"), "the page loads its script");
    for (path, kind) in [("/page.js", "text/javascript"), ("/page.css", "text/css")] {
        let r = request(server.addr, "GET", path, &[], b"");
        assert_eq!(r.status, 200, "{path}");
        assert!(
            r.header("content-type").unwrap().starts_with(kind),
            "{path}"
        );
        assert!(!r.body.is_empty());
    }
    let info = request(server.addr, "GET", "/api/info", &[], b"").json();
    let presets = info["presets"].as_array().unwrap();
    assert_eq!(presets.len(), matedit::presets::names().len());
    let r = request(
        server.addr,
        "GET",
        "/api/presets/gold-metallic-paint3/sphere.png",
        &[],
        b"",
    );
    assert_eq!(r.status, 200);
    let (w, h, _, _) = decode_png(&r.body);
    assert_eq!((w, h), (96, 96));
    let r = request(
        server.addr,
        "GET",
        "/api/presets/gold-metallic-paint3/material.json",
        &[],
        b"",
    );
    assert_eq!(r.status, 200);
    assert!(r.json().is_object());
    let r = request(
        server.addr,
        "GET",
        "/api/presets/no-such/sphere.png",
        &[],
        b"",
    );
    assert_eq!(r.status, 404);
    assert!(r.json()["error"].as_str().unwrap().contains("no-such"));
    assert_eq!(
        request(server.addr, "GET", "/etc/passwd", &[], b"").status,
        404
    );
    assert_eq!(
        request(server.addr, "GET", "/api/photos/../../etc/passwd", &[], b"").status,
        404
    );
}

#[test]
fn upload_pick_a_preset_get_the_edit() {
    let server = start(config());
    let (_, bytes) = photo(96, 80, "blue-rubber", true);
    let (id, events, text) = upload_and_wait(server.addr, &bytes);
    assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
    assert!(events.iter().any(|e| e == "progress"), "{text}");
    for f in [
        "photo.png",
        "mask.png",
        "normals.png",
        "light.png",
        "sphere.png",
    ] {
        let r = request(
            server.addr,
            "GET",
            &format!("/api/photos/{id}/{f}"),
            &[],
            b"",
        );
        assert_eq!(r.status, 200, "{f}");
        assert_eq!(r.header("content-type"), Some("image/png"), "{f}");
        decode_png(&r.body);
    }
    let report = request(
        server.addr,
        "GET",
        &format!("/api/photos/{id}/report.json"),
        &[],
        b"",
    )
    .json();
    assert_eq!(report["width"], 96);
    // the refinement keeps its best step: never worse than the predictions
    let (p, r) = (
        report["psnr_predicted_db"].as_f64().unwrap(),
        report["psnr_refined_db"].as_f64().unwrap(),
    );
    assert!(r >= p - 1e-9 && r.is_finite(), "{report}");
    let mat = request(
        server.addr,
        "GET",
        &format!("/api/photos/{id}/material.json"),
        &[],
        b"",
    );
    assert_eq!(mat.status, 200);
    assert!(matedit::io::json::parse_material(std::path::Path::new("m.json"), &mat.body).is_ok());

    let (w, h, c, before) = decode_png(
        &request(
            server.addr,
            "GET",
            &format!("/api/photos/{id}/photo.png"),
            &[],
            b"",
        )
        .body,
    );
    let (_, _, _, mask) = decode_png(
        &request(
            server.addr,
            "GET",
            &format!("/api/photos/{id}/mask.png"),
            &[],
            b"",
        )
        .body,
    );
    let edit = request(
        server.addr,
        "POST",
        &format!("/api/photos/{id}/edit"),
        &[("Content-Type", "application/json")],
        br#"{"material": "gold-metallic-paint3"}"#,
    );
    assert_eq!(edit.status, 200, "{}", edit.text());
    let (ew, eh, ec, after) = decode_png(&edit.body);
    assert_eq!((ew, eh), (w, h));
    // the object changed, the background far from it did not
    let (mut on, mut on_diff, mut off, mut off_same) = (0, 0.0, 0, 0);
    let mask_c = mask.len() / (w * h);
    for i in 0..w * h {
        let d: i32 = (0..3)
            .map(|k| (i32::from(before[i * c + k]) - i32::from(after[i * ec + k])).abs())
            .sum();
        if mask[i * mask_c] > 0 {
            on += 1;
            on_diff += f64::from(d);
        } else {
            let (x, y) = (i % w, i / w);
            let near = {
                let r = 2usize;
                (y.saturating_sub(r)..(y + r + 1).min(h)).any(|yy| {
                    (x.saturating_sub(r)..(x + r + 1).min(w))
                        .any(|xx| mask[(yy * w + xx) * mask_c] > 0)
                })
            };
            if !near {
                off += 1;
                off_same += usize::from(d == 0);
            }
        }
    }
    assert!(on > 100, "object pixels {on}");
    assert!(
        on_diff / on as f64 > 10.0,
        "mean change on the object {}",
        on_diff / on as f64
    );
    assert_eq!(off_same, off, "background pixels changed");

    // a preview is at most 256 a side; turning the light changes the edit
    let p = request(
        server.addr,
        "POST",
        &format!("/api/photos/{id}/edit"),
        &[],
        br#"{"material": "gold-metallic-paint3", "preview": true, "turn": 90, "exposure": 1}"#,
    );
    assert_eq!(p.status, 200, "{}", p.text());
    let (pw, ph, _, turned) = decode_png(&p.body);
    assert_eq!(
        (pw, ph),
        (96, 80),
        "a small photo's preview is the photo's size"
    );
    assert_ne!(turned, after);
    // the material of this photo as the material of the edit
    let like = request(
        server.addr,
        "POST",
        &format!("/api/photos/{id}/edit"),
        &[],
        format!(r#"{{"like": "{id}"}}"#).as_bytes(),
    );
    assert_eq!(like.status, 200, "{}", like.text());
}

#[test]
fn bad_requests_get_a_4xx_with_a_message() {
    let server = start(Config {
        max_upload_bytes: 64 << 10,
        max_pixels: 200 * 200,
        ..config()
    });
    let post = |path: &str, body: &[u8]| {
        request(
            server.addr,
            "POST",
            path,
            &[("X-Filename", "mine.png")],
            body,
        )
    };
    let check = |r: Reply, status: u16, words: &str| {
        assert_eq!(r.status, status, "{}", r.text());
        let m = r.json()["error"].as_str().unwrap().to_string();
        assert!(m.contains(words), "'{m}' lacks '{words}'");
        assert!(!m.contains('\n'));
    };
    check(
        post("/api/photos", b"just some text"),
        415,
        "mine.png: not a JPEG, PNG or EXR",
    );
    check(post("/api/photos", b""), 400, "empty");
    let (_, good) = photo(64, 64, "blue-rubber", false);
    check(
        post("/api/photos", &good[..good.len() / 2]),
        400,
        "mine.png",
    );
    check(
        post("/api/photos", &vec![0u8; 100 << 10]),
        413,
        "upload limit",
    );
    let (_, big) = photo(240, 240, "blue-rubber", false);
    check(post("/api/photos", &big), 413, "240x240 is over the limit");
    check(
        post("/api/photos/0123/edit", br#"{"material": "gold"}"#),
        404,
        "no such photo",
    );
    check(
        request(server.addr, "GET", "/api/photos/0123/mask.png", &[], b""),
        404,
        "no such photo",
    );
    let (id, events, text) = upload_and_wait(server.addr, &good);
    assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
    let edit = format!("/api/photos/{id}/edit");
    check(
        post(&edit, br#"{"material": "no-such"}"#),
        400,
        "no preset named 'no-such'",
    );
    check(post(&edit, b"{not json"), 400, "edit:");
    check(
        post(
            &edit,
            br#"{"material": "gold-metallic-paint3", "turn": 1e9}"#,
        ),
        400,
        "turn",
    );
    check(
        post(
            &edit,
            br#"{"material": "gold-metallic-paint3", "colour": 1}"#,
        ),
        400,
        "colour",
    );
    check(post(&edit, br#"{}"#), 400, "give one of");
    check(post(&edit, br#"{"like": "ffff"}"#), 404, "no such photo");
    check(
        request(
            server.addr,
            "GET",
            &format!("/api/photos/{id}/secret.txt"),
            &[],
            b"",
        ),
        404,
        "no file",
    );
    // a black photo: its job fails with a message
    let blank = {
        let mut b = Vec::new();
        let mut e = png::Encoder::new(&mut b, 64, 64);
        e.set_color(png::ColorType::Rgb);
        e.write_header()
            .unwrap()
            .write_image_data(&[0u8; 64 * 64 * 3])
            .unwrap();
        b
    };
    let (id, events, text) = upload_and_wait(server.addr, &blank);
    assert_eq!(events.last().map(String::as_str), Some("failed"), "{text}");
    assert!(
        text.contains(r#"{"error":"sphere.png: image: no object found"#),
        "{text}"
    );
    check(
        request(
            server.addr,
            "GET",
            &format!("/api/photos/{id}/mask.png"),
            &[],
            b"",
        ),
        409,
        "sphere.png: image: no object found",
    );
}

#[test]
fn two_clients_at_once_get_their_own_results() {
    let server = start(config());
    let addr = server.addr;
    let work = |w: usize, h: usize, material: &'static str| {
        std::thread::spawn(move || {
            let (_, bytes) = photo(w, h, material, true);
            let (id, events, text) = upload_and_wait(addr, &bytes);
            assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
            let before = decode_png(
                &request(
                    addr,
                    "GET",
                    &format!("/api/photos/{id}/photo.png"),
                    &[],
                    b"",
                )
                .body,
            );
            let r = request(
                addr,
                "POST",
                &format!("/api/photos/{id}/edit"),
                &[],
                br#"{"material": "chrome-steel"}"#,
            );
            assert_eq!(r.status, 200, "{}", r.text());
            (before, decode_png(&r.body))
        })
    };
    let (a, b) = (
        work(96, 72, "blue-rubber"),
        work(72, 96, "gold-metallic-paint3"),
    );
    for (t, size) in [(a, (96, 72)), (b, (72, 96))] {
        let (before, after) = t.join().expect("a client");
        assert_eq!((before.0, before.1), size);
        assert_eq!(
            (after.0, after.1),
            size,
            "an edit of the other client's photo"
        );
        // the top row (background) of its own photo
        let row = |p: &(usize, usize, usize, Vec<u8>)| -> Vec<u8> {
            (0..p.0)
                .flat_map(|x| p.3[x * p.2..x * p.2 + 3].to_vec())
                .collect()
        };
        assert_eq!(row(&before), row(&after));
    }
}

#[test]
fn twenty_concurrent_previews() {
    let server = start(config());
    let (_, bytes) = photo(400, 300, "blue-rubber", true);
    let (id, events, text) = upload_and_wait(server.addr, &bytes);
    assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
    let addr = server.addr;
    let threads: Vec<_> = (0..20)
        .map(|i| {
            let id = id.clone();
            std::thread::spawn(move || {
                let t = Instant::now();
                let body = format!(
                    r#"{{"material": "gold-metallic-paint3", "preview": true, "turn": {}}}"#,
                    i * 9
                );
                let r = post_edit(addr, &id, &body);
                (r.status, decode_png(&r.body).0, t.elapsed().as_secs_f64())
            })
        })
        .collect();
    let mut ms: Vec<f64> = threads
        .into_iter()
        .map(|t| {
            let (status, width, s) = t.join().unwrap();
            assert_eq!(status, 200);
            assert_eq!(width, 200, "a 400 x 300 photo's preview: box-filtered by 2");
            s * 1e3
        })
        .collect();
    ms.sort_by(f64::total_cmp);
    eprintln!(
        "20 concurrent previews (debug build): p50 {:.0} ms, p90 {:.0} ms, max {:.0} ms",
        ms[9], ms[17], ms[19]
    );
}
