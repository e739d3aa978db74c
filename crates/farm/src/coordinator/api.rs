//! The HTTP API under `/v1`, its OpenAPI document (generated from these handlers), token
//! checks and request size limits. Worker-facing endpoints are in [`super::tasks`].

use std::sync::Arc;

use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, JsonRejection};
use axum::extract::{DefaultBodyLimit, Path, Query, State};
use axum::http::{StatusCode, header};
use axum::middleware;
use axum::response::{IntoResponse, Response};
use axum::{Extension, Json};
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::auth::{Access, Caller, authorize};
use super::error::json_errors;
use super::tasks::*;
use super::{App, AppError, AppResult, now_ms};
use super::{events, ops, users, web};
use crate::bundle::{self, Bundle};
use crate::job;
use crate::protocol::*;
use crate::store::NewJob;

#[derive(OpenApi)]
#[openapi(
    info(title = "Tessera render farm", description = "Submit scenes, watch jobs, fetch OpenEXR frames; workers lease tasks and upload their results."),
    modifiers(&BearerAuth),
    tags((name = "clients", description = "Jobs, bundles and results (client token)"),
         (name = "workers", description = "Task leases (worker token)"),
         (name = "service", description = "Health and metrics (no token)"))
)]
struct ApiDoc;

struct BearerAuth;

impl utoipa::Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
        if let Some(c) = openapi.components.as_mut() {
            c.add_security_scheme(
                "token",
                SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
            );
        }
    }
}

/// `RenderSettings.integrator` lists the registry's methods (applied once the routes have
/// added their schemas).
struct MethodNames;

impl utoipa::Modify for MethodNames {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        use utoipa::openapi::RefOr;
        use utoipa::openapi::schema::{Object, Schema, SchemaType, Type};
        let Some(components) = openapi.components.as_mut() else {
            return;
        };
        let Some(RefOr::T(Schema::Object(settings))) = components.schemas.get_mut("RenderSettings")
        else {
            return;
        };
        let names: Vec<&str> = tessera_render::method::names();
        let mut field = Object::with_type(SchemaType::from_iter([Type::String, Type::Null]));
        field.enum_values = Some(names.iter().map(|n| (*n).into()).collect());
        field.description = Some(format!(
            "The rendering method (default: the scene's `integrator.type`): {}.",
            names.join(", ")
        ));
        settings
            .properties
            .insert("integrator".into(), RefOr::T(Schema::Object(field)));
    }
}

/// JSON bodies (jobs, leases, heartbeats) are small.
pub(super) const JSON_LIMIT: usize = 1 << 20;

/// Middleware: a request whose `Content-Length` claims more than `limit` bytes is refused
/// (413) before its body is believed; `flag` names the setting that raises the limit.
///
/// The refusal lingers as nginx's `lingering_close` does: up to [`LINGER_BYTES`] of the body
/// are read and dropped, for at most [`LINGER`], before the response and the close. A client
/// that sent a little too much then reads the 413 and its message; closing at once with its
/// body unread resets the connection, and the client sees a broken pipe instead.
async fn claimed_length(
    State((limit, flag)): State<(u64, &'static str)>,
    request: axum::extract::Request,
    next: middleware::Next,
) -> Response {
    let claimed = request
        .headers()
        .get(header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<u64>().ok());
    match claimed {
        Some(n) if n > limit => {
            if n <= LINGER_BYTES {
                linger(request.into_body()).await;
            }
            let mut response = AppError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!(
                    "the request claims a body of {}; this endpoint takes at most {}{flag}",
                    human_size(n),
                    human_size(limit)
                ),
            )
            .into_response();
            response.headers_mut().insert(
                header::CONNECTION,
                header::HeaderValue::from_static("close"),
            );
            response
        }
        _ => next.run(request).await,
    }
}

/// The most of a refused body read before answering (bodies claiming more are answered at once).
const LINGER_BYTES: u64 = 16 << 20;
/// The longest a refused body is read before answering.
const LINGER: std::time::Duration = std::time::Duration::from_secs(2);

/// Reads and drops `body` until it ends, fails or [`LINGER`] passes; one frame at a time.
async fn linger(body: axum::body::Body) {
    use futures_util::StreamExt;
    let mut chunks = body.into_data_stream();
    let _ = tokio::time::timeout(LINGER, async {
        while let Some(Ok(_)) = chunks.next().await {}
    })
    .await;
}

