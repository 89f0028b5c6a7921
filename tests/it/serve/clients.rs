//! Clients at once: two that each get their own results, and 20 concurrent previews.

use std::time::Instant;

use crate::http::{post_edit, request};

use super::{config, decode_png, photo, start, upload_and_wait};

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
