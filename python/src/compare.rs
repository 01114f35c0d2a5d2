//! `deepcontact.compare`: the CLI's comparison, with Python providers among the warm starts.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use deepcontact_core::registry::{Spec, split_spec_list};
use deepcontact_core::{ProviderInfo, Real, Registry, SpecError, WarmStart};
use deepcontact_experiments::compare::{self, Config, Results};
use deepcontact_experiments::full_registry;
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyList, PyString};

use crate::error::PythonBindingError;
use crate::provider::{Pending, PythonProvider, instance, provider_name};
use crate::world::world_settings;

/// How often the waiting thread checks for Ctrl-C while the comparison runs.
const SIGNAL_POLL: Duration = Duration::from_millis(20);

/// The comparison's arguments (`deepcontact._deepcontact.CompareArgs`), built once by
/// `deepcontact.compare` or a cluster task and passed to `compare_summary`, `compare_part`
/// and `compare_merge`.
#[pyclass(frozen, module = "deepcontact._deepcontact")]
#[derive(Debug)]
pub struct CompareArgs {
    /// Warm starts: registry specs or Python providers.
    pub warm_starts: Vec<Py<PyAny>>,
    /// Seeds of the worlds.
    pub seeds: Vec<u64>,
    /// Steps per world.
    pub steps: u64,
    /// Velocity solver specs.
    pub solvers: Vec<String>,
    /// Bodies of the pile.
    pub bodies: usize,
    /// Scene name.
    pub scene: String,
    /// Stop-rule tolerance.
    pub tolerance: Real,
    /// Iteration cap.
    pub max_iterations: u32,
    /// Stop-rule norm (`inf`, `l2`, `contact`).
    pub norm: String,
    /// Guard policy (`fallback`, `error`).
    pub guard: String,
    /// Worker threads (0: one per core).
    pub threads: usize,
    /// Directory for the CLI's outputs, if any.
    pub out: Option<std::path::PathBuf>,
    /// Whether to draw the figures into `out`.
    pub figures: bool,
    /// The warm start whose world sets every step's problem
    /// ([`Config::same_problems`]), if any.
    pub same_problems: Option<String>,
}

#[pymethods]
impl CompareArgs {
    /// The arguments; `out`, `figures` and `same_problems` are optional (`None`, `False`,
    /// `None`).
    #[new]
    #[pyo3(signature = (warm_starts, seeds, steps, solvers, bodies, scene, tolerance, max_iterations, norm, guard, threads, out=None, figures=false, same_problems=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        warm_starts: Vec<Py<PyAny>>,
        seeds: Vec<u64>,
        steps: u64,
        solvers: Vec<String>,
        bodies: usize,
        scene: String,
        tolerance: Real,
        max_iterations: u32,
        norm: String,
        guard: String,
        threads: usize,
        out: Option<std::path::PathBuf>,
        figures: bool,
        same_problems: Option<String>,
    ) -> Self {
        Self {
            warm_starts,
            seeds,
            steps,
            solvers,
            bodies,
            scene,
            tolerance,
            max_iterations,
            norm,
            guard,
            threads,
            out,
            figures,
            same_problems,
        }
    }
}

/// Runs the comparison (without the GIL, Ctrl-C checked every few milliseconds) and returns
/// the summary rows as dicts with the columns of the CLI's `summary.json`.
pub fn run(py: Python<'_>, args: &CompareArgs) -> Result<Py<PyList>, PythonBindingError> {
    let results = results(py, args)?;
    finish(py, &results, args)
}

/// Writes the files of `results` into `args.out` (if any) and returns the summary rows.
pub fn finish(
    py: Python<'_>,
    results: &Results,
    args: &CompareArgs,
) -> Result<Py<PyList>, PythonBindingError> {
    if let Some(dir) = &args.out {
        let dir = dir.clone();
        py.detach(|| compare::write_outputs(results, &dir, args.figures))?;
    }
    summary_rows(py, &compare::summarize(results))
}

/// The registry with `args`' Python providers registered, and the warm-start specs in
/// `args`' order (a Python provider's spec is its name).
pub fn resolve(
    py: Python<'_>,
    args: &CompareArgs,
    pending: &Arc<Pending>,
) -> Result<(Registry, Vec<Spec>), PythonBindingError> {
    let mut registry = full_registry();
    let mut warm_starts = Vec::new();
    for ws in &args.warm_starts {
        let ws = ws.bind(py);
        if let Ok(spec) = ws.cast::<PyString>() {
            warm_starts.extend(split_spec_list(&spec.to_cow()?)?);
            continue;
        }
        let name = provider_name(ws)?;
        if registry.provider_info(&name).is_some() {
            return Err(PythonBindingError::Invalid(format!(
                "the Python provider's name `{name}` is a registry provider's; give it a \
                 `name` attribute"
            )));
        }
        // Checked once here, so that a bad object fails before any world runs.
        PythonProvider::new(
            py,
            &name,
            instance(py, &ws.clone().unbind())?,
            pending.clone(),
        )?;
        let target = ws.clone().unbind();
        let slot = pending.clone();
        let label = name.clone();
        registry.register_provider(
            &name,
            ProviderInfo::new("a Python provider"),
            move |_, _| {
                Python::attach(|py| {
                    let object = instance(py, &target)?;
                    PythonProvider::new(py, &label, object, slot.clone())
                        .map(|p| Box::new(p) as Box<dyn WarmStart>)
                })
                .map_err(|e: PyErr| SpecError::Build {
                    spec: label.clone(),
                    reason: e.to_string(),
                })
            },
        );
        warm_starts.push(Spec {
            name,
            params: Default::default(),
        });
    }
    Ok((registry, warm_starts))
}

