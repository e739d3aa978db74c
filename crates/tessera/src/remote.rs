//! The farm from the command line, as a client: `tessera login`, `jobs`, `job`, `cancel`,
//! `pause`, `resume`, `requeue`, `priority`, `delete`, `download`, `workers`, `drain`,
//! `undrain`. Where the coordinator is and its token come from flags, the environment
//! (`TESSERA_COORDINATOR`, `TESSERA_CLIENT_TOKEN`, `TESSERA_CA`) or the config file that
//! `tessera login` writes (`~/.config/tessera/config.toml`), in that order.

use std::path::{Path, PathBuf};

use anyhow::Context;
use serde::{Deserialize, Serialize};
use tessera_farm::client::Client;
use tessera_farm::protocol::{AttemptStatus, JobList, JobPatch, JobState, JobStatus, WorkerStatus};

/// How to reach the coordinator.
#[derive(clap::Args, Clone, Default)]
pub struct Remote {
    /// The coordinator's URL (http:// or https://), or several of one farm, comma-separated
    /// (the next is used when one cannot be reached).
    #[arg(long, env = "TESSERA_COORDINATOR")]
    pub coordinator: Option<String>,
    /// A person's token: the coordinator's client token (an admin) or a user's (`tessera
    /// users add`).
    #[arg(long, env = "TESSERA_CLIENT_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// A private certificate authority to trust (PEM), for an https:// coordinator whose
    /// certificate it signed (or a self-signed one).
    #[arg(long, env = "TESSERA_CA")]
    pub ca: Option<PathBuf>,
}

/// `~/.config/tessera/config.toml` (`$XDG_CONFIG_HOME` if set).
#[derive(Debug, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ConfigFile {
    pub coordinator: Option<String>,
    pub token: Option<String>,
    pub ca: Option<PathBuf>,
}

/// Where the config file lives.
pub fn config_path() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("tessera").join("config.toml"))
}

fn read_config(path: &Path) -> anyhow::Result<ConfigFile> {
    match std::fs::read_to_string(path) {
        Ok(text) => toml::from_str(&text).with_context(|| {
            format!(
                "{}: expected coordinator = \"URL\", token = \"TOKEN\" and optionally ca = \"PEM file\"",
                path.display()
            )
        }),
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(ConfigFile::default()),
        Err(e) => Err(e).with_context(|| format!("reading {}", path.display())),
    }
}

impl Remote {
    /// The coordinator's URL, token and CA: flags and environment first, then the config file.
    pub fn resolve(&self) -> anyhow::Result<(String, String, Option<PathBuf>)> {
        let file = match config_path() {
            Some(p) => read_config(&p)?,
            None => ConfigFile::default(),
        };
        let where_ = config_path().map_or("the config file".into(), |p| p.display().to_string());
        let url = self.coordinator.clone().or(file.coordinator).with_context(|| {
            format!(
                "no coordinator: give --coordinator URL, set TESSERA_COORDINATOR, or run `tessera login URL` (writes {where_})"
            )
        })?;
        let token = self.token.clone().or(file.token).with_context(|| {
            format!(
                "no client token: give --token, set TESSERA_CLIENT_TOKEN, or run `tessera login {url}` (writes {where_})"
            )
        })?;
        Ok((url, token, self.ca.clone().or(file.ca)))
    }

    pub fn client(&self) -> anyhow::Result<Client> {
        let (url, token, ca) = self.resolve()?;
        Client::with_ca(&url, &token, ca.as_deref())
    }
}

#[derive(clap::Args)]
pub struct LoginArgs {
    /// The coordinator's URL.
    pub url: String,
    /// The client token (default: read from standard input).
    #[arg(long, env = "TESSERA_CLIENT_TOKEN", hide_env_values = true)]
    pub token: Option<String>,
    /// A private certificate authority to trust (PEM), kept in the config file.
    #[arg(long)]
    pub ca: Option<PathBuf>,
}

/// `tessera login URL`: checks the token against the coordinator, then keeps URL, token and
/// CA in the config file (readable by its owner only).
pub async fn login(args: LoginArgs) -> anyhow::Result<()> {
    let token = match args.token {
        Some(t) => t,
        None => {
            eprint!("client token for {}: ", args.url);
            let mut line = String::new();
            std::io::stdin()
                .read_line(&mut line)
                .context("reading the token from standard input")?;
            line.trim().to_string()
        }
    };
    anyhow::ensure!(!token.is_empty(), "no token given");
    let ca = args.ca.map(|p| std::path::absolute(&p).unwrap_or(p));
    let client = Client::with_ca(&args.url, &token, ca.as_deref())?;
    let list = client
        .jobs("limit=1")
        .await
        .with_context(|| format!("checking the token with {}", args.url))?;
    let path = config_path().context("no home directory to keep the config file in")?;
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let text = toml::to_string(&ConfigFile {
        coordinator: Some(args.url.clone()),
        token: Some(token),
        ca,
    })?;
    std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(&path, std::fs::Permissions::from_mode(0o600))
            .with_context(|| format!("restricting {}", path.display()))?;
    }
    crate::print(&format!(
        "logged in to {} ({} jobs); kept in {}\n",
        args.url,
        list.total,
        path.display()
    ))
}

