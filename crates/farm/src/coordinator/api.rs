//! The HTTP API under `/v1`, its OpenAPI document (generated from these handlers), token
//! checks and request size limits.

use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

use axum::Json;
use axum::body::Bytes;
use axum::extract::rejection::{BytesRejection, JsonRejection, QueryRejection};
use axum::extract::{DefaultBodyLimit, Path, Query, Request, State};
use axum::http::{StatusCode, header};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use utoipa::OpenApi;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::error::json_errors;
use super::{App, AppError, AppResult, now_ms};
use crate::bundle::{self, Bundle};
use crate::codec;
use crate::job::{self, FrameRange, PassKind, TaskKind, TaskSpec};
use crate::passes;
use crate::protocol::*;
use crate::store::{CacheEntry, Completion, NewJob, NewPass, PassStart, Retry};

#[derive(OpenApi)]
#[openapi(
    info(title = "Tessera render farm", description = "Submit scenes, watch jobs, fetch OpenEXR frames; workers lease tile tasks."),
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

/// JSON bodies (jobs, leases, heartbeats) are small.
const JSON_LIMIT: usize = 1 << 20;

/// Which token a route wants.
#[derive(Clone, Copy)]
enum Who {
    Client,
    Worker,
    Either,
}

pub fn router(app: Arc<App>) -> axum::Router {
    let auth = |who: Who| middleware::from_fn_with_state((app.clone(), who), require_token);
    let result_limit = codec::encoded_len((job::MAX_TILE * job::MAX_TILE) as usize)
        .max(passes::MAX_OUTPUT_BYTES)
        + 4096;
    let clients = OpenApiRouter::new()
        .routes(routes!(submit_job, list_jobs))
        .routes(routes!(job_status))
        .routes(routes!(job_tasks))
        .routes(routes!(cancel_job))
        .routes(routes!(frame_exr))
        .routes(routes!(frame_preview))
        .routes(routes!(list_workers))
        .layer(DefaultBodyLimit::max(JSON_LIMIT))
        .route_layer(auth(Who::Client));
    let upload = OpenApiRouter::new()
        .routes(routes!(upload_bundle))
        .layer(DefaultBodyLimit::max(app.config.max_upload))
        .route_layer(auth(Who::Client));
    let download = OpenApiRouter::new()
        .routes(routes!(download_bundle))
        .routes(routes!(download_artifact))
        .routes(routes!(sppm_radii))
        .route_layer(auth(Who::Either));
    let workers = OpenApiRouter::new()
        .routes(routes!(lease_task))
        .routes(routes!(heartbeat))
        .routes(routes!(fail_task))
        .layer(DefaultBodyLimit::max(JSON_LIMIT))
        .route_layer(auth(Who::Worker));
    let results = OpenApiRouter::new()
        .routes(routes!(upload_result))
        .layer(DefaultBodyLimit::max(result_limit))
        .route_layer(auth(Who::Worker));
    let open = OpenApiRouter::new()
        .routes(routes!(healthz))
        .routes(routes!(metrics));
    let (router, api) = OpenApiRouter::with_openapi(ApiDoc::openapi())
        .merge(clients)
        .merge(upload)
        .merge(download)
        .merge(workers)
        .merge(results)
        .merge(open)
        .split_for_parts();
    let api = Arc::new(api);
    router
        .route(
            "/v1/openapi.json",
            axum::routing::get(move || {
                let api = api.clone();
                async move { Json(api.as_ref().clone()) }
            }),
        )
        .fallback(|| async { AppError::not_found("no such endpoint; see /v1/openapi.json") })
        .layer(middleware::map_response(json_errors))
        .with_state(app)
}

/// Compares in time independent of where the strings differ.
fn same(a: &str, b: &str) -> bool {
    a.len() == b.len()
        && a.bytes()
            .zip(b.bytes())
            .fold(0u8, |acc, (x, y)| acc | (x ^ y))
            == 0
}

