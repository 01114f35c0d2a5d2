//! The crate's error type and its mapping to Python exceptions.

use deepcontact_core::{CoreError, SpecError};
use deepcontact_experiments::ExperimentError;
use pyo3::PyErr;
use pyo3::exceptions::{PyException, PyValueError};

pyo3::create_exception!(
    _deepcontact,
    DeepContactError,
    PyException,
    "Base class of the errors raised by deepcontact (a failed step, a failed comparison)."
);
pyo3::create_exception!(
    _deepcontact,
    WarmStartError,
    DeepContactError,
    "A warm start was rejected under guard=\"error\": the provider raised, or returned a wrong \
     shape, a wrong dtype, a non-finite value or a negative normal impulse."
);

/// Everything the binding can fail with, before it becomes a Python exception.
#[derive(Debug, thiserror::Error)]
pub enum PythonBindingError {
    /// From the core crate (bad scene, bad settings, a failed step).
    #[error(transparent)]
    Core(#[from] CoreError),
    /// From the experiment library (a failed comparison).
    #[error(transparent)]
    Experiment(#[from] ExperimentError),
    /// A bad provider or solver spec.
    #[error(transparent)]
    Spec(#[from] SpecError),
    /// A bad argument (its message names it).
    #[error("{0}")]
    Invalid(String),
    /// A comparison part that cannot be read (its index among the parts, and why).
    #[error("comparison part {part}: {reason}")]
    Part {
        /// Index of the part in the list merged.
        part: usize,
        /// What is wrong with it.
        reason: String,
    },
    /// Parts that do not make up the comparison (a run missing, doubled or foreign).
    #[error("merging the comparison's parts: {0}")]
    Merge(String),
    /// A Python exception to raise as it is (a KeyboardInterrupt, a provider's own error).
    #[error(transparent)]
    Python(#[from] PyErr),
}

impl From<PythonBindingError> for PyErr {
    fn from(e: PythonBindingError) -> Self {
        let message = e.to_string();
        match e {
            PythonBindingError::Python(err) => err,
            PythonBindingError::Invalid(_) | PythonBindingError::Spec(_) => {
                PyValueError::new_err(message)
            }
            PythonBindingError::Part { .. } | PythonBindingError::Merge(_) => {
                DeepContactError::new_err(message)
            }
            PythonBindingError::Core(err) => core_error(err, message),
            PythonBindingError::Experiment(ExperimentError::Core(err)) => core_error(err, message),
            PythonBindingError::Experiment(
                ExperimentError::Spec(_) | ExperimentError::Invalid(_),
            ) => PyValueError::new_err(message),
            PythonBindingError::Experiment(_) => DeepContactError::new_err(message),
        }
    }
}

/// The Python exception of a core error: a rejected warm start is a [`WarmStartError`], bad
/// input a `ValueError`, the rest a [`DeepContactError`].
fn core_error(err: CoreError, message: String) -> PyErr {
    match err {
        CoreError::WarmStart { .. } => WarmStartError::new_err(message),
        CoreError::InvalidSetting { .. }
        | CoreError::UnknownScene { .. }
        | CoreError::InvalidBodyParameter { .. }
        | CoreError::SceneFile { .. } => PyValueError::new_err(message),
        _ => DeepContactError::new_err(message),
    }
}

/// `err` as a Python exception whose `__cause__` is `cause` (the provider's own exception
/// behind a rejected warm start), when there is one.
pub fn with_cause(
    py: pyo3::Python<'_>,
    err: PythonBindingError,
    cause: Option<PyErr>,
) -> PythonBindingError {
    let err = PyErr::from(err);
    if err.is_instance_of::<WarmStartError>(py) {
        err.set_cause(py, cause);
    }
    PythonBindingError::Python(err)
}
