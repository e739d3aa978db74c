//! What an attacker or a careless user sends a coordinator on loopback, each input made here:
//! archives and images whose headers claim more than they hold, recorded `auto` choices past
//! the limits, links out of a scene folder, results of the wrong shape or with bytes after
//! them, frames too large to fold, a second object store, leases used under another worker's
//! name, half-sent requests. Each is refused with a JSON error that says what was expected,
//! nothing is lost, and the server keeps serving.

mod common;

use common::{CLIENT, WORKER};

use std::io::{Read, Write};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use reqwest::StatusCode;
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::coordinator::{self, Config, Running};
use tessera_farm::job::RenderSettings;
use tessera_farm::protocol::{
    ErrorBody, Failure, Heartbeat, JobRequest, JobState, LeaseGrant, LeaseRequest, WorkerInfo,
};

fn config(dir: &Path) -> Config {
    let mut config = common::config(dir);
    config.max_upload = 1 << 20;
    config.timeouts.header = Duration::from_secs(1);
    config.timeouts.body_idle = Duration::from_secs(1);
    config
}

async fn start(dir: &Path) -> Running {
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

fn tar(files: &[(&str, &[u8])]) -> Vec<u8> {
    Bundle {
        files: files
            .iter()
            .map(|(p, d)| (PathBuf::from(p), d.to_vec()))
            .collect(),
    }
    .to_tar()
    .expect("packs")
}

fn request(bundle: &str, settings: RenderSettings) -> JobRequest {
    JobRequest {
        bundle: bundle.into(),
        scene: "scene.json".into(),
        name: None,
        frames: None,
        settings,
        priority: 0,
        require_tags: Vec::new(),
    }
}

fn worker(id: &str) -> LeaseRequest {
    LeaseRequest {
        worker: WorkerInfo::simulated(id),
        wait_ms: 0,
    }
}

/// The status and JSON error of a request; the server still answers `/healthz` after it.
async fn refused(running: &Running, rb: reqwest::RequestBuilder) -> (StatusCode, String) {
    let r = rb.send().await.expect("send");
    let status = r.status();
    let ct = r
        .headers()
        .get("content-type")
        .and_then(|v| v.to_str().ok())
        .unwrap_or("")
        .to_string();
    assert!(ct.starts_with("application/json"), "content type {ct}");
    let body: ErrorBody = r.json().await.expect("JSON error body");
    let health = reqwest::get(format!("http://{}/healthz", running.addr))
        .await
        .expect("healthz");
    assert_eq!(health.status(), StatusCode::OK);
    (status, body.error)
}

/// A coordinator with the test scene uploaded: its clients' and workers' API and the
/// bundle's hash.
struct Farm {
    running: Running,
    url: String,
    client: Client,
    workers: Client,
    hash: String,
}

async fn farm(config: Config) -> Farm {
    let running = coordinator::start(config).await.expect("coordinator");
    let url = format!("http://{}", running.addr);
    let client = Client::new(&url, CLIENT).expect("client");
    let workers = Client::new(&url, WORKER).expect("worker client");
    let hash = client
        .upload_bundle(tar(&[("scene.json", SCENE.as_bytes())]))
        .await
        .expect("upload")
        .hash;
    Farm {
        running,
        url,
        client,
        workers,
        hash,
    }
}

/// A tar of one entry whose header claims `claimed` bytes, with a 100-byte body.
fn lying_tar(claimed: u64) -> Vec<u8> {
    let mut header = tar::Header::new_gnu();
    header.set_path("scene.json").expect("name");
    header.set_size(claimed);
    header.set_mode(0o644);
    header.set_entry_type(tar::EntryType::Regular);
    header.set_cksum();
    let mut out = header.as_bytes().to_vec();
    out.extend_from_slice(&[b'{'; 100]);
    out.resize(out.len().next_multiple_of(512) + 1024, 0);
    out
}

/// A valid 4×4 OpenEXR whose header then claims `side`×`side` pixels, made consistent but
/// for its pixels: its chunk count and offset table as the claimed lines need (each offset
/// pointing at the one real chunk), so a reader believes it up to the pixels.
fn lying_exr(side: i32) -> Vec<u8> {
    use exr::prelude::*;
    let mut bytes = std::io::Cursor::new(Vec::new());
    Image::from_channels(
        (4, 4),
        SpecificChannels::rgb(|_: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32)),
    )
    .write()
    .to_buffered(&mut bytes)
    .expect("write");
    let mut data = bytes.into_inner();
    // Attributes: name\0 type\0 size value, until a zero byte; then the offset table.
    let (mut pos, mut attrs) = (8, std::collections::HashMap::new());
    while data[pos] != 0 {
        let name_end = pos + data[pos..].iter().position(|&b| b == 0).expect("name");
        let type_end = name_end
            + 1
            + data[name_end + 1..]
                .iter()
                .position(|&b| b == 0)
                .expect("type");
        let size = i32::from_le_bytes(data[type_end + 1..type_end + 5].try_into().expect("size"));
        attrs.insert(data[pos..name_end].to_vec(), type_end + 5);
        pos = type_end + 5 + size as usize;
    }
    let header_end = pos + 1;
    let window = attrs[b"dataWindow".as_slice()];
    data[window + 8..window + 12].copy_from_slice(&(side - 1).to_le_bytes());
    data[window + 12..window + 16].copy_from_slice(&(side - 1).to_le_bytes());
    let lines = match data[attrs[b"compression".as_slice()]] {
        3 | 5 => 16,
        4 | 6 | 7 => 32,
        _ => 1,
    };
    let (old_chunks, new_chunks) = (4usize.div_ceil(lines), (side as usize).div_ceil(lines));
    if let Some(&at) = attrs.get(b"chunkCount".as_slice()) {
        data[at..at + 4].copy_from_slice(&(new_chunks as i32).to_le_bytes());
    }
    let first = u64::from_le_bytes(data[header_end..header_end + 8].try_into().expect("offset"));
    let moved = first + 8 * (new_chunks - old_chunks) as u64;
    let mut out = data[..header_end].to_vec();
    for _ in 0..new_chunks {
        out.extend_from_slice(&moved.to_le_bytes());
    }
    out.extend_from_slice(&data[header_end + 8 * old_chunks..]);
    out
}

