//! Who may call what: API clients and workers send their bearer token; a browser that logged
//! in to the dashboard sends its session cookie (HttpOnly, SameSite=Strict) and, with every
//! request that changes something, the session's CSRF token in a header. Tokens never travel
//! in URLs. A token is the coordinator's own (client: an admin; worker: any worker) or a
//! user's (`tessera users add`), whose role says what it may do ([`Access`]).

use std::sync::Arc;

use axum::extract::{RawPathParams, Request, State};
use axum::http::{HeaderMap, Method, StatusCode, header};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};

use super::{App, AppError, now_ms};
use crate::protocol::Role;
use crate::store::Session;

/// The session cookie's name.
pub(super) const SESSION_COOKIE: &str = "tessera_session";
/// The header a logged-in page sends its CSRF token in.
pub(super) const CSRF_HEADER: &str = "x-csrf-token";
/// How long a dashboard login lasts.
pub(super) const SESSION_MS: i64 = 12 * 3600 * 1000;

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

/// Who is calling: a token's user or a dashboard session's.
#[derive(Debug, Clone)]
pub struct Caller {
    pub name: String,
    pub role: Role,
    /// A worker's own token, good only for a worker of its name (the coordinator's shared
    /// worker token is good for any).
    pub bound: bool,
}

/// The name the coordinator's own client token acts under (an admin).
pub(super) const ADMIN: &str = "admin";
/// The name the coordinator's shared worker token acts under.
pub(super) const WORKERS: &str = "workers";

impl Caller {
    /// Whether this caller may act as the worker registered under `name`.
    pub(super) fn may_act_as(&self, name: &str) -> bool {
        !self.bound || self.name == name
    }
}

/// What a group of routes asks of its caller (docs/src/farm/roles.md is the table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Access {
    /// Jobs: read by every person; submitted by admins and artists; one job changed by
    /// admins and the artist who submitted it.
    Jobs,
    /// Uploading a scene bundle: admins and artists.
    Submit,
    /// A job's finished frames: admins and the artist who submitted it.
    OwnFrames,
    /// The farm: read by every person, changed (drain, unblock) by admins.
    Farm,
    /// Users and their tokens: admins.
    Admin,
    /// Bundles, artifacts and step inputs, which tasks read: workers and admins.
    Fetch,
    /// Leases, heartbeats, failures and results: workers.
    Work,
}

/// Why a caller may not: None if it may. `owner` is the submitter of the job the route
/// names (`Some(None)`: a job of no known submitter, the admin's); None when it names none
/// or no such job exists (the handler says so).
fn refusal(
    access: Access,
    method: &Method,
    names_job: bool,
    caller: &Caller,
    owner: Option<Option<&str>>,
) -> Option<String> {
    let role = caller.role;
    let person = role != Role::Worker;
    let admin = role == Role::Admin;
    let artist = role == Role::Artist;
    let read = matches!(*method, Method::GET | Method::HEAD);
    // A job that does not exist is the handler's to report (404).
    let own = owner.is_none_or(|o| o.unwrap_or(ADMIN) == caller.name);
    // One row per rule: whether the caller may, what it would do, who may.
    const PEOPLE: &str = "admins, artists and viewers";
    const OWNER: &str = "admins and the artist who submitted the job";
    let (ok, what, who) = match access {
        Access::Jobs if read => (person, "read jobs", PEOPLE),
        Access::Jobs if names_job => (admin || artist && own, "change another's job", OWNER),
        Access::Jobs | Access::Submit => (admin || artist, "submit jobs", "admins and artists"),
        Access::OwnFrames => (admin || artist && own, "download another's frames", OWNER),
        Access::Farm if read => (person, "read the farm's state", PEOPLE),
        Access::Farm => (admin, "change the farm's workers", "admins"),
        Access::Admin => (admin, "manage users", "admins"),
        Access::Fetch => (
            admin || role == Role::Worker,
            "fetch what tasks read",
            "workers and admins",
        ),
        Access::Work => (
            role == Role::Worker,
            "lease tasks or send their results",
            "workers",
        ),
    };
    if ok {
        return None;
    }
    Some(format!(
        "forbidden: {} is a{} {}, which may not {what}; {who} may",
        caller.name,
        if role == Role::Admin || role == Role::Artist {
            "n"
        } else {
            ""
        },
        role.as_str()
    ))
}

/// The caller a bearer token names: the coordinator's own tokens, else a user's live token.
pub(super) fn caller_of_token(app: &App, token: &str) -> Result<Option<Caller>, AppError> {
    let c = &app.config;
    if same(token, &c.client_token) {
        return Ok(Some(Caller {
            name: ADMIN.into(),
            role: Role::Admin,
            bound: false,
        }));
    }
    if same(token, &c.worker_token) {
        return Ok(Some(Caller {
            name: WORKERS.into(),
            role: Role::Worker,
            bound: false,
        }));
    }
    Ok(app
        .store
        .user_of_token(&crate::store::token_hash(token))?
        .map(|(name, role)| Caller {
            name,
            role,
            bound: role == Role::Worker,
        }))
}

/// Middleware: finds the caller (bearer token, or dashboard session and its CSRF token),
/// checks `access` against its role (and, for one job, its submitter), and hands the
/// [`Caller`] to the handler as a request extension.
pub(super) async fn authorize(
    State((app, access)): State<(Arc<App>, Access)>,
    params: RawPathParams,
    mut request: Request,
    next: Next,
) -> Response {
    let caller = match find_caller(&app, access, &request) {
        Ok(c) => c,
        Err(e) => return e.into_response(),
    };
    let job: Option<i64> = params
        .iter()
        .find(|(k, _)| *k == "id")
        .and_then(|(_, v)| v.parse().ok())
        .filter(|_| request.uri().path().starts_with("/v1/jobs/"));
    let needs_owner =
        matches!(access, Access::Jobs | Access::OwnFrames) && caller.role == Role::Artist;
    let owner = match (job, needs_owner) {
        (Some(id), true) => match app.store.job_submitter(id) {
            Ok(o) => o,
            Err(e) => return AppError::from(e).into_response(),
        },
        _ => None,
    };
    if let Some(why) = refusal(
        access,
        request.method(),
        job.is_some(),
        &caller,
        owner.as_ref().map(|o| o.as_deref()),
    ) {
        return AppError::new(StatusCode::FORBIDDEN, why).into_response();
    }
    request.extensions_mut().insert(caller);
    next.run(request).await
}

fn find_caller(app: &App, access: Access, request: &Request) -> Result<Caller, AppError> {
    let given = request
        .headers()
        .get(header::AUTHORIZATION)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.strip_prefix("Bearer "));
    if let Some(t) = given {
        return caller_of_token(app, t)?.ok_or_else(|| {
            AppError::new(
                StatusCode::UNAUTHORIZED,
                "wrong token: not a token of this coordinator (or one that was revoked)",
            )
        });
    }
    if !matches!(access, Access::Work | Access::Fetch)
        && let Some(session) = session_of(app, request.headers())
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
            return Ok(Caller {
                name: session.user,
                role: session.role,
                bound: false,
            });
        }
        return Err(AppError::new(
            StatusCode::FORBIDDEN,
            format!(
                "missing or wrong {CSRF_HEADER} header: a change from the dashboard must carry its session's CSRF token"
            ),
        ));
    }
    Err(AppError::new(
        StatusCode::UNAUTHORIZED,
        "missing token: send \"Authorization: Bearer TOKEN\" (or log in to the dashboard at /login)",
    ))
}
