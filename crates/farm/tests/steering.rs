//! Steering a coordinator through its API, on loopback, with a simulated worker (its lease
//! and failure calls, no rendering): the jobs list's filters, pages and queue order; pause,
//! resume, priority, cancel, requeue and the attempt log; drain; server-sent events; and the
//! dashboard's login, session cookie, CSRF check, logout and `/docs`.

mod common;

use common::{CLIENT, WORKER, config};

use std::path::PathBuf;
use std::time::Duration;

use futures_util::StreamExt;
use reqwest::StatusCode;
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::coordinator::{self, Running};
use tessera_farm::protocol::{
    Event, Failure, JobList, JobPatch, JobRequest, JobState, LeaseRequest, WorkerInfo,
};

async fn start(dir: &std::path::Path) -> Running {
    coordinator::start(config(dir)).await.expect("coordinator")
}

const SCENE: &str = r#"{
  "units": "m",
  "camera": { "type": "pinhole", "position": [0.5, 0.5, -2], "look_at": [0.5, 0.5, 0], "fov_deg": 40 },
  "film": { "width": 16, "height": 16 },
  "integrator": { "type": "path", "spp": 1 },
  "materials": { "white": { "type": "diffuse", "albedo": 0.5 } },
  "lights": [ { "type": "point", "position": [0.5, 0.5, -1], "intensity": 1 } ],
  "shapes": [ { "type": "sphere", "center": [0.5, 0.5, 0], "radius": 0.3, "material": "white" } ]
}"#;

/// Uploads the scene and submits `n` jobs named `job 0`, `job 1`, …; their ids.
async fn submit(client: &Client, n: usize, tags: &[&str]) -> Vec<i64> {
    let tar = Bundle {
        files: [(PathBuf::from("scene.json"), SCENE.as_bytes().to_vec())].into(),
    }
    .to_tar()
    .expect("tar");
    let bundle = client.upload_bundle(tar).await.expect("upload").hash;
    let mut ids = Vec::new();
    for i in 0..n {
        let job = client
            .submit(&JobRequest {
                bundle: bundle.clone(),
                scene: "scene.json".into(),
                name: Some(format!("job {i}")),
                frames: None,
                settings: Default::default(),
                priority: 0,
                require_tags: tags.iter().map(|t| t.to_string()).collect(),
            })
            .await
            .expect("submit");
        ids.push(job.id);
    }
    ids
}

fn worker(id: &str, tags: &[&str]) -> LeaseRequest {
    LeaseRequest {
        worker: WorkerInfo {
            tags: tags.iter().map(|t| t.to_string()).collect(),
            cpu: Some(0.5),
            ..WorkerInfo::simulated(id)
        },
        wait_ms: 0,
    }
}

