//! The uploaded photos, in memory: each under a random id that only its uploader is told,
//! the oldest dropped past a count, with its decomposition's status, the decoded photo
//! until its decomposition succeeds (to be pointed at, and analysed again after a
//! failure) and, once ready, its result.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};

use axum::http::StatusCode;
use serde_json::Value;
use tokio::sync::watch;

use super::reply::{ApiError, poisoned};
use super::work;

/// Where a photo's decomposition is.
#[derive(Clone)]
pub(super) enum Status {
    /// Held until its analysis is asked for (the page points at the object first).
    Waiting,
    Progress {
        stage: &'static str,
        done: usize,
        total: usize,
        message: String,
    },
    Ready(Value),
    Failed(String),
}

/// An uploaded photo: the client's name for it (messages only), its decomposition's
/// status, the decoded upload until the decomposition succeeds and, when ready, its result.
pub(super) struct Photo {
    pub(super) name: String,
    pub(super) status: watch::Sender<Status>,
    pub(super) source: Mutex<Option<Arc<work::Upload>>>,
    pub(super) result: Mutex<Option<Arc<work::Analysed>>>,
}

/// The status of a photo waiting for a worker.
pub(super) fn queued() -> Status {
    Status::Progress {
        stage: "queued",
        done: 0,
        total: 1,
        message: "Waiting for a free worker".into(),
    }
}

impl Photo {
    /// A photo from `upload`, waiting for a worker, or held until its analysis is asked
    /// for.
    pub(super) fn new(name: String, upload: work::Upload, held: bool) -> Self {
        let (status, _) = watch::channel(if held { Status::Waiting } else { queued() });
        Photo {
            name,
            status,
            source: Mutex::new(Some(Arc::new(upload))),
            result: Mutex::new(None),
        }
    }

    /// The decoded upload, until the decomposition has succeeded.
    pub(super) fn source(&self) -> std::result::Result<Arc<work::Upload>, ApiError> {
        self.source
            .lock()
            .map_err(poisoned)?
            .clone()
            .ok_or_else(|| {
                ApiError(
                    StatusCode::CONFLICT,
                    "the photo is analysed already: upload it again to point at another object"
                        .into(),
                )
            })
    }

    /// Queues the photo for its analysis if it is held or its last one failed; false if
    /// one is under way or done.
    pub(super) fn queue(&self) -> bool {
        self.status.send_if_modified(|s| {
            let free = matches!(s, Status::Waiting | Status::Failed(_));
            if free {
                *s = queued();
            }
            free
        })
    }
}

/// Photos by id, and their ids oldest first.
type Photos = (HashMap<String, Arc<Photo>>, VecDeque<String>);

/// The photos kept in memory.
pub(super) struct Store {
    photos: Mutex<Photos>,
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

impl Store {
    /// An empty store.
    pub(super) fn new() -> Self {
        Store {
            photos: Mutex::new((HashMap::new(), VecDeque::new())),
        }
    }

    /// Keeps `photo` under a new id, dropping the oldest past `max_photos`; returns the id.
    pub(super) fn add(
        &self,
        photo: Arc<Photo>,
        max_photos: usize,
    ) -> std::result::Result<String, ApiError> {
        let id = new_id()?;
        let mut photos = self.photos.lock().map_err(poisoned)?;
        photos.0.insert(id.clone(), photo);
        photos.1.push_back(id.clone());
        while photos.1.len() > max_photos {
            if let Some(old) = photos.1.pop_front() {
                photos.0.remove(&old);
            }
        }
        Ok(id)
    }

    /// The photo under `id`.
    pub(super) fn find(&self, id: &str) -> std::result::Result<Arc<Photo>, ApiError> {
        self.photos
            .lock()
            .map_err(poisoned)?
            .0
            .get(id)
            .cloned()
            .ok_or_else(|| {
                ApiError(
                    StatusCode::NOT_FOUND,
                    "no such photo (it may have been dropped for newer ones: upload it again)"
                        .into(),
                )
            })
    }

    /// The decomposition of the photo under `id`, once it is done.
    pub(super) fn ready(&self, id: &str) -> std::result::Result<Arc<work::Analysed>, ApiError> {
        let photo = self.find(id)?;
        match &*photo.status.borrow() {
            Status::Failed(m) => return Err(ApiError(StatusCode::CONFLICT, m.clone())),
            Status::Waiting => {
                return Err(ApiError(
                    StatusCode::CONFLICT,
                    "the photo waits for its analysis to be asked for".into(),
                ));
            }
            _ => {}
        }
        let r = photo.result.lock().map_err(poisoned)?.clone();
        r.ok_or_else(|| {
            ApiError(
                StatusCode::CONFLICT,
                "the photo is still being analysed".into(),
            )
        })
    }
}
