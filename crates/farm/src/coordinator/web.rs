//! The browser side of the coordinator: the dashboard (one page of HTML, a stylesheet and a
//! script, compiled into the binary with `include_str!`: no build step, nothing fetched from
//! elsewhere, works offline), its login and logout, and the API's browsable documentation
//! at `/docs` (Swagger UI, its files vendored into the binary by `utoipa-swagger-ui`).
//!
//! The dashboard is plain HTML with a small script that reads the JSON API with the session
//! cookie and follows `/v1/events`: one script the server needs nothing to build, that a
//! reader can read, and fast with a thousand jobs.

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::FormRejection;
use axum::extract::{Form, Path, State};
use axum::http::{HeaderMap, HeaderValue, StatusCode, header};
use axum::response::{IntoResponse, Redirect, Response};
use axum::routing::{get, post};
use serde::{Deserialize, Serialize};

use super::auth::{SESSION_COOKIE, SESSION_MS, caller_of_token, same, session_cookie, session_of};
use super::{App, AppError, AppResult, now_ms, random_token};
use crate::protocol::{ErrorBody, Role};
use crate::store::Session;

const INDEX: &str = include_str!("../../web/index.html");
const LOGIN: &str = include_str!("../../web/login.html");
const APP_JS: &str = include_str!("../../web/app.js");
const APP_CSS: &str = include_str!("../../web/app.css");

/// What the dashboard's pages may load: their own files, the API, images the API makes.
const CSP: &str = "default-src 'none'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; \
     connect-src 'self'; form-action 'self'; frame-ancestors 'none'; base-uri 'none'";

/// The dashboard, its login, its assets and `/docs`.
pub(super) fn routes(app: Arc<App>, api: utoipa::openapi::OpenApi) -> axum::Router<Arc<App>> {
    // No validator: Swagger UI would otherwise send the document to a public service.
    let docs: axum::Router<Arc<App>> = utoipa_swagger_ui::SwaggerUi::new("/docs")
        .url("/v1/openapi.json", api)
        .config(utoipa_swagger_ui::Config::new(["/v1/openapi.json"]).validator_url("none"))
        .into();
    let _ = app;
    axum::Router::new()
        .route("/", get(page))
        .route("/jobs/{id}", get(job_page))
        .route("/workers", get(page))
        .route("/login", get(login_page).post(login))
        .route("/logout", post(logout))
        .route("/assets/{file}", get(asset))
        .merge(docs)
}

/// Headers every HTML page carries.
fn html(body: String, status: StatusCode) -> Response {
    (
        status,
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CONTENT_SECURITY_POLICY, CSP),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::REFERRER_POLICY, "no-referrer"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        body,
    )
        .into_response()
}

/// The dashboard (jobs and workers are views of one page), or the login page without a
/// session.
async fn page(State(app): State<Arc<App>>, headers: HeaderMap) -> Response {
    match session_of(&app, &headers) {
        Some(_) => html(INDEX.to_string(), StatusCode::OK),
        None => Redirect::to("/login").into_response(),
    }
}

async fn job_page(
    State(app): State<Arc<App>>,
    Path(_id): Path<i64>,
    headers: HeaderMap,
) -> Response {
    page(State(app), headers).await
}

/// The dashboard's script and stylesheet.
async fn asset(Path(file): Path<String>) -> Response {
    let (body, kind) = match file.as_str() {
        "app.js" => (APP_JS, "text/javascript; charset=utf-8"),
        "app.css" => (APP_CSS, "text/css; charset=utf-8"),
        _ => return AppError::not_found(format!("no asset {file}")).into_response(),
    };
    (
        [
            (header::CONTENT_TYPE, kind),
            (header::X_CONTENT_TYPE_OPTIONS, "nosniff"),
            (header::CACHE_CONTROL, "no-cache"),
        ],
        body,
    )
        .into_response()
}

/// Text safe inside HTML.
fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
        .replace('\'', "&#39;")
}

fn login_html(error: Option<&str>) -> String {
    let message = error.map_or(String::new(), |e| {
        format!("<p class=\"error\" role=\"alert\">{}</p>", escape(e))
    });
    LOGIN.replace("{{error}}", &message)
}

async fn login_page(State(app): State<Arc<App>>, headers: HeaderMap) -> Response {
    if session_of(&app, &headers).is_some() {
        return Redirect::to("/").into_response();
    }
    html(login_html(None), StatusCode::OK)
}

