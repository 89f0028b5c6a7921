//! Pointing at the object over HTTP: a photo of two spheres, which the nets refuse to pick
//! from, held at upload, its object's mask cut out from a box before any decomposition,
//! bad boxes and points refused with the check's message, the refusal as a failed event,
//! then analysed with the box, with a mask sent as PNG, and pointed at in the upload's
//! query.

use std::net::SocketAddr;

use crate::http::{Reply, request};
use matedit::{Image, NormalMap};

use super::{config, decode_png, follow, photo, start};

/// A 160 x 80 photo of two blue rubber spheres side by side, as PNG, and the left one's
/// pixels (each half is [`photo`]`(80, 80, ..)`: a sphere of side 60 at (10, 10)).
fn two_spheres() -> (Vec<u8>, Vec<bool>) {
    let (half, _) = photo(80, 80, "blue-rubber", false);
    let (w, h) = (160, 80);
    let mut img = Image::zeros(w, h);
    for y in 0..h {
        for x in 0..w {
            img.pixels[y * w + x] = half.pixels[y * 80 + x % 80];
        }
    }
    let sphere = NormalMap::sphere(60);
    let left = (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            (10..70).contains(&x)
                && (10..70).contains(&y)
                && sphere.normals[(y - 10) * 60 + x - 10] != [0.0; 3]
        })
        .collect();
    let png = matedit::io::png::encode_preview(&img, &matedit::io::Preview::default()).unwrap();
    (png, left)
}

fn post(addr: SocketAddr, path: &str, kind: &str, body: &[u8]) -> Reply {
    request(
        addr,
        "POST",
        path,
        &[("X-Filename", "two.png"), ("Content-Type", kind)],
        body,
    )
}

/// A 400 whose one-line message contains `words`.
fn refused(r: &Reply, words: &str) {
    assert_eq!(r.status, 400, "{}", r.text());
    let m = r.json()["error"].as_str().unwrap().to_string();
    assert!(
        m.contains(words) && !m.contains('\n'),
        "'{m}' lacks '{words}'"
    );
}

/// Intersection over union of a PNG mask (white on the object) and `truth`.
fn iou(png: &[u8], truth: &[bool]) -> f64 {
    let (w, h, c, samples) = decode_png(png);
    assert_eq!(w * h, truth.len());
    let (mut both, mut either) = (0, 0);
    for (p, &t) in samples.chunks_exact(c).zip(truth) {
        let m = p[0] > 127;
        both += usize::from(m && t);
        either += usize::from(m || t);
    }
    both as f64 / either.max(1) as f64
}

fn get(addr: SocketAddr, id: &str, file: &str) -> Reply {
    request(addr, "GET", &format!("/api/photos/{id}/{file}"), &[], b"")
}

