//! Pointing at the object over HTTP: a box and points (on the object, off it) sent with the
//! upload (its query) or as JSON, checked against the photo ([`Pointing::check`]); the
//! object's mask for them before any decomposition (`segment`), and the decomposition of
//! a held photo asked for with them or with a mask (`analyse`).

use std::sync::Arc;
use std::time::Instant;

use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::App;
use super::events::run_job;
use super::reply::{ApiError, blocking, bytes, json_body};
use super::work::{self, Target, Upload};
use crate::edit::photo::Pointing;
use crate::segment::Rect;

/// The most points on the object, and off it, in one request.
pub const MAX_POINTS: usize = 64;

fn bad(m: String) -> ApiError {
    ApiError(StatusCode::BAD_REQUEST, m)
}

/// A box and points as JSON: `{"box": [x0, y0, x1, y1], "point": [[x, y], ...], "not":
/// [[x, y], ...]}` (pixels; x1 and y1 exclusive; every key optional), the names of the
/// command line's flags.
#[derive(Debug, Default, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct Prompt {
    #[serde(rename = "box", default)]
    bounds: Option<[usize; 4]>,
    #[serde(default)]
    point: Vec<[usize; 2]>,
    #[serde(default)]
    not: Vec<[usize; 2]>,
}

impl Prompt {
    /// The prompt in an upload's query (`box=X0,Y0,X1,Y1`, `point=X,Y` and `not=X,Y`, the
    /// points repeatable) and whether it asks to hold the photo until its analysis is
    /// asked for (`hold=1`).
    pub(super) fn from_query(query: Option<&str>) -> Result<(Prompt, bool), ApiError> {
        let mut p = Prompt::default();
        let mut hold = false;
        for pair in query.unwrap_or("").split('&').filter(|s| !s.is_empty()) {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            let value = value.replace("%2C", ",").replace("%2c", ",");
            let numbers = |n: usize| -> Result<Vec<usize>, ApiError> {
                let v: Option<Vec<usize>> =
                    value.split(',').map(|s| s.trim().parse().ok()).collect();
                v.filter(|v| v.len() == n).ok_or_else(|| {
                    bad(format!(
                        "{key} {}: {n} whole numbers of pixels expected",
                        value.chars().take(40).collect::<String>()
                    ))
                })
            };
            match key {
                "box" => {
                    let v = numbers(4)?;
                    p.bounds = Some([v[0], v[1], v[2], v[3]]);
                }
                "point" | "not" => {
                    let v = numbers(2)?;
                    let into = if key == "point" {
                        &mut p.point
                    } else {
                        &mut p.not
                    };
                    into.push([v[0], v[1]]);
                }
                "hold" => hold = value != "0",
                _ => {
                    return Err(bad(format!(
                        "upload: unknown parameter '{}' (box, point, not, hold)",
                        key.chars().take(40).collect::<String>()
                    )));
                }
            }
        }
        Ok((p, hold))
    }

    /// The prompt as a [`Pointing`] checked against a `width` x `height` photo; `None` if it
    /// says nothing.
    pub(super) fn pointing(
        &self,
        width: usize,
        height: usize,
    ) -> Result<Option<Pointing>, ApiError> {
        if self.point.len() > MAX_POINTS || self.not.len() > MAX_POINTS {
            return Err(bad(format!(
                "at most {MAX_POINTS} points on the object and {MAX_POINTS} off it"
            )));
        }
        let p = Pointing {
            bounds: self.bounds.map(|[x0, y0, x1, y1]| Rect { x0, y0, x1, y1 }),
            object: self.point.clone(),
            background: self.not.clone(),
        };
        if p.is_empty() {
            return Ok(None);
        }
        p.check(width, height).map_err(|e| bad(e.to_string()))?;
        Ok(Some(p))
    }

    /// Where the object of `upload` is: pointed at, else its PNG's alpha, else found.
    pub(super) fn target(&self, upload: &Upload) -> Result<Target, ApiError> {
        Ok(
            match self.pointing(upload.photo.width, upload.photo.height)? {
                Some(p) => Target::Pointed(p),
                None => upload.mask.clone().map_or(Target::Find, Target::Mask),
            },
        )
    }
}

/// A JSON prompt; an empty body says nothing.
fn prompt(what: &str, body: &[u8]) -> Result<Prompt, ApiError> {
    if body.iter().all(u8::is_ascii_whitespace) {
        return Ok(Prompt::default());
    }
    crate::io::json::from_slice(body).map_err(|e| bad(format!("{what}: {e}")))
}

/// `POST /api/photos/{id}/segment` (a JSON prompt): the object's mask at the photo's size,
/// as PNG (white on the object), before any decomposition; its pixel count in
/// `x-object-pixels`.
pub(super) async fn segment(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    body: Bytes,
) -> Result<Response, ApiError> {
    let prompt = prompt("segment", &body)?;
    let source = app.photos.find(&id)?.source()?;
    let Some(pointing) = prompt.pointing(source.photo.width, source.photo.height)? else {
        return Err(bad(
            "segment: give a box or a point on the object (\"box\", \"point\")".into(),
        ));
    };
    let _permit = app.segments.acquire().await.map_err(|_| {
        ApiError(
            StatusCode::SERVICE_UNAVAILABLE,
            "the server is stopping".into(),
        )
    })?;
    let t = Instant::now();
    let a = app.clone();
    let (png, count) =
        blocking(move || work::segment_png(&a.nets, &source.photo, &pointing)).await??;
    let mut res = bytes("image/png", png);
    for (k, v) in [
        ("x-object-pixels", count.to_string()),
        (
            "x-segment-ms",
            format!("{:.1}", t.elapsed().as_secs_f64() * 1e3),
        ),
    ] {
        if let Ok(v) = HeaderValue::from_str(&v) {
            res.headers_mut().insert(k, v);
        }
    }
    Ok(res)
}

/// `POST /api/photos/{id}/analyse`: decomposes a held photo (or one whose decomposition
/// failed) with its object pointed at (a JSON prompt), given as a mask (a PNG body of the
/// photo's size, `Content-Type: image/png`), or, with neither, its PNG's alpha or found by
/// the nets; 202, then its events as for an upload.
pub(super) async fn analyse(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Response, ApiError> {
    let photo = app.photos.find(&id)?;
    let source = photo.source()?;
    let (w, h) = (source.photo.width, source.photo.height);
    let is_png = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("image/png"));
    let target = if is_png {
        Target::Mask(blocking(move || work::decode_mask(&body, w, h)).await??)
    } else {
        prompt("analyse", &body)?.target(&source)?
    };
    if !photo.queue() {
        return Err(ApiError(
            StatusCode::CONFLICT,
            "the photo is being analysed already".into(),
        ));
    }
    tokio::spawn(run_job(app, photo, target));
    Ok((StatusCode::ACCEPTED, json_body(&json!({"id": id}))).into_response())
}
