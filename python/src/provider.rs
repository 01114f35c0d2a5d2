//! Warm-start providers written in Python, run through the world's guard like Rust ones.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};

use deepcontact_core::{Impulse, Observation, WarmStart, WarmStartContext, WarmStartError};
use numpy::{PyArray2, PyArrayMethods, PyUntypedArray, PyUntypedArrayMethods};
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyString, PyType};

use crate::island::{IslandData, IslandProblem, impulses_to_python};

/// A Python exception that must reach the caller rather than the guard: a
/// `KeyboardInterrupt` (any `BaseException` that is not an `Exception`) raised in a provider,
/// or any exception from `observe` or `reset`, which have no error path in the step. The
/// first one is kept; once set, the provider is no longer called and a running comparison
/// stops before its next step.
///
/// It also keeps the last ordinary exception a provider raised, the cause to chain to a
/// `WarmStartError` when the guard policy is `error`.
#[derive(Debug, Default)]
pub struct Pending {
    error: Mutex<Option<PyErr>>,
    set: AtomicBool,
    cause: Mutex<Option<PyErr>>,
}

impl Pending {
    /// Keeps `err` unless an earlier error is kept.
    fn keep(&self, err: PyErr) {
        if let Ok(mut slot) = self.error.lock() {
            if slot.is_none() {
                *slot = Some(err);
                self.set.store(true, Ordering::SeqCst);
            }
        }
    }

    /// Whether an error is kept.
    pub fn is_set(&self) -> bool {
        self.set.load(Ordering::SeqCst)
    }

    /// Keeps `err` as the cause of the next `WarmStartError` (replacing an older one).
    fn keep_cause(&self, err: PyErr) {
        if let Ok(mut slot) = self.cause.lock() {
            *slot = Some(err);
        }
    }

    /// Takes the last ordinary exception a provider raised, if any.
    pub fn take_cause(&self) -> Option<PyErr> {
        self.cause.lock().ok()?.take()
    }

    /// Takes the kept error, if any.
    pub fn take(&self) -> Option<PyErr> {
        let err = self.error.lock().ok()?.take();
        self.set.store(false, Ordering::SeqCst);
        err
    }
}

/// How the Python object is called.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Style {
    /// `f(island)`.
    Callable,
    /// `obj.warm_start(island)`, with `observe(island, solved)` and `reset()` if present.
    Object { observe: bool, reset: bool },
}

/// A [`WarmStart`] that calls a Python callable, or an object with a `warm_start` method and
/// optional `observe` and `reset`, with the island as an [`IslandProblem`], and reads back an
/// `(n, 2)` float64 NumPy array (copied at once, so a view of anyone's memory is safe).
///
/// A Python exception, a wrong type, dtype or shape becomes a [`WarmStartError`], which the
/// world's guard turns into a counted fallback or a typed error, like any provider's; a NaN or
/// a negative normal impulse is copied and caught by the same guard.
#[derive(Debug)]
pub struct PythonProvider {
    name: String,
    target: Py<PyAny>,
    style: Style,
    pending: std::sync::Arc<Pending>,
    /// Per island of the step, the island handed to `warm_start`, handed again to
    /// `observe` (a step asks every island's warm start before it observes any).
    islands: Vec<Option<Py<IslandProblem>>>,
}

impl PythonProvider {
    /// Wraps `target` (a callable, or an object with a `warm_start` method) under `name`.
    pub fn new(
        py: Python<'_>,
        name: &str,
        target: Py<PyAny>,
        pending: std::sync::Arc<Pending>,
    ) -> PyResult<Self> {
        let bound = target.bind(py);
        let style = if bound.hasattr("warm_start")? {
            Style::Object {
                observe: bound.hasattr("observe")?,
                reset: bound.hasattr("reset")?,
            }
        } else if bound.is_callable() {
            Style::Callable
        } else {
            return Err(pyo3::exceptions::PyTypeError::new_err(format!(
                "warm_start must be a registry spec (str), a callable or an object with a \
                 warm_start method, not {}",
                bound.get_type().name()?
            )));
        };
        Ok(Self {
            name: name.to_string(),
            target,
            style,
            pending,
            islands: Vec::new(),
        })
    }

    fn call(
        &mut self,
        py: Python<'_>,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let island = IslandData::from_context(ctx)
            .into_python(py)
            .map_err(|e| WarmStartError::Provider(e.to_string()))?;
        let target = self.target.bind(py);
        let returned = match self.style {
            Style::Callable => target.call1((island.clone(),)),
            Style::Object { .. } => target.call_method1("warm_start", (island.clone(),)),
        };
        if self.islands.len() < ctx.island_count {
            self.islands.resize_with(ctx.island_count, || None);
        }
        if let Some(slot) = self.islands.get_mut(ctx.island) {
            *slot = Some(island.unbind());
        }
        let returned = returned.map_err(|e| self.failed(py, e))?;
        read_impulses(&returned, out)
    }