pub fn router(app: Arc<App>) -> axum::Router {
    let auth = |access: Access| middleware::from_fn_with_state((app.clone(), access), authorize);
    let claimed = |limit: u64, flag: &'static str| {
        middleware::from_fn_with_state((limit, flag), claimed_length)
    };
    let json = || claimed(JSON_LIMIT as u64, "");
    let jobs = OpenApiRouter::new()
        .routes(routes!(submit_job, ops::list_jobs))
        .routes(routes!(job_status, delete_job, ops::patch_job))
        .routes(routes!(job_tasks))
        .routes(routes!(ops::job_attempts))
        .routes(routes!(cancel_job))
        .routes(routes!(ops::pause_job))
        .routes(routes!(ops::resume_job))
        .routes(routes!(ops::requeue_job))
        .routes(routes!(frame_preview))
        .layer(DefaultBodyLimit::max(JSON_LIMIT))
        .layer(json())
        .route_layer(auth(Access::Jobs));
    let frames = OpenApiRouter::new()
        .routes(routes!(frame_exr))
        .route_layer(auth(Access::OwnFrames));
    let farm = OpenApiRouter::new()
        .routes(routes!(list_workers))
        .routes(routes!(ops::drain_worker))
        .routes(routes!(ops::undrain_worker))
        .routes(routes!(ops::unblock_worker))
        .routes(routes!(list_methods))
        .routes(routes!(events::events))
        .routes(routes!(web::session))
        .layer(DefaultBodyLimit::max(JSON_LIMIT))
        .layer(json())
        .route_layer(auth(Access::Farm));
    let users = OpenApiRouter::new()
        .routes(routes!(users::list_users, users::add_user))
        .routes(routes!(users::revoke_user))
        .layer(DefaultBodyLimit::max(JSON_LIMIT))
        .layer(json())
        .route_layer(auth(Access::Admin));
    let upload = OpenApiRouter::new()
        .routes(routes!(upload_bundle))
        .layer(DefaultBodyLimit::max(app.config.max_upload))
        .layer(claimed(
            app.config.max_upload as u64,
            " (this coordinator's upload limit for a scene bundle; raise it with `tessera serve --max-upload-mib`)",
        ))
        .route_layer(auth(Access::Submit));
    let download = OpenApiRouter::new()
        .routes(routes!(download_bundle))
        .routes(routes!(download_artifact))
        .routes(routes!(step_input))
        .route_layer(auth(Access::Fetch));
    let workers = OpenApiRouter::new()
        .routes(routes!(lease_task))
        .routes(routes!(heartbeat))
        .routes(routes!(fail_task))
        .layer(DefaultBodyLimit::max(JSON_LIMIT))
        .layer(json())
        .route_layer(auth(Access::Work));
    // Results stream to disk under their own limit (`--max-result-mib`).
    let results = OpenApiRouter::new()
        .routes(routes!(upload_result))
        .layer(DefaultBodyLimit::disable())
        .layer(claimed(
            app.config.max_result,
            " (this coordinator's limit for a task result; raise it with `tessera serve --max-result-mib`)",
        ))
        .route_layer(auth(Access::Work));
    let open = OpenApiRouter::new()
        .routes(routes!(healthz))
        .routes(routes!(metrics));
    let (router, api) = OpenApiRouter::with_openapi(ApiDoc::openapi())
        .merge(jobs)
        .merge(frames)
        .merge(farm)
        .merge(users)
        .merge(upload)
        .merge(download)
        .merge(workers)
        .merge(results)
        .merge(open)
        .split_for_parts();
    let mut api = api;
    utoipa::Modify::modify(&MethodNames, &mut api);
    router
        .merge(web::routes(app.clone(), api))
        .fallback(|| async { AppError::not_found("no such endpoint; see /v1/openapi.json") })
        .layer(middleware::map_response(json_errors))
        .layer(middleware::from_fn_with_state(
            app.config.timeouts,
            super::timeouts::idle_body,
        ))
        .with_state(app)
}

/// Upload a scene bundle: a tar archive of scene.json and the files it references.
#[utoipa::path(post, path = "/v1/bundles", tag = "clients",
    request_body(content = Vec<u8>, content_type = "application/x-tar"),
    responses((status = 201, body = BundleInfo), (status = 400, body = ErrorBody), (status = 413, body = ErrorBody)),
    security(("token" = [])))]
