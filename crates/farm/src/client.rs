//! An HTTP client of the coordinator's API, for `tessera submit`, workers and tests.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering::Relaxed};
use std::time::Duration;

use anyhow::Context;
use reqwest::StatusCode;
use serde::de::DeserializeOwned;

use crate::protocol::*;

/// A client of one farm through any of its coordinators: requests go to one of them until it
/// cannot be reached, then to the next (coordinators sharing a store serve the same API).
#[derive(Clone)]
pub struct Client {
    bases: Arc<[String]>,
    /// The index of the coordinator in use, shared by clones.
    current: Arc<AtomicUsize>,
    token: String,
    http: reqwest::Client,
}

/// An answer that was not a success: the status and the coordinator's message.
#[derive(Debug, thiserror::Error)]
#[error("{status}: {message}")]
pub struct ApiError {
    pub status: StatusCode,
    pub message: String,
}

impl Client {
    pub fn new(base: &str, token: &str) -> anyhow::Result<Client> {
        Self::with_ca(base, token, None)
    }

    /// A client of the coordinator at `base` (`http://` or `https://`), or of any of several
    /// separated by commas (`http://a:8720,http://b:8720`); `ca` a PEM file of a private
    /// certificate authority to trust besides the system's (a self-signed coordinator's
    /// certificate, say).
    pub fn with_ca(
        base: &str,
        token: &str,
        ca: Option<&std::path::Path>,
    ) -> anyhow::Result<Client> {
        crate::coordinator::use_ring_for_tls();
        let mut builder = reqwest::Client::builder()
            .connect_timeout(Duration::from_secs(5))
            .timeout(Duration::from_secs(300));
        if let Some(path) = ca {
            let pem = std::fs::read(path)
                .with_context(|| format!("reading the CA certificate {}", path.display()))?;
            let certs = reqwest::Certificate::from_pem_bundle(&pem)
                .with_context(|| format!("{}: expected PEM certificates", path.display()))?;
            anyhow::ensure!(
                !certs.is_empty(),
                "{}: expected PEM certificates, found none",
                path.display()
            );
            for c in certs {
                builder = builder.add_root_certificate(c);
            }
        }
        let http = builder.build().context("cannot create the HTTP client")?;
        let bases: Vec<String> = base
            .split(',')
            .map(|b| b.trim().trim_end_matches('/').to_string())
            .filter(|b| !b.is_empty())
            .collect();
        anyhow::ensure!(
            !bases.is_empty(),
            "the coordinator URL is empty: expected http://host:port (or several, comma-separated)"
        );
        Ok(Client {
            bases: bases.into(),
            current: Arc::new(AtomicUsize::new(0)),
            token: token.to_string(),
            http,
        })
    }

