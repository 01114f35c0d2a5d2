//! A bounded solve from the carried impulses, what `presolve` and `sor` share: the inner
//! solver's stop rule (validated), its velocity buffer and its last report.

use deepcontact_core::{
    ContactProblem, CoreError, Impulse, PassCost, Real, SolveReport, SolverSettings, SpecError,
    Velocity, VelocitySolver, WarmStartError,
};
use deepcontact_pgs::{PgsSolver, Stage};

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

/// The PGS solver of a provider's own sweeps: the default settings but for the natural
/// residual, which no provider reads from its sweeps' report (it stays NaN there) and which
/// costs a scalar pass over the points each solve.
pub(crate) fn sweeper() -> PgsSolver {
    PgsSolver::with_settings(deepcontact_pgs::PgsSettings {
        natural_residual: false,
        ..deepcontact_pgs::PgsSettings::default()
    })
}

/// The inner solve's settings and buffers (kept between calls: no allocation once grown).
#[derive(Debug, Clone, Default)]
pub(crate) struct InnerSolve {
    settings: SolverSettings,
    velocities: Vec<Velocity>,
    report: SolveReport,
    /// What an iteration of the last solve weighed in passes.
    cost: PassCost,
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

    /// Solves `problem` with `solver` from `impulses` (in place); under a pass budget `cap`
    /// (`ctx.pass_budget`) only the iterations whose weight in passes
    /// ([`VelocitySolver::pass_cost`]) fits in it, none when not even one does; `what` names
    /// the solve in the error. What it weighed is [`Self::passes`].
    pub(crate) fn run(
        &mut self,
        solver: &mut dyn VelocitySolver,
        problem: &ContactProblem,
        impulses: &mut [Impulse],
        what: &str,
        cap: Option<u32>,
    ) -> Result<(), WarmStartError> {
        let cost = solver
            .pass_cost(problem, cap)
            .map_err(|e| failed(what, &e))?;
        self.run_with(problem, what, cap, cost, |settings, velocities, report| {
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
        let cost = PassCost::ONE_PER_ITERATION;
        self.run_with(problem, what, cap, cost, |settings, velocities, report| {
            solver.solve_again(problem, settings, impulses, velocities, report)
        })
    }

    /// The stages of `stages` in one solve of `problem` by `solver` from `impulses` (in place;
    /// [`PgsSolver::solve_stages`]), each stage's iterations as given (the caller keeps them
    /// within its budget and [`Self::new`]'s own cap); `what` names the solve in the error.
    /// One pass an iteration.
    pub(crate) fn run_stages(
        &mut self,
        solver: &mut PgsSolver,
        problem: &ContactProblem,
        impulses: &mut [Impulse],
        what: &str,
        stages: &[Stage<'_>],
    ) -> Result<(), WarmStartError> {
        self.reset(problem, PassCost::ONE_PER_ITERATION);
        solver
            .solve_stages(
                problem,
                &self.settings,
                stages,
                impulses,
                &mut self.velocities,
                &mut self.report,
            )
            .map_err(|e| failed(what, &e))
    }

    /// Clears the velocity buffer (one per body of `problem`) and the report before a solve
    /// whose iteration weighs `cost`.
    fn reset(&mut self, problem: &ContactProblem, cost: PassCost) {
        self.velocities.clear();
        self.velocities
            .resize(problem.bodies.len(), Velocity::default());
        self.report.clear();
        self.cost = cost;
    }

    /// The iterations [`Self::new`]'s own cap allows in a share of `share` passes, one pass
    /// an iteration.
    pub(crate) fn iterations_within(&self, share: u32) -> u32 {
        PassCost::ONE_PER_ITERATION.iterations_within(share, self.settings.max_iterations)
    }

    /// `solve` with at most the iterations of the own cap that `cost` fits in the budget
    /// `cap`, on the cleared velocity buffer and report; nothing (no iterations, an empty
    /// report) when none fits.
    fn run_with(
        &mut self,
        problem: &ContactProblem,
        what: &str,
        cap: Option<u32>,
        cost: PassCost,
        solve: impl FnOnce(&SolverSettings, &mut [Velocity], &mut SolveReport) -> Result<(), CoreError>,
    ) -> Result<(), WarmStartError> {
        self.reset(problem, cost);
        let own = self.settings.max_iterations;
        let iterations = cap.map_or(own, |budget| cost.iterations_within(budget, own));
        if iterations == 0 {
            return Ok(());
        }
        let settings = SolverSettings {
            max_iterations: iterations,
            ..self.settings
        };
        solve(&settings, &mut self.velocities, &mut self.report).map_err(|e| failed(what, &e))?;
        // A solver that iterates past the cap it was given (`pgs-rescue` finishing an island
        // PGS left at it) would spend passes the budget does not have.
        if cap.is_some() && self.report.iterations > iterations {
            return Err(WarmStartError::Provider(format!(
                "{what} failed: its solver ran {} iterations under a pass budget that allowed {iterations}",
                self.report.iterations
            )));
        }
        Ok(())
    }

    /// Forgets the last solve's report (an island with nothing to solve).
    pub(crate) fn clear_report(&mut self) {
        self.report.clear();
    }

    /// Passes the last solve weighed: its iterations at the solver's [`PassCost`] (0 before
    /// the first).
    pub(crate) fn passes(&self) -> u32 {
        self.cost.passes(self.report.iterations)
    }

    /// The report of the last solve.
    pub(crate) fn report(&self) -> &SolveReport {
        &self.report
    }
}

/// The provider error for a failed inner solve named `what`.
fn failed(what: &str, e: &CoreError) -> WarmStartError {
    WarmStartError::Provider(format!("{what} failed: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use deepcontact_core::ContactProblem;

    /// A solver that runs `extra` iterations past the cap it is given, as a finishing stage
    /// does.
    struct Overrun {
        extra: u32,
    }

    impl VelocitySolver for Overrun {
        fn name(&self) -> &str {
            "overrun"
        }
        fn solve(
            &mut self,
            _: &ContactProblem,
            settings: &SolverSettings,
            _: &mut [Impulse],
            _: &mut [Velocity],
            report: &mut SolveReport,
        ) -> Result<(), CoreError> {
            report.iterations = settings.max_iterations + self.extra;
            Ok(())
        }
    }

    #[test]
    fn a_solver_past_its_cap_under_a_budget_is_an_error_not_an_overspend() {
        let mut inner = InnerSolve::new("presolve", "iterations", 20, 100, 1e-6).unwrap();
        let problem = ContactProblem::new();
        let mut solver = Overrun { extra: 5 };
        let e = inner
            .run(&mut solver, &problem, &mut [], "presolve", Some(8))
            .unwrap_err();
        assert!(e.to_string().contains("ran 13 iterations"), "{e}");
        // Within its cap it is fine, and without a budget its own rule is its business.
        let mut solver = Overrun { extra: 0 };
        inner
            .run(&mut solver, &problem, &mut [], "presolve", Some(8))
            .unwrap();
        assert_eq!(inner.passes(), 8);
        let mut solver = Overrun { extra: 5 };
        inner
            .run(&mut solver, &problem, &mut [], "presolve", None)
            .unwrap();
        assert_eq!(inner.passes(), 25);
    }
}
