//! Steering the farm: the jobs list with its filters and pages, pausing, resuming,
//! requeueing, reprioritising a job, its attempt log; draining a worker and lifting its
//! blocklists.

use std::sync::Arc;

use axum::Json;
use axum::extract::rejection::{JsonRejection, QueryRejection};
use axum::extract::{Path, Query, State};
use serde::Deserialize;

use super::{App, AppError, AppResult, now_ms};
use crate::protocol::*;
use crate::store::JobFilter;

/// Most jobs one page of the list holds.
const MAX_PAGE: u64 = 1000;

#[derive(Deserialize, utoipa::IntoParams)]
pub(super) struct JobsQuery {
    /// Only jobs in these states, comma-separated (queued, running, paused, done, failed,
    /// cancelled).
    state: Option<String>,
    /// Only jobs whose name contains this.
    q: Option<String>,
    /// Jobs per page (default 50, at most 1000).
    limit: Option<u64>,
    /// Jobs to skip.
    offset: Option<u64>,
    /// `newest` (default) first, or `queue`: the order the queue serves them (priority, then
    /// age).
    sort: Option<String>,
}

/// List jobs, newest first (or in queue order), a page at a time, with how many match in all
/// and by state.
#[utoipa::path(get, path = "/v1/jobs", tag = "clients", params(JobsQuery),
    responses((status = 200, body = JobList), (status = 400, body = ErrorBody)), security(("token" = [])))]
pub(super) async fn list_jobs(
    State(app): State<Arc<App>>,
    query: Result<Query<JobsQuery>, QueryRejection>,
) -> AppResult<Json<JobList>> {
    let Query(q) = query?;
    let mut states = Vec::new();
    for s in q
        .state
        .iter()
        .flat_map(|s| s.split(','))
        .filter(|s| !s.is_empty())
    {
        let state = JobState::ALL
            .into_iter()
            .find(|x| x.as_str() == s)
            .ok_or_else(|| {
                let names: Vec<&str> = JobState::ALL.iter().map(|x| x.as_str()).collect();
                AppError::bad_request(format!(
                    "state: expected some of {}, got \"{s}\"",
                    names.join(", ")
                ))
            })?;
        states.push(state);
    }
    let limit = q.limit.unwrap_or(50);
    if !(1..=MAX_PAGE).contains(&limit) {
        return Err(AppError::bad_request(format!(
            "limit: expected 1 to {MAX_PAGE} jobs per page, got {limit}"
        )));
    }
    let queue_order = match q.sort.as_deref() {
        None | Some("newest") => false,
        Some("queue") => true,
        Some(other) => {
            return Err(AppError::bad_request(format!(
                "sort: expected newest or queue, got \"{other}\""
            )));
        }
    };
    let filter = JobFilter {
        states: states.clone(),
        name: q.q.filter(|s| !s.is_empty()),
        offset: q.offset.unwrap_or(0),
        limit: Some(limit),
        queue_order,
    };
    let app2 = app.clone();
    let (jobs, by_state) =
        tokio::task::spawn_blocking(move || app2.store.job_page(&filter)).await??;
    let total = by_state
        .iter()
        .filter(|(s, _)| states.is_empty() || states.iter().any(|x| x.as_str() == s))
        .map(|(_, n)| n)
        .sum();
    Ok(Json(JobList {
        total,
        by_state: by_state.into_iter().collect(),
        jobs,
    }))
}

/// A job's status after a change, and the dashboards told.
fn changed(app: &App, id: i64) -> AppResult<Json<JobStatus>> {
    app.emit(Event::Job { id });
    app.store
        .job(id)?
        .map(Json)
        .ok_or_else(|| AppError::no_job(id))
}

/// A conflict naming the job's state and what the action needs.
fn wrong_state(app: &App, id: i64, needs: &str) -> AppResult<Json<JobStatus>> {
    let state = app
        .store
        .job_state(id)?
        .ok_or_else(|| AppError::no_job(id))?;
    Err(AppError::conflict(format!(
        "job {id} is {}; {needs}",
        state.as_str()
    )))
}