    /// The coordinator in use.
    fn base(&self) -> &str {
        &self.bases[self.current.load(Relaxed) % self.bases.len()]
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base())
    }

    /// `request` sent to the coordinator in use instead of the one it was made for.
    fn rebased(&self, mut request: reqwest::Request) -> Option<reqwest::Request> {
        let url = request.url().as_str();
        let path = self
            .bases
            .iter()
            .filter(|b| url.starts_with(b.as_str()))
            .max_by_key(|b| b.len())
            .map(|b| url[b.len()..].to_string())?;
        *request.url_mut() = reqwest::Url::parse(&format!("{}{path}", self.base())).ok()?;
        Some(request)
    }

    /// After a request to `url` could not reach its coordinator, the next requests go to the
    /// next one (unless another request has moved on already).
    fn fail_over(&self, url: Option<&reqwest::Url>) {
        if self.bases.len() < 2 {
            return;
        }
        let i = self.current.load(Relaxed);
        let failed = &self.bases[i % self.bases.len()];
        if url.is_some_and(|u| u.as_str().starts_with(failed.as_str())) {
            let next = (i + 1) % self.bases.len();
            if self
                .current
                .compare_exchange(i, next, Relaxed, Relaxed)
                .is_ok()
            {
                tracing::warn!(from = %failed, to = %self.bases[next], "coordinator unreachable; using the next");
            }
        }
    }

    fn request(&self, method: reqwest::Method, path: &str) -> reqwest::RequestBuilder {
        self.http
            .request(method, self.url(path))
            .bearer_auth(&self.token)
    }

    /// Sends and turns a non-success status into an [`ApiError`] with the JSON message. A
    /// request that could not connect never reached a coordinator, so it is sent again to the
    /// next one (each is tried once; a streamed body cannot be sent twice).
    async fn send(&self, rb: reqwest::RequestBuilder) -> anyhow::Result<reqwest::Response> {
        let mut request = rb.build()?;
        let mut tries = self.bases.len();
        let response = loop {
            let again = if tries > 1 { request.try_clone() } else { None };
            match self.http.execute(request).await {
                Ok(r) => break r,
                Err(e) if e.is_connect() || e.is_timeout() => {
                    self.fail_over(e.url());
                    match again
                        .filter(|_| e.is_connect())
                        .and_then(|r| self.rebased(r))
                    {
                        Some(next) => {
                            request = next;
                            tries -= 1;
                        }
                        None => return Err(e.into()),
                    }
                }
                Err(e) => return Err(e.into()),
            }
        };
        let status = response.status();
        if status.is_success() {
            return Ok(response);
        }
        let text = response.text().await.unwrap_or_default();
        let message = serde_json::from_str::<ErrorBody>(&text)
            .map(|e| e.error)
            .unwrap_or(text);
        Err(ApiError { status, message }.into())
    }

    async fn json<T: DeserializeOwned>(&self, rb: reqwest::RequestBuilder) -> anyhow::Result<T> {
        Ok(self.send(rb).await?.json().await?)
    }

    pub async fn upload_bundle(&self, tar: Vec<u8>) -> anyhow::Result<BundleInfo> {
        self.json(
            self.request(reqwest::Method::POST, "/v1/bundles")
                .header("content-type", "application/x-tar")
                .body(tar),
        )
        .await
    }

    pub async fn download_bundle(&self, hash: &str) -> anyhow::Result<Vec<u8>> {
        let r = self
            .send(self.request(reqwest::Method::GET, &format!("/v1/bundles/{hash}")))
            .await?;
        Ok(r.bytes().await?.to_vec())
    }

    /// The body of a GET of `path` (an artifact, a step's input).
    pub async fn get_bytes(&self, path: &str) -> anyhow::Result<Vec<u8>> {
        let r = self.send(self.request(reqwest::Method::GET, path)).await?;
        Ok(r.bytes().await?.to_vec())
    }

    /// Every user (admins only).
    pub async fn users(&self) -> anyhow::Result<Vec<User>> {
        self.json(self.request(reqwest::Method::GET, "/v1/users"))
            .await
    }

    /// Adds a user; the answer holds its token, shown only this once.
    pub async fn add_user(&self, user: &NewUser) -> anyhow::Result<AddedUser> {
        self.json(self.request(reqwest::Method::POST, "/v1/users").json(user))
            .await
    }

    /// Revokes a user's token.
    pub async fn revoke_user(&self, name: &str) -> anyhow::Result<User> {
        self.json(self.request(
            reqwest::Method::DELETE,
            &format!("/v1/users/{}", urlencoding::encode(name)),
        ))
        .await
    }

    pub async fn submit(&self, job: &JobRequest) -> anyhow::Result<JobStatus> {
        self.json(self.request(reqwest::Method::POST, "/v1/jobs").json(job))
            .await
    }

    pub async fn job(&self, id: i64) -> anyhow::Result<JobStatus> {
        self.json(self.request(reqwest::Method::GET, &format!("/v1/jobs/{id}")))
            .await
    }

    /// A page of jobs; `query` as `GET /v1/jobs` takes it (`state=running&limit=20`).
    pub async fn jobs(&self, query: &str) -> anyhow::Result<JobList> {
        self.json(self.request(reqwest::Method::GET, &format!("/v1/jobs?{query}")))
            .await
    }

    /// A job's attempts, newest first (failures first if asked), at most `limit`.
    pub async fn attempts(
        &self,
        id: i64,
        failures_first: bool,
        limit: u64,
    ) -> anyhow::Result<Vec<AttemptStatus>> {
        self.json(self.request(
            reqwest::Method::GET,
            &format!("/v1/jobs/{id}/attempts?failures_first={failures_first}&limit={limit}"),
        ))
        .await
    }

    /// `POST /v1/jobs/{id}/{action}`: pause, resume, requeue.
    pub async fn job_action(&self, id: i64, action: &str) -> anyhow::Result<JobStatus> {
        self.json(self.request(reqwest::Method::POST, &format!("/v1/jobs/{id}/{action}")))
            .await
    }

    pub async fn patch_job(&self, id: i64, patch: &JobPatch) -> anyhow::Result<JobStatus> {
        self.json(
            self.request(reqwest::Method::PATCH, &format!("/v1/jobs/{id}"))
                .json(patch),
        )
        .await
    }

    /// Drains a worker, or lets it take work again.
    pub async fn drain(&self, worker: &str, drain: bool) -> anyhow::Result<WorkerStatus> {
        let action = if drain { "drain" } else { "undrain" };
        self.json(self.request(
            reqwest::Method::POST,
            &format!("/v1/workers/{}/{action}", urlencoding::encode(worker)),
        ))
        .await
    }

    /// Lifts a worker's blocklisting for `job`, or for every job.
    pub async fn unblock(&self, worker: &str, job: Option<i64>) -> anyhow::Result<WorkerStatus> {
        let query = job.map_or(String::new(), |j| format!("?job={j}"));
        self.json(self.request(
            reqwest::Method::POST,
            &format!("/v1/workers/{}/unblock{query}", urlencoding::encode(worker)),
        ))
        .await
    }

    pub async fn tasks(&self, id: i64) -> anyhow::Result<Vec<TaskStatus>> {
        self.json(self.request(reqwest::Method::GET, &format!("/v1/jobs/{id}/tasks")))
            .await
    }

    pub async fn workers(&self) -> anyhow::Result<Vec<WorkerStatus>> {
        self.json(self.request(reqwest::Method::GET, "/v1/workers"))
            .await
    }

    pub async fn cancel(&self, id: i64) -> anyhow::Result<JobStatus> {
        self.json(self.request(reqwest::Method::POST, &format!("/v1/jobs/{id}/cancel")))
            .await
    }

    pub async fn frame_exr(&self, id: i64, frame: u32) -> anyhow::Result<Vec<u8>> {
        let r = self
            .send(self.request(
                reqwest::Method::GET,
                &format!("/v1/jobs/{id}/frames/{frame}/exr"),
            ))
            .await?;
        Ok(r.bytes().await?.to_vec())
    }

    pub async fn frame_preview(&self, id: i64, frame: u32) -> anyhow::Result<Vec<u8>> {
        let r = self
            .send(self.request(
                reqwest::Method::GET,
                &format!("/v1/jobs/{id}/frames/{frame}/preview.png"),
            ))
            .await?;
        Ok(r.bytes().await?.to_vec())
    }

    /// Leases a task, waiting up to `wait_ms`; `None` when none was queued.
    pub async fn lease(&self, req: &LeaseRequest) -> anyhow::Result<Option<LeaseGrant>> {
        let r = self
            .send(
                self.request(reqwest::Method::POST, "/v1/tasks/lease")
                    .json(req),
            )
            .await?;
        if r.status() == StatusCode::NO_CONTENT {
            return Ok(None);
        }
        Ok(Some(r.json().await?))
    }

    pub async fn heartbeat(&self, task: i64, hb: &Heartbeat) -> anyhow::Result<()> {
        self.send(
            self.request(
                reqwest::Method::POST,
                &format!("/v1/tasks/{task}/heartbeat"),
            )
            .json(hb),
        )
        .await?;
        Ok(())
    }

    /// Streams a task's result (a wire stream in the file at `path`) to the coordinator.
    pub async fn upload_result(
        &self,
        task: i64,
        lease: i64,
        seconds: f64,
        path: &std::path::Path,
    ) -> anyhow::Result<()> {
        let file = tokio::fs::File::open(path)
            .await
            .with_context(|| path.display().to_string())?;
        let len = file.metadata().await?.len();
        let body = reqwest::Body::wrap_stream(tokio_util::io::ReaderStream::new(file));
        self.send(
            self.request(
                reqwest::Method::PUT,
                &format!("/v1/tasks/{task}/result?lease={lease}&seconds={seconds}"),
            )
            .header("content-type", "application/octet-stream")
            .header("content-length", len)
            .body(body),
        )
        .await?;
        Ok(())
    }

    /// Deletes a job that has ended.
    pub async fn delete(&self, id: i64) -> anyhow::Result<()> {
        self.send(self.request(reqwest::Method::DELETE, &format!("/v1/jobs/{id}")))
            .await?;
        Ok(())
    }

    pub async fn methods(&self) -> anyhow::Result<Vec<MethodStatus>> {
        self.json(self.request(reqwest::Method::GET, "/v1/methods"))
            .await
    }

    pub async fn fail(&self, task: i64, failure: &Failure) -> anyhow::Result<()> {
        self.send(
            self.request(reqwest::Method::POST, &format!("/v1/tasks/{task}/fail"))
                .json(failure),
        )
        .await?;
        Ok(())
    }
}

/// Whether an error is worth retrying: the coordinator could not be reached or answered 5xx
/// (a restart, say), as opposed to a 4xx verdict.
pub fn is_transient(e: &anyhow::Error) -> bool {
    match e.downcast_ref::<ApiError>() {
        Some(api) => api.status.is_server_error(),
        None => e.downcast_ref::<reqwest::Error>().is_some(),
    }
}

/// The status of an API error, if it was one.
pub fn status_of(e: &anyhow::Error) -> Option<StatusCode> {
    e.downcast_ref::<ApiError>().map(|a| a.status)
}
