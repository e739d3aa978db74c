//! What the end-to-end farm tests share: the binaries, a coordinator and workers as child
//! processes on loopback that die with the test, submitting and comparing frames.

#![allow(dead_code, reason = "each test file uses its own part")]

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

use tessera_farm::client::Client;
use tessera_farm::protocol::{JobState, JobStatus};

pub const CLIENT_TOKEN: &str = "client-secret";
pub const WORKER_TOKEN: &str = "worker-secret";

pub fn exe() -> &'static str {
    env!("CARGO_BIN_EXE_tessera")
}

/// A child process that is killed when dropped (a failing test leaves nothing behind).
pub struct Proc(pub Child);

impl Drop for Proc {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `tessera serve` on `listen` and returns it with its URL (read from its first line).
pub fn serve(data: &Path, listen: &str, lease_seconds: &str) -> (Proc, String) {
    serve_with(data, listen, lease_seconds, &[])
}

/// `serve` with extra arguments.
pub fn serve_with(
    data: &Path,
    listen: &str,
    lease_seconds: &str,
    extra: &[&str],
) -> (Proc, String) {
    let mut child = Command::new(exe())
        .args([
            "serve",
            "--listen",
            listen,
            "--lease-seconds",
            lease_seconds,
        ])
        .args(extra)
        .args(
            // Unless the caller names a store, one of this data directory's own.
            tessera_farm::store::test_store_url(data)
                .filter(|_| !extra.contains(&"--store"))
                .map(|url| ["--store".to_owned(), url])
                .into_iter()
                .flatten(),
        )
        .arg("--data")
        .arg(data)
        .args([
            "--client-token",
            CLIENT_TOKEN,
            "--worker-token",
            WORKER_TOKEN,
        ])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("start tessera serve");
    let stdout = child.stdout.take().expect("stdout");
    let mut line = String::new();
    BufReader::new(stdout).read_line(&mut line).expect("read");
    let url = line
        .trim()
        .rsplit(' ')
        .next()
        .filter(|u| u.starts_with("http://") || u.starts_with("https://"))
        .unwrap_or_else(|| panic!("no URL in {line:?}"))
        .to_string();
    (Proc(child), url)
}

/// Starts `tessera worker` with one slot, logging to `log`.
pub fn worker(url: &str, name: &str, log: &Path) -> Proc {
    let log = std::fs::File::create(log).expect("log file");
    Proc(
        Command::new(exe())
            .args(["worker", "--coordinator", url, "--token", WORKER_TOKEN])
            .args(["--name", name, "--slots", "1"])
            .env("RUST_LOG", "info")
            .stdout(Stdio::null())
            .stderr(log)
            .spawn()
            .expect("start tessera worker"),
    )
}

pub fn runtime() -> tokio::runtime::Runtime {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("runtime")
}

/// Submits `scene` with `args`; returns the job id.
pub fn submit_scene(url: &str, scene: &Path, args: &[&str]) -> i64 {
    let o = Command::new(exe())
        .arg("submit")
        .arg(scene)
        .args(["--coordinator", url, "--token", CLIENT_TOKEN])
        .args(args)
        .output()
        .expect("run tessera submit");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let out = String::from_utf8_lossy(&o.stdout);
    out.split_whitespace()
        .nth(1)
        .and_then(|id| id.parse().ok())
        .unwrap_or_else(|| panic!("no job id in {out}"))
}

/// `tessera render SCENE -q ARGS -o OUT`; returns the EXR's bytes.
pub fn render_locally(scene: &Path, args: &[&str], out: &Path) -> Vec<u8> {
    let o = Command::new(exe())
        .arg("render")
        .arg(scene)
        .arg("-o")
        .arg(out)
        .arg("-q")
        .args(args)
        .output()
        .expect("run tessera render");
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    std::fs::read(out).expect("rendered frame")
}

/// `tessera submit SCENE --wait ARGS` through `url`, downloaded into `dir/LABEL`, and
/// `tessera render SCENE ARGS`: the frames must be the same bytes. Returns the job id and the
/// farm's frame. `auto` measures where a job is submitted: its local render replays the
/// farm's choice (`--auto-choice`), and the job must say what it chose.
pub fn submit_and_compare(
    url: &str,
    scene: &Path,
    label: &str,
    args: &[&str],
    dir: &Path,
) -> (i64, Vec<u8>) {
    if args.windows(2).any(|w| w == ["--integrator", "auto"]) {
        return auto_and_replay(url, scene, label, args, dir);
    }
    let out = dir.join(label);
    let o = Command::new(exe())
        .arg("submit")
        .arg(scene)
        .args([
            "--coordinator",
            url,
            "--token",
            CLIENT_TOKEN,
            "--wait",
            "-q",
            "-o",
        ])
        .arg(&out)
        .args(args)
        .output()
        .expect("run tessera submit");
    assert!(
        o.status.success(),
        "{label}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    let id: i64 = String::from_utf8_lossy(&o.stdout)
        .split_whitespace()
        .nth(1)
        .and_then(|id| id.parse().ok())
        .expect("job id");
    let farm = std::fs::read(out.join("frame_0001.exr")).expect("downloaded frame");
    let local = render_locally(scene, args, &dir.join(format!("{label}.exr")));
    assert!(
        farm == local,
        "{label}: the farm's frame differs from tessera render's"
    );
    (id, farm)
}

/// [`submit_and_compare`] for an `auto` job.
fn auto_and_replay(
    url: &str,
    scene: &Path,
    label: &str,
    args: &[&str],
    dir: &Path,
) -> (i64, Vec<u8>) {
    let rt = runtime();
    let client = Client::new(url, CLIENT_TOKEN).expect("client");
    let id = submit_scene(url, scene, args);
    let job = wait_for(&rt, &client, id, Duration::from_secs(300));
    assert_eq!(job.state, JobState::Done, "{label}: {:?}", job.error);
    let choice = job
        .settings
        .choice
        .clone()
        .unwrap_or_else(|| panic!("{label}: the coordinator recorded no choice"));
    assert_eq!(job.method, choice.method, "{label}");
    assert!(
        job.decisions.iter().any(|d| d.starts_with("auto: chose ")),
        "{label}: {:#?}",
        job.decisions
    );
    let farm = rt.block_on(client.frame_exr(id, 1)).expect("frame");
    let json = serde_json::to_string(&choice).expect("choice as JSON");
    let mut replay: Vec<&str> = args.to_vec();
    replay.extend(["--auto-choice", &json]);
    let local = render_locally(scene, &replay, &dir.join(format!("{label}.exr")));
    assert!(
        farm == local,
        "{label}: the farm's frame differs from tessera render's replay of its choice"
    );
    (id, farm)
}

/// Polls the job until it ends (or `timeout`), tolerating a coordinator that is down.
pub fn wait_for(
    rt: &tokio::runtime::Runtime,
    client: &Client,
    id: i64,
    timeout: Duration,
) -> JobStatus {
    let start = Instant::now();
    loop {
        if let Ok(job) = rt.block_on(client.job(id))
            && job.state.is_final()
        {
            return job;
        }
        assert!(
            start.elapsed() < timeout,
            "job {id} did not finish in {timeout:?}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
}