#[derive(clap::Args)]
pub struct JobsArgs {
    #[command(flatten)]
    pub remote: Remote,
    /// Only jobs in these states (comma-separated: queued, running, paused, done, failed,
    /// cancelled).
    #[arg(long)]
    pub state: Option<String>,
    /// Only jobs whose name contains this.
    #[arg(long)]
    pub name: Option<String>,
    /// How many (newest first).
    #[arg(long, default_value_t = 50)]
    pub limit: u64,
    /// Skip this many first.
    #[arg(long, default_value_t = 0)]
    pub offset: u64,
    /// JSON, for scripts.
    #[arg(long)]
    pub json: bool,
}

/// The width of the terminal standard output goes to (100 when it is not one).
fn width() -> usize {
    terminal_size::terminal_size_of(std::io::stdout())
        .map_or(100, |(w, _)| w.0 as usize)
        .max(60)
}

/// A table whose column `flex` (the name) is cut to fit the terminal.
pub(crate) fn table(header: &[&str], rows: Vec<Vec<String>>, flex: usize) -> String {
    let n = header.len();
    let mut widths: Vec<usize> = header.iter().map(|h| h.chars().count()).collect();
    for r in &rows {
        for (i, c) in r.iter().enumerate() {
            widths[i] = widths[i].max(c.chars().count());
        }
    }
    let others: usize = widths
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != flex)
        .map(|(_, w)| w + 2)
        .sum();
    widths[flex] = widths[flex].min(width().saturating_sub(others).max(8));
    let line = |cells: Vec<String>| -> String {
        let mut out = String::new();
        for (i, c) in cells.into_iter().enumerate() {
            let w = widths[i];
            let c: String = if c.chars().count() > w {
                c.chars().take(w.saturating_sub(1)).chain(['…']).collect()
            } else {
                c
            };
            if i + 1 == n {
                out += &c;
            } else {
                out += &format!("{c:<w$}  ");
            }
        }
        out.trim_end().to_string() + "\n"
    };
    let mut out = line(header.iter().map(|h| h.to_string()).collect());
    for r in rows {
        out += &line(r);
    }
    out
}

/// A duration in the unit that reads best.
pub(crate) fn duration(ms: i64) -> String {
    let s = ms.max(0) / 1000;
    match s {
        s if s < 60 => format!("{s}s"),
        s if s < 3600 => format!("{}m{:02}s", s / 60, s % 60),
        s => format!("{}h{:02}m", s / 3600, (s % 3600) / 60),
    }
}

/// The method a job runs, as the jobs list and a job's page show it (the dashboard's words).
fn method_of(j: &JobStatus) -> String {
    match j.measuring {
        true => format!("{} (measuring)", j.method),
        false => j.method.clone(),
    }
}

/// Elapsed and estimated time left of a job at `now`.
fn timing(j: &JobStatus, now: i64) -> (String, String) {
    let Some(start) = j.started_ms else {
        return ("-".into(), "-".into());
    };
    let end = j.finished_ms.unwrap_or(now);
    let elapsed = end - start;
    let eta = if j.state.is_final() || j.progress <= 0.0 || j.state == JobState::Paused {
        "-".into()
    } else {
        duration((elapsed as f64 * (1.0 - j.progress) / j.progress) as i64)
    };
    (duration(elapsed), eta)
}

fn now_ms() -> i64 {
    tessera_farm::coordinator::now_ms()
}

/// `tessera jobs`.
pub async fn jobs(args: JobsArgs) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let mut query = format!("limit={}&offset={}", args.limit, args.offset);
    if let Some(s) = &args.state {
        query += &format!("&state={}", urlencode(s));
    }
    if let Some(n) = &args.name {
        query += &format!("&q={}", urlencode(n));
    }
    let list: JobList = client.jobs(&query).await?;
    if args.json {
        return crate::print(&(serde_json::to_string_pretty(&list)? + "\n"));
    }
    let now = now_ms();
    let rows = list
        .jobs
        .iter()
        .map(|j| {
            let (elapsed, eta) = timing(j, now);
            vec![
                j.id.to_string(),
                j.state.as_str().to_string(),
                format!("{:.0}%", 100.0 * j.progress),
                j.priority.to_string(),
                method_of(j),
                j.frames.to_string(),
                format!("{}×{}", j.width, j.height),
                elapsed,
                eta,
                j.name.clone(),
            ]
        })
        .collect();
    let mut text = table(
        &[
            "ID", "STATE", "DONE", "PRI", "METHOD", "FRAMES", "SIZE", "ELAPSED", "ETA", "NAME",
        ],
        rows,
        9,
    );
    let counts: Vec<String> = list
        .by_state
        .iter()
        .map(|(s, n)| format!("{n} {s}"))
        .collect();
    text += &format!(
        "{} of {} jobs ({})\n",
        list.jobs.len(),
        list.total,
        counts.join(", ")
    );
    crate::print(&text)
}

