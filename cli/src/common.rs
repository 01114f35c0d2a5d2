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
    /// A soak check failed.
    #[error("soak {warm_start}: step {step}: {what}")]
    Soak {
        /// The provider spec.
        warm_start: String,
        /// The step at which the check failed.
        step: u64,
        /// What was violated, with the body and values.
        what: String,
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
    /// Keep contact points up to this separation in metres (0 = touching only, as Box2D
    /// v2.4 circles; a small margin gives speculative contacts that do not flicker).
    #[arg(long, default_value_t = 0.0)]
    pub prediction: f64,
    /// Linear slop of the position pass in metres (the original code's 0.0005; Box2D's
    /// default is 0.005).
    #[arg(long, default_value_t = 0.0005)]
    pub linear_slop: f64,
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
            prediction: self.prediction,
            position: deepcontact_core::PositionSettings {
                linear_slop: self.linear_slop,
                ..deepcontact_core::PositionSettings::default()
            },
            ..WorldSettings::default()
        }
    }
}

/// The registry with every provider and solver this build knows.
pub fn registry() -> Registry {
    let mut registry = Registry::with_defaults();
    deepcontact_grid::register(&mut registry);
    deepcontact_onnx::register(&mut registry);
    {
        // deepcontact-lcp: PSOR and Newton on the assembled Delassus matrix (faer).
        use deepcontact_lcp::{
            AssemblyMode, NewtonSettings, NewtonSolver, PsorSettings, PsorSolver,
        };
        use deepcontact_warmstart::{Params, WarmstartError};
        fn invalid(p: &Params<'_>, param: &str, value: String, reason: &str) -> WarmstartError {
            let (spec, param, reason) =
                (p.name().to_string(), param.to_string(), reason.to_string());
            WarmstartError::InvalidParameter {
                spec,
                param,
                value,
                reason,
            }
        }
        fn assembly(p: &mut Params<'_>) -> Result<(AssemblyMode, usize), WarmstartError> {
            let mode = match p.string("assembly") {
                None | Some("auto") => AssemblyMode::Auto,
                Some("dense") => AssemblyMode::Dense,
                Some("sparse") => AssemblyMode::Sparse,
                Some(v) => {
                    return Err(invalid(
                        p,
                        "assembly",
                        v.into(),
                        "must be auto, dense or sparse",
                    ));
                }
            };
            let threshold = p.u64(
                "dense_threshold",
                deepcontact_lcp::DEFAULT_DENSE_THRESHOLD as u64,
            )?;
            Ok((mode, usize::try_from(threshold).unwrap_or(usize::MAX)))
        }
        registry.register_solver(
            "psor",
            "projected SOR on the assembled Delassus matrix; omega=1 (in (0,2); 1 = PGS without \
             block solver), assembly=auto|dense|sparse, dense_threshold=128 (rows)",
            |p| {
                let omega = p.f64("omega", 1.0)?;
                let (assembly, dense_threshold) = assembly(p)?;
                let settings = PsorSettings {
                    omega,
                    assembly,
                    dense_threshold,
                    ..PsorSettings::default()
                };
                settings
                    .validate()
                    .map_err(|e| invalid(p, "omega", omega.to_string(), &e.to_string()))?;
                Ok(Box::new(PsorSolver::with_settings(settings)))
            },
        );
        registry.register_solver(
            "newton",
            "semismooth Newton on the natural map (faer LU, Armijo line search); reg=1e-10 \
             (relative regularisation), assembly=auto|dense|sparse, dense_threshold=128 (rows)",
            |p| {
                let regularization = p.f64("reg", NewtonSettings::default().regularization)?;
                let (assembly, dense_threshold) = assembly(p)?;
                let settings = NewtonSettings {
                    regularization,
                    assembly,
                    dense_threshold,
                    ..NewtonSettings::default()
                };
                settings
                    .validate()
                    .map_err(|e| invalid(p, "reg", regularization.to_string(), &e.to_string()))?;
                Ok(Box::new(NewtonSolver::with_settings(settings)))
            },
        );
    }
    registry
}