async fn upload_bundle(
    State(app): State<Arc<App>>,
    body: Result<Bytes, BytesRejection>,
) -> AppResult<(StatusCode, Json<BundleInfo>)> {
    let body = body.map_err(|e| {
        if e.status() == StatusCode::PAYLOAD_TOO_LARGE {
            AppError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                format!(
                    "the scene bundle is over this coordinator's upload limit of {}; raise it with `tessera serve --max-upload-mib`",
                    human_size(app.config.max_upload as u64)
                ),
            )
        } else {
            e.into()
        }
    })?;
    let app2 = app.clone();
    let info = tokio::task::spawn_blocking(move || -> AppResult<BundleInfo> {
        let unpacked = Bundle::from_tar(&body).map_err(AppError::bad_request)?;
        let hash = bundle::hash(&body);
        let key = app2.bundle_key(&hash);
        if !app2.objects.exists(&key)? {
            app2.objects.put(&key, body.clone())?;
        }
        app2.store
            .insert_bundle(&hash, body.len() as u64, now_ms())?;
        Ok(BundleInfo {
            hash,
            bytes: body.len() as u64,
            files: unpacked
                .files
                .keys()
                .map(|p| p.to_string_lossy().into_owned())
                .collect(),
        })
    })
    .await??;
    tracing::info!(bundle = %info.hash, bytes = info.bytes, files = info.files.len(), "bundle stored");
    Ok((StatusCode::CREATED, Json(info)))
}

/// Download a bundle (workers fetch the scene of a job once each).
#[utoipa::path(get, path = "/v1/bundles/{hash}", tag = "workers",
    params(("hash" = String, Path, description = "SHA-256 of the bundle")),
    responses((status = 200, content_type = "application/x-tar", body = Vec<u8>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn download_bundle(
    State(app): State<Arc<App>>,
    Path(hash): Path<String>,
) -> AppResult<Response> {
    if !bundle::is_hash(&hash) || !app.store.bundle_exists(&hash)? {
        return Err(AppError::not_found(format!("no bundle {hash}")));
    }
    app.send_object(&app.bundle_key(&hash), "application/x-tar")
        .await?
        .ok_or_else(|| AppError::not_found(format!("bundle {hash} is not in the object store")))
}

/// Submit a job: a bundle's scene, frames, settings and priority. The scene is validated and
/// the job planned by its method before anything is queued; a job that asks for `auto` with no
/// recorded choice is queued with its pilot, a task a worker runs, and planned when that is
/// done (`measuring` until then).
#[utoipa::path(post, path = "/v1/jobs", tag = "clients", request_body = JobRequest,
    responses((status = 201, body = JobStatus), (status = 400, body = ErrorBody), (status = 401, body = ErrorBody)),
    security(("token" = [])))]
async fn submit_job(
    State(app): State<Arc<App>>,
    Extension(caller): Extension<Caller>,
    body: Result<Json<JobRequest>, JsonRejection>,
) -> AppResult<(StatusCode, Json<JobStatus>)> {
    let Json(req) = body?;
    check_tags(&req.require_tags, "require_tags").map_err(AppError::bad_request)?;
    if !bundle::is_hash(&req.bundle) || !app.store.bundle_exists(&req.bundle)? {
        return Err(AppError::bad_request(format!(
            "bundle: expected the hash of an uploaded bundle (POST /v1/bundles), got \"{}\"",
            req.bundle
        )));
    }
    let app2 = app.clone();
    let new = tokio::task::spawn_blocking(move || -> AppResult<NewJob> {
        let bytes = app2
            .objects
            .get(&app2.bundle_key(&req.bundle))?
            .ok_or_else(|| {
                AppError::bad_request(format!("bundle {} is not in the object store", req.bundle))
            })?;
        // Checked and planned from what the job carries; `auto` without a choice is measured
        // later, by its pilot task on a worker.
        let options = job::Options::new(&app2.config.limits);
        let compiled = job::compile_bundled(&bytes, &req.scene, &req.settings, req.frames, options)
            .map_err(AppError::bad_request)?;
        let desc = &compiled.job.desc;
        Ok(NewJob {
            name: req.name.clone().unwrap_or_else(|| desc.name.clone()),
            priority: req.priority,
            bundle: req.bundle.clone(),
            scene: req.scene.clone(),
            frames: compiled.frames,
            width: desc.film.width,
            height: desc.film.height,
            require_tags: req.require_tags.clone(),
            submitter: Some(caller.name),
            measuring: compiled.awaits_choice(),
            work: app2.work(&compiled, &req.settings)?,
        })
    })
    .await??;
    let id = app.store.insert_job(&new, now_ms())?;
    let tasks: usize = new.work.tasks.iter().map(Vec::len).sum();
    tracing::info!(job = id, name = %new.name, method = %new.work.method, frames = %new.frames, tasks, measuring = new.measuring, submitter = new.submitter.as_deref().unwrap_or(""), "job queued");
    app.wake_workers();
    app.emit(Event::Job { id });
    let status = app
        .store
        .job(id)?
        .ok_or_else(|| AppError::internal("job vanished"))?;
    Ok((StatusCode::CREATED, Json(status)))
}

