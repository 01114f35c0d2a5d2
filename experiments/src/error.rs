//! The crate's error type.

/// Everything an experiment can fail with; each message is one line.
#[derive(Debug, thiserror::Error)]
pub enum ExperimentError {
    /// From the core crate (bad scene, bad settings, failed step).
    #[error(transparent)]
    Core(#[from] deepcontact_core::CoreError),
    /// A bad provider or solver spec.
    #[error(transparent)]
    Spec(#[from] deepcontact_core::SpecError),
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
    /// A grid transfer failed on one world.
    #[error("seed {seed}: grid transfer: {reason}")]
    Grid {
        /// Seed of the world.
        seed: u64,
        /// What the grid crate reported.
        reason: String,
    },
    /// The caller's stop check answered true before the work finished
    /// ([`crate::compare::run_experiment_until`]).
    #[error("stopped before the comparison finished")]
    Stopped,
    /// A configuration value out of range (`what` names the option and the value).
    #[error("{0}")]
    Invalid(String),
}

impl ExperimentError {
    /// An [`ExperimentError::Io`] for `path`.
    pub fn io(path: &std::path::Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.display().to_string(),
            source,
        }
    }
}
