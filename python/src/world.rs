//! `deepcontact.World`: a scene stepped with registry or Python providers.

use std::sync::{Arc, Mutex};

use deepcontact_core::{
    Body, GuardPolicy, Impulse, Observation, Real, ResidualNorm, StepReport as CoreStepReport,
    VelocitySolver, WarmStart, WarmStartContext, WarmStartError, World, WorldSettings, scene,
};
use deepcontact_experiments::full_registry;
use deepcontact_pgs::PgsPositionSolver;
use numpy::{PyArray1, PyArray2};
use pyo3::prelude::*;
use pyo3::types::PyString;

use crate::error::PythonBindingError;
use crate::island::{IslandData, IslandProblem, impulses_to_python, pairs_to_python};
use crate::provider::{Pending, PythonProvider, instance, provider_name};

/// The world settings from the keyword arguments shared by the constructors and `compare`.
pub fn world_settings(
    tolerance: Real,
    max_iterations: u32,
    norm: &str,
    guard: &str,
    dt: Real,
) -> Result<WorldSettings, PythonBindingError> {
    let mut settings = WorldSettings {
        dt,
        ..WorldSettings::default()
    };
    settings.solver.tolerance = tolerance;
    settings.solver.max_iterations = max_iterations;
    settings.solver.norm = match norm {
        "inf" => ResidualNorm::Infinity,
        "l2" => ResidualNorm::L2,
        "contact" => ResidualNorm::Contact,
        other => {
            return Err(PythonBindingError::Invalid(format!(
                "norm must be 'inf', 'l2' or 'contact', not {other:?}"
            )));
        }
    };
    settings.guard = match guard {
        "fallback" => GuardPolicy::FallbackToZero,
        "error" => GuardPolicy::Error,
        other => {
            return Err(PythonBindingError::Invalid(format!(
                "guard must be 'fallback' or 'error', not {other:?}"
            )));
        }
    };
    settings.validate()?;
    Ok(settings)
}

/// What one step did: the velocity iterations, the residual curves, contacts, timings.
#[pyclass(module = "deepcontact._deepcontact", frozen, get_all)]
#[derive(Debug)]
pub struct StepReport {
    /// Index of the step (0 = the world's first).
    pub step: u64,
    /// Contact points solved.
    pub contacts: usize,
    /// Islands with contacts.
    pub islands: usize,
    /// Velocity iterations of the slowest island (what the comparison counts).
    pub iterations: u32,
    /// Velocity iterations summed over islands.
    pub iterations_sum: u64,
    /// Islands that hit the iteration cap.
    pub capped_islands: usize,
    /// Per iteration, max |Δλ| over the islands still iterating (N·s).
    pub residual_curve: Py<PyArray1<Real>>,
    /// Per iteration, the 2-norm of Δλ over those islands (N·s).
    pub residual_curve_l2: Py<PyArray1<Real>>,
    /// Largest natural-map residual over islands after the solve (N·s).
    pub natural_residual: Real,
    /// Mean squared difference between warm start and solution, normal rows ((N·s)²).
    pub mse_normal: Real,
    /// Same, tangent rows.
    pub mse_tangent: Real,
    /// Islands whose warm start was rejected and replaced by zeros.
    pub fallbacks: usize,
    /// Position iterations of the slowest island.
    pub position_iterations: u32,
    /// Smallest separation after the position pass (m).
    pub min_separation: Real,
    /// Seconds in the warm-start provider.
    pub warm_start_seconds: Real,
    /// Seconds in the velocity solver.
    pub solve_seconds: Real,
    /// Seconds of the collide stage (broad and narrow phase).
    pub collide_seconds: Real,
    /// Seconds building the islands and their problems.
    pub islands_seconds: Real,
    /// Seconds of the position pass.
    pub position_seconds: Real,
    /// Seconds of the whole step.
    pub step_seconds: Real,
}

impl StepReport {
    fn new(py: Python<'_>, r: CoreStepReport) -> Self {
        Self {
            step: r.step,
            contacts: r.contacts,
            islands: r.islands,
            iterations: r.velocity_iterations,
            iterations_sum: r.velocity_iterations_sum,
            capped_islands: r.capped_islands,
            residual_curve: PyArray1::from_vec(py, r.residual_curve).unbind(),
            residual_curve_l2: PyArray1::from_vec(py, r.residual_curve_l2).unbind(),
            natural_residual: r.natural_residual,
            mse_normal: r.mse_normal,
            mse_tangent: r.mse_tangent,
            fallbacks: r.fallbacks,
            position_iterations: r.position_iterations,
            min_separation: r.min_separation,
            warm_start_seconds: r.warm_start_seconds,
            solve_seconds: r.solve_seconds,
            collide_seconds: r.collide_seconds,
            islands_seconds: r.islands_seconds,
            position_seconds: r.position_seconds,
            step_seconds: r.step_seconds,
        }
    }
}

