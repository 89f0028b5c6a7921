//! The refusals: a 4xx with a message for every bad request, 413 past the limits, and a job
//! that fails with a message.

use crate::http::{Reply, request};
use matedit::serve::Config;

use super::{config, photo, start, upload_and_wait};

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
