//! The `copy` provider: an oracle that solves the step's problem first.

use deepcontact_core::Velocity;

use deepcontact_core::rng::PortableRng;
use deepcontact_core::{
    ContactProblem, Impulse, Real, ResidualNorm, SolveReport, SolverSettings, VelocitySolver,
    WarmStart, WarmStartContext, WarmStartError,
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
    /// Order of the island's manifolds in the oracle's own problem (default
    /// [`OracleOrder::World`]).
    pub order: OracleOrder,
}

impl Default for OracleConfig {
    fn default() -> Self {
        Self {
            tolerance: 1e-6,
            max_iterations: 10_000,
            norm: ResidualNorm::Infinity,
            order: OracleOrder::World,
        }
    }
}

/// Order of the manifolds in the problem the oracle solves.
///
/// The original thesis code's `CopyWorldModel` steps a fresh copy of the world: its contacts
/// are created all at once, so Box2D v2.3 sweeps them in another order than the world, whose
/// contacts were created one by one as the circles fell. A pile is statically indeterminate
/// and the solve stops early (1e-4), so the two orders stop at different points of the
/// solution set. [`Self::Shuffled`] reproduces that mismatch; [`Self::World`] makes the
/// oracle's solve, with the world's solver, the world's own cold solve.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OracleOrder {
    /// The world's order (default).
    #[default]
    World,
    /// The manifolds in reverse order.
    Reversed,
    /// A random permutation of the manifolds, drawn afresh for every solve from a generator
    /// seeded with this seed when the world begins (deterministic per seed).
    Shuffled(u64),
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
    /// The reordered problem and, per point of it, the point of the world's problem.
    reordered: ContactProblem,
    source: Vec<usize>,
    order: Vec<usize>,
    rng: PortableRng,
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
            reordered: ContactProblem::new(),
            source: Vec::new(),
            order: Vec::new(),
            rng: PortableRng::new(config.order.seed()),
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
            reordered: ContactProblem::new(),
            source: Vec::new(),
            order: Vec::new(),
            rng: PortableRng::new(0),
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

    /// Fills `self.reordered` with `problem`'s manifolds in the configured order and
    /// `self.source` with each of its points' index in `problem`.
    fn reorder(&mut self, problem: &ContactProblem) {
        let n = problem.manifolds.len();
        self.order.clear();
        self.order.extend(0..n);
        match self.config.order {
            OracleOrder::World => {}
            OracleOrder::Reversed => self.order.reverse(),
            OracleOrder::Shuffled(_) => {
                // Fisher–Yates.
                for i in (1..n).rev() {
                    let j = (self.rng.next_u64() % (i as u64 + 1)) as usize;
                    self.order.swap(i, j);
                }
            }
        }
        let r = &mut self.reordered;
        r.clear();
        r.bodies.extend_from_slice(&problem.bodies);
        self.source.clear();
        for (k, &m) in self.order.iter().enumerate() {
            let (s, e) = problem.manifolds[m];
            let start = r.points.len() as u32;
            for i in s as usize..e as usize {
                let mut p = problem.points[i];
                p.manifold = k as u32;
                r.points.push(p);
                self.source.push(i);
            }
            r.manifolds.push((start, r.points.len() as u32));
        }
    }
}

impl OracleOrder {
    /// The generator seed of [`Self::Shuffled`] (0 otherwise).
    fn seed(self) -> u64 {
        match self {
            Self::Shuffled(seed) => seed,
            _ => 0,
        }
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
        let world_order = self.config.order == OracleOrder::World;
        if !world_order {
            self.reorder(problem);
        }
        self.solver
            .solve(
                if world_order {
                    problem
                } else {
                    &self.reordered
                },
                &self.settings,
                &mut self.impulses,
                &mut self.velocities,
                &mut self.report,
            )
            .map_err(|e| WarmStartError::Provider(format!("oracle solve failed: {e}")))?;
        if world_order {
            out.copy_from_slice(&self.impulses);
        } else {
            for (&i, imp) in self.source.iter().zip(&self.impulses) {
                out[i] = *imp;
            }
        }
        Ok(())
    }

    fn reset(&mut self) {
        self.rng = PortableRng::new(self.config.order.seed());
    }

    /// The oracle's own solve, uncapped: it is no contender, and a budget shows what it
    /// costs.
    fn passes_spent(&self) -> u32 {
        self.report.iterations
    }
}
