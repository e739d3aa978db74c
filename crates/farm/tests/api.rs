//! Bad requests against a real coordinator on loopback: each gets a 4xx with a JSON message
//! that says what was expected, and the server keeps serving.

mod common;

use common::{CLIENT, WORKER, config};

use std::path::PathBuf;

use reqwest::StatusCode;
use tessera_farm::bundle::Bundle;
use tessera_farm::coordinator::{self, Running};
use tessera_farm::job::RenderSettings;
use tessera_farm::protocol::{ErrorBody, JobRequest, LeaseRequest, WorkerInfo};

async fn start(dir: &std::path::Path) -> Running {
    let mut config = config(dir);
    config.limits.max_resolution = 512;
    config.limits.max_spp = 1024;
    config.max_upload = 64 * 1024;
    coordinator::start(config).await.expect("coordinator")
}

const QUAD: &str = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3\nf 1 3 4\n";

fn scene(mesh_file: &str, width: u32, spp: u32) -> String {
    format!(
        r#"{{
  "units": "m",
  "camera": {{ "type": "pinhole", "position": [0.5, 0.5, -2], "look_at": [0.5, 0.5, 0], "fov_deg": 40 }},
  "film": {{ "width": {width}, "height": 16 }},
  "integrator": {{ "type": "path", "spp": {spp} }},
  "materials": {{ "white": {{ "type": "diffuse", "albedo": 0.5 }} }},
  "lights": [ {{ "type": "point", "position": [0.5, 0.5, -1], "intensity": 1 }} ],
  "shapes": [ {{ "type": "mesh", "file": "{mesh_file}", "material": "white" }} ]
}}"#
    )
}

fn bundle(files: &[(&str, &str)]) -> Vec<u8> {
    Bundle {
        files: files
            .iter()
            .map(|(p, d)| (PathBuf::from(p), d.as_bytes().to_vec()))
            .collect(),
    }
    .to_tar()
    .expect("packs")
}

struct Api {
    http: reqwest::Client,
    base: String,
}

impl Api {
    /// The API of the coordinator `running`.
    fn of(running: &Running) -> Api {
        Api {
            http: reqwest::Client::new(),
            base: format!("http://{}", running.addr),
        }
    }

    fn url(&self, path: &str) -> String {
        format!("{}{path}", self.base)
    }

    /// Sends and checks the answer: `status`, a JSON `{"error"}` containing every `needle`.
    async fn expect(&self, rb: reqwest::RequestBuilder, status: StatusCode, needles: &[&str]) {
        let r = rb.send().await.expect("send");
        assert_eq!(r.status(), status);
        let ct = r
            .headers()
            .get("content-type")
            .and_then(|v| v.to_str().ok())
            .unwrap_or("")
            .to_string();
        assert!(ct.starts_with("application/json"), "content type {ct}");
        let body: ErrorBody = r.json().await.expect("JSON error body");
        for n in needles {
            assert!(body.error.contains(n), "{n:?} not in {:?}", body.error);
        }
        // The server still serves.
        let health = self
            .http
            .get(self.url("/healthz"))
            .send()
            .await
            .expect("healthz");
        assert_eq!(health.status(), StatusCode::OK);
    }

    async fn upload(&self, tar: Vec<u8>) -> String {
        let r = self
            .http
            .post(self.url("/v1/bundles"))
            .bearer_auth(CLIENT)
            .body(tar)
            .send()
            .await
            .expect("upload");
        assert_eq!(r.status(), StatusCode::CREATED);
        let info: serde_json::Value = r.json().await.expect("bundle info");
        info["hash"].as_str().expect("hash").to_string()
    }

    fn submit(&self, bundle: &str, settings: RenderSettings) -> reqwest::RequestBuilder {
        self.http
            .post(self.url("/v1/jobs"))
            .bearer_auth(CLIENT)
            .json(&JobRequest {
                bundle: bundle.into(),
                scene: "scene.json".into(),
                name: None,
                frames: None,
                settings,
                priority: 0,
                require_tags: vec![],
            })
    }
}