#[pymethods]
impl StepReport {
    fn __repr__(&self) -> String {
        format!(
            "StepReport(step={}, contacts={}, islands={}, iterations={}, fallbacks={})",
            self.step, self.contacts, self.islands, self.iterations, self.fallbacks
        )
    }
}

/// One island of a step as training data: its problem, the start the solver used, the
/// solver's final impulses.
#[pyclass(module = "deepcontact._deepcontact", frozen, get_all)]
#[derive(Debug)]
pub struct Island {
    /// The island's problem, as a provider sees it.
    pub problem: Py<IslandProblem>,
    /// The start the solver used, (n, 2): the provider's output, or zeros after a fallback.
    pub start: Py<PyArray2<Real>>,
    /// The solver's final (normal, tangent) impulses, (n, 2).
    pub solved: Py<PyArray2<Real>>,
    /// Whether the provider's output was rejected.
    pub fell_back: bool,
    /// Velocity iterations of this island.
    pub iterations: u32,
}

/// One island recorded by [`Capture`], still without the GIL.
struct CapturedIsland {
    data: IslandData,
    start: Vec<Impulse>,
    solved: Vec<Impulse>,
    fell_back: bool,
    iterations: u32,
}

/// Wraps a provider and copies every island's context and solve (for `step_islands`).
struct Capture<'a> {
    inner: &'a mut dyn WarmStart,
    islands: Vec<CapturedIsland>,
}

impl WarmStart for Capture<'_> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.inner.warm_start(ctx, out)
    }
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.islands.push(CapturedIsland {
            data: IslandData::from_context(ctx),
            start: seen.start.to_vec(),
            solved: seen.solved.to_vec(),
            fell_back: seen.fell_back,
            iterations: seen.report.iterations,
        });
        self.inner.observe(ctx, seen);
    }
    fn reset(&mut self) {
        self.inner.reset();
    }
    fn diagnostics(&self) -> Vec<(String, Real)> {
        self.inner.diagnostics()
    }
    fn passes_spent(&self) -> u32 {
        self.inner.passes_spent()
    }
}

/// Which provider the world holds, so that the next step with the same one reuses it (and
/// its state).
#[derive(Debug)]
enum ProviderKey {
    /// A registry spec.
    Spec(String),
    /// A Python object (compared by identity; kept alive here).
    Python(Py<PyAny>),
}

/// The world and the plug-ins it was last stepped with.
struct Inner {
    world: World,
    provider: Option<(ProviderKey, Box<dyn WarmStart>)>,
    solver: Option<(String, Box<dyn VelocitySolver>)>,
    position: PgsPositionSolver,
    pending: Arc<Pending>,
}

/// A 2D world of one scene.
///
/// Built by ``World.pile``, ``World.thesis``, ``World.pyramid``, ``World.stack``,
/// ``World.resting_ball`` or ``World.scene``; stepped by ``step`` (a ``StepReport``),
/// ``run`` (several steps) or ``step_islands`` (the islands' problems and solutions too).
/// Keyword arguments of the constructors: ``tolerance`` (1e-4), ``max_iterations`` (1000),
/// ``norm`` (``"inf"``, ``"l2"`` or ``"contact"``), ``guard`` (``"fallback"``: a rejected warm
/// start counts a fallback and starts from zeros; ``"error"``: it raises ``WarmStartError``),
/// ``dt`` (0.01 s).
#[pyclass(module = "deepcontact._deepcontact", name = "World")]
pub struct PyWorld {
    inner: Mutex<Inner>,
    scene: String,
}

impl std::fmt::Debug for PyWorld {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World").field("scene", &self.scene).finish()
    }
}

impl std::fmt::Debug for Inner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Inner")
            .field("step", &self.world.step_index())
            .finish_non_exhaustive()
    }
}

impl PyWorld {
    fn build(scene: scene::Scene, settings: WorldSettings) -> Result<Self, PythonBindingError> {
        Ok(Self {
            inner: Mutex::new(Inner {
                world: scene.build(settings)?,
                provider: None,
                solver: None,
                position: PgsPositionSolver::new(),
                pending: Arc::new(Pending::default()),
            }),
            scene: scene.name,
        })
    }

