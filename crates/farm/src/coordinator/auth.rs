//! Who may call what: API clients and workers send their bearer token; a browser that logged
//! in to the dashboard sends its session cookie (HttpOnly, SameSite=Strict) and, with every
//! request that changes something, the session's CSRF token in a header. Tokens never travel
//! in URLs.

use std::sync::Arc;

use axum::extract::{Request, State};
use axum::http::{HeaderMap, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::{App, AppError, now_ms};
use crate::store::Session;

/// The session cookie's name.
pub(super) const SESSION_COOKIE: &str = "tessera_session";
/// The header a logged-in page sends its CSRF token in.
pub(super) const CSRF_HEADER: &str = "x-csrf-token";
/// How long a dashboard login lasts.
pub(super) const SESSION_MS: i64 = 12 * 3600 * 1000;

/// Which token a route wants.
#[derive(Clone, Copy)]
pub(super) enum Who {
    /// The client token, or a dashboard session.
    Client,
    Worker,
    /// Either token, or a dashboard session.
    Either,
}

/// Compares in time independent of where the strings differ.
pub(super) fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

/// The session id the request's cookie carries, if any.
pub(super) fn session_cookie(headers: &HeaderMap) -> Option<String> {
    headers
        .get_all(header::COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(';'))
        .filter_map(|c| c.trim().split_once('='))
        .find(|(k, _)| *k == SESSION_COOKIE)
        .map(|(_, v)| v.to_string())
}

/// The live session the request's cookie names.
pub(super) fn session_of(app: &App, headers: &HeaderMap) -> Option<Session> {
    let id = session_cookie(headers)?;
    app.store.session(&id, now_ms()).ok().flatten()
}

pub(super) async fn require_token(
    State((app, who)): State<(Arc<App>, Who)>,
    request: Request,
    next: Next,
) -> Response {
    let given = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "));
    let c = &app.config;
    if let Some(t) = given {
        let ok = match who {
            Who::Client => same(t, &c.client_token),
            Who::Worker => same(t, &c.worker_token),
            Who::Either => same(t, &c.client_token) || same(t, &c.worker_token),
        };
        return if ok {
            next.run(request).await
        } else {
            AppError::new(
                StatusCode::UNAUTHORIZED,
                match who {
                    Who::Worker => "wrong token: this endpoint wants the worker token",
                    _ => "wrong token: this endpoint wants the client token",
                },
            )
            .into_response()
        };
    }
    if !matches!(who, Who::Worker)
        && let Some(session) = session_of(&app, request.headers())
    {
        // A change made with the cookie must carry the page's CSRF token: another site can
        // make the browser send the cookie (were SameSite not honoured), not read the token.
        let safe = matches!(*request.method(), Method::GET | Method::HEAD);
        let csrf_ok = request
            .headers()
            .get(CSRF_HEADER)
            .and_then(|v| v.to_str().ok())
            .is_some_and(|t| same(t, &session.csrf));
        if safe || csrf_ok {
            return next.run(request).await;
        }
        return AppError::new(
            StatusCode::FORBIDDEN,
            format!("missing or wrong {CSRF_HEADER} header: a change from the dashboard must carry its session's CSRF token"),
        )
        .into_response();
    }
    AppError::new(
        StatusCode::UNAUTHORIZED,
        "missing token: send \"Authorization: Bearer TOKEN\" (or log in to the dashboard at /login)",
    )
    .into_response()
}
