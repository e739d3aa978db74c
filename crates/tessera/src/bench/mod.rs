//! `tessera bench`: figures, not assertions.
//!
//! - `tessera bench SCENE --reference REF.exr`: speed against error (`error.rs`).
//! - `tessera bench farm` / `tessera bench leases`: the farm's overhead and lease throughput
//!   (`farm.rs`).
//! - `tessera bench soak`: a simulated farm of many workers for minutes: no task lost or done
//!   twice, the store's size, the coordinator's CPU (`soak.rs`).
//! - `tessera bench flythrough`: pass artifacts cached across a fly-through's frames against
//!   built per frame: time and flicker (`flythrough.rs`).
//! - `tessera bench load SCENE`: reading, BVH building and the first pixels of a
//!   production-size scene, with the memory it takes (`load.rs`).
//! - `tessera bench rays`: ray casting throughput of the BVH, coherent and incoherent rays,
//!   optionally against Embree (`rays.rs`).
//! - `tessera bench dashboard`: the dashboard's page and API latency with a big store
//!   (`dashboard.rs`).

mod dashboard;
#[cfg(feature = "embree")]
mod embree;
mod error;
mod farm;
mod flythrough;
mod load;
mod plot;
mod rays;
mod soak;

pub use error::ErrorArgs;

#[derive(clap::Args)]
#[command(args_conflicts_with_subcommands = true)]
pub struct BenchArgs {
    #[command(subcommand)]
    pub command: Option<BenchCommand>,
    #[command(flatten)]
    pub error: ErrorArgs,
}

#[derive(clap::Subcommand)]
pub enum BenchCommand {
    /// `tessera render` against `serve --local-workers` + submit, same frame.
    Farm(farm::FarmArgs),
    /// Lease throughput with many simulated workers.
    Leases(farm::LeaseArgs),
    /// A simulated farm for minutes: no task lost or done twice, store size, coordinator CPU.
    Soak(soak::SoakArgs),
    /// A camera-only fly-through on local workers, pass artifacts cached vs built per frame.
    Flythrough(flythrough::FlythroughArgs),
    /// Load, BVH build and first pixels of a scene, and its memory.
    Load(load::LoadArgs),
    /// Ray casting throughput on one core: closest hit and occlusion, coherent and incoherent.
    Rays(rays::RaysArgs),
    /// The dashboard's page and API latency with 1,000 jobs and 100,000 tasks in the store.
    Dashboard(dashboard::DashboardArgs),
}

pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    match args.command {
        Some(BenchCommand::Farm(a)) => crate::block_on(farm::farm(a)),
        Some(BenchCommand::Leases(a)) => crate::block_on(farm::leases(a)),
        Some(BenchCommand::Soak(a)) => crate::block_on(soak::run(a)),
        Some(BenchCommand::Flythrough(a)) => crate::block_on(flythrough::run(a)),
        Some(BenchCommand::Load(a)) => load::run(a),
        Some(BenchCommand::Rays(a)) => rays::run(a),
        Some(BenchCommand::Dashboard(a)) => crate::block_on(dashboard::run(a)),
        None => error::run(args.error),
    }
}