    /// A provider's exception: an interrupt is kept for the caller, any exception becomes a
    /// [`WarmStartError::Provider`] with its message.
    fn failed(&mut self, py: Python<'_>, err: PyErr) -> WarmStartError {
        let error = WarmStartError::Provider(err.to_string());
        if !err.is_instance_of::<PyException>(py) {
            self.pending.keep(err);
        } else {
            self.pending.keep_cause(err);
        }
        error
    }
}

/// Copies an `(n, 2)` float64 array into `out`; anything else is a [`WarmStartError`].
fn read_impulses(returned: &Bound<'_, PyAny>, out: &mut [Impulse]) -> Result<(), WarmStartError> {
    let provider = |m: String| WarmStartError::Provider(m);
    let untyped = returned.cast::<PyUntypedArray>().map_err(|_| {
        let kind = returned
            .get_type()
            .name()
            .map_or_else(|_| "?".to_string(), |n| n.to_string());
        provider(format!(
            "returned {kind}, expected a numpy.ndarray of float64 with shape (n, 2)"
        ))
    })?;
    let shape = untyped.shape();
    if shape.len() != 2 || shape[1] != 2 {
        return Err(provider(format!(
            "returned an array of shape {shape:?}, expected ({}, 2)",
            out.len()
        )));
    }
    if shape[0] != out.len() {
        return Err(WarmStartError::WrongLength {
            expected: out.len(),
            got: shape[0],
        });
    }
    let array = returned.cast::<PyArray2<f64>>().map_err(|_| {
        let dtype = untyped
            .dtype()
            .str()
            .map_or_else(|_| "?".to_string(), |s| s.to_string());
        provider(format!("returned dtype {dtype}, expected float64"))
    })?;
    let view = array
        .try_readonly()
        .map_err(|e| provider(format!("cannot read the returned array: {e}")))?;
    for (o, row) in out.iter_mut().zip(view.as_array().rows()) {
        *o = Impulse::new(row[0], row[1]);
    }
    Ok(())
}

impl WarmStart for PythonProvider {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if self.pending.is_set() {
            return Err(WarmStartError::Provider(
                "not called: an earlier call was interrupted".into(),
            ));
        }
        Python::attach(|py| self.call(py, ctx, out))
    }

    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        let island = self.islands.get_mut(ctx.island).and_then(Option::take);
        if !matches!(self.style, Style::Object { observe: true, .. }) || self.pending.is_set() {
            return;
        }
        Python::attach(|py| {
            let solved = impulses_to_python(py, seen.solved);
            let called = self
                .target
                .bind(py)
                .call_method1("observe", (island, solved));
            if let Err(e) = called {
                self.pending.keep(e);
            }
        });
    }

    fn reset(&mut self) {
        if !self.has_reset() {
            return;
        }
        Python::attach(|py| {
            if let Err(e) = self.target.bind(py).call_method0("reset") {
                self.pending.keep(e);
            }
        });
    }
}

impl PythonProvider {
    fn has_reset(&self) -> bool {
        matches!(self.style, Style::Object { reset: true, .. })
    }
}

/// The name a Python provider is registered and reported under: its `name` attribute if it is
/// a string, else its `__name__` (functions, classes), else its class's name; characters a
/// registry spec does not allow become `_` (so `<lambda>` is `_lambda_`).
pub fn provider_name(obj: &Bound<'_, PyAny>) -> PyResult<String> {
    let raw = if let Ok(name) = obj
        .getattr("name")
        .and_then(|n| n.cast_into::<PyString>().map_err(PyErr::from))
    {
        name.to_string()
    } else if let Ok(name) = obj.getattr("__name__") {
        name.str()?.to_string()
    } else {
        obj.get_type().name()?.to_string()
    };
    Ok(raw
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.') {
                c
            } else {
                '_'
            }
        })
        .collect())
}

/// The object a provider wraps: a class with a `warm_start` method is instantiated (one
/// instance per world), anything else is used as it is.
pub fn instance(py: Python<'_>, obj: &Py<PyAny>) -> PyResult<Py<PyAny>> {
    let bound = obj.bind(py);
    if bound.cast::<PyType>().is_ok() && bound.hasattr("warm_start")? {
        Ok(bound.call0()?.unbind())
    } else {
        Ok(obj.clone_ref(py))
    }
}