#[tokio::test]
async fn jobs_are_listed_by_state_name_and_page_in_either_order() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let client = Client::new(&format!("http://{}", running.addr), CLIENT).expect("client");
    let ids = submit(&client, 5, &[]).await;
    client.cancel(ids[1]).await.expect("cancel");
    let page: JobList = client.jobs("limit=2").await.expect("list");
    assert_eq!(page.total, 5);
    assert_eq!(
        page.jobs.iter().map(|j| j.id).collect::<Vec<_>>(),
        [ids[4], ids[3]]
    );
    assert_eq!(page.by_state.get("queued"), Some(&4));
    assert_eq!(page.by_state.get("cancelled"), Some(&1));
    let next: JobList = client.jobs("limit=2&offset=2").await.expect("list");
    assert_eq!(
        next.jobs.iter().map(|j| j.id).collect::<Vec<_>>(),
        [ids[2], ids[1]]
    );
    let cancelled: JobList = client.jobs("state=cancelled").await.expect("list");
    assert_eq!((cancelled.total, cancelled.jobs[0].id), (1, ids[1]));
    let named: JobList = client.jobs("q=job%203").await.expect("list");
    assert_eq!((named.total, named.jobs[0].id), (1, ids[3]));
    // Queue order: priority, then age; a raised job comes first.
    client
        .patch_job(ids[2], &JobPatch { priority: Some(4) })
        .await
        .expect("priority");
    let queue: JobList = client.jobs("sort=queue&state=queued").await.expect("list");
    assert_eq!(
        queue.jobs.iter().map(|j| j.id).collect::<Vec<_>>(),
        [ids[2], ids[0], ids[3], ids[4]]
    );
    for bad in ["state=sleeping", "limit=0", "limit=5000", "sort=random"] {
        let e = client.jobs(bad).await.expect_err(bad).to_string();
        assert!(e.contains("400"), "{bad}: {e}");
    }
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn pause_resume_fail_requeue_drain_and_tags_steer_what_a_worker_leases() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let workers = Client::new(&url, WORKER).expect("worker client");
    let ids = submit(&client, 1, &[]).await;
    let tagged = submit(&client, 1, &["gpu"]).await[0];
    let job = ids[0];

    // Paused: nothing of it is leased; resumed: it is.
    assert_eq!(
        client.job_action(job, "pause").await.expect("pause").state,
        JobState::Paused
    );
    let e = client.job_action(job, "pause").await.expect_err("twice");
    assert!(e.to_string().contains("409"), "{e}");
    assert!(
        workers
            .lease(&worker("w", &[]))
            .await
            .expect("lease")
            .is_none()
    );
    assert_eq!(
        client
            .job_action(job, "resume")
            .await
            .expect("resume")
            .state,
        JobState::Queued
    );
    // The tagged job goes only to a worker with its tag.
    let g = workers
        .lease(&worker("w", &[]))
        .await
        .expect("lease")
        .expect("a task");
    assert_eq!(g.job_id, job);

    // Failed three times (max attempts), the job fails with the worker's error; the
    // attempt log has each failure, newest first.
    let (mut grant, mut holder) = (g, "w");
    for i in 0..3 {
        workers
            .fail(
                grant.task_id,
                &Failure {
                    lease: grant.lease,
                    worker: holder.into(),
                    error: format!("disk full {i}"),
                    permanent: false,
                },
            )
            .await
            .expect("fail");
        if i < 2 {
            holder = "w2";
            grant = workers
                .lease(&worker("w2", &[]))
                .await
                .expect("lease")
                .expect("the task again");
        }
    }
    let failed = client.job(job).await.expect("job");
    assert_eq!(failed.state, JobState::Failed);
    assert!(
        failed
            .error
            .as_deref()
            .unwrap_or("")
            .contains("disk full 2")
    );
    let attempts = client.attempts(job, true, 10).await.expect("attempts");
    assert_eq!(
        attempts
            .iter()
            .filter_map(|a| a.error.clone())
            .collect::<Vec<_>>(),
        ["disk full 2", "disk full 1", "disk full 0"]
    );
    // Requeued, it runs again.
    let again = client.job_action(job, "requeue").await.expect("requeue");
    assert!(matches!(again.state, JobState::Running | JobState::Queued));
    assert!(again.error.is_none());
    // A drained worker leases nothing; undrained it does.
    client.drain("w2", true).await.expect("drain");
    assert!(
        workers
            .lease(&worker("w2", &[]))
            .await
            .expect("lease")
            .is_none()
    );
    let w = client.drain("w2", false).await.expect("undrain");
    assert!(!w.draining);
    assert_eq!(
        workers
            .lease(&worker("w2", &[]))
            .await
            .expect("lease")
            .map(|g| g.job_id),
        Some(job)
    );
    // Only a worker with the tag gets the tagged job's tasks: "w3" takes the rest of the
    // first job's and then nothing.
    while let Some(g) = workers.lease(&worker("w3", &["cpu"])).await.expect("lease") {
        assert_eq!(g.job_id, job, "a worker without the tag got the tagged job");
    }
    assert_eq!(
        workers
            .lease(&worker("w4", &["gpu", "big"]))
            .await
            .expect("lease")
            .map(|g| g.job_id),
        Some(tagged)
    );
    let listed = client.workers().await.expect("workers");
    let w4 = listed.iter().find(|w| w.id == "w4").expect("w4");
    assert_eq!(
        (w4.tags.clone(), w4.cpu),
        (vec!["gpu".into(), "big".into()], Some(0.5))
    );
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn events_tell_a_listener_what_changed() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let http = reqwest::Client::new();
    let r = http
        .get(format!("{url}/v1/events"))
        .bearer_auth(CLIENT)
        .send()
        .await
        .expect("events");
    assert_eq!(r.status(), StatusCode::OK);
    assert!(
        r.headers()["content-type"]
            .to_str()
            .unwrap_or("")
            .starts_with("text/event-stream")
    );
    let mut stream = r.bytes_stream();
    let id = submit(&client, 1, &[]).await[0];
    let mut text = String::new();
    let wanted = Event::Job { id };
    let found = tokio::time::timeout(Duration::from_secs(10), async {
        while let Some(chunk) = stream.next().await {
            text += &String::from_utf8_lossy(&chunk.expect("chunk"));
            for data in text.lines().filter_map(|l| l.strip_prefix("data: ")) {
                if serde_json::from_str::<Event>(data).ok().as_ref() == Some(&wanted) {
                    return true;
                }
            }
        }
        false
    })
    .await;
    assert_eq!(found, Ok(true), "no job event in {text:?}");
    // The stream ends when the coordinator stops (a graceful stop does not hang on it).
    tokio::time::timeout(Duration::from_secs(20), running.stop())
        .await
        .expect("stops with a listener")
        .expect("stop");
}