/// A worker of another build (another wire format, or one that does not say) is refused a
/// lease with a JSON 409 naming both formats, before any task is leased to it; `/healthz`
/// says which format the coordinator reads.
#[tokio::test]
async fn workers_of_another_wire_format_are_refused_leases() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let api = Api::of(&running);
    let c = &api.http;
    let ours = tessera_render::wire::VERSION;
    let old = LeaseRequest {
        worker: WorkerInfo {
            wire: ours - 1,
            ..WorkerInfo::simulated("old-build")
        },
        wait_ms: 0,
    };
    api.expect(
        c.post(api.url("/v1/tasks/lease"))
            .bearer_auth(WORKER)
            .json(&old),
        StatusCode::CONFLICT,
        &[
            "worker.wire",
            "old-build",
            &format!("wire format {}", ours - 1),
            &format!("reads {ours}"),
        ],
    )
    .await;
    // A worker from before workers said their format.
    let mut silent = serde_json::to_value(&old).expect("serialises");
    silent["worker"]
        .as_object_mut()
        .expect("an object")
        .remove("wire");
    api.expect(
        c.post(api.url("/v1/tasks/lease"))
            .bearer_auth(WORKER)
            .json(&silent),
        StatusCode::CONFLICT,
        &["wire format 0"],
    )
    .await;
    // This build's worker is served (nothing queued: 204).
    let current = LeaseRequest {
        worker: WorkerInfo::simulated("this-build"),
        wait_ms: 0,
    };
    let r = c
        .post(api.url("/v1/tasks/lease"))
        .bearer_auth(WORKER)
        .json(&current)
        .send()
        .await
        .expect("lease");
    assert_eq!(r.status(), StatusCode::NO_CONTENT);
    let health: serde_json::Value = c
        .get(api.url("/healthz"))
        .send()
        .await
        .expect("healthz")
        .json()
        .await
        .expect("json");
    assert_eq!(health["wire"], serde_json::json!(ours));
}

/// A worker whose lease a coordinator refuses for its build (409) exits with the
/// coordinator's reason instead of asking again forever: waiting cannot mend it, and an
/// orchestrator restarts it with the coordinator's build.
#[tokio::test]
async fn a_worker_refused_for_its_build_exits_with_the_reason() {
    let reason = "worker.wire: worker w writes wire format 9 and this coordinator reads 10";
    let app = axum::Router::new().route(
        "/v1/tasks/lease",
        axum::routing::post(move || async move {
            (
                StatusCode::CONFLICT,
                axum::Json(serde_json::json!({ "error": reason })),
            )
        }),
    );
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
        .await
        .expect("binds");
    let addr = listener.local_addr().expect("address");
    tokio::spawn(async move { axum::serve(listener, app).await });
    let run = tessera_farm::worker::run(tessera_farm::worker::WorkerConfig {
        coordinator: format!("http://{addr}"),
        token: WORKER.into(),
        name: "w".into(),
        slots: 2,
        parent_pid: None,
        tags: vec![],
        fail_tasks_with: None,
        ca: None,
    });
    let ended = tokio::time::timeout(std::time::Duration::from_secs(30), run)
        .await
        .expect("the worker exits");
    let error = format!("{:#}", ended.expect_err("with an error"));
    assert!(error.contains(reason), "{error}");
}

