//! `deepcontact grid-roundtrip`: arguments of [`deepcontact_experiments::roundtrip`].

use std::path::PathBuf;

use clap::Args;
use deepcontact_experiments::preset::Preset;
use deepcontact_experiments::roundtrip::{RoundtripConfig, markdown, table, write_roundtrip};

use crate::common::CliError;

/// Options of `grid-roundtrip`.
#[derive(Debug, Clone, Args)]
pub struct GridRoundtripArgs {
    /// Number of piles (seeds `first_seed..first_seed + worlds`).
    #[arg(long, default_value_t = 25)]
    pub worlds: u64,
    /// Steps each pile is simulated before the round trip.
    #[arg(long, default_value_t = 200)]
    pub steps: u64,
    /// First seed.
    #[arg(long, default_value_t = 0)]
    pub first_seed: u64,
    /// Circles per pile (the box is scaled to keep the density).
    #[arg(long, default_value_t = 100)]
    pub bodies: usize,
    /// Output directory.
    #[arg(long, default_value = "results")]
    pub out: PathBuf,
    /// `thesis`: settle with the original's Step(0.01, 10, 10) and average per world.
    #[arg(long, default_value = "default")]
    pub preset: String,
}

/// Runs `grid-roundtrip`: prints the table and writes CSV + Markdown into `--out`.
pub fn run(args: GridRoundtripArgs) -> Result<(), CliError> {
    let config = Preset::parse(&args.preset)?.roundtrip(RoundtripConfig {
        worlds: args.worlds,
        steps: args.steps,
        first_seed: args.first_seed,
        bodies: args.bodies,
        ..RoundtripConfig::default()
    });
    let rows = table(&config)?;
    print!("{}", markdown(&rows, &config));
    let [csv, md] = write_roundtrip(&rows, &config, &args.out)?;
    println!("\nwrote {} and {}", csv.display(), md.display());
    Ok(())
}