#[tokio::test]
async fn the_dashboard_logs_in_with_a_cookie_checks_csrf_and_logs_out() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let url = format!("http://{}", running.addr);
    let http = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .expect("http");
    // Without a session: the pages send the browser to log in; the API says 401.
    let r = http.get(format!("{url}/")).send().await.expect("get /");
    assert_eq!(r.status(), StatusCode::SEE_OTHER);
    assert_eq!(r.headers()["location"], "/login");
    let login = http
        .get(format!("{url}/login"))
        .send()
        .await
        .expect("login page");
    assert_eq!(login.status(), StatusCode::OK);
    let csp = login.headers()["content-security-policy"]
        .to_str()
        .unwrap_or("")
        .to_string();
    assert!(
        csp.contains("script-src 'self'") && csp.contains("frame-ancestors 'none'"),
        "{csp}"
    );
    assert!(login.text().await.expect("html").contains("name=\"token\""));
    // A wrong token: the form again, saying so, and no cookie.
    let r = http
        .post(format!("{url}/login"))
        .form(&[("token", "guess")])
        .send()
        .await
        .expect("login");
    assert!(r.headers().get("set-cookie").is_none());
    assert!(
        r.text()
            .await
            .expect("html")
            .contains("token of this coordinator")
    );
    // The right one: an HttpOnly, SameSite=Strict session cookie, never the token itself.
    let r = http
        .post(format!("{url}/login"))
        .form(&[("token", CLIENT)])
        .send()
        .await
        .expect("login");
    assert_eq!(r.status(), StatusCode::SEE_OTHER);
    let set = r.headers()["set-cookie"]
        .to_str()
        .expect("cookie")
        .to_string();
    assert!(
        set.contains("HttpOnly") && set.contains("SameSite=Strict") && !set.contains(CLIENT),
        "{set}"
    );
    let cookie = set.split(';').next().expect("name=value").to_string();
    let page = http
        .get(format!("{url}/jobs/7"))
        .header("cookie", &cookie)
        .send()
        .await
        .expect("page");
    assert_eq!(page.status(), StatusCode::OK);
    assert!(page.text().await.expect("html").contains("/assets/app.js"));
    for asset in ["app.js", "app.css"] {
        let r = http
            .get(format!("{url}/assets/{asset}"))
            .send()
            .await
            .expect("asset");
        assert_eq!(r.status(), StatusCode::OK, "{asset}");
    }
    // The cookie reads the API; a change needs the session's CSRF token too.
    let r = http
        .get(format!("{url}/v1/jobs"))
        .header("cookie", &cookie)
        .send()
        .await
        .expect("list");
    assert_eq!(r.status(), StatusCode::OK);
    let session: serde_json::Value = http
        .get(format!("{url}/v1/session"))
        .header("cookie", &cookie)
        .send()
        .await
        .expect("session")
        .json()
        .await
        .expect("json");
    let csrf = session["csrf"].as_str().expect("csrf").to_string();
    let r = http
        .post(format!("{url}/v1/workers/nobody/drain"))
        .header("cookie", &cookie)
        .send()
        .await
        .expect("drain");
    assert_eq!(r.status(), StatusCode::FORBIDDEN);
    let r = http
        .post(format!("{url}/v1/workers/nobody/drain"))
        .header("cookie", &cookie)
        .header("x-csrf-token", &csrf)
        .send()
        .await
        .expect("drain");
    assert_eq!(
        r.status(),
        StatusCode::NOT_FOUND,
        "past the CSRF check: no such worker"
    );
    // Workers' endpoints never take the cookie.
    let r = http
        .post(format!("{url}/v1/tasks/lease"))
        .header("cookie", &cookie)
        .header("x-csrf-token", &csrf)
        .json(&worker("w", &[]))
        .send()
        .await
        .expect("lease");
    assert_eq!(r.status(), StatusCode::UNAUTHORIZED);
    // Logout needs the token in its form; after it the cookie is worth nothing.
    let r = http
        .post(format!("{url}/logout"))
        .header("cookie", &cookie)
        .form(&[("csrf", "wrong")])
        .send()
        .await
        .expect("logout");
    assert_eq!(r.status(), StatusCode::FORBIDDEN);
    let r = http
        .post(format!("{url}/logout"))
        .header("cookie", &cookie)
        .form(&[("csrf", csrf.as_str())])
        .send()
        .await
        .expect("logout");
    assert_eq!(r.status(), StatusCode::SEE_OTHER);
    assert!(
        r.headers()["set-cookie"]
            .to_str()
            .unwrap_or("")
            .contains("Max-Age=0")
    );
    let r = http
        .get(format!("{url}/v1/jobs"))
        .header("cookie", &cookie)
        .send()
        .await
        .expect("list");
    assert_eq!(r.status(), StatusCode::UNAUTHORIZED);
    // The API's documentation is browsable, from files inside the binary.
    let docs = http.get(format!("{url}/docs/")).send().await.expect("docs");
    assert_eq!(docs.status(), StatusCode::OK);
    assert!(docs.text().await.expect("html").contains("swagger"));
    running.stop().await.expect("stop");
}
