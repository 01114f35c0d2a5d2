//! Solver traits and settings.

use crate::contact::Impulse;
use crate::error::CoreError;
use crate::math::{Pose, Real, Vector, Velocity};
use crate::problem::ContactProblem;
use crate::report::SolveReport;

/// Which norm of the per-iteration impulse change the stop rule uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ResidualNorm {
    /// `max |Δλ|` over all rows (default; what the thesis text describes).
    #[default]
    Infinity,
    /// `sqrt(Σ Δλ²)` over all rows of the island. This is *not* the original code's rule,
    /// which takes per contact `sqrt(Δλn² + max(0, Δλt)²)` (signed, decreasing friction
    /// changes ignored) and stops on the largest of those over the contacts.
    L2,
    /// The original thesis code's rule (modified Box2D 2.3.2, `b2ContactSolver.cpp`): per
    /// contact `sqrt(Δλn² + max(0, Δλt)²)` — signed, so decreasing friction changes are
    /// ignored, and `Δλn` only for one-point manifolds — the largest over the contacts, and the
    /// solve stops when it is `≤` the tolerance (not `<`). Supported by `pgs`.
    Contact,
}

/// Stop rule of a velocity solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverSettings {
    /// Iteration cap (default 1000, the thesis's cap). Must be ≥ 1.
    pub max_iterations: u32,
    /// Stop when the chosen norm of the impulse change is below this (default 1e-4). ≥ 0;
    /// 0 means "always run to the cap".
    pub tolerance: Real,
    /// Norm for the stop rule (default ∞).
    pub norm: ResidualNorm,
    /// Iterations always run before the stop rule is checked (default 1, at least 1).
    pub min_iterations: u32,
}

impl Default for SolverSettings {
    fn default() -> Self {
        Self {
            max_iterations: 1000,
            tolerance: 1e-4,
            norm: ResidualNorm::Infinity,
            min_iterations: 1,
        }
    }
}

