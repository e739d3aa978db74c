//! Users and roles on a coordinator: every cell of the route-by-role table in docs/src/farm/roles.md
//! is a request made here with that identity (the table is read, not copied), and the table
//! lists every operation of the OpenAPI document. Also: a worker's own token acts only under
//! its name; a revoked token and its dashboard session are refused at once; each job records
//! who submitted it.

mod common;

use common::{CLIENT, WORKER, config};

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use reqwest::{Method, StatusCode};
use tessera_farm::bundle::Bundle;
use tessera_farm::client::Client;
use tessera_farm::coordinator::{self, Running};
use tessera_farm::job::RenderSettings;
use tessera_farm::protocol::{JobRequest, LeaseRequest, NewUser, Role, WorkerInfo};

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

/// The table of docs/src/farm/roles.md: (method, path template, one cell per column).
fn table() -> (Vec<String>, Vec<(Method, String, Vec<bool>)>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/src/farm/roles.md");
    let text = std::fs::read_to_string(&path).expect("docs/src/farm/roles.md");
    let mut lines = text
        .lines()
        .skip_while(|l| !l.starts_with("| route |"))
        .map(|l| {
            l.trim_matches('|')
                .split('|')
                .map(|c| c.trim().to_string())
                .collect::<Vec<_>>()
        });
    let header = lines.next().expect("a table headed | route |")[1..].to_vec();
    let rows = lines
        .skip(1)
        .take_while(|cells| cells.len() == header.len() + 1)
        .map(|cells| {
            let (method, route) = cells[0]
                .trim_matches('`')
                .split_once(' ')
                .expect("`METHOD /path`");
            let allowed = cells[1..]
                .iter()
                .map(|c| match c.as_str() {
                    "yes" => true,
                    "no" => false,
                    other => {
                        panic!("docs/src/farm/roles.md: {route}: expected yes or no, got {other:?}")
                    }
                })
                .collect();
            (
                method.parse().expect("a method"),
                route.to_string(),
                allowed,
            )
        })
        .collect();
    (header, rows)
}

struct Farm {
    running: Running,
    url: String,
    admin: Client,
    tokens: Vec<(String, Option<String>)>,
    bundle: String,
    worker_id: String,
}

impl Farm {
    async fn new(dir: &Path) -> Farm {
        let running = start(dir).await;
        let url = format!("http://{}", running.addr);
        let admin = Client::new(&url, CLIENT).expect("client");
        let ana = add(&admin, "ana", Role::Artist).await;
        let vic = add(&admin, "vic", Role::Viewer).await;
        let w1 = add(&admin, "w1", Role::Worker).await;
        let bundle = admin
            .upload_bundle(
                Bundle {
                    files: [(PathBuf::from("scene.json"), SCENE.as_bytes().to_vec())].into(),
                }
                .to_tar()
                .expect("tar"),
            )
            .await
            .expect("upload")
            .hash;
        // The worker w1 registers by leasing (nothing is queued yet).
        let info = WorkerInfo::simulated("w1-0001");
        let info = WorkerInfo {
            name: "w1".into(),
            ..info
        };
        let w1_client = Client::new(&url, &w1).expect("client");
        w1_client
            .lease(&LeaseRequest {
                worker: info.clone(),
                wait_ms: 0,
            })
            .await
            .expect("w1 leases");
        // One identity per column of the table, in its order.
        let tokens = vec![
            ("admin".into(), Some(CLIENT.into())),
            ("artist, own job".into(), Some(ana.clone())),
            ("artist, another's job".into(), Some(ana)),
            ("viewer".into(), Some(vic)),
            ("worker token".into(), Some(w1)),
            ("shared worker token".into(), Some(WORKER.into())),
            ("no token".into(), None),
        ];
        Farm {
            running,
            url,
            admin,
            tokens,
            bundle,
            worker_id: info.id,
        }
    }

