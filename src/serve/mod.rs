//! `matedit serve`: a local web editor over HTTP (axum on tokio). One page (HTML, CSS and
//! JS built into the binary) and a JSON API: a photo uploaded as the body of a request is
//! decoded by the command line's loaders, checked against the server's limits, and
//! decomposed by the nets and the refinement in the background while its progress streams
//! as server-sent events; an edit renders the object with another material under the
//! refined light (turned and exposed as asked), at full size or as a preview through the
//! levels of detail.
//!
//! Safe by default: loopback unless told otherwise; uploads limited in bytes (413) and in
//! pixels (413, read from the headers before decoding); only JPEG, PNG and EXR accepted
//! (415); photos live in memory under random ids that only their uploader is told, the
//! oldest dropped past a count; a failed job keeps nothing but its message; no request
//! names a file on the machine. Each request is logged as one line on stderr.

mod work;

use std::collections::{HashMap, VecDeque};
use std::convert::Infallible;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use axum::Router;
use axum::body::Bytes;
use axum::extract::{Path, Request, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use serde_json::{Value, json};
use tokio::sync::{Semaphore, watch};

use crate::edit::photo::PhotoOptions;
use crate::error::{Error, Result};
use crate::nets::Nets;
use crate::{Device, Material, Renderer};

pub use work::{PREVIEW_SIDE, PREVIEW_TOLERANCE};

/// The server's settings.
#[derive(Clone, Debug)]
pub struct Config {
    /// The largest upload, in bytes.
    pub max_upload_bytes: usize,
    /// The largest photo, in pixels (width x height).
    pub max_pixels: usize,
    /// Photos kept in memory; past this the oldest is dropped.
    pub max_photos: usize,
    /// Decompositions run at once (more wait their turn).
    pub jobs: usize,
    /// Refinement steps of material and light per photo.
    pub steps: usize,
    /// The rendering backend.
    pub device: Device,
    /// Weights of the nets (None: the built-in ones).
    pub weights: Option<std::path::PathBuf>,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            max_upload_bytes: 32 << 20,
            max_pixels: 4096 * 3072,
            max_photos: 16,
            jobs: 1,
            steps: PhotoOptions::default().steps,
            device: Device::Auto,
            weights: None,
        }
    }
}

/// Where a photo's decomposition is.
#[derive(Clone)]
enum Status {
    Progress {
        stage: &'static str,
        done: usize,
        total: usize,
        message: String,
    },
    Ready(Value),
    Failed(String),
}

/// An uploaded photo: its decomposition's status and, when ready, its result.
struct Photo {
    status: watch::Sender<Status>,
    result: Mutex<Option<Arc<work::Analysed>>>,
}

/// Photos by id, and their ids oldest first.
type Photos = (HashMap<String, Arc<Photo>>, VecDeque<String>);

struct App {
    config: Config,
    renderer: Renderer,
    nets: Nets,
    photos: Mutex<Photos>,
    /// Presets' sphere pictures, rendered on first request.
    spheres: Mutex<HashMap<String, Arc<Vec<u8>>>>,
    jobs: Semaphore,
}

