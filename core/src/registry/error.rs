//! Errors of specs and of the registry.

/// Errors from parsing specs and building providers or solvers.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SpecError {
    /// The spec text is malformed.
    #[error("malformed spec `{spec}`: {reason}")]
    MalformedSpec {
        /// The spec as given.
        spec: String,
        /// What is wrong.
        reason: String,
    },
    /// No provider of that name is registered.
    #[error("unknown warm start `{name}` (known: {known})")]
    UnknownProvider {
        /// Requested name.
        name: String,
        /// Comma-separated registered names.
        known: String,
    },
    /// No solver of that name is registered.
    #[error("unknown solver `{name}` (known: {known})")]
    UnknownSolver {
        /// Requested name.
        name: String,
        /// Comma-separated registered names.
        known: String,
    },
    /// No scene of that name is registered.
    #[error("unknown scene `{name}` (known: {known})")]
    UnknownScene {
        /// Requested name.
        name: String,
        /// Comma-separated registered names.
        known: String,
    },
    /// A parameter the provider does not take.
    #[error("`{spec}` does not take parameter `{param}` (accepted: {accepted})")]
    UnknownParameter {
        /// Provider or solver name.
        spec: String,
        /// The unexpected parameter.
        param: String,
        /// Comma-separated accepted parameters.
        accepted: String,
    },
    /// A parameter value that does not parse or is out of range.
    #[error("`{spec}`: parameter `{param}` = `{value}` is invalid: {reason}")]
    InvalidParameter {
        /// Provider or solver name.
        spec: String,
        /// Parameter name.
        param: String,
        /// The value as given.
        value: String,
        /// Why it was rejected.
        reason: String,
    },
    /// Building the provider failed for another reason (e.g. a model file).
    #[error("cannot build `{spec}`: {reason}")]
    Build {
        /// Provider or solver name.
        spec: String,
        /// What failed.
        reason: String,
    },
}
