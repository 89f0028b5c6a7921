//! The page and the JSON API: which handler answers which path, each request logged as one
//! line, the upload's limits checked before the photo is decoded, and the edits rendered on
//! the blocking pool.

use std::sync::Arc;
use std::time::Instant;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{Path, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde_json::json;

use super::App;
use super::events::{events, run_job};
use super::pointing::{self, Prompt};
use super::reply::{ApiError, blocking, bytes, json_body, page, poisoned};
use super::store::Photo;
use super::work::{self, PREVIEW_SIDE};
use crate::Material;

/// The routes of the page and the API, over the server's state.
pub(super) fn router(app: Arc<App>) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { page(include_str!("page.html"), "text/html; charset=utf-8") }),
        )
        .route(
            "/page.css",
            get(|| async { page(include_str!("page.css"), "text/css; charset=utf-8") }),
        )
        .route(
            "/page.js",
            get(|| async { page(include_str!("page.js"), "text/javascript; charset=utf-8") }),
        )
        .route("/api/info", get(info))
        .route("/api/presets/{name}/{file}", get(preset_file))
        .route("/api/photos", post(upload))
        .route("/api/photos/{id}/events", get(events))
        .route("/api/photos/{id}/edit", post(edit))
        .route("/api/photos/{id}/segment", post(pointing::segment))
        .route("/api/photos/{id}/analyse", post(pointing::analyse))
        .route("/api/photos/{id}/{file}", get(photo_file))
        .fallback(|| async { ApiError(StatusCode::NOT_FOUND, "no such page".into()) })
        .layer(middleware::from_fn(log))
        .with_state(app)
}

/// One line per request: method, path, status, milliseconds to the response's head.
async fn log(req: Request, next: Next) -> Response {
    let (method, path) = (req.method().clone(), req.uri().path().to_owned());
    let t = Instant::now();
    let res = next.run(req).await;
    eprintln!(
        "matedit: serve: {method} {path} {} {:.1} ms",
        res.status().as_u16(),
        t.elapsed().as_secs_f64() * 1e3
    );
    res
}

/// `GET /api/info`: the presets, the limits and the device.
async fn info(State(app): State<Arc<App>>) -> Response {
    json_body(&json!({
        "presets": crate::presets::names(),
        "max_upload_bytes": app.config.max_upload_bytes,
        "max_pixels": app.config.max_pixels,
        "steps": app.config.steps,
        "preview_size": PREVIEW_SIDE,
        "device": app.renderer.describe(),
    }))
    .into_response()
}

/// `GET /api/presets/{name}/{file}`: a preset's material.json or its sphere.png.
async fn preset_file(
    State(app): State<Arc<App>>,
    Path((name, file)): Path<(String, String)>,
) -> std::result::Result<Response, ApiError> {
    let material = crate::presets::lookup(&name)
        .ok_or_else(|| ApiError(StatusCode::NOT_FOUND, format!("no preset named '{name}'")))?;
    match file.as_str() {
        "material.json" => Ok(bytes(
            "application/json",
            crate::io::json::encode_material(&material, None),
        )),
        "sphere.png" => {
            let cached = app.spheres.lock().map_err(poisoned)?.get(&name).cloned();
            let png = match cached {
                Some(p) => p,
                None => {
                    let _permit = app.sphere_renders.acquire().await.map_err(|_| {
                        ApiError(
                            StatusCode::SERVICE_UNAVAILABLE,
                            "the server is stopping".into(),
                        )
                    })?;
                    // it may have been rendered while this request waited
                    let cached = app.spheres.lock().map_err(poisoned)?.get(&name).cloned();
                    match cached {
                        Some(p) => p,
                        None => {
                            let a = app.clone();
                            let p = Arc::new(
                                blocking(move || work::sphere_png(&a.renderer, &material))
                                    .await??,
                            );
                            app.spheres
                                .lock()
                                .map_err(poisoned)?
                                .insert(name, p.clone());
                            p
                        }
                    }
                }
            };
            Ok((
                [
                    (header::CONTENT_TYPE, "image/png"),
                    (header::CACHE_CONTROL, "max-age=3600"),
                ],
                png.as_ref().clone(),
            )
                .into_response())
        }
        _ => Err(ApiError(
            StatusCode::NOT_FOUND,
            format!("no file '{file}' for a preset"),
        )),
    }
}