#[test]
fn a_held_photo_is_pointed_at_then_analysed() {
    let server = start(config());
    let addr = server.addr;
    let (png, left) = two_spheres();
    let r = post(addr, "/api/photos?hold=1", "image/png", &png);
    assert_eq!(r.status, 202, "{}", r.text());
    let id = r.json()["id"].as_str().unwrap().to_string();
    // the photo shows before any decomposition; its results do not exist yet
    let shown = get(addr, &id, "photo.png");
    assert_eq!(shown.status, 200, "{}", shown.text());
    assert_eq!(decode_png(&shown.body).0, 160);
    assert_eq!(get(addr, &id, "mask.png").status, 409);

    // a box around the left sphere: its mask at the photo's size, before any decomposition
    let segment = format!("/api/photos/{id}/segment");
    let json = "application/json";
    let r = post(addr, &segment, json, br#"{"box": [2, 2, 78, 78]}"#);
    assert_eq!(r.status, 200, "{}", r.text());
    assert_eq!(r.header("content-type"), Some("image/png"));
    let (w, h, _, _) = decode_png(&r.body);
    assert_eq!((w, h), (160, 80));
    // the cut follows the sphere's edge against the gradient: 0.8 leaves room for its rim
    let found = iou(&r.body, &left);
    assert!(found > 0.8, "IoU {found:.3}");
    let count: usize = r.header("x-object-pixels").unwrap().parse().unwrap();
    assert!(count > 1000 && count < 4000, "{count}");
    // a point on the object refines it as well
    let r = post(
        addr,
        &segment,
        json,
        br#"{"box": [2, 2, 78, 78], "point": [[40, 40]], "not": [[75, 75]]}"#,
    );
    assert_eq!(r.status, 200, "{}", r.text());
    assert!(iou(&r.body, &left) > 0.8);

    // bad prompts: the check's message, one line, 400
    for (body, words) in [
        (
            &br#"{"box": [10, 10, 900, 50]}"#[..],
            "box 10,10,900,50: outside the 160x80 photo",
        ),
        (br#"{"box": [50, 10, 10, 50]}"#, "empty"),
        (
            br#"{"box": [2, 2, 78, 78], "point": [[120, 40]]}"#,
            "point 120,40: outside the box 2,2,78,78",
        ),
        (br#"{"not": [[5, 5]]}"#, "need a box or a point"),
        (
            br#"{"point": [[200, 5]]}"#,
            "point 200,5: outside the 160x80",
        ),
        (br#"{}"#, "give a box or a point"),
        (br#"{"box": [1, 2]}"#, "segment:"),
        (br#"{"box": [-1, 2, 3, 4]}"#, "segment:"),
        (br#"{"lasso": []}"#, "segment:"),
    ] {
        refused(&post(addr, &segment, json, body), words);
    }
    let many = format!(r#"{{"point": [{}]}}"#, vec!["[40, 40]"; 65].join(", "));
    refused(&post(addr, &segment, json, many.as_bytes()), "at most 64");

    // without a prompt the nets find no single object: the refusal as a failed event
    let analyse = format!("/api/photos/{id}/analyse");
    let r = post(addr, &analyse, json, b"");
    assert_eq!(r.status, 202, "{}", r.text());
    let (events, text) = follow(addr, &id);
    assert_eq!(events.last().map(String::as_str), Some("failed"), "{text}");
    assert!(text.contains("no single object found"), "{text}");
    // a bad box on analysing is refused before anything runs
    refused(
        &post(addr, &analyse, json, br#"{"box": [0, 0, 161, 80]}"#),
        "outside the 160x80 photo",
    );

    // then with the box: analysed, its mask the left sphere
    let r = post(addr, &analyse, json, br#"{"box": [2, 2, 78, 78]}"#);
    assert_eq!(r.status, 202, "{}", r.text());
    let (events, text) = follow(addr, &id);
    assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
    assert!(text.contains("Cutting out the object pointed at"), "{text}");
    let mask = get(addr, &id, "mask.png");
    assert!(iou(&mask.body, &left) > 0.8);
    // once analysed, it is neither pointed at nor analysed again
    assert_eq!(post(addr, &analyse, json, b"{}").status, 409);
    assert_eq!(
        post(addr, &segment, json, br#"{"box": [2, 2, 78, 78]}"#).status,
        409
    );
}

#[test]
fn a_mask_or_a_query_says_where_the_object_is() {
    let server = start(config());
    let addr = server.addr;
    let (png, left) = two_spheres();

    // an edited mask, as PNG, for a held photo
    let r = post(addr, "/api/photos?hold=1", "image/png", &png);
    let id = r.json()["id"].as_str().unwrap().to_string();
    let analyse = format!("/api/photos/{id}/analyse");
    let white: Vec<u8> = left.iter().map(|&m| if m { 255 } else { 0 }).collect();
    let mask_png = matedit::io::png::encode_mask(160, 80, &left).unwrap();
    refused(
        &post(
            addr,
            &analyse,
            "image/png",
            &matedit::io::png::encode_mask(80, 80, &left[..6400]).unwrap(),
        ),
        "mask: 80x80; the photo is 160x80",
    );
    refused(
        &post(addr, &analyse, "image/png", b"not a png"),
        "not a PNG",
    );
    let r = post(addr, &analyse, "image/png", &mask_png);
    assert_eq!(r.status, 202, "{}", r.text());
    let (events, text) = follow(addr, &id);
    assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
    let (_, _, c, got) = decode_png(&get(addr, &id, "mask.png").body);
    let got: Vec<u8> = got.chunks_exact(c).map(|p| p[0]).collect();
    assert_eq!(got, white);

    // the box in the upload's query
    let r = post(addr, "/api/photos?box=82,2,158,78", "image/png", &png);
    assert_eq!(r.status, 202, "{}", r.text());
    let id = r.json()["id"].as_str().unwrap().to_string();
    let (events, text) = follow(addr, &id);
    assert_eq!(events.last().map(String::as_str), Some("ready"), "{text}");
    let right: Vec<bool> = (0..160 * 80)
        .map(|i| left[i / 160 * 160 + (i % 160 + 80) % 160])
        .collect();
    assert!(iou(&get(addr, &id, "mask.png").body, &right) > 0.8);

    for (query, words) in [
        (
            "box=10,10,900,50",
            "box 10,10,900,50: outside the 160x80 photo",
        ),
        ("box=10%2C10%2C9%2C50", "box 10,10,9,50: empty"),
        ("point=1", "point 1: 2 whole numbers of pixels expected"),
        ("not=5,5", "need a box or a point"),
        ("hold=1&box=2,2,78,78", "a held photo is pointed at"),
        ("lasso=1", "unknown parameter 'lasso'"),
    ] {
        refused(
            &post(addr, &format!("/api/photos?{query}"), "image/png", &png),
            words,
        );
    }
}
