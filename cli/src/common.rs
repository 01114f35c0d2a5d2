//! Options shared by the subcommands, and the tool's error type.

use clap::{Args, ValueEnum};
use deepcontact_core::{ResidualNorm, SolverSettings, WorldSettings};
use deepcontact_experiments::ExperimentError;
use deepcontact_experiments::preset::Preset;

/// Errors of the command-line tool: one line each, exit code 1.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// From the experiment library (and through it core, specs, files, figures).
    #[error(transparent)]
    Experiment(#[from] ExperimentError),
    /// A bad command-line value not caught by the parser.
    #[error("{0}")]
    Usage(String),
}

impl From<deepcontact_core::CoreError> for CliError {
    fn from(e: deepcontact_core::CoreError) -> Self {
        Self::Experiment(e.into())
    }
}

impl From<deepcontact_core::SpecError> for CliError {
    fn from(e: deepcontact_core::SpecError) -> Self {
        Self::Experiment(e.into())
    }
}

/// Norm of the stop rule.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum NormArg {
    /// max |Δλ| over the rows (the thesis text's rule).
    Inf,
    /// sqrt(Σ Δλ²) over the rows.
    L2,
    /// The original thesis code's rule: per contact sqrt(Δλn² + max(0, Δλt)²), largest over
    /// the contacts, ≤ tolerance (pgs only).
    Contact,
}

/// Velocity-solver stop rule options shared by `simulate`, `compare` and `generate`.
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
    /// Keep contact points up to this separation in metres (0 = touching only, as Box2D
    /// v2.4 circles; a small margin gives speculative contacts that do not flicker).
    #[arg(long, default_value_t = 0.0)]
    pub prediction: f64,
    /// Linear slop of the position pass in metres (the original code's 0.0005; Box2D's
    /// default is 0.005).
    #[arg(long, default_value_t = 0.0005)]
    pub linear_slop: f64,
    /// What the position pass's stop rule measures: the largest correction C (m), or the
    /// largest position impulse −C/K, as the original thesis code.
    #[arg(long, value_enum, default_value = "correction")]
    pub position_stop: PositionStopArg,
    /// How the position pass measures a circle contact: `fixed` (the narrow phase's normal,
    /// anchors rotating with the bodies, Box2D v3) or `remeasured` (from the current centres
    /// every iteration, Box2D v2.3 as the original thesis code).
    #[arg(long, value_enum, default_value = "fixed")]
    pub circle_contact: CircleContactArg,
    /// `thesis`: the original code's choices (its stop rules, raw warm starts, its `copy`
    /// oracles, its initial worlds where the command has a scene left at `pile`), overriding
    /// `--norm`, `--position-stop`, `--circle-contact` (remeasured), `--tolerance` and
    /// `--max-iterations`; see `deepcontact_experiments::preset`.
    #[arg(long, default_value = "default")]
    pub preset: String,
}

/// How the position pass measures a circle contact.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum CircleContactArg {
    /// The narrow phase's normal held fixed, anchors rotating (Box2D v3).
    Fixed,
    /// Re-measured from the current centres every iteration (Box2D v2.3).
    Remeasured,
}

/// What the position pass's stop rule measures.
#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum PositionStopArg {
    /// The largest correction C (m) < tolerance (Box2D v2.4).
    Correction,
    /// The largest position impulse −C/K ≤ tolerance (the original thesis code).
    Impulse,
}

impl SolverArgs {
    /// The preset named by `--preset`.
    pub fn preset(&self) -> Result<Preset, CliError> {
        Ok(Preset::parse(&self.preset)?)
    }

    /// The solver spec with the preset's options.
    pub fn solver_spec(&self) -> Result<String, CliError> {
        let spec: deepcontact_core::Spec = self.solver.parse()?;
        Ok(self.preset()?.solver(&spec).to_string())
    }

    /// World settings (thesis defaults) with this stop rule and the preset's rules.
    pub fn preset_world_settings(&self) -> Result<WorldSettings, CliError> {
        Ok(self.preset()?.world(self.world_settings()))
    }

    /// World settings (thesis defaults) with this stop rule.
    pub fn world_settings(&self) -> WorldSettings {
        WorldSettings {
            solver: SolverSettings {
                max_iterations: self.max_iterations,
                tolerance: self.tolerance,
                norm: match self.norm {
                    NormArg::Inf => ResidualNorm::Infinity,
                    NormArg::L2 => ResidualNorm::L2,
                    NormArg::Contact => ResidualNorm::Contact,
                },
                min_iterations: 1,
            },
            prediction: self.prediction,
            position: deepcontact_core::PositionSettings {
                linear_slop: self.linear_slop,
                stop_on_impulse: matches!(self.position_stop, PositionStopArg::Impulse),
                circle_contact: match self.circle_contact {
                    CircleContactArg::Fixed => deepcontact_core::CircleContact::Fixed,
                    CircleContactArg::Remeasured => deepcontact_core::CircleContact::Remeasured,
                },
                ..deepcontact_core::PositionSettings::default()
            },
            ..WorldSettings::default()
        }
    }
}
