//! `deepcontact generate`: arguments of [`deepcontact_experiments::generate`] (the format is
//! documented in `models/README.md`).

use std::path::PathBuf;

use clap::Args;
use deepcontact_core::Registry;
use deepcontact_experiments::generate::{GenerateConfig, parse_shard, run_generate};
use deepcontact_experiments::seeds::parse_seeds;

use crate::common::{CliError, SolverArgs};

/// Options of `generate`.
#[derive(Debug, Clone, Args)]
pub struct GenerateArgs {
    /// Seeds: comma-separated `a`, `a..b` (end exclusive) or `a..=b` (`0..110`, `0..100,105`).
    #[arg(long, default_value = "0..110")]
    pub seeds: String,
    /// Output directory (created if missing).
    #[arg(long, default_value = "data")]
    pub out: PathBuf,
    /// Steps per seed.
    #[arg(long, default_value_t = 250)]
    pub steps: u64,
    /// Only the seeds `i` with `i mod N == K` (`K/N`, e.g. `0/4`).
    #[arg(long)]
    pub shard: Option<String>,
    /// Number of bodies of the pile.
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Worker threads (0 = all cores).
    #[arg(long, default_value_t = 0)]
    pub jobs: usize,
    /// Regenerate files that already exist.
    #[arg(long)]
    pub force: bool,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
    /// Leave out the input and label grids (for per-contact and graph models; ~40× smaller).
    #[arg(long)]
    pub no_grids: bool,
    /// Velocity solver and stop rule of the simulations.
    #[command(flatten)]
    pub solver: SolverArgs,
}

impl GenerateArgs {
    /// The run these options describe (with `--preset thesis`: the original's stop rules and
    /// raw warm starts; the piles stay ours, as the original's training worlds came from other
    /// seeds than its ten comparison worlds).
    pub fn config(&self) -> Result<GenerateConfig, CliError> {
        let mut seeds = parse_seeds(&self.seeds)?;
        if let Some(shard) = &self.shard {
            let (k, n) = parse_shard(shard)?;
            seeds.retain(|s| s % n == k);
        }
        Ok(GenerateConfig {
            seeds,
            out: self.out.clone(),
            steps: self.steps,
            bodies: self.bodies,
            threads: self.jobs,
            force: self.force,
            progress: !self.quiet,
            solver: self.solver.solver_spec()?,
            world: self.solver.preset_world_settings()?,
            grids: !self.no_grids,
        })
    }
}

/// Runs `generate`.
pub fn run(args: GenerateArgs, registry: &Registry) -> Result<(), CliError> {
    let config = args.config()?;
    let outcome = run_generate(&config, registry)?;
    if !args.quiet {
        eprintln!(
            "generate: {} seed file(s) written, {} already complete, in {}",
            outcome.written,
            outcome.skipped,
            args.out.display()
        );
    }
    Ok(())
}
