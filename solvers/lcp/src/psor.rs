//! Projected Gauss-Seidel / successive over-relaxation on the assembled Delassus matrix.

use std::time::Instant;

use deepcontact_core::math::{Real, Velocity};
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, PassCost, SolveReport, SolverSettings, VelocitySolver,
};

use crate::LcpError;
use crate::assembly::{
    AssemblyMode, DEFAULT_DENSE_THRESHOLD, Delassus, impulses_to_rows, rows_to_impulses, sor_sweep,
    sweep_order,
};
use crate::point_graph::PointGraph;
use crate::weight::{PsorWork, island_size};
use deepcontact_core::solver::begin_solve;

/// Options of [`PsorSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PsorSettings {
    /// Relaxation factor ω in (0, 2) (default 1: plain projected Gauss-Seidel, which reaches
    /// the same impulses as deepcontact-pgs with its block solver off).
    pub omega: Real,
    /// Dense or sparse storage of `W` (default [`AssemblyMode::Auto`]).
    pub assembly: AssemblyMode,
    /// Largest number of rows stored densely in `Auto` mode (default
    /// [`DEFAULT_DENSE_THRESHOLD`] = 128 rows, i.e. 64 points).
    pub dense_threshold: usize,
    /// Validate the problem before solving (default true).
    pub validate: bool,
}

impl Default for PsorSettings {
    fn default() -> Self {
        Self {
            omega: 1.0,
            assembly: AssemblyMode::Auto,
            dense_threshold: DEFAULT_DENSE_THRESHOLD,
            validate: true,
        }
    }
}

impl PsorSettings {
    /// Rejects ω outside (0, 2) or non-finite.
    pub fn validate(&self) -> Result<(), LcpError> {
        if !(self.omega > 0.0 && self.omega < 2.0) {
            return Err(LcpError::InvalidSetting {
                name: "omega",
                value: self.omega,
                reason: "must be in (0, 2)",
            });
        }
        Ok(())
    }
}

/// Projected SOR on `W = J M⁻¹ Jᵀ`: each sweep visits the rows in deepcontact-pgs's order
/// (per manifold: tangent rows, then normal rows) and sets
/// `λ_i ← proj(λ_i − ω m_i (Wλ + q)_i)`, with `m_i` the problem's effective mass and the
/// projection onto `λn ≥ 0`, `|λt| ≤ μ λn` using the current `λn`.
///
/// The impulses returned are projected once more onto the final friction cone (as PGS does).
/// The per-sweep residuals are `max |Δλ|` and `sqrt(Σ Δλ²)` after clamping, as in PGS, so
/// the same stop rule and figures apply. With ω = 1 this is PGS on the assembled matrix: a
/// cross-check of both implementations (see the tests).
#[derive(Debug, Default)]
pub struct PsorSolver {
    /// Options.
    pub settings: PsorSettings,
    delassus: Delassus,
    order: Vec<u32>,
    x: Vec<Real>,
    w: Vec<Real>,
    graph: PointGraph,
}

impl PsorSolver {
    /// A solver with default options (ω = 1).
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options.
    pub fn with_settings(settings: PsorSettings) -> Self {
        Self {
            settings,
            ..Self::default()
        }
    }

    /// The system assembled by the last solve.
    pub fn delassus(&self) -> &Delassus {
        &self.delassus
    }

    /// The structure of one sweep on `problem`, from the points and the bodies they touch
    /// (without assembling `W`).
    pub fn work(&mut self, problem: &ContactProblem) -> Result<PsorWork, LcpError> {
        self.graph.of_problem(problem)?;
        let (points, paired_points, w_entries) = island_size(
            problem,
            self.settings.assembly,
            self.settings.dense_threshold,
            self.graph.blocks(),
        );
        Ok(PsorWork {
            points,
            paired_points,
            w_entries,
        })
    }

    /// [`VelocitySolver::solve`] with this crate's error type.
    pub fn solve_lcp(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), LcpError> {
        let t0 = Instant::now();
        self.settings.validate()?;
        settings.require_norm_supported(self.name())?;
        begin_solve(
            problem,
            settings,
            self.settings.validate,
            impulses,
            velocities,
            report,
        )?;
        self.delassus.assemble(
            problem,
            self.settings.assembly,
            self.settings.dense_threshold,
        )?;
        sweep_order(problem, &mut self.order);
        impulses_to_rows(impulses, &mut self.x);
        let mut it = 0;
        while it < settings.max_iterations {
            let (max_d, sum_sq, finite) = sor_sweep(
                &self.delassus,
                &self.order,
                &mut self.x,
                self.settings.omega,
            );
            it += 1;
            let l2 = sum_sq.sqrt();
            report.residual_inf.push(max_d);
            report.residual_l2.push(l2);
            if !(finite && max_d.is_finite()) {
                let row = self.x.iter().position(|v| !v.is_finite()).unwrap_or(0);
                return Err(LcpError::NonFinite {
                    what: "impulse",
                    row,
                    iteration: it,
                });
            }
            if settings.converged(it, max_d, l2, Real::INFINITY) {
                report.converged = true;
                break;
            }
        }
        report.iterations = it;
        // Friction rows were clamped against the normal impulse of their sweep; a last
        // projection onto the final cone makes the impulses admissible even at the cap
        // (deepcontact-pgs does the same).
        self.delassus.project(&mut self.x);
        rows_to_impulses(&self.x, impulses);
        self.delassus.body_velocities(&self.x, velocities);
        self.w.resize(self.x.len(), 0.0);
        self.delassus.velocity_of(&self.x, &mut self.w);
        report.natural_residual = self.delassus.natural_residual(&self.x, &self.w);
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }
}

impl VelocitySolver for PsorSolver {
    fn name(&self) -> &str {
        "psor"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.solve_lcp(problem, settings, impulses, velocities, report)
            .map_err(|e| e.into_core("psor"))
    }

    /// [`PsorWork::pass_cost`] of `problem` (from its structure; exact whatever the budget).
    fn pass_cost(
        &mut self,
        problem: &ContactProblem,
        budget: Option<u32>,
    ) -> Result<PassCost, CoreError> {
        let _ = budget;
        self.work(problem)
            .map(|w| w.pass_cost())
            .map_err(|e| e.into_core("psor"))
    }
}