#[tokio::test]
async fn uploads_whose_headers_claim_more_than_they_hold_are_refused() {
    let dir = tempfile::tempdir().expect("dir");
    let running = start(dir.path()).await;
    let http = reqwest::Client::new();
    let upload = |body: Vec<u8>| {
        http.post(format!("http://{}/v1/bundles", running.addr))
            .bearer_auth(CLIENT)
            .body(body)
    };
    // A 2 KB archive claiming a 64 GiB entry.
    let body = lying_tar(64 << 30);
    assert!(body.len() <= 2048);
    let (status, e) = refused(&running, upload(body)).await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(e.contains("scene.json") && e.contains("68719476736"), "{e}");
    // No body at all, or an archive of no file.
    for body in [Vec::new(), vec![0u8; 1024]] {
        let (status, e) = refused(&running, upload(body)).await;
        assert_eq!(status, StatusCode::BAD_REQUEST);
        assert!(e.contains("no file"), "{e}");
    }

    // A small environment image whose header claims 60000×60000 pixels: refused when the
    // job is validated, naming the file, the claim and the limit.
    let scene = SCENE.replace(
        r#""units": "m","#,
        r#""units": "m", "environment": { "image": "sky.exr" },"#,
    );
    // Half a megabyte (an offset a line) standing for 43 GB of float RGB.
    let exr = lying_exr(60000);
    assert!(exr.len() < 1 << 20, "{} bytes", exr.len());
    let client = Client::new(&format!("http://{}", running.addr), CLIENT).expect("client");
    let hash = client
        .upload_bundle(tar(&[("scene.json", scene.as_bytes()), ("sky.exr", &exr)]))
        .await
        .expect("upload")
        .hash;
    let (status, e) = refused(
        &running,
        http.post(format!("http://{}/v1/jobs", running.addr))
            .bearer_auth(CLIENT)
            .json(&request(&hash, RenderSettings::default())),
    )
    .await;
    assert_eq!(status, StatusCode::BAD_REQUEST);
    assert!(
        e.contains("sky.exr") && e.contains("60000×60000") && e.contains("limit"),
        "{e}"
    );
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn a_recorded_choice_and_a_frame_too_large_to_fold_are_refused_with_figures() {
    let dir = tempfile::tempdir().expect("dir");
    let mut config = config(dir.path());
    config.limits.max_spp = 1024;
    config.limits.max_memory = 2 << 30;
    let Farm {
        running,
        client,
        hash,
        ..
    } = farm(config).await;
    let http = reqwest::Client::new();
    let submit = |settings: serde_json::Value| {
        let mut body =
            serde_json::to_value(request(&hash, RenderSettings::default())).expect("json");
        body["settings"] = settings;
        http.post(format!("http://{}/v1/jobs", running.addr))
            .bearer_auth(CLIENT)
            .json(&body)
    };
    for (settings, needle) in [
        (
            serde_json::json!({ "integrator": "auto", "choice": { "method": "path", "spp": 3000000, "report": [] } }),
            "choice.spp",
        ),
        (
            serde_json::json!({ "integrator": "auto", "choice": { "method": "path", "spp": 4294967295u32, "report": [] } }),
            "choice.spp",
        ),
        (
            serde_json::json!({ "integrator": "auto", "choice": { "method": "photon", "spp": 4, "photons": 4294967295u32, "report": [] } }),
            "choice.photons",
        ),
        (serde_json::json!({ "size": [16384, 16384] }), "GiB"),
    ] {
        let (status, e) = refused(&running, submit(settings)).await;
        assert_eq!(status, StatusCode::BAD_REQUEST, "{e}");
        assert!(e.contains(needle), "{needle:?} not in {e}");
    }
    let (_, e) = refused(
        &running,
        submit(serde_json::json!({ "size": [16384, 16384] })),
    )
    .await;
    assert!(
        e.contains("16384×16384") && e.contains("--max-job-memory-gib"),
        "{e}"
    );
    // Nothing was queued; a job within the limits still is.
    let queued = client
        .submit(&request(&hash, RenderSettings::default()))
        .await
        .expect("submit");
    assert_eq!(queued.state, JobState::Queued);
    running.stop().await.expect("stop");
}

#[cfg(unix)]
#[test]
fn a_link_out_of_the_scene_folder_is_not_bundled() {
    let outside = tempfile::tempdir().expect("dir");
    std::fs::write(outside.path().join("secret.obj"), "v 0 0 0\n").expect("write");
    let scene_dir = tempfile::tempdir().expect("dir");
    std::os::unix::fs::symlink(
        outside.path().join("secret.obj"),
        scene_dir.path().join("leak.obj"),
    )
    .expect("link");
    let scene = SCENE.replace(
        r#"{ "type": "sphere", "center": [0.5, 0.5, 0], "radius": 0.3, "material": "white" }"#,
        r#"{ "type": "mesh", "file": "leak.obj", "material": "white" }"#,
    );
    std::fs::write(scene_dir.path().join("scene.json"), scene).expect("write");
    let e = Bundle::pack_scene(&scene_dir.path().join("scene.json"))
        .map(|_| ())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("leak.obj") && e.contains("outside the scene folder"),
        "{e}"
    );
}