impl SolverSettings {
    /// Rejects a zero cap, a negative or non-finite tolerance, or `min_iterations` = 0.
    pub fn validate(&self) -> Result<(), CoreError> {
        if self.max_iterations == 0 {
            return Err(CoreError::InvalidSetting {
                name: "max_iterations",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        if self.min_iterations == 0 {
            return Err(CoreError::InvalidSetting {
                name: "min_iterations",
                value: 0.0,
                reason: "must be >= 1",
            });
        }
        if !(self.tolerance.is_finite() && self.tolerance >= 0.0) {
            return Err(CoreError::InvalidSetting {
                name: "tolerance",
                value: self.tolerance,
                reason: "must be finite and >= 0",
            });
        }
        Ok(())
    }

    /// Whether a solve that has run `iteration` iterations (1-based) with these residuals may
    /// stop; `residual_contact` is the [`ResidualNorm::Contact`] measure (solvers that do not
    /// compute it refuse that norm and pass anything).
    #[inline]
    pub fn converged(
        &self,
        iteration: u32,
        residual_inf: Real,
        residual_l2: Real,
        residual_contact: Real,
    ) -> bool {
        iteration >= self.min_iterations
            && match self.norm {
                ResidualNorm::Infinity => residual_inf < self.tolerance,
                ResidualNorm::L2 => residual_l2 < self.tolerance,
                ResidualNorm::Contact => residual_contact <= self.tolerance,
            }
    }

    /// The error of a solver that does not compute the [`ResidualNorm::Contact`] measure.
    pub fn require_norm_supported(&self, solver: &str) -> Result<(), CoreError> {
        if self.norm == ResidualNorm::Contact {
            return Err(CoreError::Solver {
                solver: solver.to_string(),
                reason: "the contact stop rule (norm contact, the thesis code's) is supported by \
                         pgs only"
                    .into(),
            });
        }
        Ok(())
    }
}

/// One island of a [`VelocitySolver::solve_many`] call: what [`VelocitySolver::solve`] takes,
/// and where its outcome goes.
#[derive(Debug)]
pub struct IslandSolve<'a> {
    /// The island's contact problem.
    pub problem: &'a ContactProblem,
    /// In: the start impulses, one per point (N·s); out: the solved impulses.
    pub impulses: &'a mut [Impulse],
    /// Out: the body velocities after the solve, one per body of `problem` (m/s, rad/s).
    pub velocities: &'a mut [Velocity],
    /// Out: the solve's report.
    pub report: &'a mut SolveReport,
    /// Out: the solve's outcome (`Ok(())` before the solve).
    pub result: Result<(), CoreError>,
}

impl<'a> IslandSolve<'a> {
    /// An island to solve from the start in `impulses`.
    pub fn new(
        problem: &'a ContactProblem,
        impulses: &'a mut [Impulse],
        velocities: &'a mut [Velocity],
        report: &'a mut SolveReport,
    ) -> Self {
        Self {
            problem,
            impulses,
            velocities,
            report,
            result: Ok(()),
        }
    }
}

/// Checks the buffers handed to [`VelocitySolver::solve`]: one impulse per point and one
/// velocity per body of `problem`. Solvers call it before touching the buffers.
pub fn check_solve_buffers(
    problem: &ContactProblem,
    impulses: &[Impulse],
    velocities: &[Velocity],
) -> Result<(), CoreError> {
    if impulses.len() != problem.points.len() {
        return Err(CoreError::LengthMismatch {
            what: "impulses",
            expected: problem.points.len(),
            got: impulses.len(),
        });
    }
    if velocities.len() != problem.bodies.len() {
        return Err(CoreError::LengthMismatch {
            what: "velocities",
            expected: problem.bodies.len(),
            got: velocities.len(),
        });
    }
    Ok(())
}

/// The prologue every [`VelocitySolver::solve`] shares: clears `report`, validates the stop
/// rule, the problem (when `validate_problem`; it costs one pass over the data) and the
/// buffers' lengths.
pub fn begin_solve(
    problem: &ContactProblem,
    settings: &SolverSettings,
    validate_problem: bool,
    impulses: &[Impulse],
    velocities: &[Velocity],
    report: &mut SolveReport,
) -> Result<(), CoreError> {
    report.clear();
    settings.validate()?;
    if validate_problem {
        problem.validate()?;
    }
    check_solve_buffers(problem, impulses, velocities)
}

/// What a solve costs in PGS passes ([`VelocitySolver::pass_cost`]): `set_up` once per solve
/// that iterates at all, then `per_iteration` an iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PassCost {
    /// Passes the solve's set-up weighs (assembly, analysis), paid when it runs an iteration.
    pub set_up: u32,
    /// Passes one iteration weighs (≥ 1).
    pub per_iteration: u32,
}

impl Default for PassCost {
    /// [`PassCost::ONE_PER_ITERATION`].
    fn default() -> Self {
        Self::ONE_PER_ITERATION
    }
}

impl PassCost {
    /// PGS's cost: no set-up counted, one pass an iteration.
    pub const ONE_PER_ITERATION: Self = Self {
        set_up: 0,
        per_iteration: 1,
    };

    /// Passes of a solve that ran `iterations` iterations (0 for none), saturating.
    pub fn passes(&self, iterations: u32) -> u32 {
        if iterations == 0 {
            return 0;
        }
        self.per_iteration
            .max(1)
            .saturating_mul(iterations)
            .saturating_add(self.set_up)
    }

    /// The most iterations, up to `cap`, whose [`Self::passes`] fit in `budget` (0 when
    /// not even one does).
    pub fn iterations_within(&self, budget: u32, cap: u32) -> u32 {
        let per = self.per_iteration.max(1);
        budget
            .checked_sub(self.set_up)
            .map_or(0, |left| (left / per).min(cap))
    }
}

/// Solves the velocity-level contact problem of one island.
///
/// The solver starts from `impulses` (the warm start, one per point), applies them to the
/// free velocities, iterates under `settings`, and leaves the final impulses in `impulses`
/// and the final body velocities in `velocities` (one per body of the problem).
/// A finite start outside the friction cone (λn < 0 or |λt| > μ λn) is projected onto it
/// first; a non-finite one is an error. Object safe; implementations reuse their internal buffers between calls.
pub trait VelocitySolver: Send {
    /// Short name used in reports (`"pgs"`, `"psor"`, ...).
    fn name(&self) -> &str;

    /// Solves `problem` from the start in `impulses`.
    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError>;

