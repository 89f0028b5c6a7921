//! One client's whole path: a photo uploaded and followed to its decomposition by
//! server-sent events, a preset picked, the edit and its previews fetched.

use crate::http::request;

use super::{config, decode_png, photo, start, upload_and_wait};

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
