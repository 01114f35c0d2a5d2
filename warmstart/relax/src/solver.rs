//! `learned-pgs`: the learned schedules inside the world's own solve.
//!
//! Under a budget of `K` passes `learned-sor` sweeps its share of them over-relaxed, by the
//! learned schedule of that budget, before the world's PGS runs the rest. Its sweeps end every
//! pile lower than builtin's for the same passes, but they are a solve of their own (a plan, a
//! set-up, an end), which costs 4 to 18 of builtin's passes a step (docs/RESEARCH.md). The same
//! schedule run by the world's PGS itself ([`OverRelaxation`]: the single-point manifolds'
//! effective masses scaled share by share, the last sweep plain) has no such cost. It is a
//! solver, not a start: the warm start stays the carried impulses or any provider's.

use deepcontact_core::{
    ContactProblem, CoreError, Impulse, IslandSolve, Real, SolveReport, SolverSettings, Vector,
    Velocity, VelocitySolver,
};
use deepcontact_pgs::{OverRelaxation, PgsSettings, PgsSolver};
use deepcontact_warmstart::BudgetSchedules;

/// PGS whose first `max_iterations − 1` sweeps follow the learned schedule of that budget
/// ([`BudgetSchedules::for_pass_budget`] of `max_iterations − 1`, the passes `learned-sor` is
/// offered under a world budget of `max_iterations`). A cap of more than twice the table's
/// largest budget (a solve run to a tolerance) is swept plain: the schedules are fitted for
/// fixed budgets.
#[derive(Debug, Clone)]
pub struct ScheduledPgs {
    pgs: PgsSolver,
    schedules: BudgetSchedules,
}

impl ScheduledPgs {
    /// PGS under `settings` (its own [`PgsSettings::over_relaxation`] is replaced each solve)
    /// with `schedules`.
    pub fn new(settings: PgsSettings, schedules: BudgetSchedules) -> Self {
        Self {
            pgs: PgsSolver::with_settings(settings),
            schedules,
        }
    }

    /// The schedule a solve capped at `max_iterations` sweeps by.
    pub fn schedule_for(&self, max_iterations: u32) -> OverRelaxation {
        let largest = self.schedules.entries().last().map_or(0, |&(k, _)| k);
        if max_iterations < 2 || max_iterations > largest.saturating_mul(2) {
            return OverRelaxation::NONE;
        }
        self.schedules
            .for_pass_budget(max_iterations - 1)
            .map_or(OverRelaxation::NONE, |s| s.over_relaxation())
    }

    /// Sets the PGS's schedule for a solve capped at `max_iterations`.
    fn arm(&mut self, max_iterations: u32) {
        self.pgs.settings.over_relaxation = self.schedule_for(max_iterations);
    }
}

impl VelocitySolver for ScheduledPgs {
    fn name(&self) -> &str {
        "learned-pgs"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.arm(settings.max_iterations);
        self.pgs
            .solve(problem, settings, impulses, velocities, report)
    }

    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        self.arm(settings.max_iterations);
        self.pgs.solve_many(settings, islands);
    }

    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        Some(Box::new(Self::new(
            PgsSettings {
                threads: 1,
                ..self.pgs.settings
            },
            self.schedules.clone(),
        )))
    }

    fn threads_for(&self, points: usize) -> usize {
        self.pgs.threads_for(points)
    }

    fn begin_step(&mut self, dt: Real, gravity: Vector) {
        self.pgs.begin_step(dt, gravity);
    }

    fn projects_start(&self) -> bool {
        self.pgs.projects_start()
    }
}
