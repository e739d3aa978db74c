//! `tessera bench dashboard`: how fast the dashboard's page and the API calls it makes answer
//! with a big store — by default 1,000 jobs of 100 tasks (100,000 tasks): most done, some
//! running, failed, cancelled and queued, with their attempts — as latency percentiles.

use std::time::Instant;

use anyhow::Context;
use tessera_farm::coordinator::{self, Config, now_ms};
use tessera_farm::job::{FrameRange, RenderSettings, TaskSpec};
use tessera_farm::protocol::WorkerInfo;
use tessera_farm::store::{NewJob, RetryPolicy, Store, Work};

#[derive(clap::Args)]
pub struct DashboardArgs {
    /// Jobs in the store.
    #[arg(long, default_value_t = 1000)]
    pub jobs: u32,
    /// Tasks per job.
    #[arg(long, default_value_t = 100)]
    pub tasks: u32,
    /// Requests per measured call.
    #[arg(long, default_value_t = 50)]
    pub requests: u32,
}

fn worker(id: &str) -> WorkerInfo {
    WorkerInfo {
        cpu: Some(1.0),
        ..WorkerInfo::simulated(id)
    }
}

/// Fills `store` with `jobs` jobs of `tasks` tile tasks each: 70 % done, 5 % half done
/// (running), 5 % failed, 5 % cancelled, the rest queued. Returns a running job's id.
fn fill(store: &Store, jobs: u32, tasks: u32) -> anyhow::Result<i64> {
    store.insert_bundle("0".repeat(64).as_str(), 1, 0)?;
    let side = (tasks as f64).sqrt().ceil() as u32;
    let job = |i: u32| NewJob {
        name: format!("shot {:03} v{}", i / 3, i % 3),
        priority: (i % 4) as i32,
        bundle: "0".repeat(64),
        scene: "scene.json".into(),
        frames: FrameRange::single(1),
        width: side * 32,
        height: side * 32,
        require_tags: vec![],
        submitter: None,
        measuring: false,
        work: Work {
            settings: RenderSettings::default(),
            spp: 64,
            method: "path".into(),
            decisions: vec!["integrator: path — a benchmark's".into()],
            tasks: vec![
                (0..tasks)
                    .map(|t| {
                        TaskSpec::new("tile", 1, 0, t)
                            .with_rect(tessera_render::Tile {
                                x0: (t % side) * 32,
                                y0: (t / side) * 32,
                                x1: (t % side) * 32 + 32,
                                y1: (t / side) * 32 + 32,
                            })
                            .with_range(0, 64)
                    })
                    .collect(),
            ],
            passes: vec![],
            planned_tasks: tasks as u64,
        },
    };
    let policy = RetryPolicy {
        max_attempts: 1,
        blocklist_after: u32::MAX,
        alive_ms: i64::MAX / 4,
    };
    let w = worker("bench-worker");
    let (done, running, failed, cancelled) = (
        jobs * 70 / 100,
        jobs * 5 / 100,
        jobs * 5 / 100,
        jobs * 5 / 100,
    );
    let mut next = 0u32;
    // Inserts `count` jobs, each then `finish`ed; the last one's id.
    let mut phase = |count: u32, finish: &dyn Fn(&Store, i64) -> anyhow::Result<()>| {
        let mut last = 0;
        for _ in 0..count {
            last = store.insert_job(&job(next), now_ms())?;
            next += 1;
            finish(store, last)?;
        }
        anyhow::Ok(last)
    };
    let lease_and = |store: &Store, n: u32, complete: bool| -> anyhow::Result<()> {
        for _ in 0..n {
            let g = store
                .lease(&w, now_ms(), 600_000)?
                .context("a queued task")?;
            if complete {
                store.complete(g.task_id, g.lease, 0.01, (1000, 4000), now_ms())?;
            } else {
                store.fail(
                    g.task_id,
                    g.lease,
                    "a benchmark's failure",
                    now_ms(),
                    &policy,
                )?;
            }
        }
        Ok(())
    };
    phase(done, &|s, id| {
        lease_and(s, tasks, true)?;
        s.frame_stitched(id, 1, &[], None, now_ms())?;
        Ok(())
    })?;
    phase(failed, &|s, _| lease_and(s, 1, false))?;
    phase(cancelled, &|s, id| {
        s.cancel(id, now_ms())?;
        Ok(())
    })?;
    // Half of each running job's tasks done: the others held back (paused) meanwhile.
    let first_running = (done + failed + cancelled) as i64 + 1;
    let running_id = phase(running, &|s, id| {
        lease_and(s, tasks / 2, true)?;
        s.pause(id)?;
        Ok(())
    })?;
    for id in first_running..=running_id {
        store.resume(id)?;
    }
    phase(jobs - done - failed - cancelled - running, &|_, _| Ok(()))?;
    Ok(running_id)
}