    /// One value per body, as a 1-D array.
    fn body_column<'py, T: numpy::Element>(
        &self,
        py: Python<'py>,
        value: impl Fn(&Body) -> T,
    ) -> Result<Bound<'py, PyArray1<T>>, PythonBindingError> {
        let v: Vec<T> = self.lock()?.world.bodies().iter().map(value).collect();
        Ok(PyArray1::from_vec(py, v))
    }

    /// A pair of values per body, as an `(n, 2)` array.
    fn body_rows<'py>(
        &self,
        py: Python<'py>,
        value: impl Fn(&Body) -> [Real; 2],
    ) -> Result<Bound<'py, PyArray2<Real>>, PythonBindingError> {
        let rows: Vec<[Real; 2]> = self.lock()?.world.bodies().iter().map(value).collect();
        Ok(rows_to_python(py, &rows))
    }

    fn lock(&self) -> Result<std::sync::MutexGuard<'_, Inner>, PythonBindingError> {
        self.inner.try_lock().map_err(|_| {
            PythonBindingError::Invalid("the world is busy: a step is running (from another thread, or this call comes from its provider)".into())
        })
    }
}

impl Inner {
    /// Makes `warm_start` and `solver` the world's plug-ins (reusing the current ones when
    /// they are the same).
    fn select(
        &mut self,
        py: Python<'_>,
        warm_start: &Bound<'_, PyAny>,
        solver: &str,
    ) -> Result<(), PythonBindingError> {
        let registry = full_registry();
        let same = match (&self.provider, warm_start.cast::<PyString>()) {
            (Some((ProviderKey::Spec(s), _)), Ok(spec)) => *s == spec.to_cow()?,
            (Some((ProviderKey::Python(obj), _)), Err(_)) => obj.bind(py).is(warm_start),
            _ => false,
        };
        if !same {
            let built = if let Ok(spec) = warm_start.cast::<PyString>() {
                let spec = spec.to_cow()?.to_string();
                (
                    ProviderKey::Spec(spec.clone()),
                    registry.build_provider(&spec)?,
                )
            } else {
                let name = provider_name(warm_start)?;
                let target = instance(py, &warm_start.clone().unbind())?;
                let provider = PythonProvider::new(py, &name, target, self.pending.clone())?;
                (
                    ProviderKey::Python(warm_start.clone().unbind()),
                    Box::new(provider) as Box<dyn WarmStart>,
                )
            };
            self.provider = Some(built);
        }
        if self.solver.as_ref().is_none_or(|(s, _)| s != solver) {
            self.solver = Some((solver.to_string(), registry.build_solver(solver)?));
        }
        Ok(())
    }

    /// One step without the GIL (a Python provider takes it for its calls), `capture`
    /// recording the islands.
    fn step(
        &mut self,
        py: Python<'_>,
        capture: bool,
    ) -> Result<(CoreStepReport, Vec<CapturedIsland>), PythonBindingError> {
        let Inner {
            world,
            provider,
            solver,
            position,
            pending,
        } = self;
        let (Some((_, provider)), Some((_, solver))) = (provider, solver) else {
            return Err(PythonBindingError::Invalid("no provider or solver".into()));
        };
        let result = py.detach(|| {
            if capture {
                let mut recorder = Capture {
                    inner: provider.as_mut(),
                    islands: Vec::new(),
                };
                world
                    .step(&mut recorder, solver.as_mut(), position)
                    .map(|r| (r, recorder.islands))
            } else {
                world
                    .step(provider.as_mut(), solver.as_mut(), position)
                    .map(|r| (r, Vec::new()))
            }
        });
        if let Some(err) = pending.take() {
            return Err(err.into());
        }
        let cause = pending.take_cause();
        result.map_err(|e| crate::error::with_cause(py, e.into(), cause))
    }
}

#[pymethods]
impl PyWorld {
    /// The thesis pile: ``bodies`` circles (r = 0.5 m) placed by ``seed`` in a box of 15 m
    /// scaled by sqrt(bodies / 100).
    #[staticmethod]
    #[pyo3(signature = (seed = 12345, bodies = 100, *, tolerance = 1e-4, max_iterations = 1000, norm = "inf", guard = "fallback", dt = 0.01))]
    fn pile(
        seed: u64,
        bodies: usize,
        tolerance: Real,
        max_iterations: u32,
        norm: &str,
        guard: &str,
        dt: Real,
    ) -> Result<Self, PythonBindingError> {
        let settings = world_settings(tolerance, max_iterations, norm, guard, dt)?;
        Self::build(scene::pile(seed, bodies)?, settings)
    }

