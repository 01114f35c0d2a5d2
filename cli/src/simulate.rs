//! `deepcontact simulate`.

use clap::Args;

use crate::common::{CliError, SolverArgs};

/// Options of `simulate`.
#[derive(Debug, Args)]
pub struct SimulateArgs {
    /// Scene: pile, pyramid, stack, resting_ball.
    #[arg(long, default_value = "pile")]
    pub scene: String,
    /// Number of bodies (pile: circles, box scaled to keep the density).
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Seed of the scene.
    #[arg(long, default_value_t = 12345)]
    pub seed: u64,
    /// Steps to run.
    #[arg(long, default_value_t = 250)]
    pub steps: u64,
    /// Warm-start provider (registry spec).
    #[arg(long, default_value = "builtin")]
    pub warm_start: String,
    #[command(flatten)]
    pub solver: SolverArgs,
}

/// Runs `simulate`.
pub fn run(args: SimulateArgs) -> Result<(), CliError> {
    let _ = args;
    Ok(())
}
