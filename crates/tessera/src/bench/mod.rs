//! `tessera bench`: figures, not assertions.
//!
//! - `tessera bench SCENE --reference REF.exr`: speed against error (`error.rs`).
//! - `tessera bench farm` / `tessera bench leases`: the farm's overhead and lease throughput
//!   (`farm.rs`).

mod error;
mod farm;
mod plot;

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
}

pub fn run(args: BenchArgs) -> anyhow::Result<()> {
    match args.command {
        Some(BenchCommand::Farm(a)) => crate::block_on(farm::farm(a)),
        Some(BenchCommand::Leases(a)) => crate::block_on(farm::leases(a)),
        None => error::run(args.error),
    }
}
