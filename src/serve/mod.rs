//! `matedit serve`: a local web editor over HTTP (axum on tokio). One page (HTML, CSS and
//! JS built into the binary) and a JSON API: a photo uploaded as the body of a request is
//! decoded by the command line's loaders, checked against the server's limits, and
//! decomposed by the nets and the refinement in the background while its progress streams
//! as server-sent events; an edit renders the object with another material under the
//! refined light, blurred as for `matedit edit` (turned and exposed as asked), at full
//! size or as a preview through the levels of detail.
//!
//! Safe by default: loopback unless told otherwise; uploads limited in bytes (413) and in
//! pixels (413, read from the headers before decoding); only JPEG, PNG and EXR accepted
//! (415); photos live in memory under random ids that only their uploader is told, the
//! oldest dropped past a count; a photo can be held until it is pointed at (a box and
//! points, checked against it; its mask cut out before any decomposition); a failed job
//! keeps its message and the photo, to be pointed at again; no request names a file on
//! the machine. Each request is logged as one line on stderr.
//!
//! Here: the settings and start-up. `routes` answers the requests, `store` keeps the
//! photos, `pointing` takes the box and points, `events` runs their decompositions and
//! streams the progress, `work` computes
//! (decoding, decomposition, edits) and `reply` shapes the answers and errors.

mod events;
mod pointing;
mod reply;
mod routes;
mod store;
mod work;

use std::collections::HashMap;
use std::net::SocketAddr;
use std::sync::{Arc, Mutex};

use tokio::sync::Semaphore;

use crate::edit::photo::PhotoOptions;
use crate::error::{Error, Result};
use crate::nets::Nets;
use crate::{Device, Renderer};
use store::Store;

pub use pointing::MAX_POINTS;
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
    /// The nets also see each photo mirrored ([`Nets::with_mirror`]).
    pub mirror: bool,
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
            mirror: true,
        }
    }
}

/// The server's state, shared by every request.
struct App {
    config: Config,
    renderer: Renderer,
    nets: Nets,
    photos: Store,
    /// Presets' sphere pictures, rendered on first request.
    spheres: Mutex<HashMap<String, Arc<Vec<u8>>>>,
    /// Sphere pictures rendered at once: one. The page asks for the whole gallery as it
    /// opens; rendered all together they took both cores for as long as the gallery took
    /// and starved a photo's analysis (in the browser test a 128 x 128 photo's analysis
    /// took 38 s beside them in a debug build).
    sphere_renders: Semaphore,
    jobs: Semaphore,
    /// Masks cut out for a pointing ([`pointing`]) at once.
    segments: Semaphore,
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
    }
    .with_mirror(config.mirror);
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
        segments: Semaphore::new(2),
        config,
        renderer,
        nets,
        photos: Store::new(),
        spheres: Mutex::new(HashMap::new()),
        sphere_renders: Semaphore::new(1),
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
            if let Err(e) = axum::serve(listener, routes::router(app))
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