    /// A new job submitted with `token`.
    async fn job(&self, token: &str) -> i64 {
        Client::new(&self.url, token)
            .expect("client")
            .submit(&JobRequest {
                bundle: self.bundle.clone(),
                scene: "scene.json".into(),
                name: None,
                frames: None,
                settings: RenderSettings::default(),
                priority: 0,
                require_tags: vec![],
            })
            .await
            .expect("submit")
            .id
    }
}

/// Adds a user; its token.
async fn add(admin: &Client, name: &str, role: Role) -> String {
    admin
        .add_user(&NewUser {
            name: name.into(),
            role,
        })
        .await
        .expect("user added")
        .token
}

/// A body the route takes (or at least parses), so that what is checked is the token.
fn body(method: &Method, route: &str, worker_id: &str) -> Option<serde_json::Value> {
    Some(match (method.as_str(), route) {
        ("POST", "/v1/tasks/lease") => serde_json::json!({
            "worker": WorkerInfo { name: "w1".into(), ..WorkerInfo::simulated(worker_id) },
            "wait_ms": 0
        }),
        ("POST", "/v1/tasks/{id}/heartbeat") => {
            serde_json::json!({"lease": 1, "worker": worker_id})
        }
        ("POST", "/v1/tasks/{id}/fail") => {
            serde_json::json!({"lease": 1, "worker": worker_id, "error": "x"})
        }
        ("PATCH", _) => serde_json::json!({"priority": 1}),
        ("POST", "/v1/users") => serde_json::json!({"name": "newcomer", "role": "viewer"}),
        _ => return None,
    })
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_cell_of_the_route_by_role_table_holds() {
    let dir = tempfile::tempdir().expect("temp dir");
    let farm = Farm::new(&dir.path().join("data")).await;
    let (header, rows) = table();
    let columns: Vec<&str> = farm.tokens.iter().map(|(c, _)| c.as_str()).collect();
    assert_eq!(
        header, columns,
        "docs/src/farm/roles.md: the table's columns"
    );
    // The table lists every operation of the API.
    let doc: serde_json::Value = reqwest::get(format!("{}/v1/openapi.json", farm.url))
        .await
        .expect("openapi")
        .json()
        .await
        .expect("json");
    let mut documented = BTreeSet::new();
    for (path, ops) in doc["paths"].as_object().expect("paths") {
        for method in ops.as_object().expect("operations").keys() {
            documented.insert(format!("{} {path}", method.to_uppercase()));
        }
    }
    let listed: BTreeSet<String> = rows.iter().map(|(m, r, _)| format!("{m} {r}")).collect();
    assert_eq!(
        listed, documented,
        "docs/src/farm/roles.md lists every operation, and only those"
    );
    let http = reqwest::Client::new();
    let mut wrong = Vec::new();
    for (method, route, allowed) in &rows {
        // Fresh jobs for each route that names one: what one cell did (a cancel) changes
        // nothing another checks.
        let (own, others) = match route.contains("{id}") && route.starts_with("/v1/jobs/") {
            true => (
                farm.job(&farm.tokens[1].1.clone().expect("ana")).await,
                farm.job(CLIENT).await,
            ),
            false => (1, 1),
        };
        for (column, ((name, token), &yes)) in farm.tokens.iter().zip(allowed).enumerate() {
            let id = if column == 2 { others } else { own };
            let path = route
                .replace("{id}", &id.to_string())
                .replace("{frame}", "1")
                .replace("{step}", "0")
                .replace("{hash}", &farm.bundle)
                .replace("{key}", "nothing")
                .replace("{name}", "nobody");
            let path = match route.as_str() {
                "/v1/tasks/{id}/result" => format!("{path}?lease=1"),
                _ => path,
            };
            let mut rb = http.request(method.clone(), format!("{}{path}", farm.url));
            if let Some(t) = token {
                rb = rb.bearer_auth(t);
            }
            if let Some(b) = body(method, route, &farm.worker_id) {
                rb = rb.json(&b);
            }
            let status = rb.send().await.expect("request").status();
            let refused = matches!(status, StatusCode::UNAUTHORIZED | StatusCode::FORBIDDEN);
            let expected_refusal = match token {
                None => StatusCode::UNAUTHORIZED,
                Some(_) => StatusCode::FORBIDDEN,
            };
            if refused == yes || (refused && status != expected_refusal) {
                wrong.push(format!(
                    "{method} {route} as {name}: {status}, the table says {}",
                    if yes { "yes" } else { "no" }
                ));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "cells that do not hold:\n{}",
        wrong.join("\n")
    );
    farm.running.stop().await.expect("stop");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_worker_token_acts_only_under_its_name_and_revoked_tokens_stop_at_once() {
    let dir = tempfile::tempdir().expect("temp dir");
    let farm = Farm::new(&dir.path().join("data")).await;
    let w1 = farm.tokens[4].1.clone().expect("w1's token");
    let worker = Client::new(&farm.url, &w1).expect("client");
    // Leasing under another worker's name.
    let other = WorkerInfo::simulated("w2-0001");
    let err = worker
        .lease(&LeaseRequest {
            worker: other,
            wait_ms: 0,
        })
        .await
        .expect_err("refused");
    let api = err
        .downcast::<tessera_farm::client::ApiError>()
        .expect("an API error");
    assert_eq!(api.status, StatusCode::FORBIDDEN);
    assert!(api.message.contains("worker w1's"), "{}", api.message);
    // A job records its submitter.
    let ana = farm.tokens[1].1.clone().expect("ana's token");
    let id = farm.job(&ana).await;
    let status = farm.admin.job(id).await.expect("status");
    assert_eq!(status.submitter.as_deref(), Some("ana"));
    let own = farm.job(CLIENT).await;
    assert_eq!(
        farm.admin
            .job(own)
            .await
            .expect("status")
            .submitter
            .as_deref(),
        Some("admin")
    );
    // A dashboard session of ana's, then her token revoked: both refused from then on.
    let http = reqwest::Client::builder()
        .redirect(reqwest::redirect::Policy::none())
        .build()
        .expect("http");
    let login = http
        .post(format!("{}/login", farm.url))
        .form(&[("token", ana.as_str())])
        .send()
        .await
        .expect("login");
    let cookie = login
        .headers()
        .get_all(reqwest::header::SET_COOKIE)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .find(|v| v.starts_with("tessera_session="))
        .and_then(|v| v.split(';').next())
        .expect("a session cookie")
        .to_string();
    let session = |c: &str| {
        http.get(format!("{}/v1/session", farm.url))
            .header(reqwest::header::COOKIE, c.to_string())
            .send()
    };
    let info: serde_json::Value = session(&cookie)
        .await
        .expect("session")
        .json()
        .await
        .expect("json");
    assert_eq!(info["user"], "ana");
    assert_eq!(info["role"], "artist");
    let revoked = farm.admin.revoke_user("ana").await.expect("revoked");
    assert!(revoked.revoked_ms.is_some());
    let status = Client::new(&farm.url, &ana)
        .expect("client")
        .job(id)
        .await
        .expect_err("revoked")
        .downcast::<tessera_farm::client::ApiError>()
        .expect("an API error")
        .status;
    assert_eq!(status, StatusCode::UNAUTHORIZED);
    assert_eq!(
        session(&cookie).await.expect("session").status(),
        StatusCode::UNAUTHORIZED
    );
    // The name can be given again, with a new token; the old one stays refused.
    let again = farm
        .admin
        .add_user(&NewUser {
            name: "ana".into(),
            role: Role::Viewer,
        })
        .await
        .expect("added again");
    assert_ne!(again.token, ana);
    let users = farm.admin.users().await.expect("users");
    let names: Vec<(&str, Role)> = users.iter().map(|u| (u.name.as_str(), u.role)).collect();
    assert!(names.contains(&("ana", Role::Viewer)), "{names:?}");
    assert!(names.contains(&("w1", Role::Worker)), "{names:?}");
    farm.running.stop().await.expect("stop");
}
