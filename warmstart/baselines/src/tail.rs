//! The `tail` provider: last step's impulses with the rest of last step's solve added.
//!
//! PGS stops when `|Δλ| ≤ tol`, but near the answer its increments shrink geometrically,
//! `Δλ_{k+1} ≈ ρ Δλ_k` with ρ the rate of the slowest mode of the pile (0.98–0.999), so
//! the iterate it stops at is still `Σ_{j≥1} Δλ_j ≈ Δλ_1 / (1 − ρ)` from the converged
//! answer, up to a hundred times the tolerance. `builtin` carries that truncation error into
//! the next step. After each solve this provider runs `sweeps` more sweeps, measures ρ from
//! the last two increments (Aitken's Δ² along the slow mode) and stores
//! `λ + Δλ_last ρ / (1 − ρ)`, projected onto the friction cone, under each point's
//! [`ContactId`](deepcontact_core::ContactId); the next step starts from it (carried impulses where a point has none).

use deepcontact_core::{
    Impulse, Observation, Real, SolveReport, SolverSettings, SpecError, Velocity, VelocitySolver,
    WarmStart, WarmStartContext, WarmStartError,
};

use crate::by_contact::StartsByContact;
use crate::rows::in_cone;

/// Parameters of [`TailWarmStart`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TailConfig {
    /// Sweeps run after each solve, from its answer (default 2, in 1..=[`TailWarmStart::MAX_SWEEPS`]).
    pub sweeps: u32,
    /// Largest rate ρ trusted in the extrapolation (default 0.995: a gain of at most 199
    /// times the last increment; in [0, 1)).
    pub max_rate: Real,
    /// Add the extrapolated tail (default true); false keeps just the extra sweeps, which
    /// with many sweeps is "carry the converged answer" (a diagnostic).
    pub extrapolate: bool,
    /// Multiple of the tail added to the solve's answer (default 1).
    pub factor: Real,
}

impl Default for TailConfig {
    fn default() -> Self {
        Self {
            sweeps: 2,
            max_rate: 0.995,
            extrapolate: true,
            factor: 1.0,
        }
    }
}

/// Carried impulses corrected by the extrapolated tail of the previous solve (see the
/// module docs). Its provider time includes the extra sweeps (they run in
/// [`WarmStart::observe`]). Buffers and maps are kept between steps.
///
/// ```
/// use deepcontact_core::WarmStart;
/// use deepcontact_warmstart::{TailConfig, TailWarmStart};
///
/// let tail = TailWarmStart::new(Box::new(deepcontact_pgs::PgsSolver::new()), TailConfig::default()).unwrap();
/// assert_eq!(tail.name(), "tail");
/// ```
pub struct TailWarmStart {
    solver: Box<dyn VelocitySolver>,
    config: TailConfig,
    sweep: SolverSettings,
    starts: StartsByContact,
    lambda: Vec<Impulse>,
    before: Vec<Impulse>,
    velocities: Vec<Velocity>,
    report: SolveReport,
    rate_sum: Real,
    rate_count: u64,
    /// The sweeps the last island's `observe` runs (see `passes_spent`).
    last_passes: u32,
}

impl std::fmt::Debug for TailWarmStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TailWarmStart")
            .field("solver", &self.solver.name())
            .field("config", &self.config)
            .finish()
    }
}

impl TailWarmStart {
    /// Most sweeps per solve (each costs about one PGS iteration of the island).
    pub const MAX_SWEEPS: u32 = 10_000;

    /// A provider sweeping with `solver` (one iteration per call) under `config`
    /// (validated: `1 ≤ sweeps ≤ MAX_SWEEPS`, `0 ≤ max_rate < 1`, `factor` finite).
    pub fn new(solver: Box<dyn VelocitySolver>, config: TailConfig) -> Result<Self, SpecError> {
        let invalid = |param: &str, value: String, reason: &str| SpecError::InvalidParameter {
            spec: "tail".into(),
            param: param.into(),
            value,
            reason: reason.into(),
        };
        if !(1..=Self::MAX_SWEEPS).contains(&config.sweeps) {
            return Err(invalid(
                "sweeps",
                config.sweeps.to_string(),
                "must be in 1..=10000",
            ));
        }
        if !config.factor.is_finite() {
            return Err(invalid(
                "factor",
                config.factor.to_string(),
                "must be finite",
            ));
        }
        if !(0.0..1.0).contains(&config.max_rate) {
            return Err(invalid(
                "max_rate",
                config.max_rate.to_string(),
                "must be in [0, 1)",
            ));
        }
        Ok(Self {
            solver,
            config,
            sweep: SolverSettings {
                max_iterations: 1,
                tolerance: 0.0,
                min_iterations: 1,
                ..SolverSettings::default()
            },
            starts: StartsByContact::default(),
            lambda: Vec::new(),
            before: Vec::new(),
            velocities: Vec::new(),
            report: SolveReport::default(),
            rate_sum: 0.0,
            rate_count: 0,
            last_passes: 0,
        })
    }