/// A result stream for `grant`'s task whose data covers 8×8 pixels, with `extra` bytes
/// after it.
fn result_stream(grant: &LeaseGrant, pixels: [u32; 4], extra: &[u8]) -> Vec<u8> {
    use tessera_render::method::TilePartial;
    use tessera_render::method::film::{AovSums, FilmSums};
    let [x0, y0, x1, y1] = pixels;
    let n = ((x1 - x0) * (y1 - y0)) as usize;
    let rect = [x0, y0, x1, y1];
    let partial = if grant.task.kind == "aov" {
        TilePartial::Aov(AovSums {
            rect,
            weight: vec![1.0; n],
            hit: vec![1.0; n],
            albedo: vec![[half::f16::ZERO; 3]; n],
            normal: vec![[half::f16::ZERO; 3]; n],
            depth: vec![1.0; n],
        })
    } else {
        TilePartial::Tile {
            sums: FilmSums {
                rect,
                samples: grant.task.end - grant.task.start,
                sum: vec![[0.0; 3]; n],
                weight: vec![1.0; n],
                m2: Vec::new(),
            },
            stats: Default::default(),
        }
    };
    let mut header = tessera_render::wire::Header::new(
        "result",
        &format!("path/{}", tessera_render::wire::VERSION),
    );
    header.task = Some(grant.task.clone());
    let (mut out, _) = tessera_render::wire::write(Vec::new(), &header, &partial).expect("write");
    out.extend_from_slice(extra);
    out
}

