//! The crate's error type.

use deepcontact_core::{CoreError, Real};

/// Everything that can go wrong in this crate. Variants carry the offending data.
///
/// At the [`deepcontact_core::VelocitySolver`] boundary the error is converted into a
/// [`CoreError`] with [`LcpError::into_core`] (or `From`, which names the solver `"lcp"`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum LcpError {
    /// The problem, the stop rule or the buffers handed to a solver failed validation.
    #[error("invalid problem: {0}")]
    InvalidProblem(#[from] CoreError),
    /// A solver setting is out of range.
    #[error("invalid setting {name} = {value}: {reason}")]
    InvalidSetting {
        /// Setting name, e.g. `"omega"`.
        name: &'static str,
        /// The rejected value.
        value: Real,
        /// Why it was rejected.
        reason: &'static str,
    },
    /// The Newton system stayed singular (non-finite or inaccurate solution) even with the
    /// largest allowed regularisation.
    #[error(
        "Newton system of {rows} rows singular in iteration {iteration} even with regularisation {regularization:e}"
    )]
    Singular {
        /// Size of the linear system.
        rows: usize,
        /// Last (largest) relative regularisation tried.
        regularization: Real,
        /// Iteration (1-based).
        iteration: u32,
    },
    /// An iterate, a velocity or a matrix entry became non-finite.
    #[error("non-finite {what} at row {row} in iteration {iteration}")]
    NonFinite {
        /// What became non-finite (`"impulse"`, `"Delassus entry"`, ...).
        what: &'static str,
        /// Row (2 × point for normal rows, 2 × point + 1 for tangent rows).
        row: usize,
        /// Iteration (1-based; 0 = before the first iteration).
        iteration: u32,
    },
    /// A forced dense assembly of a problem too large for dense storage.
    #[error("dense assembly of {rows} rows exceeds the limit of {limit} rows")]
    TooLargeForDense {
        /// Rows of the problem (2 per point).
        rows: usize,
        /// Largest dense size allowed ([`crate::MAX_DENSE_ROWS`]).
        limit: usize,
    },
    /// The exact (enumerating) solver was given too many points.
    #[error("exact solver: {points} points exceed the limit of {limit}")]
    TooManyPointsForExact {
        /// Points in the problem.
        points: usize,
        /// Largest number of points the enumeration accepts ([`crate::EXACT_MAX_POINTS`]).
        limit: usize,
    },
    /// The exact solver found no active set whose solution is complementary and admissible.
    #[error("exact solver: none of the {combinations} active sets gives an admissible solution")]
    NoExactSolution {
        /// Active sets tried.
        combinations: usize,
    },
    /// faer reported a failure of a sparse factorisation.
    #[error("sparse factorisation of {rows} rows failed: {reason}")]
    Factorization {
        /// Size of the matrix.
        rows: usize,
        /// faer's message.
        reason: String,
    },
}

impl LcpError {
    /// Converts into the core error, naming the solver that failed.
    pub fn into_core(self, solver: &str) -> CoreError {
        match self {
            LcpError::InvalidProblem(e) => e,
            LcpError::InvalidSetting {
                name,
                value,
                reason,
            } => CoreError::InvalidSetting {
                name,
                value,
                reason,
            },
            other => CoreError::Solver {
                solver: solver.to_string(),
                reason: other.to_string(),
            },
        }
    }
}

impl From<LcpError> for CoreError {
    fn from(e: LcpError) -> Self {
        e.into_core("lcp")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn conversion_into_core_errors_keeps_the_data() {
        let lengths = CoreError::LengthMismatch {
            what: "impulses",
            expected: 3,
            got: 2,
        };
        assert_eq!(LcpError::from(lengths.clone()).into_core("psor"), lengths);
        let e = LcpError::InvalidSetting {
            name: "omega",
            value: 2.5,
            reason: "must be in (0, 2)",
        };
        assert!(matches!(
            CoreError::from(e),
            CoreError::InvalidSetting { name: "omega", .. }
        ));
        let inner = CoreError::InvalidProblem("x".into());
        assert_eq!(LcpError::from(inner.clone()).into_core("newton"), inner);
        let e = LcpError::Singular {
            rows: 6,
            regularization: 100.0,
            iteration: 3,
        };
        match e.into_core("newton") {
            CoreError::Solver { solver, reason } => {
                assert_eq!(solver, "newton");
                assert!(
                    reason.contains("6 rows") && reason.contains("iteration 3"),
                    "{reason}"
                );
            }
            other => panic!("{other:?}"),
        }
    }
}
