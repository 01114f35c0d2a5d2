//! `deepcontact`: simulate the thesis scenes, compare warm starts, and more.

use clap::{Parser, Subcommand};
use deepcontact_cli::{compare, generate, grid_roundtrip, simulate, soak};

/// 2D rigid-body contacts solved iteratively, with pluggable warm starts.
#[derive(Debug, Parser)]
#[command(name = "deepcontact", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run one scene with one warm start and report every step.
    Simulate(simulate::SimulateArgs),
    /// Training data for the CNN warm starts: input and label grids per step, one safetensors file per seed.
    Generate(generate::GenerateArgs),
    /// Compare warm starts (× solvers) on the thesis pile over several seeds: tables and figures.
    Compare(compare::CompareArgs),
    /// The thesis's Table 1: body-mass and contact-impulse loss of particles → grid → particles.
    GridRoundtrip(grid_roundtrip::GridRoundtripArgs),
    /// The pile for 20 000 steps with each baseline warm start: no NaN, no escape, energy bounded.
    Soak(soak::SoakArgs),
}

fn main() {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Simulate(args) => simulate::run(args),
        Command::Generate(args) => generate::run(args),
        Command::Compare(args) => compare::run(args),
        Command::GridRoundtrip(args) => grid_roundtrip::run(args),
        Command::Soak(args) => soak::run(args),
    };
    if let Err(e) = result {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
