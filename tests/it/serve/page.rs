//! The page and the parts it loads.

use crate::http::request;

use super::{config, decode_png, start};

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
