//! The crate's error type.

use std::path::PathBuf;

/// Errors from loading a relaxation policy or learned schedules.
#[derive(Debug, thiserror::Error)]
pub enum RelaxError {
    /// Reading the policy file failed.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The OS error.
        #[source]
        source: std::io::Error,
    },
    /// The file is not JSON of the policy format.
    #[error("relaxation policy {path}: {reason}")]
    Format {
        /// The file (or `<embedded>`).
        path: PathBuf,
        /// What is wrong.
        reason: String,
    },
    /// The policy's features, weights or span do not fit this build.
    #[error("relaxation policy {path}: {reason}")]
    Policy {
        /// The file (or `<embedded>`).
        path: PathBuf,
        /// What is wrong (which field, what was expected, what was found).
        reason: String,
    },
    /// A schedule file's budgets or factors do not fit this build.
    #[error("learned schedules {path}: {reason}")]
    Schedule {
        /// The file (or `<embedded>`).
        path: PathBuf,
        /// What is wrong (which budget, what was found).
        reason: String,
    },
}