/// A running server; dropping it stops it.
pub struct Handle {
    /// The address it listens on.
    pub addr: SocketAddr,
    stop: Option<tokio::sync::oneshot::Sender<()>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Handle {
    /// Blocks until the server stops (on Ctrl-C).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for Handle {
    fn drop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

/// Loads the nets, binds `addr` ("127.0.0.1:8000"; port 0 for any free one) and serves on
/// a thread of its own until the handle is dropped or the process gets Ctrl-C.
pub fn start(config: Config, addr: &str) -> Result<Handle> {
    if config.max_upload_bytes == 0
        || config.max_pixels == 0
        || config.max_photos == 0
        || config.jobs == 0
    {
        return Err(Error::Invalid(
            "serve: the upload, pixel, photo and job limits must be at least 1".into(),
        ));
    }
    let nets = match &config.weights {
        Some(w) => Nets::load(w)?,
        None => Nets::builtin()?,
    };
    let renderer = Renderer::new(config.device)?;
    let listener = std::net::TcpListener::bind(addr)
        .map_err(|e| Error::Invalid(format!("serve: cannot listen on {addr}: {e}")))?;
    listener
        .set_nonblocking(true)
        .map_err(|e| Error::Invalid(format!("serve: {addr}: {e}")))?;
    let local = listener
        .local_addr()
        .map_err(|e| Error::Invalid(format!("serve: {addr}: {e}")))?;
    let app = Arc::new(App {
        jobs: Semaphore::new(config.jobs),
        config,
        renderer,
        nets,
        photos: Mutex::new((HashMap::new(), VecDeque::new())),
        spheres: Mutex::new(HashMap::new()),
    });
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .map_err(|e| Error::Invalid(format!("serve: cannot start the runtime: {e}")))?;
    let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
    let thread = std::thread::spawn(move || {
        runtime.block_on(async move {
            let listener = match tokio::net::TcpListener::from_std(listener) {
                Ok(l) => l,
                Err(e) => {
                    eprintln!("matedit: serve: {e}");
                    return;
                }
            };
            let shutdown = async {
                tokio::select! {
                    _ = stopped => {}
                    _ = tokio::signal::ctrl_c() => {}
                }
            };
            if let Err(e) = axum::serve(listener, router(app))
                .with_graceful_shutdown(shutdown)
                .await
            {
                eprintln!("matedit: serve: {e}");
            }
        });
        // jobs still running on the blocking pool are not waited for
        runtime.shutdown_background();
    });
    Ok(Handle {
        addr: local,
        stop: Some(stop),
        thread: Some(thread),
    })
}

fn router(app: Arc<App>) -> Router {
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

/// An error as JSON `{"error": message}` with its status.
struct ApiError(StatusCode, String);

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (self.0, json_body(&json!({"error": self.1}))).into_response()
    }
}

impl From<Error> for ApiError {
    fn from(e: Error) -> Self {
        let code = if e.is_input_error() {
            StatusCode::BAD_REQUEST
        } else {
            StatusCode::INTERNAL_SERVER_ERROR
        };
        ApiError(code, e.to_string())
    }
}

/// A JSON body, never cached.
fn json_body(v: &Value) -> Response {
    bytes("application/json", v.to_string().into_bytes())
}

fn page(text: &'static str, kind: &'static str) -> Response {
    ([(header::CONTENT_TYPE, kind)], text).into_response()
}

fn bytes(kind: &'static str, data: Vec<u8>) -> Response {
    (
        [
            (header::CONTENT_TYPE, kind),
            (header::CACHE_CONTROL, "no-store"),
        ],
        data,
    )
        .into_response()
}

/// Runs `f` on the blocking pool.
async fn blocking<T: Send + 'static>(
    f: impl FnOnce() -> T + Send + 'static,
) -> std::result::Result<T, ApiError> {
    tokio::task::spawn_blocking(f).await.map_err(|e| {
        ApiError(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("internal error: {e}"),
        )
    })
}

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
                    let a = app.clone();
                    let p = Arc::new(
                        blocking(move || work::sphere_png(&a.renderer, &material)).await??,
                    );
                    app.spheres
                        .lock()
                        .map_err(poisoned)?
                        .insert(name, p.clone());
                    p
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

fn poisoned<T>(_: T) -> ApiError {
    ApiError(
        StatusCode::INTERNAL_SERVER_ERROR,
        "internal error: a lock was poisoned".into(),
    )
}

/// 32 hex digits from the OS's random source.
fn new_id() -> std::result::Result<String, ApiError> {
    let mut b = [0u8; 16];
    getrandom::fill(&mut b).map_err(|e| {
        ApiError(
            StatusCode::INTERNAL_SERVER_ERROR,
            format!("no random source: {e}"),
        )
    })?;
    Ok(b.iter().map(|x| format!("{x:02x}")).collect())
}

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
    let id = new_id()?;
    let (status, _) = watch::channel(Status::Progress {
        stage: "queued",
        done: 0,
        total: 1,
        message: "Waiting for a free worker".into(),
    });
    let photo = Arc::new(Photo {
        status,
        result: Mutex::new(None),
    });
    {
        let mut photos = app.photos.lock().map_err(poisoned)?;
        photos.0.insert(id.clone(), photo.clone());
        photos.1.push_back(id.clone());
        while photos.1.len() > app.config.max_photos {
            if let Some(old) = photos.1.pop_front() {
                photos.0.remove(&old);
            }
        }
    }
    tokio::spawn(run_job(app, photo, upload, name));
    Ok((
        StatusCode::ACCEPTED,
        json_body(&json!({"id": id, "width": w, "height": h})),
    )
        .into_response())
}

