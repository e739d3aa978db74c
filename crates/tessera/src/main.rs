//! `tessera`: the command-line interface of the Tessera render farm.

mod bench;
mod compare;
mod export;
mod farm;
mod reference;
mod remote;
mod render;
mod users;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "tessera",
    version,
    about = "Physically based rendering, on one machine or a farm"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene on this machine and write an OpenEXR image (plus a PNG preview).
    Render(render::RenderArgs),
    /// Compare an image with a reference: relMSE, RMSE and mean ratio.
    Compare(compare::CompareArgs),
    /// Render a converged reference (adaptive, with a stated stopping rule).
    Reference(reference::ReferenceArgs),
    /// Write a scene as Mitsuba 3 reads it (scene.xml and PLY meshes), as Tessera resolved it.
    Export(export::ExportArgs),
    /// Run the coordinator: HTTP API, job store, scheduler (and local workers).
    Serve(farm::ServeArgs),
    /// Run a worker: lease tasks from a coordinator and render them.
    Worker(farm::WorkerArgs),
    /// Submit a scene to a coordinator (and wait for its frames).
    Submit(farm::SubmitArgs),
    /// Keep a coordinator's URL and client token (and CA) for the commands below.
    Login(remote::LoginArgs),
    /// List a coordinator's jobs.
    Jobs(remote::JobsArgs),
    /// A job's status, frames, failures and decisions.
    Job(remote::JobArgs),
    /// Cancel a job.
    Cancel(remote::ActionArgs),
    /// Pause a job (leased tasks finish; nothing more is leased).
    Pause(remote::ActionArgs),
    /// Resume a paused job.
    Resume(remote::ActionArgs),
    /// Requeue a failed or cancelled job's unfinished tasks.
    Requeue(remote::ActionArgs),
    /// Change a job's priority.
    Priority(remote::PriorityArgs),
    /// Delete a job that has ended, with its frames and results.
    Delete(remote::ActionArgs),
    /// Download a job's finished frames.
    Download(remote::DownloadArgs),
    /// List a coordinator's workers.
    Workers(remote::WorkersArgs),
    /// Drain a worker: it finishes what it holds and takes nothing more.
    Drain(remote::DrainArgs),
    /// Let a drained worker take work again.
    Undrain(remote::DrainArgs),
    /// A coordinator's users and their tokens: add, list, revoke (an admin's token).
    Users(users::UsersArgs),
    /// List the rendering methods (`--integrator`, `integrator.type`).
    Methods,
    /// Measure: speed against error for a scene (or `bench farm`, `bench leases`).
    Bench(bench::BenchArgs),
}

/// Runs an async command on a multi-threaded runtime.
fn block_on<F: std::future::Future<Output = anyhow::Result<()>>>(f: F) -> anyhow::Result<()> {
    tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?
        .block_on(f)
}

/// Writes to standard output; a reader that went away (a closed pipe) is not an error.
fn print(text: &str) -> anyhow::Result<()> {
    use std::io::Write;
    match std::io::stdout().lock().write_all(text.as_bytes()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    // Services log what they do; one-shot commands only warnings. RUST_LOG overrides.
    let default = match cli.command {
        Command::Serve(_) | Command::Worker(_) => "info",
        _ => "warn",
    };
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env()
                .unwrap_or_else(|_| tracing_subscriber::EnvFilter::new(default)),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let result = match cli.command {
        Command::Render(args) => render::run(args),
        Command::Compare(args) => compare::run(args),
        Command::Reference(args) => reference::run(args),
        Command::Export(args) => export::run(args),
        Command::Serve(args) => block_on(farm::serve(args)),
        Command::Worker(args) => block_on(farm::worker(args)),
        Command::Submit(args) => block_on(farm::submit(args)),
        Command::Login(args) => block_on(remote::login(args)),
        Command::Jobs(args) => block_on(remote::jobs(args)),
        Command::Job(args) => block_on(remote::job(args)),
        Command::Cancel(args) => block_on(remote::act(remote::Action::Cancel, args)),
        Command::Pause(args) => block_on(remote::act(remote::Action::Pause, args)),
        Command::Resume(args) => block_on(remote::act(remote::Action::Resume, args)),
        Command::Requeue(args) => block_on(remote::act(remote::Action::Requeue, args)),
        Command::Priority(args) => block_on(remote::priority(args)),
        Command::Delete(args) => block_on(remote::act(remote::Action::Delete, args)),
        Command::Download(args) => block_on(remote::download(args)),
        Command::Workers(args) => block_on(remote::workers(args)),
        Command::Users(args) => block_on(users::run(args)),
        Command::Drain(args) => block_on(remote::drain(args, true)),
        Command::Undrain(args) => block_on(remote::drain(args, false)),
        Command::Methods => farm::methods(),
        Command::Bench(args) => bench::run(args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            // Bad input (the scene) is exit code 2, everything else 1.
            if e.downcast_ref::<tessera_scene::SceneError>().is_some() {
                ExitCode::from(2)
            } else {
                ExitCode::FAILURE
            }
        }
    }
}