/// Median and 95th percentile of `n` timings of `f`, in milliseconds.
async fn time<F, Fut>(n: u32, mut f: F) -> anyhow::Result<(f64, f64)>
where
    F: FnMut() -> Fut,
    Fut: std::future::Future<Output = anyhow::Result<()>>,
{
    let mut ms = Vec::with_capacity(n as usize);
    for _ in 0..n {
        let t = Instant::now();
        f().await?;
        ms.push(t.elapsed().as_secs_f64() * 1000.0);
    }
    ms.sort_by(f64::total_cmp);
    let pick = |q: f64| ms[((ms.len() - 1) as f64 * q).round() as usize];
    Ok((pick(0.5), pick(0.95)))
}

pub async fn run(args: DashboardArgs) -> anyhow::Result<()> {
    let dir = super::farm::tempfile_dir()?;
    let data = dir.join("data");
    std::fs::create_dir_all(&data)?;
    let t = Instant::now();
    let running_job = {
        let store = Store::open(&data.join("tessera.db"))?;
        fill(&store, args.jobs, args.tasks)?
    };
    let total_tasks = args.jobs as u64 * args.tasks as u64;
    crate::print(&format!(
        "store: {} jobs, {total_tasks} tasks (70 % done, 5 % running, 5 % failed, 5 % cancelled, 15 % queued), filled in {:.1} s\n",
        args.jobs,
        t.elapsed().as_secs_f64()
    ))?;
    let config = Config::new(
        "127.0.0.1:0".parse()?,
        data.clone(),
        "bench-client".into(),
        "bench-worker".into(),
    );
    let running = coordinator::start(config).await?;
    let url = format!("http://{}", running.addr);
    let http = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()?;
    let login = http
        .post(format!("{url}/login"))
        .form(&[("token", "bench-client")])
        .send()
        .await?;
    let cookie = login
        .headers()
        .get("set-cookie")
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.split(';').next())
        .context("no session cookie")?
        .to_string();
    let get = |path: String| {
        let (http, cookie, url) = (http.clone(), cookie.clone(), url.clone());
        async move {
            let r = http
                .get(format!("{url}{path}"))
                .header("cookie", cookie)
                .send()
                .await?;
            anyhow::ensure!(r.status().is_success(), "{path}: {}", r.status());
            r.bytes().await?;
            anyhow::Ok(())
        }
    };
    let calls: Vec<(&str, String)> = vec![
        ("the dashboard page", "/".into()),
        ("jobs, first page of 50", "/v1/jobs?limit=50".into()),
        (
            "jobs, last page",
            format!("/v1/jobs?limit=50&offset={}", args.jobs.saturating_sub(50)),
        ),
        (
            "jobs, running only",
            "/v1/jobs?limit=50&state=running".into(),
        ),
        (
            "jobs, in queue order",
            "/v1/jobs?limit=50&sort=queue".into(),
        ),
        ("jobs, by name", "/v1/jobs?limit=50&q=shot%20042".into()),
        ("a job", format!("/v1/jobs/{running_job}")),
        (
            "a job's tasks (tile map)",
            format!("/v1/jobs/{running_job}/tasks?frame=1"),
        ),
        (
            "a job's attempts",
            format!("/v1/jobs/{running_job}/attempts?failures_first=true&limit=100"),
        ),
        ("workers", "/v1/workers".into()),
    ];
    let mut text = format!(
        "{} requests each, one at a time, on loopback (median / 95th percentile):\n",
        args.requests
    );
    for (what, path) in calls {
        let (p50, p95) = time(args.requests, || get(path.clone())).await?;
        text += &format!("  {what:<28} {p50:>7.2} ms  {p95:>7.2} ms   GET {path}\n");
    }
    // A worker asking for work, with 15 % of the jobs queued.
    let client = tessera_farm::client::Client::new(&url, "bench-worker")?;
    let req = tessera_farm::protocol::LeaseRequest {
        worker: worker("bench-lease"),
        wait_ms: 0,
    };
    let (p50, p95) = time(args.requests, || async {
        client.lease(&req).await?.context("a task")?;
        Ok(())
    })
    .await?;
    text += &format!(
        "  {:<28} {p50:>7.2} ms  {p95:>7.2} ms   POST /v1/tasks/lease\n",
        "a lease"
    );
    crate::print(&text)?;
    running.stop().await?;
    let _ = std::fs::remove_dir_all(&dir);
    Ok(())
}