/// A job's state, progress per frame, errors and the decisions made about its scene.
#[utoipa::path(get, path = "/v1/jobs/{id}", tag = "clients",
    params(("id" = i64, Path)), responses((status = 200, body = JobStatus), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn job_status(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
) -> AppResult<Json<JobStatus>> {
    app.store
        .job(id)?
        .map(Json)
        .ok_or_else(|| AppError::no_job(id))
}

/// Delete a job that has ended (done, failed or cancelled) with its frames, results and
/// bundle (if no other job uses it). Cancel a running job first.
#[utoipa::path(delete, path = "/v1/jobs/{id}", tag = "clients",
    params(("id" = i64, Path)),
    responses((status = 204, description = "deleted"), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
async fn delete_job(State(app): State<Arc<App>>, Path(id): Path<i64>) -> AppResult<StatusCode> {
    let Some(state) = app.store.job_state(id)? else {
        return Err(AppError::no_job(id));
    };
    if !state.is_final() {
        return Err(AppError::conflict(format!(
            "job {id} is {}; cancel it (POST /v1/jobs/{id}/cancel) before deleting it",
            state.as_str()
        )));
    }
    let app2 = app.clone();
    tokio::task::spawn_blocking(move || app2.delete_job(id))
        .await?
        .map_err(|e| AppError::internal(format!("deleting job {id}: {e:#}")))?
        .ok_or_else(|| AppError::conflict(format!("job {id} changed while being deleted")))?;
    app.emit(Event::JobDeleted { id });
    Ok(StatusCode::NO_CONTENT)
}

#[derive(serde::Deserialize, utoipa::IntoParams)]
struct TasksQuery {
    /// Only this frame's tasks (0: the passes' tasks).
    frame: Option<u32>,
}

/// Every task of a job (or of one frame) with its state, attempts and result size.
#[utoipa::path(get, path = "/v1/jobs/{id}/tasks", tag = "clients",
    params(("id" = i64, Path), TasksQuery), responses((status = 200, body = Vec<TaskStatus>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn job_tasks(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
    Query(q): Query<TasksQuery>,
) -> AppResult<Json<Vec<TaskStatus>>> {
    if !app.store.job_exists(id)? {
        return Err(AppError::no_job(id));
    }
    Ok(Json(app.store.tasks(id, q.frame)?))
}

/// Cancel a job: queued tasks are dropped, running ones' results ignored.
#[utoipa::path(post, path = "/v1/jobs/{id}/cancel", tag = "clients",
    params(("id" = i64, Path)),
    responses((status = 200, body = JobStatus), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
async fn cancel_job(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
) -> AppResult<Json<JobStatus>> {
    let Some(state) = app.store.job_state(id)? else {
        return Err(AppError::no_job(id));
    };
    if !app.store.cancel(id, now_ms())? {
        return Err(AppError::conflict(format!(
            "job {id} has already ended ({})",
            state.as_str()
        )));
    }
    app.forget_job(id);
    app.emit(Event::Job { id });
    tracing::info!(job = id, "job cancelled");
    app.store
        .job(id)?
        .map(Json)
        .ok_or_else(|| AppError::no_job(id))
}

fn frame_state(app: &App, id: i64, frame: u32) -> AppResult<String> {
    if !app.store.job_exists(id)? {
        return Err(AppError::no_job(id));
    }
    app.store
        .frame_state(id, frame)?
        .ok_or_else(|| AppError::not_found(format!("job {id} has no frame {frame}")))
}

/// Download a finished frame as OpenEXR.
#[utoipa::path(get, path = "/v1/jobs/{id}/frames/{frame}/exr", tag = "clients",
    params(("id" = i64, Path), ("frame" = u32, Path)),
    responses((status = 200, content_type = "image/x-exr", body = Vec<u8>), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
async fn frame_exr(
    State(app): State<Arc<App>>,
    Path((id, frame)): Path<(i64, u32)>,
) -> AppResult<Response> {
    if frame_state(&app, id, frame)? != "done" {
        return Err(AppError::conflict(format!(
            "frame {frame} of job {id} is not finished; its preview is at /v1/jobs/{id}/frames/{frame}/preview.png"
        )));
    }
    let key = app.frame_key(id, frame);
    app.send_object(&key, "image/x-exr")
        .await?
        .ok_or_else(|| AppError::internal(format!("{key} is not in the object store")))
}

/// A PNG preview of a frame: what its results folded so far make, or the finished frame.
/// With several coordinators, the one folding the frame has it; another answers 409 naming it.
#[utoipa::path(get, path = "/v1/jobs/{id}/frames/{frame}/preview.png", tag = "clients",
    params(("id" = i64, Path), ("frame" = u32, Path)),
    responses((status = 200, content_type = "image/png", body = Vec<u8>), (status = 404, body = ErrorBody),
        (status = 409, description = "another coordinator folds the frame", body = ErrorBody)),
    security(("token" = [])))]
async fn frame_preview(
    State(app): State<Arc<App>>,
    Path((id, frame)): Path<(i64, u32)>,
) -> AppResult<Response> {
    let state = frame_state(&app, id, frame)?;
    let bytes = if state == "done" {
        let key = app.preview_key(id, frame);
        let app2 = app.clone();
        tokio::task::spawn_blocking(move || app2.objects.get(&key))
            .await??
            .ok_or_else(|| AppError::internal("the frame's PNG is not in the object store"))?
            .to_vec()
    } else if let Some(job) = (state == "queued")
        .then(|| app.store.job(id))
        .transpose()?
        .flatten()
        .filter(|j| j.measuring)
    {
        // A job awaiting `auto`'s choice has nothing planned to fold: a black frame of the
        // film's size.
        let image = tessera_render::Image::new(job.width, job.height);
        tokio::task::spawn_blocking(move || tessera_render::output::encode_png(&image))
            .await?
            .map_err(AppError::internal)?
    } else {
        let image = app.preview_of(id, frame).await.map_err(|e| match e
            .downcast_ref::<super::fold::FoldedElsewhere>()
        {
            Some(elsewhere) => AppError::conflict(elsewhere.to_string()),
            None => AppError::internal(format!("{e:#}")),
        })?;
        tokio::task::spawn_blocking(move || tessera_render::output::encode_png(&image))
            .await?
            .map_err(AppError::internal)?
    };
    Ok(([(header::CONTENT_TYPE, "image/png")], bytes).into_response())
}

/// Workers, with the tasks they hold.
#[utoipa::path(get, path = "/v1/workers", tag = "clients",
    responses((status = 200, body = Vec<WorkerStatus>)), security(("token" = [])))]
async fn list_workers(State(app): State<Arc<App>>) -> AppResult<Json<Vec<WorkerStatus>>> {
    Ok(Json(app.store.workers(now_ms(), app.alive_ms())?))
}

/// The rendering methods a job may ask for (`settings.integrator`), with what `spp` counts
/// for each and the scene settings it reads.
#[utoipa::path(get, path = "/v1/methods", tag = "clients",
    responses((status = 200, body = Vec<MethodStatus>)), security(("token" = [])))]