/// Change a job: its priority (its queued tasks move in the queue with it).
#[utoipa::path(patch, path = "/v1/jobs/{id}", tag = "clients", params(("id" = i64, Path)),
    request_body = JobPatch,
    responses((status = 200, body = JobStatus), (status = 400, body = ErrorBody), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn patch_job(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
    body: Result<Json<JobPatch>, JsonRejection>,
) -> AppResult<Json<JobStatus>> {
    let Json(patch) = body?;
    if let Some(p) = patch.priority {
        if !app.store.set_priority(id, p)? {
            return Err(AppError::no_job(id));
        }
        tracing::info!(job = id, priority = p, "priority changed");
        app.wake_workers();
    }
    changed(&app, id)
}

/// Pause a queued or running job: nothing more of it is leased; leased tasks finish.
#[utoipa::path(post, path = "/v1/jobs/{id}/pause", tag = "clients", params(("id" = i64, Path)),
    responses((status = 200, body = JobStatus), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn pause_job(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
) -> AppResult<Json<JobStatus>> {
    if !app.store.pause(id)? {
        return wrong_state(&app, id, "only a queued or running job can be paused");
    }
    tracing::info!(job = id, "job paused");
    changed(&app, id)
}

/// Resume a paused job.
#[utoipa::path(post, path = "/v1/jobs/{id}/resume", tag = "clients", params(("id" = i64, Path)),
    responses((status = 200, body = JobStatus), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn resume_job(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
) -> AppResult<Json<JobStatus>> {
    if !app.store.resume(id)? {
        return wrong_state(&app, id, "only a paused job can be resumed");
    }
    tracing::info!(job = id, "job resumed");
    app.wake_workers();
    changed(&app, id)
}

/// Requeue a failed or cancelled job: its failed and cancelled tasks run again, its earlier
/// failures and blocklist forgotten; what it finished is kept.
#[utoipa::path(post, path = "/v1/jobs/{id}/requeue", tag = "clients", params(("id" = i64, Path)),
    responses((status = 200, body = JobStatus), (status = 404, body = ErrorBody), (status = 409, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn requeue_job(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
) -> AppResult<Json<JobStatus>> {
    let Some(tasks) = app.store.requeue(id, now_ms())? else {
        return wrong_state(&app, id, "only a failed or cancelled job can be requeued");
    };
    app.forget_job(id);
    // Steps whose tasks were all done when the job ended are folded now.
    for key in app.store.finished_steps()? {
        if key.job == id {
            app.spawn_fold(key);
        }
    }
    tracing::info!(job = id, tasks, "job requeued");
    app.wake_workers();
    changed(&app, id)
}

#[derive(Deserialize, utoipa::IntoParams)]
pub(super) struct AttemptsQuery {
    /// At most this many (default 200, at most 10000).
    limit: Option<u64>,
    /// Failures (failed, expired, unreadable) before the others.
    #[serde(default)]
    failures_first: bool,
}

/// A job's attempt log: every lease of its tasks, newest first, with the worker, how it
/// ended and the error.
#[utoipa::path(get, path = "/v1/jobs/{id}/attempts", tag = "clients",
    params(("id" = i64, Path), AttemptsQuery),
    responses((status = 200, body = Vec<AttemptStatus>), (status = 404, body = ErrorBody)),
    security(("token" = [])))]
pub(super) async fn job_attempts(
    State(app): State<Arc<App>>,
    Path(id): Path<i64>,
    query: Result<Query<AttemptsQuery>, QueryRejection>,
) -> AppResult<Json<Vec<AttemptStatus>>> {
    let Query(q) = query?;
    if !app.store.job_exists(id)? {
        return Err(AppError::no_job(id));
    }
    let limit = q.limit.unwrap_or(200).clamp(1, 10_000);
    Ok(Json(app.store.attempts(id, q.failures_first, limit)?))
}

/// A worker's status after a change, and the dashboards told.
fn worker_changed(app: &App, id: &str) -> AppResult<Json<WorkerStatus>> {
    app.emit(Event::Worker { id: id.to_string() });
    app.store
        .workers(now_ms(), app.alive_ms())?
        .into_iter()
        .find(|w| w.id == id)
        .map(Json)
        .ok_or_else(|| AppError::not_found(format!("no worker {id}")))
}

/// Drain a worker: it finishes the tasks it holds and takes no more.
#[utoipa::path(post, path = "/v1/workers/{id}/drain", tag = "clients", params(("id" = String, Path)),
    responses((status = 200, body = WorkerStatus), (status = 404, body = ErrorBody)), security(("token" = [])))]
pub(super) async fn drain_worker(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> AppResult<Json<WorkerStatus>> {
    if !app.store.set_draining(&id, true)? {
        return Err(AppError::not_found(format!("no worker {id}")));
    }
    tracing::info!(worker = %id, "worker draining");
    worker_changed(&app, &id)
}

/// Let a drained worker take work again.
#[utoipa::path(post, path = "/v1/workers/{id}/undrain", tag = "clients", params(("id" = String, Path)),
    responses((status = 200, body = WorkerStatus), (status = 404, body = ErrorBody)), security(("token" = [])))]
pub(super) async fn undrain_worker(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
) -> AppResult<Json<WorkerStatus>> {
    if !app.store.set_draining(&id, false)? {
        return Err(AppError::not_found(format!("no worker {id}")));
    }
    tracing::info!(worker = %id, "worker takes work again");
    app.wake_workers();
    worker_changed(&app, &id)
}

#[derive(Deserialize, utoipa::IntoParams)]
pub(super) struct UnblockQuery {
    /// Only this job's blocklist entry (default: every job's).
    job: Option<i64>,
}

/// Lift a worker's blocklisting: for one job, or for every job.
#[utoipa::path(post, path = "/v1/workers/{id}/unblock", tag = "clients",
    params(("id" = String, Path), UnblockQuery),
    responses((status = 200, body = WorkerStatus), (status = 404, body = ErrorBody)), security(("token" = [])))]
pub(super) async fn unblock_worker(
    State(app): State<Arc<App>>,
    Path(id): Path<String>,
    query: Result<Query<UnblockQuery>, QueryRejection>,
) -> AppResult<Json<WorkerStatus>> {
    let Query(q) = query?;
    let n = app.store.unblock(&id, q.job)?;
    tracing::info!(worker = %id, job = ?q.job, entries = n, "worker's blocklisting lifted");
    if let Some(job) = q.job {
        app.emit(Event::Job { id: job });
    }
    app.wake_workers();
    worker_changed(&app, &id)
}