    /// Solves independent islands, each to the bits [`Self::solve`] gives it alone (its
    /// outcome in [`IslandSolve::result`]), in any order or interleaving; the default solves
    /// them one after another. The world's step hands its islands over here. A solver may
    /// sweep small islands side by side, so that their short dependent chains overlap on the
    /// core; their reports then share out the time they took together
    /// ([`SolveReport::seconds`]).
    ///
    /// ```
    /// use deepcontact_core::{ContactProblem, IslandSolve, SolveReport, SolverSettings};
    /// use deepcontact_core::{Impulse, Velocity, VelocitySolver};
    ///
    /// fn solve_all(solver: &mut dyn VelocitySolver, problems: &[ContactProblem]) {
    ///     let mut impulses: Vec<Vec<Impulse>> =
    ///         problems.iter().map(|p| vec![Impulse::default(); p.len()]).collect();
    ///     let mut velocities: Vec<Vec<Velocity>> = problems
    ///         .iter()
    ///         .map(|p| vec![Velocity::default(); p.bodies.len()])
    ///         .collect();
    ///     let mut reports = vec![SolveReport::default(); problems.len()];
    ///     let mut islands: Vec<IslandSolve> = problems
    ///         .iter()
    ///         .zip(&mut impulses)
    ///         .zip(&mut velocities)
    ///         .zip(&mut reports)
    ///         .map(|(((p, i), v), r)| IslandSolve::new(p, i, v, r))
    ///         .collect();
    ///     solver.solve_many(&SolverSettings::default(), &mut islands);
    ///     assert!(islands.iter().all(|island| island.result.is_ok()));
    /// }
    /// ```
    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        for island in islands {
            island.result = self.solve(
                island.problem,
                settings,
                island.impulses,
                island.velocities,
                island.report,
            );
        }
    }

    /// A solver with the same settings for another thread, which must solve every problem
    /// to the same bits as this one (default `None`: islands are solved one after another).
    /// The world asks for forks when [`crate::WorldSettings::island_threads`] > 1, after
    /// [`Self::begin_step`], so a fork keeps what that call told the solver.
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        None
    }

    /// The threads this solver shares one island of `points` contact points over (default 1:
    /// it solves an island on the calling thread). When one island outweighs a thread's share
    /// of the points, the world solves it with this solver if that is 2 or more and the other
    /// islands on forks after it, else the largest on a fork beside the others.
    fn threads_for(&self, points: usize) -> usize {
        let _ = points;
        1
    }

    /// The world step's length `dt` (s) and `gravity` (m/s²), told once per step before its
    /// solves (default: ignored). A solver that integrates inside the step (substeps) needs
    /// them; the problem's velocities already hold the whole step's `dt × gravity`.
    fn begin_step(&mut self, dt: Real, gravity: Vector) {
        let _ = (dt, gravity);
    }

    /// Whether the solver clamps a start's tangent impulses onto the friction cone
    /// `|λt| ≤ μ λn` before iterating (default `true`, as this trait's contract says). A solver
    /// that applies them as given (PGS with `raw_start`, the original code's choice) returns
    /// `false`, and the world then measures the start with its tangents as given
    /// ([`crate::project_start`]).
    fn projects_start(&self) -> bool {
        true
    }

    /// What a solve of `problem` costs in PGS passes (sweeps of every row of the island), the
    /// unit in which a pass budget ([`crate::WarmStartContext::pass_budget`]) counts a
    /// provider's inner solve (default [`PassCost::ONE_PER_ITERATION`]: an iteration is one
    /// pass). Counted from the problem's structure alone, so that a budget decides the same
    /// way on every machine and for every start. A solver whose iteration is other work (a
    /// factorisation, an assembled matrix) says what it weighs here. Exact whenever
    /// `budget` is `None` or a solve of one iteration fits in it; when not, the solver may
    /// return a lower bound that already exceeds the budget, without working out the rest.
    fn pass_cost(
        &mut self,
        problem: &ContactProblem,
        budget: Option<u32>,
    ) -> Result<PassCost, CoreError> {
        let _ = (problem, budget);
        Ok(PassCost::ONE_PER_ITERATION)
    }

    /// Whether the solver moves its islands' bodies itself (default `false`). When `true`,
    /// the world solves each island with [`Self::solve_with_positions`], moves the island's
    /// dynamic bodies by the displacements it returns (instead of `dt ×` their velocity) and
    /// runs no position pass on them.
    fn owns_positions(&self) -> bool {
        false
    }

    /// [`Self::solve`], also integrating positions over the step: `displacements` (one per
    /// body of `problem`) receives each body's change of position (m) and angle (rad) since
    /// the problem was built. Only called when [`Self::owns_positions`] is `true`; the
    /// default, for solvers that do not, is an error.
    fn solve_with_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        displacements: &mut [Pose],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let _ = (
            problem,
            settings,
            impulses,
            velocities,
            displacements,
            report,
        );
        Err(CoreError::Solver {
            solver: self.name().to_string(),
            reason: "does not integrate positions (owns_positions is false)".into(),
        })
    }
}