#[tokio::test]
async fn results_that_do_not_fit_their_task_are_refused_and_the_task_runs_again() {
    let dir = tempfile::tempdir().expect("dir");
    let Farm {
        running,
        client,
        workers,
        hash,
        ..
    } = farm(config(dir.path())).await;
    let job = client
        .submit(&request(&hash, RenderSettings::default()))
        .await
        .expect("submit")
        .id;
    let grant = workers
        .lease(&worker("w"))
        .await
        .expect("lease")
        .expect("a task");
    let t = &grant.task;
    let whole = [t.x0, t.y0, t.x1, t.y1];
    assert_eq!(whole, [0, 0, 16, 16], "{t:?}");
    let file = dir.path().join("result.tswf");
    for (stream, needle) in [
        // A well-formed stream naming the 16×16 task, carrying 8×8 data.
        (
            result_stream(&grant, [0, 0, 8, 8], b""),
            "does not fit its task",
        ),
        // The right data with a byte after the stream's end.
        (result_stream(&grant, whole, b"x"), "bytes follow"),
    ] {
        std::fs::write(&file, stream).expect("write");
        let e = workers
            .upload_result(grant.task_id, grant.lease, 0.1, &file)
            .await
            .expect_err("refused")
            .to_string();
        assert!(
            e.contains("400") && e.contains(needle),
            "{needle:?} not in {e}"
        );
        let status = client.job(job).await.expect("job");
        assert_ne!(status.state, JobState::Failed, "{:?}", status.error);
    }
    // The worker reports the failure; the task is leased again, and the right result is
    // then taken.
    workers
        .fail(
            grant.task_id,
            &Failure {
                lease: grant.lease,
                worker: "w".into(),
                error: "upload refused".into(),
                permanent: false,
            },
        )
        .await
        .expect("fail");
    let again = workers
        .lease(&worker("w"))
        .await
        .expect("lease")
        .expect("the task");
    assert_eq!(again.task_id, grant.task_id);
    std::fs::write(&file, result_stream(&again, whole, b"")).expect("write");
    workers
        .upload_result(again.task_id, again.lease, 0.1, &file)
        .await
        .expect("a result that fits is taken");
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn a_task_no_worker_left_can_run_fails_its_job_with_the_reason() {
    let dir = tempfile::tempdir().expect("dir");
    let mut config = config(dir.path());
    config.lease_ms = 1000;
    let Farm {
        running,
        client,
        workers,
        hash,
        ..
    } = farm(config).await;
    let req = request(&hash, RenderSettings::default());
    let submit = || client.submit(&req);
    let job = submit().await.expect("submit").id;
    // A second worker is seen once (it asks for work, then goes quiet); the first fails the
    // job's tasks until it is blocklisted for the job.
    assert!(
        workers
            .lease(&worker("quiet"))
            .await
            .expect("lease")
            .is_some()
    );
    for i in 0..3 {
        let g = workers
            .lease(&worker("w"))
            .await
            .expect("lease")
            .expect("a task");
        workers
            .fail(
                g.task_id,
                &Failure {
                    lease: g.lease,
                    worker: "w".into(),
                    error: format!("the renderer panicked: index out of bounds {i}"),
                    permanent: false,
                },
            )
            .await
            .expect("fail");
    }
    // Once the quiet worker counts as gone, no worker is left that could run the job (the
    // blocklisted one still asks for work, and gets none of it).
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        assert!(workers.lease(&worker("w")).await.expect("lease").is_none());
        let s = client.job(job).await.expect("job");
        if s.state != JobState::Running && s.state != JobState::Queued || Instant::now() > deadline
        {
            break s;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    };
    assert_eq!(status.state, JobState::Failed);
    let e = status.error.unwrap_or_default();
    assert!(
        e.contains("blocklisted") && e.contains("index out of bounds"),
        "{e}"
    );

    // A failure no retry can mend fails its job at once, with the reason.
    let job = submit().await.expect("submit").id;
    let g = workers
        .lease(&worker("v"))
        .await
        .expect("lease")
        .expect("a task");
    assert_eq!(g.job_id, job);
    workers
        .fail(
            g.task_id,
            &Failure {
                lease: g.lease,
                worker: "v".into(),
                error: "bundle ab12 is not in the object store".into(),
                permanent: true,
            },
        )
        .await
        .expect("fail");
    let status = client.job(job).await.expect("job");
    assert_eq!(status.state, JobState::Failed);
    assert!(
        status
            .error
            .unwrap_or_default()
            .contains("not in the object store"),
        "the reason"
    );
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn a_lease_is_its_holders_alone() {
    let dir = tempfile::tempdir().expect("dir");
    let Farm {
        running,
        url,
        client,
        workers,
        hash,
    } = farm(config(dir.path())).await;
    client
        .submit(&request(&hash, RenderSettings::default()))
        .await
        .expect("submit");
    let g = workers
        .lease(&worker("w"))
        .await
        .expect("lease")
        .expect("a task");
    let http = reqwest::Client::new();
    let beat = |name: &str| {
        http.post(format!("{url}/v1/tasks/{}/heartbeat", g.task_id))
            .bearer_auth(WORKER)
            .json(&Heartbeat {
                lease: g.lease,
                worker: name.into(),
                cpu: None,
            })
    };
    let (status, e) = refused(&running, beat("mallory")).await;
    assert_eq!(status, StatusCode::FORBIDDEN);
    assert!(e.contains("held by worker w, not mallory"), "{e}");
    let (status, e) = refused(
        &running,
        http.post(format!("{url}/v1/tasks/{}/fail", g.task_id))
            .bearer_auth(WORKER)
            .json(&Failure {
                lease: g.lease,
                worker: "mallory".into(),
                error: "no".into(),
                permanent: true,
            }),
    )
    .await;
    assert_eq!(status, StatusCode::FORBIDDEN, "{e}");
    // The holder's own heartbeat renews it; the job is untouched.
    assert_eq!(
        beat("w").send().await.expect("beat").status(),
        StatusCode::OK
    );
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn coordinators_of_one_job_store_must_share_its_object_store() {
    let first = tempfile::tempdir().expect("dir");
    let other = tempfile::tempdir().expect("dir");
    let running = start(first.path()).await;
    running.stop().await.expect("stop");
    // The same job store (its PostgreSQL schema, or its SQLite file), another object store.
    let mut config = config(other.path());
    match tessera_farm::store::test_store_url(first.path()) {
        Some(url) => config.store = Some(url),
        None => {
            config.data = first.path().to_path_buf();
            config.objects = Some(other.path().join("objects").display().to_string());
        }
    }
    let e = coordinator::start(config)
        .await
        .map(|_| ())
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains("is not the one this farm's job store records") && e.contains("--objects"),
        "{e}"
    );
    // The first comes back with its own.
    let again = start(first.path()).await;
    again.stop().await.expect("stop");
}

#[cfg(unix)]
/// Two object stores at one path — a local directory of the same name on each host: the
/// second coordinator's is empty where the first's holds the farm's id, and it is refused,
/// naming the path, rather than taking the id as its own.
#[tokio::test]
async fn a_second_object_store_at_the_same_path_is_refused() {
    let dir = tempfile::tempdir().expect("dir");
    let objects = dir.path().join("objects");
    let with_objects = || {
        let mut config = config(dir.path());
        config.objects = Some(objects.display().to_string());
        config
    };
    let running = coordinator::start(with_objects())
        .await
        .expect("coordinator");
    running.stop().await.expect("stop");
    // What the other host's directory of that path holds: nothing yet.
    let first_hosts = dir.path().join("objects-of-the-first-host");
    std::fs::rename(&objects, &first_hosts).expect("move");
    std::fs::create_dir(&objects).expect("dir");
    let e = coordinator::start(with_objects())
        .await
        .map(|_| ())
        .expect_err("refused")
        .to_string();
    assert!(
        e.contains(&objects.display().to_string())
            && e.contains("another store at the same path")
            && e.contains("--objects"),
        "{e}"
    );
    // Nothing was written into it; with the first host's store back, the farm starts.
    assert_eq!(std::fs::read_dir(&objects).expect("dir").count(), 0);
    std::fs::remove_dir(&objects).expect("remove");
    std::fs::rename(&first_hosts, &objects).expect("move back");
    let again = coordinator::start(with_objects())
        .await
        .expect("coordinator");
    again.stop().await.expect("stop");
}

#[tokio::test]
async fn the_job_store_is_readable_by_its_owner_alone() {
    use std::os::unix::fs::PermissionsExt;
    let dir = tempfile::tempdir().expect("dir");
    let data = dir.path().join("data");
    let running = start(&data).await;
    let mode = |p: &Path| std::fs::metadata(p).expect("metadata").permissions().mode() & 0o777;
    assert_eq!(mode(&data), 0o700);
    if tessera_farm::store::test_store_url(&data).is_none() {
        assert_eq!(mode(&data.join("tessera.db")), 0o600);
    }
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn half_sent_requests_are_cut_off() {
    let dir = tempfile::tempdir().expect("dir");
    let running = start(dir.path()).await;
    let addr = running.addr;
    tokio::task::spawn_blocking(move || {
        // Half the headers, then nothing: the connection is closed after the header timeout.
        let mut s = std::net::TcpStream::connect(addr).expect("connect");
        s.set_read_timeout(Some(Duration::from_secs(10))).expect("timeout");
        s.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n").expect("write");
        let started = Instant::now();
        let mut buf = Vec::new();
        let _ = s.read_to_end(&mut buf);
        assert!(started.elapsed() < Duration::from_secs(5), "{:?}", started.elapsed());
        // A body claimed within the upload limit, 10 bytes of it sent: the request fails after
        // the idle timeout, not when the claimed bytes would have come; one claimed past the
        // limit is refused before any of it is read.
        for (length, status) in [(500_000, "HTTP/1.1 400"), (600_000_000, "HTTP/1.1 413")] {
            let mut s = std::net::TcpStream::connect(addr).expect("connect");
            s.set_read_timeout(Some(Duration::from_secs(10))).expect("timeout");
            write!(
                s,
                "POST /v1/bundles HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {CLIENT}\r\nContent-Length: {length}\r\n\r\n0123456789"
            )
            .expect("write");
            let started = Instant::now();
            let mut answer = vec![0u8; 4096];
            let n = s.read(&mut answer).unwrap_or(0);
            let answer = String::from_utf8_lossy(&answer[..n]).into_owned();
            assert!(started.elapsed() < Duration::from_secs(5), "{:?}", started.elapsed());
            assert!(answer.starts_with(status), "{length}: {answer}");
            assert!(answer.contains("\"error\""), "a JSON error: {answer}");
        }
    })
    .await
    .expect("client");
    running.stop().await.expect("stop");
}