async fn list_methods() -> Json<Vec<MethodStatus>> {
    Json(
        tessera_render::method::methods()
            .into_iter()
            .map(|m| MethodStatus {
                name: m.name.into(),
                summary: m.summary.into(),
                spp: m.spp.into(),
                settings: m
                    .settings
                    .iter()
                    .map(|s| SettingStatus {
                        name: s.name.into(),
                        values: s.kind.describe(),
                        doc: s.doc.into(),
                    })
                    .collect(),
            })
            .collect(),
    )
}

/// Liveness: the process serves and its job store answers; with its version and the wire
/// format it reads (a worker must write the same).
#[utoipa::path(get, path = "/healthz", tag = "service", responses((status = 200, description = "ok")))]
async fn healthz(State(app): State<Arc<App>>) -> AppResult<Json<serde_json::Value>> {
    let g = app.store.gauges()?;
    Ok(Json(serde_json::json!({
        "status": "ok",
        "queued": g.queued,
        "leased": g.leased,
        "version": env!("CARGO_PKG_VERSION"),
        "wire": tessera_render::wire::VERSION,
    })))
}

/// Prometheus metrics: queue depth, tasks leased/done/failed, task seconds, result bytes per
/// task and per pixel by method, workers alive.
#[utoipa::path(get, path = "/metrics", tag = "service",
    responses((status = 200, content_type = "text/plain", body = String)))]
async fn metrics(State(app): State<Arc<App>>) -> AppResult<Response> {
    let g = app.store.gauges()?;
    let workers_alive = app
        .store
        .workers(now_ms(), app.alive_ms())?
        .iter()
        .filter(|w| w.alive)
        .count() as u64;
    let text = app.metrics.render(&g, workers_alive);
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response())
}
