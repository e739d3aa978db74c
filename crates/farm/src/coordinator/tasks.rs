//! The worker-facing API: leases, heartbeats, failures, results (streamed to disk, checked,
//! then folded), artifacts and step inputs.

use std::sync::Arc;
use std::sync::atomic::Ordering::Relaxed;
use std::time::{Duration, Instant};

use axum::body::Body;
use axum::extract::rejection::{JsonRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::{Extension, Json};
use futures_util::StreamExt;
use serde::Deserialize;
use tokio::io::AsyncWriteExt;

use super::auth::Caller;
use super::{App, AppError, AppResult, now_ms};
use crate::bundle;
use crate::job::TaskSpec;
use crate::protocol::*;
use crate::store::{Completion, Retry};

/// Lease the next task (priority, then age). Waits up to `wait_ms` for one; 204 if none.
#[utoipa::path(post, path = "/v1/tasks/lease", tag = "workers", request_body = LeaseRequest,
    responses((status = 200, body = LeaseGrant), (status = 204, description = "no task queued"),
        (status = 409, description = "the worker writes another wire format than the coordinator reads (another Tessera build)")),
    security(("token" = [])))]
pub(super) async fn lease_task(
    State(app): State<Arc<App>>,
    Extension(caller): Extension<Caller>,
    body: Result<Json<LeaseRequest>, JsonRejection>,
) -> AppResult<Response> {
    let Json(req) = body?;
    if !caller.may_act_as(&req.worker.name) {
        return Err(AppError::new(
            StatusCode::FORBIDDEN,
            format!(
                "worker.name: this token is worker {}'s, and the request names worker {}",
                caller.name, req.worker.name
            ),
        ));
    }
    check_tags(&req.worker.tags, "worker.tags").map_err(AppError::bad_request)?;
    // Its results would not decode here (or, with a layout of the same shape, decode wrong).
    let wire = tessera_render::wire::VERSION;
    if req.worker.wire != wire {
        return Err(AppError::conflict(format!(
            "worker.wire: worker {} writes wire format {} and this coordinator reads {wire}; run workers of the coordinator's Tessera build",
            req.worker.name, req.worker.wire
        )));
    }
    let deadline = Instant::now() + Duration::from_millis(req.wait_ms.min(20_000));
    loop {
        // Listen before looking, so a job queued in between is not missed.
        let notified = app.work.notified();
        tokio::pin!(notified);
        notified.as_mut().enable();
        if let Some(mut grant) = app
            .store
            .lease(&req.worker, now_ms(), app.config.lease_ms)?
        {
            app.metrics.leased.fetch_add(1, Relaxed);
            grant.max_result_bytes = Some(app.config.max_result);
            let t = &grant.task;
            // A store that cannot say offers the input: the worker's fetch then tells.
            let input = app.input_key(grant.job_id, t.frame, t.step);
            if !t.is_pass() && app.objects.exists_async(&input).await.unwrap_or(true) {
                grant.input = Some(format!(
                    "/v1/jobs/{}/frames/{}/steps/{}/input",
                    grant.job_id, t.frame, t.step
                ));
            }
            tracing::debug!(job = grant.job_id, task = grant.task_id, lease = grant.lease, worker = %req.worker.name, "task leased");
            app.emit(Event::Job { id: grant.job_id });
            app.emit(Event::Worker {
                id: req.worker.id.clone(),
            });
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

/// A size in bytes as people read it.
fn stale(task: i64, lease: i64) -> AppError {
    AppError::conflict(format!(
        "lease {lease} is no longer current for task {task} (it expired and the task was reassigned, or the job ended)"
    ))
}

/// Renew a lease. 409 when it is no longer current: stop working on the task.
#[utoipa::path(post, path = "/v1/tasks/{id}/heartbeat", tag = "workers",
    params(("id" = i64, Path)), request_body = Heartbeat,
    responses((status = 200, body = Heartbeat), (status = 409, body = ErrorBody)), security(("token" = [])))]
pub(super) async fn heartbeat(
    State(app): State<Arc<App>>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<i64>,
    body: Result<Json<Heartbeat>, JsonRejection>,
) -> AppResult<Json<Heartbeat>> {
    let Json(hb) = body?;
    acts_as(&app, &caller, &hb.worker)?;
    if app.store.heartbeat(
        id,
        hb.lease,
        &hb.worker,
        hb.cpu,
        now_ms(),
        app.config.lease_ms,
    )? {
        Ok(Json(hb))
    } else {
        Err(not_holder(&app, id, hb.lease, &hb.worker)?)
    }
}

/// Refuses a worker's own token acting for a worker process registered under another name
/// (the coordinator's shared worker token acts for any).
fn acts_as(app: &App, caller: &Caller, worker_id: &str) -> AppResult<()> {
    if !caller.bound {
        return Ok(());
    }
    match app.store.worker_name(worker_id)? {
        Some(name) if caller.may_act_as(&name) => Ok(()),
        name => Err(AppError::new(
            StatusCode::FORBIDDEN,
            format!(
                "this token is worker {}'s, and worker {worker_id} runs as {}",
                caller.name,
                name.as_deref()
                    .unwrap_or("no worker this coordinator knows")
            ),
        )),
    }
}

/// Why a lease is not `worker`'s to renew, fail or complete: it is not current (409), or it
/// is another worker's (403).
fn not_holder(app: &App, task: i64, lease: i64, worker: &str) -> AppResult<AppError> {
    Ok(match app.store.lease_holder(task, lease)? {
        Some((_, holder)) if holder != worker => AppError::new(
            StatusCode::FORBIDDEN,
            format!("lease {lease} of task {task} is held by worker {holder}, not {worker}"),
        ),
        _ => stale(task, lease),
    })
}

#[derive(Deserialize, utoipa::IntoParams)]
pub(super) struct ResultQuery {
    /// The lease the result was rendered under.
    lease: i64,
    /// Seconds the worker spent rendering.
    #[serde(default)]
    seconds: f64,
}

/// Checks a result written to `path` against the task it is of: a whole wire stream (length
/// and CRC) and nothing after it, of the task's schema, naming the task, whose value decodes
/// and fits the task (its pixels, samples, lengths: what the fold will take). Returns the
/// payload's length.
fn check_result(
    app: &App,
    job: i64,
    spec: &TaskSpec,
    path: &std::path::Path,
) -> anyhow::Result<u64> {
    let file = std::io::BufReader::new(std::fs::File::open(path)?);
    if crate::job::is_pilot(spec) {
        return crate::job::read_choice(spec, file).map(|(_, payload)| payload);
    }
    let plan = app.job_plan(job)?;
    crate::job::check_result(plan.plan.as_ref(), spec, file)
}

/// Upload a task's result: a wire stream (versioned, chunked, zstd-compressed, CRC-checked)
/// naming its task. Accepted only under the task's current lease, and folded into its frame
/// or pass as soon as the results before it are.
#[utoipa::path(put, path = "/v1/tasks/{id}/result", tag = "workers",
    params(("id" = i64, Path), ResultQuery),
    request_body(content = Vec<u8>, content_type = "application/octet-stream"),
    responses((status = 200, description = "accepted"), (status = 400, body = ErrorBody), (status = 409, body = ErrorBody), (status = 413, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn upload_result(
    State(app): State<Arc<App>>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<i64>,
    query: Result<Query<ResultQuery>, QueryRejection>,
    body: Body,
) -> AppResult<StatusCode> {
    let Query(q) = query?;
    if caller.bound
        && let Some((_, holder)) = app.store.lease_holder(id, q.lease)?
    {
        acts_as(&app, &caller, &holder)?;
    }
    let Some((job_id, spec)) = app.store.current_lease(id, q.lease)? else {
        app.metrics.stale_results.fetch_add(1, Relaxed);
        tracing::warn!(task = id, lease = q.lease, "stale result dropped");
        return Err(stale(id, q.lease));
    };
    let key = app.result_key(job_id, id, q.lease);
    let tmp = app.objects.spool_file(&key);
    // Streamed to the spool in the chunks it arrives in, never held whole.
    let mut file = tokio::fs::File::create(&tmp).await?;
    let mut stream = body.into_data_stream();
    let mut written: u64 = 0;
    while let Some(chunk) = stream.next().await {
        let chunk = match chunk {
            Ok(c) => c,
            Err(e) => {
                let _ = tokio::fs::remove_file(&tmp).await;
                return Err(AppError::bad_request(format!(
                    "result of task {id}: the upload broke off after {written} bytes: {e}"
                )));
            }
        };
        written += chunk.len() as u64;
        if written > app.config.max_result {
            drop(file);
            let _ = tokio::fs::remove_file(&tmp).await;
            // Most HTTP clients read no answer before they have sent their whole body: the
            // rest is read and dropped (up to the limit again, at least 64 MiB) so that the
            // client hears why rather than a broken pipe.
            let drain = app.config.max_result.max(64 << 20);
            let mut rest: u64 = 0;
            while let Some(Ok(chunk)) = stream.next().await {
                rest += chunk.len() as u64;
                if rest > drain {
                    break;
                }
            }
            return Err(AppError::new(
                StatusCode::PAYLOAD_TOO_LARGE,
                result_over_limit(id, None, app.config.max_result),
            ));
        }
        file.write_all(&chunk).await?;
    }
    file.flush().await?;
    drop(file);
    let app2 = app.clone();
    let (tmp2, spec2) = (tmp.clone(), spec.clone());
    let checked =
        tokio::task::spawn_blocking(move || check_result(&app2, job_id, &spec2, &tmp2)).await?;
    let payload = match checked {
        Ok(p) => p,
        Err(e) => {
            let _ = tokio::fs::remove_file(&tmp).await;
            return Err(AppError::bad_request(format!("result of task {id}: {e:#}")));
        }
    };
    {
        // Into the object store, where any coordinator folding the frame finds it.
        let (app, key, from) = (app.clone(), key.clone(), tmp.clone());
        let stored = tokio::task::spawn_blocking(move || app.objects.put_file(&key, &from)).await?;
        if let Err(e) = stored {
            let _ = tokio::fs::remove_file(&tmp).await;
            return Err(AppError::unavailable(format!("result of task {id}: {e:#}")));
        }
    }
    match app
        .store
        .complete(id, q.lease, q.seconds, (written, payload), now_ms())?
    {
        Completion::Stale => {
            let app2 = app.clone();
            tokio::task::spawn_blocking(move || app2.discard(&key)).await?;
            app.metrics.stale_results.fetch_add(1, Relaxed);
            Err(stale(id, q.lease))
        }
        Completion::Accepted { step, .. } => {
            let plan = (!crate::job::is_pilot(&spec)).then(|| app.job_plan(job_id));
            let method = match &plan {
                None => "auto",
                Some(Ok(p)) => p.plan.method(),
                Some(Err(_)) => "unknown",
            };
            app.metrics.accepted(
                method,
                &spec.kind,
                (written, payload),
                spec.pixels(),
                q.seconds,
            );
            tracing::debug!(
                job = job_id,
                task = id,
                seconds = q.seconds,
                bytes = written,
                "result accepted"
            );
            app.spawn_fold(step);
            app.emit(Event::Job { id: step.job });
            Ok(StatusCode::OK)
        }
    }
}

/// Report that a task could not be rendered. It is retried a bounded number of times, then
/// its job fails with this error; at once where the failure is `permanent`.
#[utoipa::path(post, path = "/v1/tasks/{id}/fail", tag = "workers",
    params(("id" = i64, Path)), request_body = Failure,
    responses((status = 200, description = "recorded"), (status = 409, body = ErrorBody)), security(("token" = [])))]
pub(super) async fn fail_task(
    State(app): State<Arc<App>>,
    Extension(caller): Extension<Caller>,
    Path(id): Path<i64>,
    body: Result<Json<Failure>, JsonRejection>,
) -> AppResult<StatusCode> {
    let Json(f) = body?;
    acts_as(&app, &caller, &f.worker)?;
    let holder = app.store.lease_holder(id, f.lease)?;
    if holder.as_ref().is_some_and(|(_, w)| *w != f.worker) {
        return Err(not_holder(&app, id, f.lease, &f.worker)?);
    }
    app.metrics.failed.fetch_add(1, Relaxed);
    let job = holder.map(|(job, _)| job);
    let outcome = if f.permanent {
        app.store
            .fail_permanently(id, f.lease, &f.error, now_ms())?
    } else {
        app.store
            .fail(id, f.lease, &f.error, now_ms(), &app.config.retry_policy())?
    };
    if let Some(job) = job {
        app.emit(Event::Job { id: job });
    }
    app.emit(Event::Worker {
        id: f.worker.clone(),
    });
    match outcome {
        Retry::Stale => Err(stale(id, f.lease)),
        Retry::Requeued => {
            tracing::warn!(task = id, ?job, worker = %f.worker, error = %f.error, "task failed; requeued");
            app.wake_workers();
            Ok(StatusCode::OK)
        }
        Retry::JobFailed(message) => {
            tracing::error!(task = id, ?job, error = %message, "job failed");
            if let Some(job) = job {
                app.forget_job(job);
            }
            Ok(StatusCode::OK)
        }
    }
}

/// Download a pass artifact by key (a wire stream).
#[utoipa::path(get, path = "/v1/artifacts/{key}", tag = "workers",
    params(("key" = String, Path, description = "the artifact's key (a SHA-256)")),
    responses((status = 200, content_type = "application/octet-stream", body = Vec<u8>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn download_artifact(
    State(app): State<Arc<App>>,
    Path(key): Path<String>,
) -> AppResult<Response> {
    let entry = match bundle::is_hash(&key) {
        true => app.store.cached(&key)?,
        false => None,
    };
    let Some(entry) = entry else {
        return Err(AppError::not_found(format!("no artifact {key}")));
    };
    app.store.touch(&key, now_ms())?;
    app.send_object(&entry.path, "application/octet-stream")
        .await?
        .ok_or_else(|| AppError::not_found(format!("no artifact {key}")))
}

/// Download what a step of a frame reads besides the artifacts (a wire stream; an SPPM
/// iteration's radii, say); there while the step runs.
#[utoipa::path(get, path = "/v1/jobs/{id}/frames/{frame}/steps/{step}/input", tag = "workers",
    params(("id" = i64, Path), ("frame" = u32, Path), ("step" = u32, Path)),
    responses((status = 200, content_type = "application/octet-stream", body = Vec<u8>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn step_input(
    State(app): State<Arc<App>>,
    Path((id, frame, step)): Path<(i64, u32, u32)>,
) -> AppResult<Response> {
    app.send_object(
        &app.input_key(id, frame, step),
        "application/octet-stream",
    )
    .await?
    .ok_or_else(|| {
        AppError::not_found(format!(
            "job {id} frame {frame} has no input for step {step} (not running, or it reads none)"
        ))
    })
}
