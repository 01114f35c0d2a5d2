//! The `presolve` provider: carried impulses refined by a bounded solve with another solver.
//!
//! What costs PGS its iterations from the carried impulses is the slow, load-redistributing
//! part of the start's error (docs/RESEARCH.md): modes of the Delassus matrix with tiny
//! eigenvalues that PGS's local updates move by a sliver per sweep. A Newton method on the
//! natural map (deepcontact-lcp's `newton`) fixes every mode at once once it has the active
//! set, so a few Newton iterations from the carried impulses leave PGS almost nothing to do
//! on most islands (median 1 iteration after it on the pile). The price is the Newton
//! iterations themselves (assembly, sparse factorisations, line searches), counted as
//! provider time.

use deepcontact_core::{
    Impulse, Real, SolveReport, SolverSettings, SpecError, Velocity, VelocitySolver, WarmStart,
    WarmStartContext, WarmStartError,
};

/// Parameters of [`PresolveWarmStart`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PresolveConfig {
    /// Iterations of the inner solver per island (default 20, tuned on seeds 100–109; in
    /// 1..=[`PresolveWarmStart::MAX_ITERATIONS`]).
    pub iterations: u32,
    /// Stop rule of the inner solve (∞-norm of its impulse change, N·s; default 1e-6, ≥ 0).
    pub tolerance: Real,
}

impl Default for PresolveConfig {
    fn default() -> Self {
        Self {
            iterations: 20,
            tolerance: 1e-6,
        }
    }
}

/// Carried impulses (zeros for new points) refined by at most `iterations` iterations of an
/// inner solver, typically the semismooth Newton method of deepcontact-lcp. Unlike `copy` it
/// never sees a solution it did not compute within its budget: its cost is the inner
/// solver's iterations, counted as provider time. Buffers are kept between calls.
///
/// ```
/// use deepcontact_core::WarmStart;
/// use deepcontact_warmstart::{PresolveConfig, PresolveWarmStart};
///
/// let solver = Box::new(deepcontact_pgs::PgsSolver::new());
/// let provider = PresolveWarmStart::new(solver, PresolveConfig::default()).unwrap();
/// assert_eq!(provider.name(), "presolve");
/// ```
pub struct PresolveWarmStart {
    solver: Box<dyn VelocitySolver>,
    /// One solver per island after the first (forks of `solver`, when it forks), so each
    /// island keeps what its solver kept from the last step (Newton: the analysis of an
    /// unchanged contact graph).
    forks: Vec<Box<dyn VelocitySolver>>,
    config: PresolveConfig,
    settings: SolverSettings,
    velocities: Vec<Velocity>,
    report: SolveReport,
}

impl std::fmt::Debug for PresolveWarmStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PresolveWarmStart")
            .field("solver", &self.solver.name())
            .field("config", &self.config)
            .finish()
    }
}

impl PresolveWarmStart {
    /// Most inner iterations per island.
    pub const MAX_ITERATIONS: u32 = 10_000;

    /// A provider refining with `solver` under `config` (validated: 1 to `MAX_ITERATIONS`
    /// iterations, a finite tolerance ≥ 0).
    pub fn new(solver: Box<dyn VelocitySolver>, config: PresolveConfig) -> Result<Self, SpecError> {
        let invalid = |param: &str, value: String, reason: &str| SpecError::InvalidParameter {
            spec: "presolve".into(),
            param: param.into(),
            value,
            reason: reason.into(),
        };
        if !(1..=Self::MAX_ITERATIONS).contains(&config.iterations) {
            return Err(invalid(
                "iterations",
                config.iterations.to_string(),
                "must be in 1..=10000",
            ));
        }
        if !(config.tolerance.is_finite() && config.tolerance >= 0.0) {
            return Err(invalid(
                "tolerance",
                config.tolerance.to_string(),
                "must be finite and >= 0",
            ));
        }
        let settings = SolverSettings {
            max_iterations: config.iterations,
            tolerance: config.tolerance,
            ..SolverSettings::default()
        };
        Ok(Self {
            solver,
            forks: Vec::new(),
            config,
            settings,
            velocities: Vec::new(),
            report: SolveReport::default(),
        })
    }

    /// The config.
    pub fn config(&self) -> &PresolveConfig {
        &self.config
    }

    /// The report of the last inner solve.
    pub fn last_report(&self) -> &SolveReport {
        &self.report
    }
}

impl WarmStart for PresolveWarmStart {
    fn name(&self) -> &str {
        "presolve"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        for (i, o) in out.iter_mut().enumerate() {
            *o = ctx.carried_or_zero(i);
        }
        if out.is_empty() {
            return Ok(());
        }
        self.velocities.clear();
        self.velocities
            .resize(ctx.problem.bodies.len(), Velocity::default());
        self.report.clear();
        let solver = match ctx.island.checked_sub(1) {
            Some(k) => {
                while self.forks.len() <= k {
                    match self.solver.fork() {
                        Some(fork) => self.forks.push(fork),
                        None => break,
                    }
                }
                match self.forks.get_mut(k) {
                    Some(fork) => fork,
                    None => &mut self.solver,
                }
            }
            None => &mut self.solver,
        };
        solver
            .solve(
                ctx.problem,
                &self.settings,
                out,
                &mut self.velocities,
                &mut self.report,
            )
            .map_err(|e| WarmStartError::Provider(format!("presolve failed: {e}")))
    }
}
