//! The core crate's error type.

use crate::math::Real;

/// Everything that can go wrong in the core crate. Variants carry the offending data.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CoreError {
    /// A body or shape parameter is out of range or not finite.
    #[error("body {body}: {field} = {value} is invalid ({reason})")]
    InvalidBodyParameter {
        /// Index the body would have (or has) in the world.
        body: usize,
        /// Name of the field, e.g. `"density"`.
        field: &'static str,
        /// The rejected value.
        value: Real,
        /// Why it was rejected.
        reason: &'static str,
    },
    /// A polygon that is not convex, has fewer than 3 vertices or no area.
    #[error("body {body}: degenerate polygon ({reason})")]
    DegeneratePolygon {
        /// Index of the body.
        body: usize,
        /// What is wrong with it.
        reason: &'static str,
    },
    /// A scene name that [`crate::scene::by_name`] does not know.
    #[error("unknown scene `{name}` (known: {known})")]
    UnknownScene {
        /// The name asked for.
        name: String,
        /// The names accepted, comma separated.
        known: String,
    },
    /// A world or solver setting is out of range.
    #[error("invalid setting {name} = {value}: {reason}")]
    InvalidSetting {
        /// Setting name, e.g. `"dt"`.
        name: &'static str,
        /// The rejected value.
        value: Real,
        /// Why it was rejected.
        reason: &'static str,
    },
    /// A body's state (position, angle or velocity) is not finite when a step starts.
    #[error("body {body}: non-finite {field} entering step {step}")]
    NonFiniteState {
        /// Index of the body.
        body: usize,
        /// `"position"`, `"angle"`, `"linear velocity"` or `"angular velocity"`.
        field: &'static str,
        /// The step about to run.
        step: u64,
    },
    /// A scene file that cannot be read: the line (1-based), the field and why.
    #[error("scene file {file}, line {line}, field {field}: {reason}")]
    SceneFile {
        /// The file (or `"<embedded>"` for the data compiled in).
        file: String,
        /// Line number, 1-based (0 for the file as a whole).
        line: usize,
        /// Column name.
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A handle that does not name a body of this world.
    #[error("unknown body handle {0}")]
    UnknownBody(usize),
    /// A contact problem handed to a solver is inconsistent.
    #[error("invalid contact problem: {0}")]
    InvalidProblem(String),
    /// Buffers handed to a solver have the wrong length.
    #[error("buffer length mismatch for {what}: expected {expected}, got {got}")]
    LengthMismatch {
        /// Which buffer.
        what: &'static str,
        /// Expected length.
        expected: usize,
        /// Actual length.
        got: usize,
    },
    /// The warm-start provider failed and the guard policy says to report it.
    #[error("warm start `{provider}` failed on island {island} of step {step}: {source}")]
    WarmStart {
        /// Provider name.
        provider: String,
        /// Step index.
        step: u64,
        /// Island index within the step.
        island: usize,
        /// What the provider (or the output check) reported.
        #[source]
        source: crate::warm_start::WarmStartError,
    },
    /// A solver reported a failure.
    #[error("solver `{solver}` failed: {reason}")]
    Solver {
        /// Solver name.
        solver: String,
        /// Description of the failure.
        reason: String,
    },
}
