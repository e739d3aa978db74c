//! Steering the farm end to end, with real processes on loopback: a worker that fails every
//! task is blocklisted for the job, which completes on the other worker bit-identical to
//! `tessera render`; and every farm command of the CLI against a coordinator serving HTTPS
//! with a self-signed certificate, its URL, token and CA kept by `tessera login`.

mod common;

use std::path::Path;
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};

use common::*;
use tessera_farm::client::Client;
use tessera_farm::protocol::{JobList, JobState, WorkerStatus};

fn cornell() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/cornell-box/scene.json")
}

/// Polls `f` until it gives a value, for at most `timeout`.
fn until<T>(what: &str, timeout: Duration, mut f: impl FnMut() -> Option<T>) -> T {
    let start = Instant::now();
    loop {
        if let Some(v) = f() {
            return v;
        }
        assert!(start.elapsed() < timeout, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(100));
    }
}

#[test]
fn a_job_whose_tasks_fail_on_one_worker_completes_on_the_other_bit_identical() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (_serve, url) = serve_with(&dir.path().join("data"), "127.0.0.1:0", "5", &[]);
    let rt = runtime();
    let client = Client::new(&url, CLIENT_TOKEN).expect("client");
    // The broken machine first, so that it takes tasks; then a good one.
    let _broken = Proc(
        Command::new(exe())
            .args(["worker", "--coordinator", &url, "--token", WORKER_TOKEN])
            .args(["--name", "broken", "--slots", "1"])
            .args(["--fail-tasks-with", "simulated fault: no GPU"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .expect("start the broken worker"),
    );
    until("the broken worker", Duration::from_secs(30), || {
        rt.block_on(client.workers())
            .ok()
            .filter(|w| w.iter().any(|w| w.name == "broken"))
    });
    let _good = worker(&url, "good", &dir.path().join("good.log"));
    let args = ["--size", "64x48", "--spp", "4", "--tile", "8"];
    let (id, _) = submit_and_compare(&url, &cornell(), "survivor", &args, dir.path());
    let job = rt.block_on(client.job(id)).expect("status");
    assert_eq!(job.state, JobState::Done);
    assert_eq!(job.blocklist.len(), 1, "{:?}", job.blocklist);
    let b = &job.blocklist[0];
    assert!(b.worker.starts_with("broken-") && b.failures == 3, "{b:?}");
    assert_eq!(b.last_error.as_deref(), Some("simulated fault: no GPU"));
    // Its failures are in the attempt log; the worker list shows it blocklisted.
    let attempts = rt
        .block_on(client.attempts(id, true, 10))
        .expect("attempts");
    assert!(
        attempts[..3]
            .iter()
            .all(|a| a.outcome.as_deref() == Some("failed") && a.worker == b.worker)
    );
    let workers = rt.block_on(client.workers()).expect("workers");
    let broken = workers
        .iter()
        .find(|w| w.id == b.worker)
        .expect("broken worker");
    assert_eq!(
        (broken.blocklisted_for.clone(), broken.failures),
        (vec![id], 3)
    );
    // Lifted, it may take the job's tasks again (none are left).
    let broken = rt
        .block_on(client.unblock(&b.worker, Some(id)))
        .expect("unblock");
    assert!(broken.blocklisted_for.is_empty());
}

/// A self-signed certificate for 127.0.0.1 and localhost: (certificate, key) PEM files.
fn self_signed(dir: &Path) -> (std::path::PathBuf, std::path::PathBuf) {
    let c = rcgen::generate_simple_self_signed(vec!["127.0.0.1".into(), "localhost".into()])
        .expect("certificate");
    let (cert, key) = (dir.join("cert.pem"), dir.join("key.pem"));
    std::fs::write(&cert, c.cert.pem()).expect("write cert");
    std::fs::write(&key, c.key_pair.serialize_pem()).expect("write key");
    (cert, key)
}

/// `tessera ARGS` with the config directory `config` and no coordinator in the environment.
fn cli(config: &Path, args: &[&str]) -> Output {
    Command::new(exe())
        .args(args)
        .env("XDG_CONFIG_HOME", config)
        .env_remove("TESSERA_COORDINATOR")
        .env_remove("TESSERA_CLIENT_TOKEN")
        .env_remove("TESSERA_CA")
        .output()
        .expect("run tessera")
}

/// Its standard output, after checking it succeeded.
fn ok(o: Output) -> String {
    assert!(
        o.status.success(),
        "{}\n{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    );
    String::from_utf8_lossy(&o.stdout).into_owned()
}

#[test]
fn every_farm_command_works_over_tls_with_a_self_signed_certificate() {
    let dir = tempfile::tempdir().expect("temp dir");
    let (cert, key) = self_signed(dir.path());
    let (cert_s, key_s) = (cert.to_string_lossy(), key.to_string_lossy());
    let (_serve, url) = serve_with(
        &dir.path().join("data"),
        "127.0.0.1:0",
        "5",
        &[
            "--local-workers",
            "2",
            "--tls-cert",
            &cert_s,
            "--tls-key",
            &key_s,
        ],
    );
    assert!(url.starts_with("https://"), "{url}");
    let config = dir.path().join("config");

    // Without the CA the certificate is refused; with it, `login` keeps all three.
    let refused = cli(
        &config,
        &["jobs", "--coordinator", &url, "--token", CLIENT_TOKEN],
    );
    assert!(
        !refused.status.success(),
        "an unknown certificate was accepted"
    );
    let wrong = cli(
        &config,
        &["login", &url, "--token", "nope", "--ca", &cert_s],
    );
    assert!(
        !wrong.status.success() && String::from_utf8_lossy(&wrong.stderr).contains("401"),
        "{}",
        String::from_utf8_lossy(&wrong.stderr)
    );
    let out = ok(cli(
        &config,
        &["login", &url, "--token", CLIENT_TOKEN, "--ca", &cert_s],
    ));
    assert!(out.contains("logged in"), "{out}");
    let file = config.join("tessera").join("config.toml");
    let kept = std::fs::read_to_string(&file).expect("config file");
    assert!(kept.contains(&url) && kept.contains(CLIENT_TOKEN), "{kept}");
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let mode = std::fs::metadata(&file).expect("meta").permissions().mode();
        assert_eq!(mode & 0o077, 0, "the token file is readable by others");
    }

    // From here on no flags: the config file says where and who.
    let scene = cornell();
    let scene_s = scene.to_string_lossy();
    let small = ["--size", "48x32", "--spp", "4"];
    let frames = dir.path().join("frames");
    let frames_s = frames.to_string_lossy();
    let out = ok(cli(
        &config,
        &[
            &["submit", &scene_s, "--wait", "-q", "-o", &frames_s],
            &small[..],
        ]
        .concat(),
    ));
    let first: i64 = out
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("job id");
    let farm = std::fs::read(frames.join("frame_0001.exr")).expect("frame");
    let local = render_locally(&scene, &small, &dir.path().join("local.exr"));
    assert!(
        farm == local,
        "the frame over TLS differs from tessera render's"
    );

    let listing = ok(cli(&config, &["jobs"]));
    assert!(
        listing
            .lines()
            .any(|l| l.starts_with(&format!("{first} ")) && l.contains("done")),
        "{listing}"
    );
    let list: JobList =
        serde_json::from_str(&ok(cli(&config, &["jobs", "--json", "--state", "done"])))
            .expect("jobs --json");
    assert_eq!((list.total, list.jobs[0].id), (1, first));
    let detail = ok(cli(&config, &["job", &first.to_string()]));
    assert!(
        detail.contains("done") && detail.contains("decisions:"),
        "{detail}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&ok(cli(&config, &["job", &first.to_string(), "--json"])))
            .expect("job --json");
    assert_eq!(json["job"]["id"], first);

    let workers: Vec<WorkerStatus> =
        serde_json::from_str(&ok(cli(&config, &["workers", "--json"]))).expect("workers --json");
    assert_eq!(workers.iter().filter(|w| w.alive).count(), 2);
    let table = ok(cli(&config, &["workers"]));
    assert!(
        table.contains("local-1") && table.contains("local-2"),
        "{table}"
    );

    // A longer job to steer: pause, resume, reprioritise, cancel, requeue, download, delete.
    let out = ok(cli(
        &config,
        &[
            "submit", &scene_s, "--size", "96x64", "--spp", "256", "--tile", "16",
        ],
    ));
    let id: i64 = out
        .split_whitespace()
        .nth(1)
        .and_then(|s| s.parse().ok())
        .expect("job id");
    let ids = id.to_string();
    assert!(ok(cli(&config, &["pause", &ids])).contains("paused"));
    assert!(ok(cli(&config, &["resume", &ids])).contains(&format!("job {id}:")));
    assert!(ok(cli(&config, &["priority", &ids, "7"])).contains("priority 7"));
    assert!(ok(cli(&config, &["priority", &ids, "-2"])).contains("priority -2"));
    assert!(ok(cli(&config, &["cancel", &ids])).contains("cancelled"));
    let not_ended = cli(&config, &["requeue", &first.to_string()]);
    assert!(
        !not_ended.status.success()
            && String::from_utf8_lossy(&not_ended.stderr).contains("only a failed or cancelled"),
        "{}",
        String::from_utf8_lossy(&not_ended.stderr)
    );
    assert!(ok(cli(&config, &["requeue", &ids])).contains(&format!("job {id}:")));
    until("the requeued job", Duration::from_secs(240), || {
        let j: serde_json::Value =
            serde_json::from_str(&ok(cli(&config, &["job", &ids, "--json"]))).ok()?;
        (j["job"]["state"] == "done").then_some(())
    });
    let down = dir.path().join("down");
    let out = ok(cli(
        &config,
        &["download", &ids, "-o", &down.to_string_lossy()],
    ));
    assert!(out.contains("frame_0001.exr"), "{out}");
    assert!(down.join("frame_0001.exr").is_file());
    assert!(ok(cli(&config, &["delete", &ids])).contains("deleted"));
    let gone = cli(&config, &["job", &ids]);
    assert!(!gone.status.success() && String::from_utf8_lossy(&gone.stderr).contains("404"));

    // Drain a worker and let it work again.
    let w = &workers[0].id;
    assert!(ok(cli(&config, &["drain", w])).contains("draining"));
    assert!(ok(cli(&config, &["undrain", w])).contains("takes work"));

    // Users: an artist's token reads the farm but may not steer the admin's job; revoked, it
    // is refused.
    let out = ok(cli(&config, &["users", "add", "ana", "--role", "artist"]));
    let ana = out
        .lines()
        .last()
        .expect("the token line")
        .trim()
        .to_string();
    assert!(
        out.contains("added ana (artist)") && ana.len() >= 32,
        "{out}"
    );
    let listing = ok(cli(&config, &["users", "list"]));
    assert!(
        listing
            .lines()
            .any(|l| l.starts_with("ana ") && l.contains("artist")),
        "{listing}"
    );
    let as_ana = |args: &[&str]| cli(&config, &[args, &["--token", &ana]].concat());
    assert!(ok(as_ana(&["jobs"])).contains(&format!("{first} ")));
    let refused = as_ana(&["delete", &first.to_string()]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("403"), "{err}");
    assert!(ok(cli(&config, &["users", "revoke", "ana"])).contains("revoked ana"));
    let refused = as_ana(&["jobs"]);
    let err = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && err.contains("401"), "{err}");
    let unknown = cli(&config, &["users", "add", "bob", "--role", "boss"]);
    assert!(
        !unknown.status.success()
            && String::from_utf8_lossy(&unknown.stderr)
                .contains("expected admin, artist, viewer or worker"),
        "{}",
        String::from_utf8_lossy(&unknown.stderr)
    );
}