impl<S: VelocitySolver + ?Sized> VelocitySolver for Box<S> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        (**self).solve_many(settings, islands);
    }
    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        (**self).solve(problem, settings, impulses, velocities, report)
    }
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        (**self).fork()
    }
    fn threads_for(&self, points: usize) -> usize {
        (**self).threads_for(points)
    }
    fn begin_step(&mut self, dt: Real, gravity: Vector) {
        (**self).begin_step(dt, gravity);
    }
    fn projects_start(&self) -> bool {
        (**self).projects_start()
    }
    fn pass_cost(
        &mut self,
        problem: &ContactProblem,
        budget: Option<u32>,
    ) -> Result<PassCost, CoreError> {
        (**self).pass_cost(problem, budget)
    }
    fn owns_positions(&self) -> bool {
        (**self).owns_positions()
    }
    fn solve_with_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        displacements: &mut [Pose],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        (**self).solve_with_positions(
            problem,
            settings,
            impulses,
            velocities,
            displacements,
            report,
        )
    }
}

/// Settings of the position pass (Box2D v2.4 non-linear Gauss-Seidel).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PositionSettings {
    /// Iteration cap (default 250).
    pub max_iterations: u32,
    /// Stop when the largest correction is below this (default 1e-4 m)...
    pub tolerance: Real,
    /// ...and the deepest penetration is within `penetration_factor × linear_slop` (default 3).
    pub penetration_factor: Real,
    /// Fraction of the overlap removed per iteration (default 0.2).
    pub baumgarte: Real,
    /// Penetration allowed without correction (default 0.0005 m, the original code's value).
    pub linear_slop: Real,
    /// Largest correction per point per iteration (default 0.2 m).
    pub max_linear_correction: Real,
    /// Measure the stop rule on the largest position impulse `−C/K` (kg·m) instead of the
    /// largest correction `C` (m), as the original thesis code does (default false).
    pub stop_on_impulse: bool,
    /// How a circle contact is measured at the current poses (default
    /// [`CircleContact::Fixed`]).
    pub circle_contact: CircleContact,
}

/// How the position pass measures a circle contact (a point whose anchor on every rotating
/// body is parallel to its normal) at the current poses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum CircleContact {
    /// Like every other contact (Box2D v3's relax step): the narrow phase's normal held fixed,
    /// the anchors moving and rotating with their bodies (default).
    #[default]
    Fixed,
    /// As Box2D v2.3's `b2PositionSolverManifold` (the original thesis code): between two
    /// movable circles the normal is re-measured from the current centres every iteration,
    /// separation `|cB − cA| − (rA + rB)`, anchors on the line of centres; a circle on an
    /// immovable body keeps the fixed normal and translates only. Neither has an angular term.
    Remeasured,
}

impl Default for PositionSettings {
    fn default() -> Self {
        Self {
            max_iterations: 250,
            tolerance: 1e-4,
            penetration_factor: 3.0,
            baumgarte: 0.2,
            linear_slop: 0.0005,
            max_linear_correction: 0.2,
            stop_on_impulse: false,
            circle_contact: CircleContact::Fixed,
        }
    }
}

