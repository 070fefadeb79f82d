//! The live view's HTTP server (axum): the page, its event stream (server-sent events)
//! and the finished images.
//!
//! | path | what |
//! | --- | --- |
//! | `/` | the page (`page.html`, self-contained) |
//! | `/events` | server-sent events: the current frame's log replayed, then new messages |
//! | `/image.png`, `/image.exr` | the finished frame (404 until the render is done) |

use super::board::Board;
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{Html, IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

/// The page: one HTML file with its script and style inline, no external assets.
const PAGE: &str = include_str!("page.html");

/// Longest pause between two batches sent to a page: batches coalesce changes.
const BATCH: Duration = Duration::from_millis(40);

/// The routes over `board`.
pub fn router(board: Arc<Board>) -> Router {
    Router::new()
        .route("/", get(|| async { Html(PAGE) }))
        .route("/events", get(events))
        .route("/image.png", get(|s: State<Arc<Board>>| async move { image(&s, "png") }))
        .route("/image.exr", get(|s: State<Arc<Board>>| async move { image(&s, "exr") }))
        .with_state(board)
}

/// Counts a page in [`Board::watching`] while its stream's task runs.
struct Watching(Arc<Board>);

impl Watching {
    fn new(board: Arc<Board>) -> Watching {
        board.watching.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
        Watching(board)
    }
}

impl Drop for Watching {
    fn drop(&mut self) {
        self.0.watching.fetch_sub(1, std::sync::atomic::Ordering::SeqCst);
    }
}

fn image(board: &Board, kind: &str) -> Response {
    let finals = board.lock().finals.clone();
    let (bytes, mime) = match kind {
        "png" => (finals.png, "image/png"),
        _ => (finals.exr, "image/x-exr"),
    };
    match bytes {
        Some(b) => (
            [
                (header::CONTENT_TYPE, mime.to_string()),
                (header::CONTENT_DISPOSITION, format!("inline; filename=\"magg.{kind}\"")),
                (header::CACHE_CONTROL, "no-store".to_string()),
            ],
            b.as_ref().clone(),
        )
            .into_response(),
        None => (StatusCode::NOT_FOUND, "the render is not finished yet\n").into_response(),
    }
}

/// One page's stream: everything of the current frame so far, then what follows, with
/// the latest stage, node table and light pass preview whenever they change.
async fn events(State(board): State<Arc<Board>>) -> Sse<impl tokio_stream::Stream<Item = Result<Event, Infallible>>> {
    let (tx, rx) = tokio::sync::mpsc::channel::<String>(256);
    let mut version = board.version.subscribe();
    board.viewers.fetch_add(1, std::sync::atomic::Ordering::SeqCst);
    tokio::spawn(async move {
        let _watching = Watching::new(board.clone());
        let (mut epoch, mut sent) = (u64::MAX, 0usize);
        let (mut stage_v, mut nodes_v, mut preview_v, mut done_sent) = (u64::MAX, u64::MAX, u64::MAX, false);
        loop {
            version.borrow_and_update();
            let batch = {
                let s = board.lock();
                if s.epoch != epoch {
                    (epoch, sent) = (s.epoch, 0);
                }
                let mut batch: Vec<String> = s.log[sent.min(s.log.len())..].iter().map(|m| m.to_string()).collect();
                sent = s.log.len();
                if s.stage_version != stage_v {
                    stage_v = s.stage_version;
                    batch.push(s.stage_message());
                }
                if s.nodes_version != nodes_v {
                    nodes_v = s.nodes_version;
                    batch.push(s.nodes_message());
                }
                if s.preview_version != preview_v {
                    preview_v = s.preview_version;
                    batch.extend(s.preview.as_ref().map(|m| m.to_string()));
                }
                if let (Some(done), false) = (&s.done, done_sent) {
                    batch.push(done.clone());
                    done_sent = true;
                }
                batch
            };
            for m in batch {
                if tx.send(m).await.is_err() {
                    return; // the page went away
                }
            }
            if version.changed().await.is_err() {
                return; // the board is gone: the server is stopping
            }
            tokio::time::sleep(BATCH).await;
        }
    });
    let stream =
        tokio_stream::StreamExt::map(tokio_stream::wrappers::ReceiverStream::new(rx), |m| Ok(Event::default().data(m)));
    Sse::new(stream).keep_alive(KeepAlive::default())
}