#[tokio::test]
async fn bad_requests_get_4xx_json_errors_and_the_server_keeps_serving() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let api = Api::of(&running);
    let c = &api.http;
    let unauthorized = StatusCode::UNAUTHORIZED;
    let bad = StatusCode::BAD_REQUEST;

    // Tokens: none, wrong (401), and the other role's (403, saying who may).
    api.expect(c.get(api.url("/v1/jobs")), unauthorized, &["missing token"])
        .await;
    api.expect(
        c.get(api.url("/v1/jobs")).bearer_auth("nope"),
        unauthorized,
        &["wrong token"],
    )
    .await;
    api.expect(
        c.get(api.url("/v1/jobs")).bearer_auth(WORKER),
        StatusCode::FORBIDDEN,
        &["is a worker", "admins, artists and viewers may"],
    )
    .await;
    api.expect(
        c.post(api.url("/v1/tasks/lease"))
            .bearer_auth(CLIENT)
            .body("{}"),
        StatusCode::FORBIDDEN,
        &["admin is an admin", "workers may"],
    )
    .await;

    // Malformed JSON, and JSON of the wrong shape.
    api.expect(
        c.post(api.url("/v1/jobs"))
            .bearer_auth(CLIENT)
            .header("content-type", "application/json")
            .body("{\"bundle\": "),
        bad,
        &["request body"],
    )
    .await;
    api.expect(
        c.post(api.url("/v1/jobs"))
            .bearer_auth(CLIENT)
            .header("content-type", "application/json")
            .body("{\"bundel\": \"x\"}"),
        StatusCode::UNPROCESSABLE_ENTITY,
        &["bundel"],
    )
    .await;
    api.expect(
        api.submit("0123", RenderSettings::default()),
        bad,
        &["bundle", "POST /v1/bundles"],
    )
    .await;

    // A scene whose mesh is missing from the bundle.
    let hash = api
        .upload(bundle(&[("scene.json", &scene("quad.obj", 16, 4))]))
        .await;
    api.expect(
        api.submit(&hash, RenderSettings::default()),
        bad,
        &["quad.obj", "cannot read"],
    )
    .await;

    // A scene path that leaves the bundle, and a tar entry that does.
    let hash = api
        .upload(bundle(&[
            ("scene.json", &scene("../quad.obj", 16, 4)),
            ("quad.obj", QUAD),
        ]))
        .await;
    api.expect(
        api.submit(&hash, RenderSettings::default()),
        bad,
        &["scene.json", "shapes[0].file", "leaves"],
    )
    .await;
    let mut builder = tar::Builder::new(Vec::new());
    let mut header = tar::Header::new_gnu();
    header.set_size(QUAD.len() as u64);
    header.set_entry_type(tar::EntryType::Regular);
    let name = b"../outside.obj";
    header.as_old_mut().name[..name.len()].copy_from_slice(name);
    header.set_cksum();
    builder.append(&header, QUAD.as_bytes()).expect("append");
    let evil = builder.into_inner().expect("tar");
    api.expect(
        c.post(api.url("/v1/bundles"))
            .bearer_auth(CLIENT)
            .body(evil),
        bad,
        &["../outside.obj", "leaves"],
    )
    .await;

    // NaN in a vertex.
    let nan = QUAD.replace("v 1 1 0", "v 1 nan 0");
    let hash = api
        .upload(bundle(&[
            ("scene.json", &scene("quad.obj", 16, 4)),
            ("quad.obj", &nan),
        ]))
        .await;
    api.expect(
        api.submit(&hash, RenderSettings::default()),
        bad,
        &["quad.obj", "line 3"],
    )
    .await;

    // Resolution and sample count over this coordinator's limits.
    let hash = api
        .upload(bundle(&[
            ("scene.json", &scene("quad.obj", 4096, 4)),
            ("quad.obj", QUAD),
        ]))
        .await;
    api.expect(
        api.submit(&hash, RenderSettings::default()),
        bad,
        &["film", "512×512"],
    )
    .await;
    let hash = api
        .upload(bundle(&[
            ("scene.json", &scene("quad.obj", 16, 4)),
            ("quad.obj", QUAD),
        ]))
        .await;
    let many = RenderSettings {
        spp: Some(5000),
        ..Default::default()
    };
    api.expect(api.submit(&hash, many), bad, &["spp", "1024"])
        .await;
    // BDPT refines every pixel at once (its splats land anywhere): no adaptive sampling.
    let bdpt = RenderSettings {
        integrator: Some("bdpt".into()),
        target_error: Some(0.01),
        ..Default::default()
    };
    api.expect(api.submit(&hash, bdpt), bad, &["target_error", "bdpt"])
        .await;

    // An upload over the size limit.
    let big = bundle(&[
        ("scene.json", &scene("quad.obj", 16, 4)),
        ("big.obj", &"#".repeat(100_000)),
    ]);
    api.expect(
        c.post(api.url("/v1/bundles")).bearer_auth(CLIENT).body(big),
        StatusCode::PAYLOAD_TOO_LARGE,
        &["upload limit", "--max-upload-mib"],
    )
    .await;

    // Unknown job, frame, route; a stale lease.
    api.expect(
        c.get(api.url("/v1/jobs/999")).bearer_auth(CLIENT),
        StatusCode::NOT_FOUND,
        &["no job 999"],
    )
    .await;
    api.expect(
        c.get(api.url("/v1/jobs/999/frames/1/exr"))
            .bearer_auth(CLIENT),
        StatusCode::NOT_FOUND,
        &["no job 999"],
    )
    .await;
    api.expect(
        c.get(api.url("/v1/nothing")).bearer_auth(CLIENT),
        StatusCode::NOT_FOUND,
        &["no such endpoint"],
    )
    .await;
    api.expect(
        c.put(api.url("/v1/tasks/1/result?lease=7"))
            .bearer_auth(WORKER)
            .body(vec![0u8; 10]),
        StatusCode::CONFLICT,
        &["no longer current"],
    )
    .await;

    // A method the registry does not have.
    let unknown = RenderSettings {
        integrator: Some("raytrace".into()),
        ..Default::default()
    };
    api.expect(
        api.submit(&hash, unknown),
        bad,
        &["integrator.type", "expected one of", "bdpt", "raytrace"],
    )
    .await;

    // And a good job is still accepted; it cannot be deleted while it runs; it can be
    // cancelled once, then deleted with its files.
    let r = api
        .submit(&hash, RenderSettings::default())
        .send()
        .await
        .expect("submit");
    assert_eq!(r.status(), StatusCode::CREATED);
    let job: serde_json::Value = r.json().await.expect("job");
    let this_job = api.url(&format!("/v1/jobs/{}", job["id"]));
    api.expect(
        c.delete(&this_job).bearer_auth(CLIENT),
        StatusCode::CONFLICT,
        &["cancel it"],
    )
    .await;
    let cancel = api.url(&format!("/v1/jobs/{}/cancel", job["id"]));
    let r = c
        .post(&cancel)
        .bearer_auth(CLIENT)
        .send()
        .await
        .expect("cancel");
    assert_eq!(r.status(), StatusCode::OK);
    let job: serde_json::Value = r.json().await.expect("job");
    assert_eq!(job["state"], "cancelled");
    assert_eq!(job["tasks"]["cancelled"], job["tasks"]["total"]);
    api.expect(
        c.post(&cancel).bearer_auth(CLIENT),
        StatusCode::CONFLICT,
        &["already ended"],
    )
    .await;
    api.expect(
        c.get(api.url(&format!("/v1/jobs/{}/frames/1/exr", job["id"])))
            .bearer_auth(CLIENT),
        StatusCode::CONFLICT,
        &["not finished"],
    )
    .await;
    let bundles_before = std::fs::read_dir(dir.path().join("bundles"))
        .expect("bundles")
        .count();
    let r = c
        .delete(&this_job)
        .bearer_auth(CLIENT)
        .send()
        .await
        .expect("delete");
    assert_eq!(r.status(), StatusCode::NO_CONTENT);
    api.expect(
        c.get(&this_job).bearer_auth(CLIENT),
        StatusCode::NOT_FOUND,
        &["no job"],
    )
    .await;
    api.expect(
        c.delete(&this_job).bearer_auth(CLIENT),
        StatusCode::NOT_FOUND,
        &["no job"],
    )
    .await;
    assert!(!dir.path().join("jobs").join(job["id"].to_string()).exists());
    // Its bundle went with it (no other job used it).
    // (A directory the object store leaves empty goes too.)
    let bundles_after = std::fs::read_dir(dir.path().join("bundles")).map_or(0, |d| d.count());
    assert_eq!(bundles_after + 1, bundles_before);
    running.stop().await.expect("stop");
}

