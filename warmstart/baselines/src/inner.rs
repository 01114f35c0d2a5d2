//! A bounded solve from the carried impulses, what `presolve` and `sor` share: the inner
//! solver's stop rule (validated), its velocity buffer and its last report.

use deepcontact_core::{
    ContactProblem, CoreError, Impulse, Real, SolveReport, SolverSettings, SpecError, Velocity,
    VelocitySolver, WarmStartError,
};
use deepcontact_pgs::PgsSolver;

/// `value`, `spec`'s parameter `param`, if it lies in `range`; else the error naming the range.
pub(crate) fn in_range(
    spec: &str,
    param: &str,
    value: u32,
    range: std::ops::RangeInclusive<u32>,
) -> Result<u32, SpecError> {
    if range.contains(&value) {
        return Ok(value);
    }
    Err(SpecError::InvalidParameter {
        spec: spec.into(),
        param: param.into(),
        value: value.to_string(),
        reason: format!("must be in {}..={}", range.start(), range.end()),
    })
}

/// `value`, `spec`'s parameter `param`, if it is finite and ≥ 0; else the error saying so.
pub(crate) fn non_negative(spec: &str, param: &str, value: Real) -> Result<Real, SpecError> {
    if value.is_finite() && value >= 0.0 {
        return Ok(value);
    }
    Err(SpecError::InvalidParameter {
        spec: spec.into(),
        param: param.into(),
        value: value.to_string(),
        reason: "must be finite and >= 0".into(),
    })
}

/// The inner solve's settings and buffers (kept between calls: no allocation once grown).
#[derive(Debug, Clone, Default)]
pub(crate) struct InnerSolve {
    settings: SolverSettings,
    velocities: Vec<Velocity>,
    report: SolveReport,
}

impl InnerSolve {
    /// At most `iterations` (in 1..=`max`) iterations, stopping below `tolerance` (finite,
    /// ≥ 0); `spec` and `param` name the provider and its iterations parameter in errors.
    pub(crate) fn new(
        spec: &str,
        param: &str,
        iterations: u32,
        max: u32,
        tolerance: Real,
    ) -> Result<Self, SpecError> {
        in_range(spec, param, iterations, 1..=max)?;
        non_negative(spec, "tolerance", tolerance)?;
        Ok(Self {
            settings: SolverSettings {
                max_iterations: iterations,
                tolerance,
                ..SolverSettings::default()
            },
            ..Self::default()
        })
    }

    /// Solves `problem` with `solver` from `impulses` (in place), at most `cap` iterations
    /// when a budget caps them (`ctx.pass_budget`; below the own cap it wins); `what` names
    /// the solve in the error. The iterations run are [`Self::passes`].
    pub(crate) fn run(
        &mut self,
        solver: &mut dyn VelocitySolver,
        problem: &ContactProblem,
        impulses: &mut [Impulse],
        what: &str,
        cap: Option<u32>,
    ) -> Result<(), WarmStartError> {
        self.run_with(problem, what, cap, |settings, velocities, report| {
            solver.solve(problem, settings, impulses, velocities, report)
        })
    }

    /// [`Self::run`] on the plan `solver`'s last solve built for `problem`
    /// ([`PgsSolver::solve_again`]: the same bits without the plan's set-up).
    pub(crate) fn run_again(
        &mut self,
        solver: &mut PgsSolver,
        problem: &ContactProblem,
        impulses: &mut [Impulse],
        what: &str,
        cap: Option<u32>,
    ) -> Result<(), WarmStartError> {
        self.run_with(problem, what, cap, |settings, velocities, report| {
            solver.solve_again(problem, settings, impulses, velocities, report)
        })
    }

    /// `solve` with the capped settings on the cleared velocity buffer and report; nothing
    /// (no iterations, an empty report) when the cap is 0.
    fn run_with(
        &mut self,
        problem: &ContactProblem,
        what: &str,
        cap: Option<u32>,
        solve: impl FnOnce(&SolverSettings, &mut [Velocity], &mut SolveReport) -> Result<(), CoreError>,
    ) -> Result<(), WarmStartError> {
        self.velocities.clear();
        self.velocities
            .resize(problem.bodies.len(), Velocity::default());
        self.report.clear();
        if cap == Some(0) {
            return Ok(());
        }
        let settings = self.capped(cap);
        solve(&settings, &mut self.velocities, &mut self.report)
            .map_err(|e| WarmStartError::Provider(format!("{what} failed: {e}")))
    }

    /// The inner settings with at most `cap` iterations (≥ 1) when a budget caps them (below
    /// the own cap it wins).
    fn capped(&self, cap: Option<u32>) -> SolverSettings {
        SolverSettings {
            max_iterations: cap.map_or(self.settings.max_iterations, |c| {
                self.settings.max_iterations.min(c)
            }),
            ..self.settings
        }
    }

    /// Forgets the last solve's report (an island with nothing to solve).
    pub(crate) fn clear_report(&mut self) {
        self.report.clear();
    }

    /// Iterations of the last solve (0 before the first).
    pub(crate) fn passes(&self) -> u32 {
        self.report.iterations
    }

    /// The report of the last solve.
    pub(crate) fn report(&self) -> &SolveReport {
        &self.report
    }
}
