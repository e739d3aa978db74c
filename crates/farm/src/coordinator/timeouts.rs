//! How long the HTTP server waits on a client: for a request's headers, and between the
//! pieces of its body. A connection that sends half a request (or claims a body it never
//! sends) is closed, so idle clients cannot hold the coordinator's connections or memory;
//! a slow but steady upload takes as long as it needs.

use std::future::Future;
use std::pin::Pin;
use std::task::{Context, Poll};
use std::time::Duration;

use axum::body::Body;
use axum::extract::{Request, State};
use axum::middleware::Next;
use axum::response::Response;
use bytes::Bytes;
use http_body::{Frame, SizeHint};
use hyper_util::rt::TokioExecutor;
use hyper_util::rt::TokioTimer;
use hyper_util::server::conn::auto::Builder;

/// How long the server waits on a client.
#[derive(Debug, Clone, Copy)]
pub struct Timeouts {
    /// For a request's headers once a connection is ready for one (the first, or the next on
    /// a kept-alive connection): then the connection is closed.
    pub header: Duration,
    /// For the next piece of a request's body: then the request fails.
    pub body_idle: Duration,
}

impl Default for Timeouts {
    fn default() -> Self {
        Timeouts {
            header: Duration::from_secs(10),
            body_idle: Duration::from_secs(30),
        }
    }
}

/// Sets the header timeout on the server's HTTP/1 connections and a keep-alive ping on its
/// HTTP/2 ones.
pub fn configure(builder: &mut Builder<TokioExecutor>, t: Timeouts) {
    builder
        .http1()
        .timer(TokioTimer::new())
        .header_read_timeout(t.header);
    builder
        .http2()
        .timer(TokioTimer::new())
        .keep_alive_interval(t.header)
        .keep_alive_timeout(t.header);
}

/// Middleware: the request's body fails once no piece of it came for `body_idle`.
pub async fn idle_body(State(t): State<Timeouts>, request: Request, next: Next) -> Response {
    let (parts, body) = request.into_parts();
    let body = Body::new(IdleBody {
        inner: body,
        wait: t.body_idle,
        idle: Box::pin(tokio::time::sleep(t.body_idle)),
        ended: false,
    });
    next.run(Request::from_parts(parts, body)).await
}

/// A body whose wait for each frame is bounded; its size hint is the inner body's, so a
/// claimed length over a route's limit is still refused before anything is read.
struct IdleBody {
    inner: Body,
    wait: Duration,
    idle: Pin<Box<tokio::time::Sleep>>,
    ended: bool,
}

impl http_body::Body for IdleBody {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, axum::Error>>> {
        if self.ended {
            return Poll::Ready(None);
        }
        match Pin::new(&mut self.inner).poll_frame(cx) {
            Poll::Ready(frame) => {
                let deadline = tokio::time::Instant::now() + self.wait;
                self.idle.as_mut().reset(deadline);
                Poll::Ready(frame)
            }
            Poll::Pending => match self.idle.as_mut().poll(cx) {
                Poll::Ready(()) => {
                    self.ended = true;
                    Poll::Ready(Some(Err(axum::Error::new(std::io::Error::new(
                        std::io::ErrorKind::TimedOut,
                        format!(
                            "no part of the request body arrived for {:.1} s",
                            self.wait.as_secs_f64()
                        ),
                    )))))
                }
                Poll::Pending => Poll::Pending,
            },
        }
    }

    fn is_end_stream(&self) -> bool {
        self.ended || self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.inner.size_hint()
    }
}
