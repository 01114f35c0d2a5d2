//! `deepcontact soak`: arguments of [`deepcontact_experiments::soak`].

use std::time::Instant;

use clap::Args;
use deepcontact_core::Registry;
use deepcontact_core::registry::split_spec_list;
use deepcontact_experiments::soak::{DEFAULT_SOAK_WARM_STARTS, SoakConfig, run_soak, soak_table};

use crate::common::CliError;

/// Options of `soak`.
#[derive(Debug, Clone, Args)]
pub struct SoakArgs {
    /// Warm starts to soak (comma-separated registry specs).
    #[arg(long, default_value = DEFAULT_SOAK_WARM_STARTS)]
    pub warm_starts: String,
    /// Steps per warm start (200 s of simulated time at dt = 0.01).
    #[arg(long, default_value_t = 20_000)]
    pub steps: u64,
    /// Steps for the oracle providers (`copy…`, `grid`), which solve every step twice.
    #[arg(long, default_value_t = 2_000)]
    pub oracle_steps: u64,
    /// Steps after which the pile counts as settled (energy and penetration checked from here).
    #[arg(long, default_value_t = 1_000)]
    pub settle: u64,
    /// Seed of the pile.
    #[arg(long, default_value_t = 12345)]
    pub seed: u64,
    /// Circles in the pile.
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Worker threads (default: one per core); one provider per thread.
    #[arg(long)]
    pub threads: Option<usize>,
}

/// Runs `soak`: every provider, then the table on stdout.
pub fn run(args: SoakArgs, registry: &Registry) -> Result<(), CliError> {
    let config = SoakConfig {
        warm_starts: split_spec_list(&args.warm_starts)?,
        steps: args.steps,
        oracle_steps: args.oracle_steps,
        settle: args.settle,
        seed: args.seed,
        bodies: args.bodies,
        threads: args.threads.unwrap_or(0),
    };
    let t0 = Instant::now();
    let (runs, threads) = run_soak(&config, registry)?;
    print!(
        "{}",
        soak_table(&config, &runs, threads, t0.elapsed().as_secs_f64())
    );
    Ok(())
}
