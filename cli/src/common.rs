//! Options and helpers shared by the subcommands.

use clap::{Args, ValueEnum};
use deepcontact_core::{ResidualNorm, SolverSettings, WorldSettings};
use deepcontact_warmstart::Registry;

/// Errors of the command-line tool: one line each, exit code 1.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// From the core crate (bad scene, bad settings, failed step).
    #[error(transparent)]
    Core(#[from] deepcontact_core::CoreError),
    /// From the registry (bad provider or solver spec).
    #[error(transparent)]
    Spec(#[from] deepcontact_warmstart::WarmstartError),
    /// Reading or writing a file.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: String,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// Drawing a figure.
    #[error("plot {path}: {reason}")]
    Plot {
        /// The output file.
        path: String,
        /// What failed.
        reason: String,
    },
    /// A bad command-line value not caught by the parser.
    #[error("{0}")]
    Usage(String),
}

/// Norm of the stop rule.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum NormArg {
    /// max |Δλ|
    Inf,
    /// sqrt(Σ Δλ²)
    L2,
}

/// Velocity-solver stop rule options shared by `simulate` and `compare`.
#[derive(Debug, Clone, Args)]
pub struct SolverArgs {
    /// Velocity solver (registry spec, e.g. `pgs` or `pgs:block=false`).
    #[arg(long, default_value = "pgs")]
    pub solver: String,
    /// Stop when the impulse change is below this (0 = always run to the cap).
    #[arg(long, default_value_t = 1e-4)]
    pub tolerance: f64,
    /// Iteration cap of the velocity solver.
    #[arg(long, default_value_t = 1000)]
    pub max_iterations: u32,
    /// Norm of the stop rule.
    #[arg(long, value_enum, default_value = "inf")]
    pub norm: NormArg,
}

impl SolverArgs {
    /// World settings (thesis defaults) with this stop rule.
    pub fn world_settings(&self) -> WorldSettings {
        WorldSettings {
            solver: SolverSettings {
                max_iterations: self.max_iterations,
                tolerance: self.tolerance,
                norm: match self.norm {
                    NormArg::Inf => ResidualNorm::Infinity,
                    NormArg::L2 => ResidualNorm::L2,
                },
                min_iterations: 1,
            },
            ..WorldSettings::default()
        }
    }
}

/// The registry with every provider and solver this build knows.
pub fn registry() -> Registry {
    let mut registry = Registry::with_defaults();
    deepcontact_onnx::register(&mut registry);
    registry
}