/// The comparison's [`Results`] (without the GIL, Ctrl-C checked every few milliseconds).
pub fn results(py: Python<'_>, args: &CompareArgs) -> Result<Results, PythonBindingError> {
    let pending = Arc::new(Pending::default());
    let (registry, warm_starts) = resolve(py, args, &pending)?;
    let config = config(args, warm_starts)?;

    let stop = AtomicBool::new(false);
    let (results, interrupt) = std::thread::scope(|scope| {
        let worker = scope.spawn(|| {
            let stop_check = || stop.load(Ordering::SeqCst) || pending.is_set();
            compare::run_experiment_until(&config, &registry, &stop_check)
        });
        let mut interrupt = None;
        while !worker.is_finished() {
            py.detach(|| std::thread::sleep(SIGNAL_POLL));
            if interrupt.is_none()
                && let Err(e) = py.check_signals()
            {
                stop.store(true, Ordering::SeqCst);
                interrupt = Some(e);
            }
        }
        (worker.join(), interrupt)
    });
    if let Some(err) = interrupt.or_else(|| pending.take()) {
        return Err(err.into());
    }
    results
        .map_err(|_| PythonBindingError::Invalid("the comparison's thread panicked".into()))?
        .map_err(|e| crate::error::with_cause(py, e.into(), pending.take_cause()))
}

/// The comparison `args` describe, with `warm_starts` resolved.
pub fn config(args: &CompareArgs, warm_starts: Vec<Spec>) -> Result<Config, PythonBindingError> {
    let solvers = args
        .solvers
        .iter()
        .map(|s| s.parse::<Spec>())
        .collect::<Result<Vec<_>, _>>()?;
    Ok(Config {
        warm_starts,
        solvers,
        seeds: args.seeds.clone(),
        steps: args.steps,
        bodies: args.bodies,
        scene: args.scene.clone(),
        scene_spec: None,
        world: world_settings(
            args.tolerance,
            args.max_iterations,
            &args.norm,
            &args.guard,
            0.01,
        )?,
        threads: args.threads,
        progress: false,
        same_problems: args.same_problems.clone(),
    })
}

/// The summary rows as dicts, in the column order of summary.csv.
fn summary_rows(
    py: Python<'_>,
    rows: &[compare::Summary],
) -> Result<Py<PyList>, PythonBindingError> {
    let json = serde_json::to_value(rows)
        .map_err(|e| PythonBindingError::Invalid(format!("summary: {e}")))?;
    let list = PyList::empty(py);
    for row in json.as_array().into_iter().flatten() {
        // serde_json's maps sort their keys: the columns are read in summary.csv's order.
        let dict = PyDict::new(py);
        for column in compare::SUMMARY_COLUMNS.split(',') {
            let value = row.get(column).unwrap_or(&serde_json::Value::Null);
            dict.set_item(column, json_to_python(py, value)?)?;
        }
        list.append(dict)?;
    }
    Ok(list.unbind())
}

/// A JSON value as the equal Python object (objects become dicts, in key order).
fn json_to_python<'py>(py: Python<'py>, v: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    use pyo3::IntoPyObjectExt;
    use serde_json::Value;
    Ok(match v {
        Value::Null => py.None().into_bound(py),
        Value::Bool(b) => b.into_bound_py_any(py)?,
        Value::Number(n) => {
            if let Some(i) = n.as_i64() {
                i.into_bound_py_any(py)?
            } else if let Some(u) = n.as_u64() {
                u.into_bound_py_any(py)?
            } else {
                n.as_f64().unwrap_or(f64::NAN).into_bound_py_any(py)?
            }
        }
        Value::String(s) => s.into_bound_py_any(py)?,
        Value::Array(items) => {
            let list = PyList::empty(py);
            for item in items {
                list.append(json_to_python(py, item)?)?;
            }
            list.into_any()
        }
        Value::Object(map) => {
            let dict = PyDict::new(py);
            for (k, item) in map {
                dict.set_item(k, json_to_python(py, item)?)?;
            }
            dict.into_any()
        }
    })
}
