//! `--local-workers N`: worker processes of this same binary, restarted if they die.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use super::App;

/// Starts the local workers; they stop with the coordinator (and, should it be killed, notice
/// their parent is gone and exit).
pub fn spawn(app: &Arc<App>, addr: SocketAddr, stop: tokio::sync::watch::Receiver<bool>) {
    let n = app.config.local_workers;
    let cores = std::thread::available_parallelism().map_or(1, |c| c.get()) as u32;
    let slots = (cores / n).max(1);
    let host = if addr.ip().is_unspecified() {
        SocketAddr::new(std::net::Ipv4Addr::LOCALHOST.into(), addr.port())
    } else {
        addr
    };
    // Over TLS they trust the coordinator's own certificate (a self-signed one, or the
    // chain's leaf), which must name the address they dial.
    let (scheme, ca) = match &app.config.tls {
        Some((cert, _)) => ("https", Some(cert.clone())),
        None => ("http", None),
    };
    let url = format!("{scheme}://{host}");
    let log = app.config.worker_log.clone();
    for i in 1..=n {
        let (url, token, mut stop) = (url.clone(), app.config.worker_token.clone(), stop.clone());
        let (log, ca) = (log.clone(), ca.clone());
        tokio::spawn(async move {
            let exe = match std::env::current_exe() {
                Ok(exe) => exe,
                Err(e) => {
                    tracing::error!(error = %e, "cannot find the tessera binary to start workers");
                    return;
                }
            };
            let name = format!("local-{i}");
            let mut restarts = 0u32;
            loop {
                let child = tokio::process::Command::new(&exe)
                    .args(["worker", "--coordinator", &url, "--name", &name])
                    .args(["--slots", &slots.to_string()])
                    .args(["--parent-pid", &std::process::id().to_string()])
                    .args(
                        ca.iter()
                            .flat_map(|c| [std::ffi::OsStr::new("--ca"), c.as_os_str()]),
                    )
                    .env("TESSERA_WORKER_TOKEN", &token)
                    .envs(log.iter().map(|l| ("RUST_LOG", l.as_str())))
                    .kill_on_drop(true)
                    .spawn();
                let mut child = match child {
                    Ok(c) => c,
                    Err(e) => {
                        tracing::error!(worker = %name, error = %e, "cannot start a local worker");
                        return;
                    }
                };
                tracing::info!(worker = %name, pid = child.id(), slots, "local worker started");
                tokio::select! {
                    status = child.wait() => {
                        restarts += 1;
                        tracing::warn!(worker = %name, ?status, restarts, "local worker exited; restarting");
                    }
                    _ = stop.changed() => {
                        let _ = child.kill().await;
                        return;
                    }
                }
                // Back off so a worker that cannot start does not spin.
                let delay = Duration::from_millis(250 * u64::from(restarts.min(20)));
                tokio::select! {
                    _ = tokio::time::sleep(delay) => {}
                    _ = stop.changed() => return,
                }
            }
        });
    }
}