fn urlencode(s: &str) -> String {
    s.bytes()
        .map(|b| match b {
            b'A'..=b'Z' | b'a'..=b'z' | b'0'..=b'9' | b'-' | b'_' | b'.' | b',' => {
                (b as char).to_string()
            }
            b => format!("%{b:02X}"),
        })
        .collect()
}

#[derive(clap::Args)]
pub struct JobArgs {
    /// The job's id.
    pub id: i64,
    #[command(flatten)]
    pub remote: Remote,
    /// JSON (the job's status and its failed attempts), for scripts.
    #[arg(long)]
    pub json: bool,
}

/// `tessera job ID`: status, frames, passes, decisions, failures.
pub async fn job(args: JobArgs) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let j = client.job(args.id).await?;
    let attempts: Vec<AttemptStatus> = client.attempts(args.id, true, 20).await?;
    let failures: Vec<&AttemptStatus> = attempts
        .iter()
        .filter(|a| {
            matches!(
                a.outcome.as_deref(),
                Some("failed" | "expired" | "unreadable")
            )
        })
        .collect();
    if args.json {
        let v = serde_json::json!({"job": j, "failures": failures});
        return crate::print(&(serde_json::to_string_pretty(&v)? + "\n"));
    }
    let (elapsed, eta) = timing(&j, now_ms());
    let mut t = format!(
        "job {} \"{}\": {} — {:.1}% ({} of {} tasks), priority {}\n",
        j.id,
        j.name,
        j.state.as_str(),
        100.0 * j.progress,
        j.tasks.done,
        j.tasks.total.max(j.tasks.planned),
        j.priority
    );
    t += &format!(
        "{} at {}×{}, {} spp, frames {}; elapsed {elapsed}, eta {eta}\n",
        method_of(&j),
        j.width,
        j.height,
        j.spp,
        j.frames
    );
    if !j.require_tags.is_empty() {
        t += &format!("requires worker tags: {}\n", j.require_tags.join(", "));
    }
    if let Some(e) = &j.error {
        t += &format!("error: {e}\n");
    }
    for p in &j.passes {
        t += &format!(
            "pass {}: {} ({}/{} tasks){}\n",
            p.name,
            p.state,
            p.tasks_done,
            p.tasks_total,
            p.summary
                .as_deref()
                .map_or(String::new(), |s| format!(" — {s}"))
        );
    }
    let rows = j
        .frame_status
        .iter()
        .map(|f| {
            vec![
                f.frame.to_string(),
                f.state.clone(),
                format!("{}/{}", f.tasks_done, f.tasks_total),
                f.step.to_string(),
                f.estimated_rel_mse
                    .map_or("-".into(), |e| format!("{e:.2e}")),
            ]
        })
        .collect();
    t += &table(&["FRAME", "STATE", "TASKS", "STEP", "EST. RELMSE"], rows, 1);
    for b in &j.blocklist {
        t += &format!(
            "blocklisted: worker {} after {} failures ({})\n",
            b.worker,
            b.failures,
            b.last_error.as_deref().unwrap_or("")
        );
    }
    if !failures.is_empty() {
        t += "failures (newest first):\n";
        for a in failures {
            t += &format!(
                "  task {} ({} {} of frame {}) on {}: {} — {}\n",
                a.task_id,
                a.kind,
                a.index,
                a.frame,
                a.worker,
                a.outcome.as_deref().unwrap_or(""),
                a.error.as_deref().unwrap_or("")
            );
        }
    }
    if !j.decisions.is_empty() {
        t += "decisions:\n";
        for d in &j.decisions {
            t += &format!("  {d}\n");
        }
    }
    crate::print(&t)
}

/// What an action on a job does.
#[derive(Clone, Copy, PartialEq, Eq)]
pub enum Action {
    Cancel,
    Pause,
    Resume,
    Requeue,
    Delete,
}

#[derive(clap::Args)]
pub struct ActionArgs {
    /// The job's id.
    pub id: i64,
    #[command(flatten)]
    pub remote: Remote,
}