#[tokio::test]
async fn the_methods_are_the_registry_in_the_api_and_its_document() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let base = format!("http://{}", running.addr);
    let methods: Vec<serde_json::Value> = reqwest::Client::new()
        .get(format!("{base}/v1/methods"))
        .bearer_auth(CLIENT)
        .send()
        .await
        .expect("get")
        .json()
        .await
        .expect("JSON");
    let names: Vec<&str> = methods.iter().filter_map(|m| m["name"].as_str()).collect();
    assert_eq!(names, tessera_render::method::names());
    for (listed, m) in methods.iter().zip(tessera_render::method::methods()) {
        let settings: Vec<(&str, &str)> = listed["settings"]
            .as_array()
            .expect("settings")
            .iter()
            .map(|s| {
                (
                    s["name"].as_str().unwrap_or(""),
                    s["values"].as_str().unwrap_or(""),
                )
            })
            .collect();
        let described: Vec<String> = m.settings.iter().map(|s| s.kind.describe()).collect();
        let expected: Vec<(&str, &str)> = m
            .settings
            .iter()
            .zip(&described)
            .map(|(s, d)| (s.name, d.as_str()))
            .collect();
        assert_eq!(settings, expected, "{}", m.name);
    }
    let doc: serde_json::Value = reqwest::get(format!("{base}/v1/openapi.json"))
        .await
        .expect("get")
        .json()
        .await
        .expect("JSON");
    let listed =
        &doc["components"]["schemas"]["RenderSettings"]["properties"]["integrator"]["enum"];
    let listed: Vec<&str> = listed
        .as_array()
        .expect("the integrator's names in the document")
        .iter()
        .filter_map(|v| v.as_str())
        .collect();
    assert_eq!(listed, tessera_render::method::names());
    running.stop().await.expect("stop");
}

