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
    CarriedWarmStart, Impulse, Real, SolveReport, SpecError, VelocitySolver, WarmStart,
    WarmStartContext, WarmStartError,
};

use crate::inner::InnerSolve;

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
/// solver's iterations, counted as provider time and, under a pass budget, at the weight the
/// solver states ([`VelocitySolver::pass_cost`]). Buffers are kept between calls.
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
    inner: InnerSolve,
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
        let inner = InnerSolve::new(
            "presolve",
            "iterations",
            config.iterations,
            Self::MAX_ITERATIONS,
            config.tolerance,
        )?;
        Ok(Self {
            solver,
            forks: Vec::new(),
            config,
            inner,
        })
    }

    /// The config.
    pub fn config(&self) -> &PresolveConfig {
        &self.config
    }

    /// The report of the last inner solve.
    pub fn last_report(&self) -> &SolveReport {
        self.inner.report()
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
        CarriedWarmStart.warm_start(ctx, out)?;
        if out.is_empty() {
            self.inner.clear_report();
            return Ok(());
        }
        let solver = solver_for(&mut self.solver, &mut self.forks, ctx.island);
        self.inner
            .run(solver, ctx.problem, out, "presolve", ctx.pass_budget)
    }

    /// What the inner solve weighed on the last island, in passes
    /// ([`VelocitySolver::pass_cost`]: a Newton iteration weighs tens; 0 on an empty island or
    /// when not one iteration fitted the budget).
    fn passes_spent(&self) -> u32 {
        self.inner.passes()
    }
}

/// The solver for island `island`: the first island's is `solver`, the others' its forks
/// (made on first use), or `solver` again when it does not fork.
fn solver_for<'a>(
    solver: &'a mut Box<dyn VelocitySolver>,
    forks: &'a mut Vec<Box<dyn VelocitySolver>>,
    island: usize,
) -> &'a mut dyn VelocitySolver {
    while island > forks.len() {
        match solver.fork() {
            Some(fork) => forks.push(fork),
            None => return solver.as_mut(),
        }
    }
    match island.checked_sub(1) {
        Some(k) => forks[k].as_mut(),
        None => solver.as_mut(),
    }
}