/// `POST /api/photos`: a photo as the body (its name in `x-filename`), decoded within the
/// limits and queued for decomposition, with the object pointed at by the query
/// ([`Prompt::from_query`]), or held until `analyse` asks for it (`hold=1`); answers its
/// id and size.
async fn upload(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    req: Request,
) -> std::result::Result<Response, ApiError> {
    let limit = app.config.max_upload_bytes;
    let name: String = headers
        .get("x-filename")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("the upload")
        .chars()
        .filter(|c| !c.is_control())
        .take(100)
        .collect();
    let too_large = |name: &str| {
        ApiError(
            StatusCode::PAYLOAD_TOO_LARGE,
            format!(
                "{name}: over the upload limit of {} MB",
                limit as f64 / (1 << 20) as f64
            ),
        )
    };
    let (prompt, held) = Prompt::from_query(req.uri().query())?;
    if held && prompt.pointing(usize::MAX, usize::MAX)?.is_some() {
        return Err(ApiError(
            StatusCode::BAD_REQUEST,
            "upload: a held photo is pointed at when its analysis is asked for".into(),
        ));
    }
    if let Some(n) = headers
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok()?.parse::<usize>().ok())
        && n > limit
    {
        return Err(too_large(&name));
    }
    let body = axum::body::to_bytes(req.into_body(), limit)
        .await
        .map_err(|_| too_large(&name))?;
    if body.is_empty() {
        return Err(ApiError(
            StatusCode::BAD_REQUEST,
            format!("{name}: the upload is empty"),
        ));
    }
    let max_pixels = app.config.max_pixels;
    let decoded = {
        let name = name.clone();
        blocking(move || work::decode_upload(&name, &body, max_pixels)).await?
    };
    let upload = decoded.map_err(|r| match r {
        work::Refusal::TooLarge(m) => ApiError(StatusCode::PAYLOAD_TOO_LARGE, m),
        work::Refusal::Unsupported(m) => ApiError(StatusCode::UNSUPPORTED_MEDIA_TYPE, m),
        work::Refusal::Bad(m) => ApiError(StatusCode::BAD_REQUEST, m),
    })?;
    let (w, h) = (upload.photo.width, upload.photo.height);
    let target = if held {
        None
    } else {
        Some(prompt.target(&upload)?)
    };
    let photo = Arc::new(Photo::new(name, upload, held));
    let id = app.photos.add(photo.clone(), app.config.max_photos)?;
    if let Some(target) = target {
        tokio::spawn(run_job(app, photo, target));
    }
    Ok((
        StatusCode::ACCEPTED,
        json_body(&json!({"id": id, "width": w, "height": h})),
    )
        .into_response())
}

/// `GET /api/photos/{id}/{file}`: report.json or one of the decomposition's pictures;
/// photo.png also before the decomposition is done.
async fn photo_file(
    State(app): State<Arc<App>>,
    Path((id, file)): Path<(String, String)>,
) -> std::result::Result<Response, ApiError> {
    if file == "photo.png"
        && let Ok(source) = app.photos.find(&id)?.source()
    {
        let png = blocking(move || work::photo_png(&source.photo)).await??;
        return Ok(bytes("image/png", png));
    }
    let a = app.photos.ready(&id)?;
    if file == "report.json" {
        return Ok(bytes(
            "application/json",
            serde_json::to_vec_pretty(&a.report).unwrap_or_default(),
        ));
    }
    let (_, kind, data) = a
        .files
        .iter()
        .find(|(name, _, _)| *name == file)
        .ok_or_else(|| {
            ApiError(
                StatusCode::NOT_FOUND,
                format!("no file '{file}' for a photo"),
            )
        })?;
    Ok(bytes(kind, data.clone()))
}

/// The body of an edit: a preset's name or another photo's id, and the light's turn
/// (degrees), exposure (stops) and whether a preview is enough.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct EditBody {
    material: Option<String>,
    like: Option<String>,
    #[serde(default)]
    turn: f64,
    #[serde(default)]
    exposure: f64,
    #[serde(default)]
    preview: bool,
}

/// `POST /api/photos/{id}/edit`: the photo with its object in another material, as PNG.
async fn edit(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    body: Bytes,
) -> std::result::Result<Response, ApiError> {
    let bad = |m: String| ApiError(StatusCode::BAD_REQUEST, m);
    let req: EditBody =
        crate::io::json::from_slice(&body).map_err(|e| bad(format!("edit: {e}")))?;
    if !(req.turn.is_finite() && req.turn.abs() <= 360.0) {
        return Err(bad(format!(
            "edit: turn {}: expected degrees in [-360, 360]",
            req.turn
        )));
    }
    if !(req.exposure.is_finite() && req.exposure.abs() <= 10.0) {
        return Err(bad(format!(
            "edit: exposure {}: expected stops in [-10, 10]",
            req.exposure
        )));
    }
    let a = app.photos.ready(&id)?;
    let material: Material = match (&req.material, &req.like) {
        (Some(name), None) => crate::presets::lookup(name)
            .ok_or_else(|| bad(format!("edit: no preset named '{name}'")))?,
        (None, Some(other)) => app.photos.ready(other)?.d.material.clone(),
        _ => {
            return Err(bad(
                "edit: give one of \"material\" (a preset) or \"like\" (a photo's id)".into(),
            ));
        }
    };
    let t = Instant::now();
    let app2 = app.clone();
    let png = blocking(move || {
        work::edit_png(
            &app2.renderer,
            &a,
            &work::EditRequest {
                material: &material,
                turn: req.turn,
                exposure: req.exposure,
                preview: req.preview,
            },
        )
    })
    .await??;
    let mut res = bytes("image/png", png);
    if let Ok(v) = HeaderValue::from_str(&format!("{:.1}", t.elapsed().as_secs_f64() * 1e3)) {
        res.headers_mut().insert("x-render-ms", v);
    }
    Ok(res)
}