    /// The original thesis code's exact initial world of ``seed`` (12345 to 12354).
    #[staticmethod]
    #[pyo3(signature = (seed = 12345, *, tolerance = 1e-4, max_iterations = 1000, norm = "inf", guard = "fallback", dt = 0.01))]
    fn thesis(
        seed: u64,
        tolerance: Real,
        max_iterations: u32,
        norm: &str,
        guard: &str,
        dt: Real,
    ) -> Result<Self, PythonBindingError> {
        let settings = world_settings(tolerance, max_iterations, norm, guard, dt)?;
        Self::build(scene::by_name("thesis", seed, 100)?, settings)
    }

    /// A pyramid of boxes with ``base`` boxes at the bottom.
    #[staticmethod]
    #[pyo3(signature = (base = 10, *, tolerance = 1e-4, max_iterations = 1000, norm = "inf", guard = "fallback", dt = 0.01))]
    fn pyramid(
        base: usize,
        tolerance: Real,
        max_iterations: u32,
        norm: &str,
        guard: &str,
        dt: Real,
    ) -> Result<Self, PythonBindingError> {
        let settings = world_settings(tolerance, max_iterations, norm, guard, dt)?;
        Self::build(scene::by_name("pyramid", 0, base)?, settings)
    }

    /// A vertical stack of ``count`` boxes.
    #[staticmethod]
    #[pyo3(signature = (count = 10, *, tolerance = 1e-4, max_iterations = 1000, norm = "inf", guard = "fallback", dt = 0.01))]
    fn stack(
        count: usize,
        tolerance: Real,
        max_iterations: u32,
        norm: &str,
        guard: &str,
        dt: Real,
    ) -> Result<Self, PythonBindingError> {
        let settings = world_settings(tolerance, max_iterations, norm, guard, dt)?;
        Self::build(scene::by_name("stack", 0, count)?, settings)
    }

    /// One ball resting on the ground.
    #[staticmethod]
    #[pyo3(signature = (*, tolerance = 1e-4, max_iterations = 1000, norm = "inf", guard = "fallback", dt = 0.01))]
    fn resting_ball(
        tolerance: Real,
        max_iterations: u32,
        norm: &str,
        guard: &str,
        dt: Real,
    ) -> Result<Self, PythonBindingError> {
        let settings = world_settings(tolerance, max_iterations, norm, guard, dt)?;
        Self::build(scene::resting_ball(), settings)
    }

    /// A scene by name (``pile``, ``thesis``, ``pyramid``, ``stack``, ``resting_ball``), as the
    /// CLI's ``--scene``, ``--seed`` and ``--bodies`` choose it.
    #[staticmethod]
    #[pyo3(signature = (name, seed = 12345, bodies = 100, *, tolerance = 1e-4, max_iterations = 1000, norm = "inf", guard = "fallback", dt = 0.01))]
    #[allow(clippy::too_many_arguments)]
    fn scene(
        name: &str,
        seed: u64,
        bodies: usize,
        tolerance: Real,
        max_iterations: u32,
        norm: &str,
        guard: &str,
        dt: Real,
    ) -> Result<Self, PythonBindingError> {
        let settings = world_settings(tolerance, max_iterations, norm, guard, dt)?;
        Self::build(scene::by_name(name, seed, bodies)?, settings)
    }

    /// Advances one step. ``warm_start``: a registry spec (``"builtin"``, ``"none"``,
    /// ``"random:seed=3"``, ...), a callable ``f(island) -> (n, 2) float64 array``, or an object
    /// (or class, instantiated once) with ``warm_start(island)`` and optional
    /// ``observe(island, solved)`` and ``reset()``. ``solver``: a registry spec (``"pgs"``,
    /// ``"newton"``, ...). The same provider object keeps its state across steps. Returns a
    /// ``StepReport``; the GIL is released while the step runs.
    #[pyo3(signature = (warm_start = None, solver = "pgs"))]
    fn step(
        &self,
        py: Python<'_>,
        warm_start: Option<&Bound<'_, PyAny>>,
        solver: &str,
    ) -> Result<StepReport, PythonBindingError> {
        let mut inner = self.lock()?;
        let default = PyString::new(py, "builtin");
        inner.select(py, warm_start.unwrap_or(default.as_any()), solver)?;
        let (report, _) = inner.step(py, false)?;
        Ok(StepReport::new(py, report))
    }

