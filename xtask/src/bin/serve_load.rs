//! Latency of `matedit serve` over loopback HTTP: one photo decomposed, then previews one
//! at a time, N previews at once, and full-size edits, each a different turn of the light.
//!
//!   cargo run --release -- render --sphere 1024 --preset blue-rubber -o /tmp/sphere.png
//!   cargo xtask serve_load -- /tmp/sphere.png [N]
//!
//! Prints the percentiles (ms, from the request's start to the last byte of the PNG).

#[path = "../../../tests/it/http/mod.rs"]
mod http;

use std::time::Instant;

use http::{post_edit, request};
use matedit::serve::{self, Config};

fn percentiles(mut ms: Vec<f64>) -> String {
    ms.sort_by(f64::total_cmp);
    let at = |q: f64| ms[((ms.len() - 1) as f64 * q).round() as usize];
    format!(
        "p50 {:7.1}  p90 {:7.1}  p99 {:7.1}  max {:7.1}",
        at(0.5),
        at(0.9),
        at(0.99),
        at(1.0)
    )
}

/// One edit of photo `id` with the light turned by `turn` degrees; milliseconds.
fn edit(addr: std::net::SocketAddr, id: &str, turn: f64, preview: bool) -> f64 {
    let body =
        format!(r#"{{"material": "gold-metallic-paint3", "turn": {turn}, "preview": {preview}}}"#);
    let t = Instant::now();
    let r = post_edit(addr, id, &body);
    assert_eq!(r.status, 200, "{}", r.text());
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let Some(path) = args.get(1) else {
        eprintln!("usage: serve_load PHOTO [N]");
        std::process::exit(2);
    };
    let n: usize = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(20);
    let bytes = std::fs::read(path).expect("reads the photo");
    let server = serve::start(Config::default(), "127.0.0.1:0").expect("starts");
    let addr = server.addr;
    let t = Instant::now();
    let r = request(addr, "POST", "/api/photos", &[("X-Filename", path)], &bytes);
    assert_eq!(r.status, 202, "{}", r.text());
    let id = r.json()["id"].as_str().unwrap().to_string();
    let ev = request(addr, "GET", &format!("/api/photos/{id}/events"), &[], b"").text();
    assert!(ev.contains("event: ready"), "{ev}");
    let decompose_s = t.elapsed().as_secs_f64();
    let info = request(addr, "GET", "/api/info", &[], b"").json();
    let report = request(
        addr,
        "GET",
        &format!("/api/photos/{id}/report.json"),
        &[],
        b"",
    )
    .json();
    edit(addr, &id, 0.0, true); // the preset's first use
    let one_at_a_time: Vec<f64> = (0..n)
        .map(|i| edit(addr, &id, i as f64 * 7.0, true))
        .collect();
    let t = Instant::now();
    let threads: Vec<_> = (0..n)
        .map(|i| {
            let id = id.clone();
            std::thread::spawn(move || edit(addr, &id, i as f64 * 11.0, true))
        })
        .collect();
    let at_once: Vec<f64> = threads
        .into_iter()
        .map(|t| t.join().expect("a client"))
        .collect();
    let at_once_s = t.elapsed().as_secs_f64();
    let full: Vec<f64> = (0..5)
        .map(|i| edit(addr, &id, i as f64 * 13.0, false))
        .collect();
    println!(
        "photo {} ({} x {}), {} object pixels; {}",
        path, report["width"], report["height"], report["object_pixels"], info["device"]
    );
    println!("decomposition (upload to the ready event): {decompose_s:.2} s");
    println!(
        "preview, one at a time ({n}):  {}",
        percentiles(one_at_a_time)
    );
    println!(
        "preview, {n} at once:           {}  (all done in {:.2} s)",
        percentiles(at_once),
        at_once_s
    );
    println!("full size, one at a time (5): {}", percentiles(full));
}
