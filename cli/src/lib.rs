//! Library side of the `deepcontact` command-line tool: argument parsing for every
//! subcommand, each a module with its arguments and a `run` function that calls
//! [`deepcontact_experiments`].
//!
//! [`main_with`] is the whole tool: a user's own binary gets every subcommand, with their
//! own providers and solvers added to the registry:
//!
//! ```no_run
//! use deepcontact_core::{ProviderInfo, ZeroWarmStart, WarmStart};
//!
//! fn main() {
//!     let mut registry = deepcontact_experiments::full_registry();
//!     registry.register_provider("mine", ProviderInfo::new("my provider"), |_, _| {
//!         Ok(Box::new(ZeroWarmStart) as Box<dyn WarmStart>)
//!     });
//!     deepcontact_cli::main_with(registry); // `my-binary compare --warm-starts builtin,mine`
//! }
//! ```
//!
//! Use it for your own copy of the tool with your providers, scenes or solvers registered.
//!
//! Guides, with code that CI compiles and runs: [write a
//! provider](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/provider.md), [use
//! deepcontact from your own
//! crate](https://github.com/deepcontact/deepcontact/blob/main/docs/guide/depend.md).
#![warn(missing_docs)]

#[cfg(not(any(feature = "tract", feature = "onnxruntime")))]
compile_error!("deepcontact-cli needs a CNN backend: enable `tract` (default) or `onnxruntime`");

pub mod common;
pub mod compare;
pub mod generate;
pub mod grid_roundtrip;
pub mod simulate;
pub mod soak;

use clap::{Parser, Subcommand};
use deepcontact_core::Registry;

pub use common::CliError;

/// 2D rigid-body contacts solved iteratively, with pluggable warm starts.
#[derive(Debug, Parser)]
#[command(name = "deepcontact", version, about)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
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
    /// List the registered warm starts, solvers and scenes with their parameters.
    List,
}

/// Runs one parsed command with the providers and solvers of `registry`.
pub fn run(cli: Cli, registry: &Registry) -> Result<(), CliError> {
    match cli.command {
        Command::Simulate(args) => simulate::run(args, registry),
        Command::Generate(args) => generate::run(args, registry),
        Command::Compare(args) => compare::run(args, registry),
        Command::GridRoundtrip(args) => grid_roundtrip::run(args),
        Command::Soak(args) => soak::run(args, registry),
        Command::List => {
            println!("warm starts:");
            for (name, help) in registry.providers() {
                let info = registry.provider_info(name);
                let tags: Vec<&str> = [
                    (info.is_some_and(|i| i.oracle), "oracle"),
                    (info.is_some_and(|i| i.learned), "learned"),
                    (info.is_some_and(|i| i.needs_world), "needs the world"),
                ]
                .into_iter()
                .filter_map(|(on, tag)| on.then_some(tag))
                .collect();
                let tags = if tags.is_empty() {
                    String::new()
                } else {
                    format!(" [{}]", tags.join(", "))
                };
                println!("  {name}{tags}: {help}");
            }
            println!("solvers:");
            for (name, help) in registry.solvers() {
                println!("  {name}: {help}");
            }
            println!("scenes:");
            for (name, help) in registry.scenes() {
                println!("  {name}: {help}");
            }
            Ok(())
        }
    }
}

/// The whole `deepcontact` tool on `registry`: parses the process's arguments, runs the
/// command, and exits with status 1 and one line on stderr on an error.
pub fn main_with(registry: Registry) {
    if let Err(e) = run(Cli::parse(), &registry) {
        eprintln!("error: {e}");
        std::process::exit(1);
    }
}