/// The OpenAPI document a running coordinator serves.
async fn openapi(running: &Running) -> serde_json::Value {
    reqwest::get(format!("http://{}/v1/openapi.json", running.addr))
        .await
        .expect("get")
        .json()
        .await
        .expect("JSON")
}

#[tokio::test]
async fn openapi_document_describes_the_api() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let doc = openapi(&running).await;
    let paths = doc["paths"].as_object().expect("paths");
    for p in [
        "/v1/bundles",
        "/v1/jobs",
        "/v1/jobs/{id}",
        "/v1/jobs/{id}/cancel",
        "/v1/jobs/{id}/frames/{frame}/exr",
        "/v1/jobs/{id}/frames/{frame}/preview.png",
        "/v1/jobs/{id}/frames/{frame}/steps/{step}/input",
        "/v1/artifacts/{key}",
        "/v1/methods",
        "/v1/workers",
        "/v1/tasks/lease",
        "/v1/tasks/{id}/heartbeat",
        "/v1/tasks/{id}/result",
        "/healthz",
        "/metrics",
    ] {
        assert!(paths.contains_key(p), "{p} missing from {:?}", paths.keys());
    }
    assert!(doc["components"]["schemas"]["JobStatus"].is_object());
    let metrics = reqwest::get(format!("http://{}/metrics", running.addr))
        .await
        .expect("get")
        .text()
        .await
        .expect("text");
    for m in [
        "tessera_queue_depth 0",
        "tessera_tasks_leased_total 0",
        "tessera_workers_alive 0",
        "tessera_task_seconds_total",
        "tessera_result_payload_bytes_per_pixel",
    ] {
        assert!(metrics.contains(m), "{m} missing from\n{metrics}");
    }
    running.stop().await.expect("stop");
}

