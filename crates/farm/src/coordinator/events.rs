//! What changed, as server-sent events (`GET /v1/events`): dashboards listen and fetch again
//! what an event names, instead of polling everything.

use std::convert::Infallible;
use std::sync::Arc;
use std::time::Duration;

use axum::extract::State;
use axum::response::sse::{Event as SseEvent, KeepAlive, Sse};
use futures_util::Stream;

use super::App;
use crate::protocol::Event;

/// Events kept for a slow listener; one that falls further behind is told to fetch
/// everything again (a `resync` event).
pub(super) const CAPACITY: usize = 1024;

impl App {
    /// Tells the dashboards listening that something changed.
    pub(super) fn emit(&self, event: Event) {
        // No listener is not an error.
        let _ = self.events.send(event);
    }
}

/// Server-sent events, one JSON object each (`{"type": "job", "id": 3}`, `{"type":
/// "job_deleted", "id": 3}`, `{"type": "worker", "id": "…"}`), and `resync` (data `{}`) when
/// events were missed: fetch everything again. The stream ends when the coordinator stops.
#[utoipa::path(get, path = "/v1/events", tag = "clients",
    responses((status = 200, content_type = "text/event-stream", body = Event)),
    security(("token" = [])))]
pub(super) async fn events(
    State(app): State<Arc<App>>,
) -> Sse<impl Stream<Item = Result<SseEvent, Infallible>>> {
    let mut rx = app.events.subscribe();
    let mut stopping = app.stopping.clone();
    let stream = async_stream(move |tx| async move {
        loop {
            tokio::select! {
                r = rx.recv() => {
                    let event = match r {
                        Ok(e) => SseEvent::default()
                            .event("change")
                            .json_data(&e)
                            .unwrap_or_else(|_| SseEvent::default().event("resync").data("{}")),
                        Err(tokio::sync::broadcast::error::RecvError::Lagged(_)) => {
                            SseEvent::default().event("resync").data("{}")
                        }
                        Err(tokio::sync::broadcast::error::RecvError::Closed) => break,
                    };
                    if tx.send(Ok(event)).await.is_err() {
                        break;
                    }
                }
                _ = stopping.changed() => break,
            }
        }
    });
    Sse::new(stream).keep_alive(KeepAlive::new().interval(Duration::from_secs(15)))
}

/// A stream fed by `body` through a small channel (the receiving half as a stream).
fn async_stream<T, F, Fut>(body: F) -> impl Stream<Item = T>
where
    T: Send + 'static,
    F: FnOnce(tokio::sync::mpsc::Sender<T>) -> Fut,
    Fut: std::future::Future<Output = ()> + Send + 'static,
{
    let (tx, rx) = tokio::sync::mpsc::channel(16);
    tokio::spawn(body(tx));
    futures_util::stream::unfold(rx, |mut rx| async move { rx.recv().await.map(|v| (v, rx)) })
}