async fn require_token(
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
    let ok = given.is_some_and(|t| match who {
        Who::Client => same(t, &c.client_token),
        Who::Worker => same(t, &c.worker_token),
        Who::Either => same(t, &c.client_token) || same(t, &c.worker_token),
    });
    match (given, ok) {
        (_, true) => next.run(request).await,
        (None, _) => AppError::new(
            StatusCode::UNAUTHORIZED,
            "missing token: send \"Authorization: Bearer TOKEN\"",
        )
        .into_response(),
        (Some(_), _) => AppError::new(
            StatusCode::UNAUTHORIZED,
            match who {
                Who::Worker => "wrong token: this endpoint wants the worker token",
                _ => "wrong token: this endpoint wants the client token",
            },
        )
        .into_response(),
    }
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
    let body = body?;
    let app2 = app.clone();
    let info = tokio::task::spawn_blocking(move || -> AppResult<BundleInfo> {
        let unpacked = Bundle::from_tar(&body).map_err(AppError::bad_request)?;
        let hash = bundle::hash(&body);
        let path = app2.bundle_path(&hash);
        if !path.exists() {
            let tmp = path.with_extension("tmp");
            std::fs::write(&tmp, &body)?;
            std::fs::rename(&tmp, &path)?;
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
    let bytes = tokio::fs::read(app.bundle_path(&hash)).await?;
    Ok(([(header::CONTENT_TYPE, "application/x-tar")], bytes).into_response())
}

/// Download a pass artifact (photon maps, irradiance records) by key.
#[utoipa::path(get, path = "/v1/artifacts/{key}", tag = "workers",
    params(("key" = String, Path, description = "the artifact's key (a SHA-256)")),
    responses((status = 200, content_type = "application/octet-stream", body = Vec<u8>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn download_artifact(
    State(app): State<Arc<App>>,
    Path(key): Path<String>,
) -> AppResult<Response> {
    let entry = if bundle::is_hash(&key) {
        app.cached(&key)?
    } else {
        None
    };
    let Some(entry) = entry else {
        return Err(AppError::not_found(format!("no artifact {key}")));
    };
    let bytes = tokio::fs::read(app.config.data.join(&entry.path)).await?;
    Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
}

/// Download the squared gathering radii (f32 per pixel) that iteration `iteration` of an SPPM
/// frame gathers within; there while that iteration runs.
#[utoipa::path(get, path = "/v1/jobs/{id}/frames/{frame}/sppm/{iteration}/radii", tag = "workers",
    params(("id" = i64, Path), ("frame" = u32, Path), ("iteration" = u32, Path)),
    responses((status = 200, content_type = "application/octet-stream", body = Vec<u8>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn sppm_radii(
    State(app): State<Arc<App>>,
    Path((id, frame, iteration)): Path<(i64, u32, u32)>,
) -> AppResult<Response> {
    let path = app.sppm_path(id, frame, &format!("{iteration}.radii"));
    match tokio::fs::read(&path).await {
        Ok(bytes) => {
            Ok(([(header::CONTENT_TYPE, "application/octet-stream")], bytes).into_response())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Err(AppError::not_found(format!(
            "job {id} frame {frame} has no sppm iteration {iteration} running"
        ))),
        Err(e) => Err(e.into()),
    }
}

/// Submit a job: a bundle's scene, frames, settings and priority. The scene is validated
/// before anything is queued.
#[utoipa::path(post, path = "/v1/jobs", tag = "clients", request_body = JobRequest,
    responses((status = 201, body = JobStatus), (status = 400, body = ErrorBody), (status = 401, body = ErrorBody)),
    security(("token" = [])))]
async fn submit_job(
    State(app): State<Arc<App>>,
    body: Result<Json<JobRequest>, JsonRejection>,
) -> AppResult<(StatusCode, Json<JobStatus>)> {
    let Json(req) = body?;
    if !bundle::is_hash(&req.bundle) || !app.store.bundle_exists(&req.bundle)? {
        return Err(AppError::bad_request(format!(
            "bundle: expected the hash of an uploaded bundle (POST /v1/bundles), got \"{}\"",
            req.bundle
        )));
    }
    let app2 = app.clone();
    let new = tokio::task::spawn_blocking(move || -> AppResult<NewJob> {
        let bytes = std::fs::read(app2.bundle_path(&req.bundle))?;
        let bundle = Bundle::from_tar(&bytes).map_err(AppError::bad_request)?;
        let mut desc = bundle
            .load(&req.scene)
            .map_err(|e| AppError::bad_request(e.to_string()))?;
        let frames = req.frames.unwrap_or(FrameRange {
            first: 1,
            last: desc.frame_count(),
        });
        job::apply(&mut desc, &req.settings, frames, &app2.config.limits)
            .map_err(AppError::bad_request)?;
        let analysis = tessera_render::analysis::analyze(&desc);
        let tasks: Vec<Vec<TaskSpec>> = frames
            .iter()
            .map(|f| job::plan_frame(&desc, &req.settings, f))
            .collect();
        let mut decisions = job::decisions(&desc);
        if crate::bdpt::film_tasks(analysis.integrator) {
            decisions.push(crate::bdpt::decision(&desc, &req.settings));
        }
        if analysis.integrator == tessera_scene::IntegratorKind::Sppm {
            let s = crate::sppm::settings(&desc).1;
            decisions.push(format!(
                "{} — each frame's iterations run in turn (each one's radii come from the one before), each iteration in {} photon tasks",
                s.describe(),
                crate::sppm::iteration_tasks(&desc, frames.first, 0).len()
            ));
        }
        let mut new_passes = Vec::new();
        let reuse = req.settings.reuse.unwrap_or(true);
        let cached = |key: &str| -> AppResult<Option<CacheEntry>> {
            Ok(if reuse { app2.cached(key)? } else { None })
        };
        if let Some(plan) = passes::plan(&desc, &analysis, frames) {
            decisions.extend(plan.decisions.iter().cloned());
            let photons = cached(&plan.photons_key)?;
            decisions.push(match &photons {
                Some(e) => format!(
                    "photon maps: reused — artifact {} ({} bytes) built by job {} has the same geometry, materials, lights and photon settings",
                    &e.key[..12], e.bytes, e.job
                ),
                None => format!(
                    "photon maps: built by this job in {} tasks{}",
                    plan.photon_tasks().len(),
                    if reuse { " (no cached artifact with this key)" } else { " (reuse disabled)" }
                ),
            });
            new_passes.push(NewPass {
                kind: PassKind::Photons,
                key: plan.photons_key.clone(),
                start: if photons.is_some() {
                    PassStart::Reused
                } else {
                    PassStart::Build(plan.photon_tasks())
                },
            });
            if let Some(key) = &plan.records_key {
                let records = if photons.is_some() { cached(key)? } else { None };
                decisions.push(match &records {
                    Some(e) => format!(
                        "irradiance cache: reused — artifact {} built by job {} (same maps, keyframes {:?} and gather settings)",
                        &e.key[..12], e.job, plan.keyframes
                    ),
                    None => format!(
                        "irradiance cache: built by this job from keyframes {:?}, frozen before any frame renders",
                        plan.keyframes
                    ),
                });
                new_passes.push(NewPass {
                    kind: PassKind::Records,
                    key: key.clone(),
                    start: match (&photons, &records) {
                        (Some(_), Some(_)) => PassStart::Reused,
                        (Some(_), None) => PassStart::Build(plan.record_tasks(&desc)),
                        (None, _) => PassStart::Waiting,
                    },
                });
            }
        }
        if let Some(plan) = crate::subsurface::plan(&desc) {
            let cached = cached(&plan.key)?;
            decisions.push(match &cached {
                Some(e) => format!(
                    "subsurface point cloud: reused — artifact {} ({} bytes) built by job {} has the same geometry, materials, lights and irradiance settings",
                    &e.key[..12], e.bytes, e.job
                ),
                None => format!(
                    "subsurface point cloud: built by this job in {} tasks ({} points)",
                    plan.tasks().len(),
                    plan.points
                ),
            });
            new_passes.push(NewPass {
                kind: PassKind::Subsurface,
                key: plan.key.clone(),
                start: if cached.is_some() {
                    PassStart::Reused
                } else {
                    PassStart::Build(plan.tasks())
                },
            });
        }
        // Everything the job will queue: passes, tiles, and every SPPM iteration.
        let mut planned_tasks: u64 = tasks.iter().map(|t| t.len() as u64).sum();
        if analysis.integrator == tessera_scene::IntegratorKind::Sppm {
            planned_tasks *= desc.integrator.spp as u64;
        }
        for p in &new_passes {
            planned_tasks += match &p.start {
                PassStart::Reused => 0,
                PassStart::Build(tasks) => tasks.len() as u64,
                // Only the irradiance cache waits (for the photon maps).
                PassStart::Waiting => passes::plan(&desc, &analysis, frames)
                    .map_or(0, |plan| plan.record_tasks(&desc).len() as u64),
            };
        }
        Ok(NewJob {
            name: req.name.clone().unwrap_or_else(|| desc.name.clone()),
            priority: req.priority,
            bundle: req.bundle.clone(),
            scene: req.scene.clone(),
            settings: req.settings.clone(),
            frames,
            width: desc.film.width,
            height: desc.film.height,
            spp: desc.integrator.spp,
            decisions,
            planned_tasks,
            tasks,
            passes: new_passes,
        })
    })
    .await??;
    let id = app.store.insert_job(&new, now_ms())?;
    let tasks: usize = new.tasks.iter().map(Vec::len).sum();
    tracing::info!(job = id, name = %new.name, frames = %new.frames, tasks, "job queued");
    app.work.notify_waiters();
    let status = app
        .store
        .job(id)?
        .ok_or_else(|| AppError::internal("job vanished"))?;
    Ok((StatusCode::CREATED, Json(status)))
}

/// List jobs, newest first.
#[utoipa::path(get, path = "/v1/jobs", tag = "clients",
    responses((status = 200, body = Vec<JobStatus>)), security(("token" = [])))]
async fn list_jobs(State(app): State<Arc<App>>) -> AppResult<Json<Vec<JobStatus>>> {
    Ok(Json(app.store.jobs()?))
}

fn job_not_found(id: i64) -> AppError {
    AppError::not_found(format!("no job {id}"))
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
        .ok_or_else(|| job_not_found(id))
}

/// Every task of a job with its state and attempts.
#[utoipa::path(get, path = "/v1/jobs/{id}/tasks", tag = "clients",
    params(("id" = i64, Path)), responses((status = 200, body = Vec<TaskStatus>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn job_tasks(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
) -> AppResult<Json<Vec<TaskStatus>>> {
    if !app.store.job_exists(id)? {
        return Err(job_not_found(id));
    }
    Ok(Json(app.store.tasks(id)?))
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
    let Some(job) = app.store.job(id)? else {
        return Err(job_not_found(id));
    };
    if !app.store.cancel(id, now_ms())? {
        return Err(AppError::conflict(format!(
            "job {id} has already ended ({})",
            job.state.as_str()
        )));
    }
    tracing::info!(job = id, "job cancelled");
    app.store
        .job(id)?
        .map(Json)
        .ok_or_else(|| job_not_found(id))
}

fn frame_state(app: &App, id: i64, frame: u32) -> AppResult<String> {
    if !app.store.job_exists(id)? {
        return Err(job_not_found(id));
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
    let bytes = tokio::fs::read(app.frame_path(id, frame)).await?;
    Ok(([(header::CONTENT_TYPE, "image/x-exr")], bytes).into_response())
}

/// A PNG preview of a frame: the tiles done so far (black elsewhere; for SPPM, the estimate
/// after the iterations done so far), or the finished frame.
#[utoipa::path(get, path = "/v1/jobs/{id}/frames/{frame}/preview.png", tag = "clients",
    params(("id" = i64, Path), ("frame" = u32, Path)),
    responses((status = 200, content_type = "image/png", body = Vec<u8>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
async fn frame_preview(
    State(app): State<Arc<App>>,
    Path((id, frame)): Path<(i64, u32)>,
) -> AppResult<Response> {
    let state = frame_state(&app, id, frame)?;
    let bytes = if state == "done" {
        tokio::fs::read(app.frame_path(id, frame).with_extension("png")).await?
    } else {
        let app = app.clone();
        tokio::task::spawn_blocking(move || -> AppResult<Vec<u8>> {
            let scene = app
                .job_scene(id)
                .map_err(|e| AppError::internal(format!("{e:#}")))?;
            let film = scene.desc.film;
            let image = if scene.sppm.is_some() {
                // SPPM: the estimate after the iterations folded so far.
                app.sppm_preview(id, frame, &scene.desc)
                    .map_err(|e| AppError::internal(format!("{e:#}")))?
            } else if scene.bdpt {
                // BDPT: the sample ranges done so far.
                app.bdpt_frame(id, frame, &scene.desc)
                    .map_err(|e| AppError::internal(format!("{e:#}")))?
                    .0
            } else {
                let outputs = app
                    .frame_outputs(id, frame)
                    .map_err(|e| AppError::internal(format!("{e:#}")))?;
                job::stitch(film.width, film.height, &outputs).0
            };
            tessera_render::output::encode_png(&image).map_err(AppError::internal)
        })
        .await??
    };
    Ok(([(header::CONTENT_TYPE, "image/png")], bytes).into_response())
}

/// Workers, with the tasks they hold.
#[utoipa::path(get, path = "/v1/workers", tag = "clients",
    responses((status = 200, body = Vec<WorkerStatus>)), security(("token" = [])))]
async fn list_workers(State(app): State<Arc<App>>) -> AppResult<Json<Vec<WorkerStatus>>> {
    Ok(Json(app.store.workers(now_ms(), alive_ms(&app))?))
}

/// A worker is alive if seen within two lease periods.
fn alive_ms(app: &App) -> i64 {
    2 * app.config.lease_ms as i64
}

/// Lease the next task (priority, then age). Waits up to `wait_ms` for one; 204 if none.
#[utoipa::path(post, path = "/v1/tasks/lease", tag = "workers", request_body = LeaseRequest,
    responses((status = 200, body = LeaseGrant), (status = 204, description = "no task queued")),
    security(("token" = [])))]
async fn lease_task(
    State(app): State<Arc<App>>,
    body: Result<Json<LeaseRequest>, JsonRejection>,
) -> AppResult<Response> {
    let Json(req) = body?;
    let deadline = Instant::now() + Duration::from_millis(req.wait_ms.min(20_000));
    loop {
        // Listen before looking, so a job queued in between is not missed.
        let notified = app.work.notified();
        tokio::pin!(notified);
        notified.as_mut().enable();
        if let Some(grant) = app
            .store
            .lease(&req.worker, now_ms(), app.config.lease_ms)?
        {
            app.metrics.leased.fetch_add(1, Relaxed);
            tracing::debug!(job = grant.job_id, task = grant.task_id, lease = grant.lease, worker = %req.worker.name, "task leased");
            return Ok(Json(grant).into_response());
        }
        let left = deadline.saturating_duration_since(Instant::now());
        let mut stopping = app.stopping.clone();
        if left.is_zero() || *stopping.borrow() {
            return Ok(StatusCode::NO_CONTENT.into_response());
        }
        tokio::select! {
            _ = notified => {}
            _ = tokio::time::sleep(left) => return Ok(StatusCode::NO_CONTENT.into_response()),
            _ = stopping.changed() => return Ok(StatusCode::NO_CONTENT.into_response()),
        }
    }
}

fn stale(task: i64, lease: i64) -> AppError {
    AppError::conflict(format!(
        "lease {lease} is no longer current for task {task} (it expired and the task was reassigned, or the job ended)"
    ))
}

/// Renew a lease. 409 when it is no longer current: stop working on the task.
#[utoipa::path(post, path = "/v1/tasks/{id}/heartbeat", tag = "workers",
    params(("id" = i64, Path)), request_body = Heartbeat,
    responses((status = 200, body = Heartbeat), (status = 409, body = ErrorBody)), security(("token" = [])))]
async fn heartbeat(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
    body: Result<Json<Heartbeat>, JsonRejection>,
) -> AppResult<Json<Heartbeat>> {
    let Json(hb) = body?;
    if app
        .store
        .heartbeat(id, hb.lease, &hb.worker, now_ms(), app.config.lease_ms)?
    {
        Ok(Json(hb))
    } else {
        Err(stale(id, hb.lease))
    }
}

#[derive(Deserialize, utoipa::IntoParams)]
struct ResultQuery {
    /// The lease the result was rendered under.
    lease: i64,
    /// Seconds the worker spent rendering.
    #[serde(default)]
    seconds: f64,
}

/// Upload a task's result (binary tile sums). Accepted only under the task's current lease.
#[utoipa::path(put, path = "/v1/tasks/{id}/result", tag = "workers",
    params(("id" = i64, Path), ResultQuery),
    request_body(content = Vec<u8>, content_type = "application/octet-stream"),
    responses((status = 200, description = "accepted"), (status = 400, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
async fn upload_result(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
    query: Result<Query<ResultQuery>, QueryRejection>,
    body: Result<Bytes, BytesRejection>,
) -> AppResult<StatusCode> {
    let Query(q) = query?;
    let body = body?;
    let Some((job_id, spec)) = app.store.current_lease(id, q.lease)? else {
        app.metrics.stale_results.fetch_add(1, Relaxed);
        tracing::warn!(task = id, lease = q.lease, "stale result dropped");
        return Err(stale(id, q.lease));
    };
    let checked = match spec.kind {
        TaskKind::Tile => codec::decode(&body, &spec).map(|_| ()),
        TaskKind::Sppm => {
            let (w, h) = app
                .store
                .film_size(job_id)?
                .ok_or_else(|| AppError::not_found(format!("no job {job_id}")))?;
            crate::sppm::decode_output(&body, &spec, w * h).map(|_| ())
        }
        TaskKind::Bdpt => crate::bdpt::decode_output(&body, &spec).map(|_| ()),
        _ => passes::decode_output(&body, &spec).map(|_| ()),
    };
    checked.map_err(|e| AppError::bad_request(format!("result of task {id}: {e}")))?;
    let path = app.tile_path(job_id, id, q.lease);
    let dir = path.parent().map(|p| p.to_path_buf());
    let tmp = path.with_extension("tmp");
    tokio::task::spawn_blocking({
        let (tmp, path) = (tmp.clone(), path.clone());
        move || -> std::io::Result<()> {
            if let Some(dir) = dir {
                std::fs::create_dir_all(dir)?;
            }
            std::fs::write(&tmp, &body)?;
            std::fs::rename(&tmp, &path)
        }
    })
    .await??;
    match app.store.complete(id, q.lease, q.seconds, now_ms())? {
        Completion::Stale => {
            let _ = tokio::fs::remove_file(&path).await;
            app.metrics.stale_results.fetch_add(1, Relaxed);
            Err(stale(id, q.lease))
        }
        Completion::Accepted {
            frame_complete,
            pass_complete,
        } => {
            app.metrics.done.fetch_add(1, Relaxed);
            app.metrics.add_tile_seconds(q.seconds);
            tracing::debug!(
                job = job_id,
                task = id,
                seconds = q.seconds,
                "result accepted"
            );
            if let Some(frame) = frame_complete {
                app.spawn_finish_frame(job_id, frame);
            }
            if let Some(pass) = pass_complete {
                app.spawn_finish_pass(job_id, pass);
            }
            Ok(StatusCode::OK)
        }
    }
}

/// Report that a task could not be rendered. It is retried a bounded number of times, then
/// its job fails with this error.
#[utoipa::path(post, path = "/v1/tasks/{id}/fail", tag = "workers",
    params(("id" = i64, Path)), request_body = Failure,
    responses((status = 200, description = "recorded"), (status = 409, body = ErrorBody)), security(("token" = [])))]
async fn fail_task(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
    body: Result<Json<Failure>, JsonRejection>,
) -> AppResult<StatusCode> {
    let Json(f) = body?;
    app.metrics.failed.fetch_add(1, Relaxed);
    match app
        .store
        .fail(id, f.lease, &f.error, now_ms(), app.config.max_attempts)?
    {
        Retry::Stale => Err(stale(id, f.lease)),
        Retry::Requeued => {
            tracing::warn!(task = id, worker = %f.worker, error = %f.error, "task failed; requeued");
            app.work.notify_waiters();
            Ok(StatusCode::OK)
        }
        Retry::JobFailed(message) => {
            tracing::error!(task = id, error = %message, "job failed");
            Ok(StatusCode::OK)
        }
    }
}

/// Liveness: the process serves and its job store answers.
#[utoipa::path(get, path = "/healthz", tag = "service", responses((status = 200, description = "ok")))]
async fn healthz(State(app): State<Arc<App>>) -> AppResult<Json<serde_json::Value>> {
    let g = app.store.gauges()?;
    Ok(Json(
        serde_json::json!({ "status": "ok", "queued": g.queued, "leased": g.leased }),
    ))
}

/// Prometheus metrics: queue depth, tasks leased/done/failed, tile seconds, workers alive.
#[utoipa::path(get, path = "/metrics", tag = "service",
    responses((status = 200, content_type = "text/plain", body = String)))]
async fn metrics(State(app): State<Arc<App>>) -> AppResult<Response> {
    let g = app.store.gauges()?;
    let workers_alive = app
        .store
        .workers(now_ms(), alive_ms(&app))?
        .iter()
        .filter(|w| w.alive)
        .count() as u64;
    let text = app.metrics.render(&g, workers_alive);
    Ok(([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], text).into_response())
}