#[derive(Deserialize)]
struct LoginForm {
    token: String,
}

/// The session cookie: HttpOnly (no script reads it), SameSite=Strict (no other site's page
/// sends it), Secure when served over TLS.
fn cookie(app: &App, value: &str, max_age_s: i64) -> HeaderValue {
    let secure = if app.config.tls.is_some() {
        "; Secure"
    } else {
        ""
    };
    HeaderValue::from_str(&format!(
        "{SESSION_COOKIE}={value}; Path=/; HttpOnly; SameSite=Strict; Max-Age={max_age_s}{secure}"
    ))
    .unwrap_or_else(|_| HeaderValue::from_static("tessera_session=; Max-Age=0"))
}

/// Log in with the client token (a form post: the token never appears in a URL).
async fn login(
    State(app): State<Arc<App>>,
    form: Result<Form<LoginForm>, FormRejection>,
) -> Response {
    let Ok(Form(form)) = form else {
        return html(
            login_html(Some("Expected the client token in the form.")),
            StatusCode::BAD_REQUEST,
        );
    };
    // A person's token: the coordinator's own client token or a user's (not a worker's).
    let caller = match caller_of_token(&app, form.token.trim()) {
        Ok(c) => c.filter(|c| c.role != Role::Worker),
        Err(e) => return e.into_response(),
    };
    let Some(caller) = caller else {
        tracing::warn!("dashboard login with a wrong token");
        // The form again with the reason (a page, not an error: browsers log failed loads).
        return html(
            login_html(Some(
                "That is not a person's token of this coordinator: its client token (printed \
                 when `tessera serve` starts, kept in DIR/tokens.json) or a user's (`tessera \
                 users add`).",
            )),
            StatusCode::OK,
        );
    };
    let (Ok(id), Ok(csrf)) = (random_token(), random_token()) else {
        return AppError::internal("no OS randomness for a session").into_response();
    };
    let now = now_ms();
    let session = Session {
        id,
        csrf,
        expires_ms: now + SESSION_MS,
        user: caller.name,
        role: caller.role,
    };
    if let Err(e) = app.store.insert_session(&session, now) {
        return AppError::from(e).into_response();
    }
    tracing::info!("dashboard login");
    let mut r = Redirect::to("/").into_response();
    r.headers_mut().insert(
        header::SET_COOKIE,
        cookie(&app, &session.id, SESSION_MS / 1000),
    );
    r
}

#[derive(Deserialize)]
struct LogoutForm {
    csrf: String,
}

/// End the session (its CSRF token in the form: another site cannot log a user out).
async fn logout(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
    form: Result<Form<LogoutForm>, FormRejection>,
) -> Response {
    let Some(session) = session_of(&app, &headers) else {
        return Redirect::to("/login").into_response();
    };
    let ok = form.is_ok_and(|Form(f)| same(&f.csrf, &session.csrf));
    if !ok {
        return AppError::new(StatusCode::FORBIDDEN, "logout needs the page's CSRF token")
            .into_response();
    }
    if let Some(id) = session_cookie(&headers)
        && let Err(e) = app.store.delete_session(&id)
    {
        return AppError::from(e).into_response();
    }
    let mut r = Redirect::to("/login").into_response();
    r.headers_mut()
        .insert(header::SET_COOKIE, cookie(&app, "", 0));
    r
}

/// A dashboard session as its page sees it.
#[derive(Debug, Clone, Serialize, Deserialize, utoipa::ToSchema)]
pub struct SessionInfo {
    /// Send it in the `X-CSRF-Token` header with every request that changes something.
    pub csrf: String,
    pub expires_ms: i64,
    /// Whose session it is.
    pub user: String,
    pub role: Role,
}

/// The dashboard session of the request's cookie: its CSRF token (for the page's script).
#[utoipa::path(get, path = "/v1/session", tag = "clients",
    responses((status = 200, body = SessionInfo), (status = 404, body = ErrorBody)))]
pub(super) async fn session(
    State(app): State<Arc<App>>,
    headers: HeaderMap,
) -> AppResult<Json<SessionInfo>> {
    let s = session_of(&app, &headers).ok_or_else(|| {
        AppError::not_found(
            "no dashboard session: log in at /login (API clients use the bearer token)",
        )
    })?;
    Ok(Json(SessionInfo {
        csrf: s.csrf,
        expires_ms: s.expires_ms,
        user: s.user,
        role: s.role,
    }))
}
