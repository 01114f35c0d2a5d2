//! The `copy` provider: an oracle that solves the step's problem first.

use deepcontact_core::Velocity;

use deepcontact_core::{
    Impulse, Real, ResidualNorm, SolveReport, SolverSettings, VelocitySolver, WarmStart,
    WarmStartContext, WarmStartError,
};

use deepcontact_core::SpecError;

/// Stop rule of the oracle's own solve.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OracleConfig {
    /// Tolerance of the oracle's solve (default 1e-6, a hundred times tighter than the
    /// world's 1e-4, so the world's solve from the oracle's answer stops almost at once).
    pub tolerance: Real,
    /// Iteration cap of the oracle's solve (default 10 000).
    pub max_iterations: u32,
    /// Norm of the oracle's stop rule (default ∞-norm; the thesis preset uses
    /// [`ResidualNorm::Contact`], the original's rule).
    pub norm: ResidualNorm,
}

impl Default for OracleConfig {
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            max_iterations: 10_000,
            norm: ResidualNorm::Infinity,
        }
    }
}

impl OracleConfig {
    /// The solver settings of the oracle's solve (at least one iteration).
    pub fn settings(&self) -> SolverSettings {
        SolverSettings {
            max_iterations: self.max_iterations,
            tolerance: self.tolerance,
            norm: self.norm,
            ..SolverSettings::default()
        }
    }
}

/// The thesis's "copy" oracle: before the world solves a problem, the oracle solves the
/// very same problem from zeros to a tight tolerance with its own solver and offers that
/// solution as the warm start. It shows the best a predictor could ever do, and what an
/// almost-exact start is worth; its provider time includes the whole oracle solve.
///
/// Buffers are kept between calls, so a step allocates nothing once they have grown.
///
/// ```
/// use deepcontact_warmstart::{OracleConfig, OracleWarmStart};
/// use deepcontact_core::WarmStart;
///
/// let oracle = OracleWarmStart::new(Box::new(deepcontact_pgs::PgsSolver::new()), OracleConfig::default()).unwrap();
/// assert_eq!(oracle.name(), "copy");
/// ```
pub struct OracleWarmStart {
    solver: Box<dyn VelocitySolver>,
    config: OracleConfig,
    settings: SolverSettings,
    impulses: Vec<Impulse>,
    velocities: Vec<Velocity>,
    report: SolveReport,
}

impl std::fmt::Debug for OracleWarmStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OracleWarmStart")
            .field("solver", &self.solver.name())
            .field("config", &self.config)
            .field("last_report", &self.report)
            .finish()
    }
}

impl OracleWarmStart {
    /// An oracle solving with `solver` under `config` (validated: cap ≥ 1, tolerance
    /// finite and ≥ 0).
    pub fn new(solver: Box<dyn VelocitySolver>, config: OracleConfig) -> Result<Self, SpecError> {
        let settings = config.settings();
        settings.validate().map_err(|e| SpecError::Build {
            spec: "copy".into(),
            reason: e.to_string(),
        })?;
        Ok(Self {
            solver,
            config,
            settings,
            impulses: Vec::new(),
            velocities: Vec::new(),
            report: SolveReport::default(),
        })
    }

    /// An oracle with the PGS solver and the default config.
    pub fn pgs() -> Self {
        let config = OracleConfig::default();
        Self {
            solver: Box::new(deepcontact_pgs::PgsSolver::new()),
            config,
            settings: config.settings(),
            impulses: Vec::new(),
            velocities: Vec::new(),
            report: SolveReport::default(),
        }
    }

    /// The config.
    pub fn config(&self) -> &OracleConfig {
        &self.config
    }

    /// The report of the oracle's last solve (iterations, residuals, time).
    pub fn last_report(&self) -> &SolveReport {
        &self.report
    }
}

impl WarmStart for OracleWarmStart {
    fn name(&self) -> &str {
        "copy"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let problem = ctx.problem;
        if out.len() != problem.len() {
            return Err(WarmStartError::WrongLength {
                expected: problem.len(),
                got: out.len(),
            });
        }
        self.impulses.clear();
        self.impulses.resize(problem.len(), Impulse::ZERO);
        self.velocities.clear();
        self.velocities
            .resize(problem.bodies.len(), Velocity::default());
        self.report.clear();
        self.solver
            .solve(
                problem,
                &self.settings,
                &mut self.impulses,
                &mut self.velocities,
                &mut self.report,
            )
            .map_err(|e| WarmStartError::Provider(format!("oracle solve failed: {e}")))?;
        out.copy_from_slice(&self.impulses);
        Ok(())
    }
}