impl PositionSettings {
    /// Rejects out-of-range values.
    pub fn validate(&self) -> Result<(), CoreError> {
        let check = |name, value: Real, ok: bool, reason| {
            if ok {
                Ok(())
            } else {
                Err(CoreError::InvalidSetting {
                    name,
                    value,
                    reason,
                })
            }
        };
        check(
            "position.tolerance",
            self.tolerance,
            self.tolerance.is_finite() && self.tolerance >= 0.0,
            "must be finite and >= 0",
        )?;
        check(
            "position.baumgarte",
            self.baumgarte,
            self.baumgarte > 0.0 && self.baumgarte <= 1.0,
            "must be in (0, 1]",
        )?;
        check(
            "position.linear_slop",
            self.linear_slop,
            self.linear_slop.is_finite() && self.linear_slop >= 0.0,
            "must be finite and >= 0",
        )?;
        check(
            "position.max_linear_correction",
            self.max_linear_correction,
            self.max_linear_correction.is_finite() && self.max_linear_correction > 0.0,
            "must be finite and > 0",
        )?;
        check(
            "position.penetration_factor",
            self.penetration_factor,
            self.penetration_factor.is_finite() && self.penetration_factor >= 0.0,
            "must be finite and >= 0",
        )
    }
}

/// Outcome of a position pass.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PositionReport {
    /// Iterations run (0 if there was nothing to do).
    pub iterations: u32,
    /// Smallest separation seen in the last iteration (negative = penetration).
    pub min_separation: Real,
    /// Largest correction applied in the last iteration (m).
    pub max_correction: Real,
}

/// Removes overlap by moving positions directly (not warm-started).
///
/// `poses` holds `(centre of mass, angle)` of each body of `problem` after the position
/// integration; the pass updates them in place. The problem's `position`/`angle` fields are
/// the poses at which the contacts were computed, so separations can be updated from the
/// displacement since then.
pub trait PositionSolver: Send {
    /// Short name.
    fn name(&self) -> &str;

    /// Runs the position pass.
    fn solve_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
    ) -> Result<PositionReport, CoreError>;

    /// A pass with the same settings for another thread, which must correct every problem
    /// to the same bits as this one (default `None`: islands are corrected one after
    /// another). The world asks for forks when [`crate::WorldSettings::island_threads`] > 1
    /// (see [`Self::threads_for`]); a fork corrects whole islands on one thread.
    fn fork(&self) -> Option<Box<dyn PositionSolver>> {
        None
    }

    /// The threads this pass shares one island of `points` contact points over (default 1),
    /// as [`VelocitySolver::threads_for`].
    fn threads_for(&self, points: usize) -> usize {
        let _ = points;
        1
    }
}

impl<S: PositionSolver + ?Sized> PositionSolver for Box<S> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn solve_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
    ) -> Result<PositionReport, CoreError> {
        (**self).solve_positions(problem, settings, poses)
    }
    fn fork(&self) -> Option<Box<dyn PositionSolver>> {
        (**self).fork()
    }
    fn threads_for(&self, points: usize) -> usize {
        (**self).threads_for(points)
    }
}

#[cfg(test)]
mod tests {
    use super::PassCost;

    #[test]
    fn a_solve_weighs_its_set_up_once_and_its_iterations_each() {
        let cost = PassCost {
            set_up: 60,
            per_iteration: 25,
        };
        assert_eq!(cost.passes(0), 0);
        assert_eq!(cost.passes(1), 85);
        assert_eq!(cost.passes(3), 135);
        assert_eq!(cost.iterations_within(84, 20), 0);
        assert_eq!(cost.iterations_within(85, 20), 1);
        assert_eq!(cost.iterations_within(134, 20), 2);
        assert_eq!(cost.iterations_within(10_000, 20), 20);
        assert_eq!(cost.iterations_within(59, 20), 0);
    }

    #[test]
    fn pgs_cost_is_one_pass_an_iteration() {
        let cost = PassCost::default();
        assert_eq!(cost, PassCost::ONE_PER_ITERATION);
        assert_eq!(cost.passes(7), 7);
        assert_eq!(cost.iterations_within(7, 300), 7);
        assert_eq!(cost.iterations_within(0, 300), 0);
        let huge = PassCost {
            set_up: u32::MAX,
            per_iteration: 0,
        };
        assert_eq!(huge.passes(5), u32::MAX, "saturates");
        assert_eq!(huge.iterations_within(u32::MAX, 3), 0);
    }
}