/// `tessera cancel|pause|resume|requeue|delete ID`.
pub async fn act(action: Action, args: ActionArgs) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let id = args.id;
    let status = match action {
        Action::Cancel => client.cancel(id).await?,
        Action::Pause => client.job_action(id, "pause").await?,
        Action::Resume => client.job_action(id, "resume").await?,
        Action::Requeue => client.job_action(id, "requeue").await?,
        Action::Delete => {
            client
                .delete(id)
                .await
                .with_context(|| format!("deleting job {id}"))?;
            return crate::print(&format!("job {id} deleted\n"));
        }
    };
    crate::print(&format!("job {id}: {}\n", status.state.as_str()))
}

#[derive(clap::Args)]
pub struct PriorityArgs {
    /// The job's id.
    pub id: i64,
    /// Its new priority (higher runs first).
    #[arg(allow_hyphen_values = true)]
    pub priority: i32,
    #[command(flatten)]
    pub remote: Remote,
}

/// `tessera priority ID N`.
pub async fn priority(args: PriorityArgs) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let j = client
        .patch_job(
            args.id,
            &JobPatch {
                priority: Some(args.priority),
            },
        )
        .await?;
    crate::print(&format!("job {}: priority {}\n", j.id, j.priority))
}

#[derive(clap::Args)]
pub struct DownloadArgs {
    /// The job's id.
    pub id: i64,
    #[command(flatten)]
    pub remote: Remote,
    /// Where the frames go (frame_0001.exr, ...).
    #[arg(short, long, default_value = ".")]
    pub output: PathBuf,
}

/// `tessera download ID`: the job's finished frames.
pub async fn download(args: DownloadArgs) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let j = client.job(args.id).await?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("creating {}", args.output.display()))?;
    let mut written = 0;
    for f in j.frame_status.iter().filter(|f| f.state == "done") {
        let bytes = client.frame_exr(j.id, f.frame).await?;
        let path = args
            .output
            .join(tessera_farm::job::frame_file_name(f.frame));
        std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
        crate::print(&format!("wrote {}\n", path.display()))?;
        written += 1;
    }
    let left = j.frame_status.len() - written;
    if left > 0 {
        crate::print(&format!(
            "{left} of {} frames not finished yet (job {})\n",
            j.frame_status.len(),
            j.state.as_str()
        ))?;
    }
    anyhow::ensure!(
        written > 0 || j.frame_status.is_empty(),
        "job {} has no finished frame yet",
        j.id
    );
    Ok(())
}

#[derive(clap::Args)]
pub struct WorkersArgs {
    #[command(flatten)]
    pub remote: Remote,
    /// JSON, for scripts.
    #[arg(long)]
    pub json: bool,
}

/// `tessera workers`.
pub async fn workers(args: WorkersArgs) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let list: Vec<WorkerStatus> = client.workers().await?;
    if args.json {
        return crate::print(&(serde_json::to_string_pretty(&list)? + "\n"));
    }
    let now = now_ms();
    let rows = list
        .iter()
        .map(|w| {
            let state = match (w.alive, w.draining) {
                (false, _) => "gone",
                (true, true) => "draining",
                (true, false) if w.leased_tasks.is_empty() => "idle",
                _ => "busy",
            };
            vec![
                w.id.clone(),
                state.into(),
                w.leased_tasks
                    .iter()
                    .map(|t| t.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
                w.tags.join(","),
                w.samples_per_second
                    .map_or("-".into(), |s| format!("{:.2}M", s / 1e6)),
                w.cpu.map_or("-".into(), |c| format!("{c:.1}")),
                format!("{} ago", duration(now - w.last_seen_ms)),
                w.tasks_done.to_string(),
                w.failures.to_string(),
                w.blocklisted_for
                    .iter()
                    .map(|j| j.to_string())
                    .collect::<Vec<_>>()
                    .join(","),
            ]
        })
        .collect();
    crate::print(&table(
        &[
            "WORKER",
            "STATE",
            "TASKS",
            "TAGS",
            "SAMPLES/S",
            "CPU",
            "SEEN",
            "DONE",
            "FAILED",
            "BLOCKED FOR",
        ],
        rows,
        0,
    ))
}

#[derive(clap::Args)]
pub struct DrainArgs {
    /// The worker's id (as `tessera workers` lists it).
    pub worker: String,
    #[command(flatten)]
    pub remote: Remote,
}

/// `tessera drain WORKER` (or `undrain`).
pub async fn drain(args: DrainArgs, drain: bool) -> anyhow::Result<()> {
    let client = args.remote.client()?;
    let w = client.drain(&args.worker, drain).await?;
    crate::print(&format!(
        "worker {}: {}\n",
        w.id,
        if w.draining {
            "draining (finishes what it holds, takes nothing more)"
        } else {
            "takes work"
        }
    ))
}