/// Decomposes a photo on the blocking pool when a worker is free; its status follows.
async fn run_job(app: Arc<App>, photo: Arc<Photo>, upload: work::Upload, name: String) {
    let Ok(_permit) = app.jobs.acquire().await else {
        return;
    };
    let (a, p) = (app.clone(), photo.clone());
    let result = tokio::task::spawn_blocking(move || {
        let options = PhotoOptions {
            steps: a.config.steps,
            ..PhotoOptions::default()
        };
        work::analyse(&a.renderer, &a.nets, upload, &options, &mut |stage| {
            let (stage, done, total, message) = work::describe(stage);
            p.status.send_replace(Status::Progress {
                stage,
                done,
                total,
                message,
            });
        })
    })
    .await;
    let status = match result {
        Ok(Ok(analysed)) => {
            let report = analysed.report.clone();
            if let Ok(mut r) = photo.result.lock() {
                *r = Some(Arc::new(analysed));
            }
            Status::Ready(report)
        }
        Ok(Err(e)) => Status::Failed(format!("{name}: {e}")),
        Err(e) => Status::Failed(format!("{name}: internal error: {e}")),
    };
    photo.status.send_replace(status);
}

fn find(app: &App, id: &str) -> std::result::Result<Arc<Photo>, ApiError> {
    app.photos
        .lock()
        .map_err(poisoned)?
        .0
        .get(id)
        .cloned()
        .ok_or_else(|| {
            ApiError(
                StatusCode::NOT_FOUND,
                "no such photo (it may have been dropped for newer ones: upload it again)".into(),
            )
        })
}

fn ready(app: &App, id: &str) -> std::result::Result<Arc<work::Analysed>, ApiError> {
    let photo = find(app, id)?;
    if let Status::Failed(m) = &*photo.status.borrow() {
        return Err(ApiError(StatusCode::CONFLICT, m.clone()));
    }
    let r = photo.result.lock().map_err(poisoned)?.clone();
    r.ok_or_else(|| {
        ApiError(
            StatusCode::CONFLICT,
            "the photo is still being analysed".into(),
        )
    })
}

async fn events(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> std::result::Result<Response, ApiError> {
    let photo = find(&app, &id)?;
    let rx = photo.status.subscribe();
    // (receiver, the photo kept alive, first event sent, last event sent)
    let stream = futures_util::stream::unfold(
        (rx, photo, false, false),
        |(mut rx, photo, started, ended)| async move {
            if ended {
                return None;
            }
            if started && rx.changed().await.is_err() {
                return None;
            }
            let status = rx.borrow_and_update().clone();
            let (event, last) = match status {
                Status::Progress {
                    stage,
                    done,
                    total,
                    message,
                } => (
                    Event::default().event("progress").data(
                        json!({"stage": stage, "done": done, "total": total, "message": message})
                            .to_string(),
                    ),
                    false,
                ),
                Status::Ready(report) => (
                    Event::default().event("ready").data(report.to_string()),
                    true,
                ),
                Status::Failed(m) => (
                    Event::default()
                        .event("failed")
                        .data(json!({"error": m}).to_string()),
                    true,
                ),
            };
            Some((Ok::<_, Infallible>(event), (rx, photo, true, last)))
        },
    );
    Ok(Sse::new(stream)
        .keep_alive(KeepAlive::default())
        .into_response())
}

async fn photo_file(
    State(app): State<Arc<App>>,
    Path((id, file)): Path<(String, String)>,
) -> std::result::Result<Response, ApiError> {
    let a = ready(&app, &id)?;
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
    let a = ready(&app, &id)?;
    let material: Material = match (&req.material, &req.like) {
        (Some(name), None) => crate::presets::lookup(name)
            .ok_or_else(|| bad(format!("edit: no preset named '{name}'")))?,
        (None, Some(other)) => ready(&app, other)?.d.material.clone(),
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