/// The book's API page lists every operation of the OpenAPI document with its summary: the
/// table between its markers is rendered from the document here and must equal the page's
/// (`TESSERA_BLESS=1` writes it).
#[tokio::test]
async fn the_books_api_page_is_the_openapi_document() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    let doc = openapi(&running).await;
    running.stop().await.expect("stop");
    let mut table = String::from("| operation | group | what |\n|---|---|---|\n");
    for (path, ops) in doc["paths"].as_object().expect("paths") {
        for (method, op) in ops.as_object().expect("operations") {
            let tag = op["tags"][0].as_str().unwrap_or("");
            let summary = op["summary"].as_str().unwrap_or("");
            let summary = summary.split_whitespace().collect::<Vec<_>>().join(" ");
            let summary = summary.replace('|', "\\|");
            assert!(
                !summary.is_empty(),
                "{method} {path} has no summary (its handler's doc comment)"
            );
            table.push_str(&format!(
                "| `{} {path}` | {tag} | {summary} |\n",
                method.to_uppercase()
            ));
        }
    }
    let page = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../docs/src/farm/api.md");
    let text = std::fs::read_to_string(&page).expect("docs/src/farm/api.md");
    let (begin, end) = ("<!-- openapi:begin -->\n", "<!-- openapi:end -->");
    let (Some(i), Some(k)) = (text.find(begin), text.find(end)) else {
        panic!("docs/src/farm/api.md: no {begin:?} … {end:?} markers");
    };
    let written = &text[i + begin.len()..k];
    if std::env::var_os("TESSERA_BLESS").is_some() {
        let fresh = format!("{}{begin}{table}{}", &text[..i], &text[k..]);
        std::fs::write(&page, fresh).expect("write docs/src/farm/api.md");
    } else {
        assert_eq!(
            written, table,
            "docs/src/farm/api.md is not the OpenAPI document's table; \
             TESSERA_BLESS=1 cargo test -p tessera-farm --test api the_books_api_page rewrites it"
        );
    }
}

/// A client given several coordinators moves to the next when one cannot be reached (the
/// request included), and stays there.
#[tokio::test]
async fn a_client_of_several_coordinators_fails_over_to_one_that_answers() {
    let dir = tempfile::tempdir().expect("temp dir");
    let running = start(dir.path()).await;
    // A port nobody listens on: bound, then closed.
    let dead = std::net::TcpListener::bind("127.0.0.1:0").expect("bind");
    let dead_addr = dead.local_addr().expect("addr");
    drop(dead);
    let urls = format!("http://{dead_addr}, http://{}/", running.addr);
    let client = tessera_farm::client::Client::new(&urls, CLIENT).expect("client");
    // The request that found the first down is sent again to the second, and later requests
    // (of clones too) go to the second first.
    client.jobs("limit=1").await.expect("the second answers");
    assert_eq!(client.url("/x"), format!("http://{}/x", running.addr));
    client
        .clone()
        .jobs("limit=1")
        .await
        .expect("still the second");
    // With every coordinator down, the error is the connection's: worth retrying later.
    let down =
        tessera_farm::client::Client::new(&format!("http://{dead_addr}"), CLIENT).expect("client");
    let e = down.jobs("limit=1").await.expect_err("nobody listens");
    assert!(tessera_farm::client::is_transient(&e), "{e:#}");
    // A list with nothing in it is refused, naming what was expected.
    let empty = tessera_farm::client::Client::new(" , ", CLIENT)
        .err()
        .expect("refused");
    assert!(
        format!("{empty}").contains("expected http://host:port"),
        "{empty}"
    );
}