    /// Advances ``steps`` steps (checking for Ctrl-C between them); returns their reports.
    #[pyo3(signature = (steps, warm_start = None, solver = "pgs"))]
    fn run(
        &self,
        py: Python<'_>,
        steps: u64,
        warm_start: Option<&Bound<'_, PyAny>>,
        solver: &str,
    ) -> Result<Vec<StepReport>, PythonBindingError> {
        let mut inner = self.lock()?;
        let default = PyString::new(py, "builtin");
        inner.select(py, warm_start.unwrap_or(default.as_any()), solver)?;
        let mut reports = Vec::new();
        for _ in 0..steps {
            py.check_signals()?;
            let (report, _) = inner.step(py, false)?;
            reports.push(StepReport::new(py, report));
        }
        Ok(reports)
    }

    /// Advances one step like ``step`` and also returns every island as training data: a
    /// ``(StepReport, [Island])`` pair, each ``Island`` holding the problem arrays, the start
    /// used and the solver's final impulses. No files are written.
    #[pyo3(signature = (warm_start = None, solver = "pgs"))]
    fn step_islands(
        &self,
        py: Python<'_>,
        warm_start: Option<&Bound<'_, PyAny>>,
        solver: &str,
    ) -> Result<(StepReport, Vec<Island>), PythonBindingError> {
        let mut inner = self.lock()?;
        let default = PyString::new(py, "builtin");
        inner.select(py, warm_start.unwrap_or(default.as_any()), solver)?;
        let (report, captured) = inner.step(py, true)?;
        let islands = captured
            .into_iter()
            .map(|c| {
                Ok(Island {
                    problem: c.data.into_python(py)?.unbind(),
                    start: impulses_to_python(py, &c.start).unbind(),
                    solved: impulses_to_python(py, &c.solved).unbind(),
                    fell_back: c.fell_back,
                    iterations: c.iterations,
                })
            })
            .collect::<PyResult<Vec<_>>>()?;
        Ok((StepReport::new(py, report), islands))
    }

    /// The scene's name.
    #[getter]
    fn scene_name(&self) -> &str {
        &self.scene
    }

    /// Index of the next step (the steps taken so far).
    #[getter]
    fn step_index(&self) -> Result<u64, PythonBindingError> {
        Ok(self.lock()?.world.step_index())
    }

    /// Number of bodies (static walls included).
    fn __len__(&self) -> Result<usize, PythonBindingError> {
        Ok(self.lock()?.world.bodies().len())
    }

    /// Body centres (m), shape (bodies, 2), in handle order.
    #[getter]
    fn positions<'py>(
        &self,
        py: Python<'py>,
    ) -> Result<Bound<'py, PyArray2<Real>>, PythonBindingError> {
        self.body_rows(py, |b| [b.position.x, b.position.y])
    }

    /// Body angles (rad), shape (bodies,).
    #[getter]
    fn angles<'py>(
        &self,
        py: Python<'py>,
    ) -> Result<Bound<'py, PyArray1<Real>>, PythonBindingError> {
        self.body_column(py, |b| b.angle)
    }

    /// Linear velocities (m/s), shape (bodies, 2).
    #[getter]
    fn velocities<'py>(
        &self,
        py: Python<'py>,
    ) -> Result<Bound<'py, PyArray2<Real>>, PythonBindingError> {
        self.body_rows(py, |b| [b.linear_velocity.x, b.linear_velocity.y])
    }

    /// Angular velocities (rad/s), shape (bodies,).
    #[getter]
    fn angular_velocities<'py>(
        &self,
        py: Python<'py>,
    ) -> Result<Bound<'py, PyArray1<Real>>, PythonBindingError> {
        self.body_column(py, |b| b.angular_velocity)
    }

    /// Masses (kg; 0 for static bodies), shape (bodies,).
    #[getter]
    fn masses<'py>(
        &self,
        py: Python<'py>,
    ) -> Result<Bound<'py, PyArray1<Real>>, PythonBindingError> {
        self.body_column(py, |b| b.mass)
    }

    /// Whether each body is dynamic, shape (bodies,).
    #[getter]
    fn dynamic<'py>(
        &self,
        py: Python<'py>,
    ) -> Result<Bound<'py, PyArray1<bool>>, PythonBindingError> {
        self.body_column(py, |b| b.is_dynamic())
    }

    /// Total kinetic energy of the dynamic bodies (J).
    fn kinetic_energy(&self) -> Result<Real, PythonBindingError> {
        Ok(self.lock()?.world.kinetic_energy())
    }

    fn __repr__(&self) -> String {
        let step = self.lock().map(|i| i.world.step_index()).unwrap_or(0);
        format!("World(scene={:?}, step={step})", self.scene)
    }
}

/// Rows of two as an `(n, 2)` array.
fn rows_to_python<'py>(py: Python<'py>, rows: &[[Real; 2]]) -> Bound<'py, PyArray2<Real>> {
    pairs_to_python(py, rows.iter().flatten().copied().collect())
}
