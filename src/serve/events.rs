//! A photo's decomposition in the background, one at a time per worker, and its progress
//! streamed to the page as server-sent events.

use std::convert::Infallible;
use std::sync::Arc;

use axum::extract::{Path, State};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use serde_json::json;

use super::App;
use super::reply::ApiError;
use super::store::{Photo, Status};
use super::work;
use crate::edit::photo::PhotoOptions;

/// Decomposes a queued photo ([`Photo::queue`]) with its object at `target` on the blocking
/// pool when a worker is free; its status follows. The decoded upload is let go once the
/// decomposition has succeeded.
pub(super) async fn run_job(app: Arc<App>, photo: Arc<Photo>, target: work::Target) {
    let name = photo.name.clone();
    let Ok(_permit) = app.jobs.acquire().await else {
        return;
    };
    let image = match photo.source() {
        Ok(s) => s.photo.clone(),
        Err(e) => {
            photo
                .status
                .send_replace(Status::Failed(format!("{name}: {}", e.1)));
            return;
        }
    };
    let (a, p) = (app.clone(), photo.clone());
    let result = tokio::task::spawn_blocking(move || {
        let options = PhotoOptions {
            steps: a.config.steps,
            ..PhotoOptions::default()
        };
        work::analyse(
            &a.renderer,
            &a.nets,
            image,
            &target,
            &options,
            &mut |stage| {
                let (stage, done, total, message) = work::describe(stage);
                p.status.send_replace(Status::Progress {
                    stage,
                    done,
                    total,
                    message,
                });
            },
        )
    })
    .await;
    let status = match result {
        Ok(Ok(analysed)) => {
            let report = analysed.report.clone();
            if let Ok(mut r) = photo.result.lock() {
                *r = Some(Arc::new(analysed));
            }
            if let Ok(mut s) = photo.source.lock() {
                *s = None;
            }
            Status::Ready(report)
        }
        Ok(Err(e)) => Status::Failed(format!("{name}: {e}")),
        Err(e) => Status::Failed(format!("{name}: internal error: {e}")),
    };
    photo.status.send_replace(status);
}

/// `GET /api/photos/{id}/events`: the status now and each change, until ready or failed.
pub(super) async fn events(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> std::result::Result<Response, ApiError> {
    let photo = app.photos.find(&id)?;
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
                Status::Waiting => (
                    Event::default().event("progress").data(
                        json!({"stage": "waiting", "done": 0, "total": 1,
                            "message": "Waiting for the analysis to be asked for"})
                        .to_string(),
                    ),
                    false,
                ),
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
