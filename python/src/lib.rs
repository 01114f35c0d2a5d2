//! # deepcontact-python
//!
//! The native module `deepcontact._deepcontact` of the Python package `deepcontact` (built
//! with maturin from `python/pyproject.toml`; the pure-Python package `python/deepcontact/`
//! wraps it). It converts and calls the libraries, nothing more:
//!
//! * `World` — a scene of [`deepcontact_core::scene`] stepped with registry specs or Python
//!   providers; body state and step reports as NumPy arrays; `step_islands` returns every
//!   island's problem and solution (training data without files);
//! * Python providers — `PythonProvider`, a
//!   [`WarmStart`](deepcontact_core::WarmStart) calling a Python callable or object, its output
//!   checked by the world's guard like a Rust provider's;
//! * `compare` — [`deepcontact_experiments::compare`] with the Python providers registered
//!   into [`deepcontact_experiments::full_registry`], Ctrl-C checked between steps;
//! * comparison parts — the runs of some seeds as exact bytes, and parts merged into the
//!   one-machine comparison's files (what `deepcontact.cluster` fans out and gathers).
//!
//! The GIL is released while Rust works and taken only to call a Python provider.
#![warn(missing_docs)]

mod compare;
mod error;
mod island;
mod parts;
mod provider;
mod world;

use pyo3::prelude::*;

pub use error::PythonBindingError;

/// Runs the comparison of the CLI's `compare` and returns its summary rows (see
/// `deepcontact.compare`, which wraps it).
#[pyfunction]
fn compare_summary(
    py: Python<'_>,
    args: PyRef<'_, compare::CompareArgs>,
) -> Result<Py<pyo3::types::PyList>, PythonBindingError> {
    compare::run(py, &args)
}

/// Runs the comparison of a few seeds and returns its runs as bytes (a part for
/// `compare_merge`; what a cluster task of `deepcontact.cluster` returns). `args.out` and
/// `args.figures` are not used: a part writes nothing.
#[pyfunction]
fn compare_part(
    py: Python<'_>,
    args: PyRef<'_, compare::CompareArgs>,
) -> Result<Py<pyo3::types::PyBytes>, PythonBindingError> {
    let bytes = parts::run_part(py, &args)?;
    Ok(pyo3::types::PyBytes::new(py, &bytes).unbind())
}

/// Merges the parts of a comparison (every seed's runs exactly once) into the files and summary
/// rows of the one-machine comparison; `total_threads` and `wall_seconds` are reported as its
/// threads and wall time.
#[pyfunction]
fn compare_merge(
    py: Python<'_>,
    args: PyRef<'_, compare::CompareArgs>,
    parts: Vec<Vec<u8>>,
    total_threads: usize,
    wall_seconds: f64,
) -> Result<Py<pyo3::types::PyList>, PythonBindingError> {
    parts::merge(py, &args, &parts, total_threads, wall_seconds)
}

/// The providers and solvers of the full registry: `(providers, solvers)`, each a list of
/// `(name, help)` pairs.
#[pyfunction]
#[allow(clippy::type_complexity)]
fn registry() -> (Vec<(String, String)>, Vec<(String, String)>) {
    let registry = deepcontact_experiments::full_registry();
    let pairs = |it: &mut dyn Iterator<Item = (&str, &str)>| {
        it.map(|(n, h)| (n.to_string(), h.to_string())).collect()
    };
    (
        pairs(&mut registry.providers()),
        pairs(&mut registry.solvers()),
    )
}

/// The native module.
#[pymodule]
fn _deepcontact(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    m.add_class::<compare::CompareArgs>()?;
    m.add_class::<world::PyWorld>()?;
    m.add_class::<world::StepReport>()?;
    m.add_class::<world::Island>()?;
    m.add_class::<island::IslandProblem>()?;
    m.add_function(wrap_pyfunction!(compare_summary, m)?)?;
    m.add_function(wrap_pyfunction!(compare_part, m)?)?;
    m.add_function(wrap_pyfunction!(compare_merge, m)?)?;
    m.add_function(wrap_pyfunction!(registry, m)?)?;
    m.add("DeepContactError", py.get_type::<error::DeepContactError>())?;
    m.add("WarmStartError", py.get_type::<error::WarmStartError>())?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