    /// The config.
    pub fn config(&self) -> &TailConfig {
        &self.config
    }

    /// Runs `sweeps` sweeps from `solved`; returns the rate of the last increment against the
    /// one before (`previous_norm`, the solve's last 2-norm residual, for one sweep).
    fn sweep_from(
        &mut self,
        ctx: &WarmStartContext<'_>,
        solved: &[Impulse],
        previous_norm: Real,
        sweeps: u32,
    ) -> Result<Real, deepcontact_core::CoreError> {
        self.lambda.clear();
        self.lambda.extend_from_slice(solved);
        self.velocities.clear();
        self.velocities
            .resize(ctx.problem.bodies.len(), Velocity::default());
        let mut last = previous_norm;
        let mut rate = 0.0;
        for _ in 0..sweeps {
            self.before.clear();
            self.before.extend_from_slice(&self.lambda);
            self.solver.solve(
                ctx.problem,
                &self.sweep,
                &mut self.lambda,
                &mut self.velocities,
                &mut self.report,
            )?;
            let norm = self.report.residual_l2.last().copied().unwrap_or(0.0);
            rate = if last > 0.0 { norm / last } else { 0.0 };
            last = norm;
        }
        Ok(rate.clamp(0.0, self.config.max_rate))
    }
}

impl WarmStart for TailWarmStart {
    fn name(&self) -> &str {
        "tail"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.starts.fill(ctx, out);
        self.last_passes = ctx.passes_allowed(self.config.sweeps);
        Ok(())
    }

    /// Runs the sweeps (as many as the context's pass budget allows; none: the island's
    /// points get the carried impulses next step) and stores the extrapolated starts.
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        let sweeps = ctx.passes_allowed(self.config.sweeps);
        if sweeps == 0 {
            return;
        }
        let previous_norm = seen.report.residual_l2.last().copied().unwrap_or(0.0);
        let Ok(rate) = self.sweep_from(ctx, seen.solved, previous_norm, sweeps) else {
            // A sweep that fails leaves this island to the carried impulses.
            return;
        };
        self.rate_sum += rate;
        self.rate_count += 1;
        let gain = if self.config.extrapolate {
            rate / (1.0 - rate)
        } else {
            0.0
        };
        let factor = self.config.factor;
        let points = ctx.problem.points.iter().zip(seen.solved);
        for (((p, s), l), b) in points.zip(&self.lambda).zip(&self.before) {
            let tail_n = l.normal + gain * (l.normal - b.normal) - s.normal;
            let tail_t = l.tangent + gain * (l.tangent - b.tangent) - s.tangent;
            let start = in_cone(
                s.normal + factor * tail_n,
                s.tangent + factor * tail_t,
                p.friction,
            );
            self.starts.insert(p.id, start);
        }
    }

    fn reset(&mut self) {
        self.starts.clear();
        self.rate_sum = 0.0;
        self.rate_count = 0;
    }

    /// The extra sweeps it runs on the last island after the solve (in `observe`), which
    /// make the next step's start: its cost per island and step, `sweeps` or fewer under a
    /// pass budget ([`WarmStartContext::pass_budget`], which `observe` gets too).
    fn passes_spent(&self) -> u32 {
        self.last_passes
    }

    fn diagnostics(&self) -> Vec<(String, Real)> {
        let mean = if self.rate_count > 0 {
            self.rate_sum / self.rate_count as Real
        } else {
            0.0
        };
        vec![("mean_rate".into(), mean)]
    }
}
