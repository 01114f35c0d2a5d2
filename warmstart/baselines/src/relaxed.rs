//! The `sor` provider: carried impulses refined by over-relaxed Gauss-Seidel sweeps.
//!
//! PGS is Gauss-Seidel; what it is slow at is the slow, load-redistributing part of the
//! start's error (docs/RESEARCH.md), whose modes it shrinks by `1 − O(μ)` per sweep. Successive
//! over-relaxation moves each row `ω` times as far as Gauss-Seidel would,
//! `λ ← proj(λ − ω m (v − b))`, which shrinks smooth error modes at a rate close to
//! `1 − O(√μ)` for a good `ω` ∈ (1, 2). Scaling a row's effective mass `m` by `ω` *is* that
//! update, so the provider runs the ordinary PGS solver (colours, lanes) on a copy of the
//! problem whose effective masses are scaled by `ω`, for at most `sweeps` sweeps from the
//! carried impulses, and hands the result to the world's (unrelaxed) PGS, which then only
//! has to settle what over-relaxation overshoots. Its sweeps are provider time.
//!
//! A two-point manifold (a box face) keeps its effective masses by default: its normals go
//! through Box2D's block solver, which the scaling would not reach, and relaxing its friction
//! rows alone made a box pyramid's first step diverge to 1e74 N·s
//! (`regression_sor_blew_up_a_box_pyramid`). With [`RelaxedConfig::pairs`] above 1 the relaxed
//! copy splits each such manifold into two one-point rows, normals included, relaxed as a
//! whole by that factor: projected SOR on the pair's rows instead of the block's exact 2 × 2
//! solve, which is what lets the sweeps reach towers and box piles. As a guard, sweeps whose last impulse
//! change is larger than their first (diverging) are dropped: the carried impulses are
//! returned instead and the drop is counted (`diagnostics`: `dropped`).
//!
//! The sweeps can refine another provider's start instead of the carried impulses
//! ([`RelaxedWarmStart::with_start`], `sor:start=NAME`), and each point can get its own
//! factor ω_i from a [`Relaxation`] policy ([`RelaxedWarmStart::with_relaxation`]; a learned
//! one is deepcontact-relax's `learned-sor`). A [`Schedule`] instead gives each equal share of
//! the sweeps its own factor ([`RelaxedConfig::schedule`], or one per pass budget:
//! [`RelaxedWarmStart::with_budget_schedules`]), a large one first and one near 1 last being
//! what lowers the residual of a few sweeps (docs/RESEARCH.md).

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, Observation, Real, SolveReport, SpecError,
    WarmStart, WarmStartContext, WarmStartError,
};
use deepcontact_pgs::{PgsSolver, Stage};

use crate::inner::{InnerSolve, non_negative, sweeper};
use crate::{AndersonConfig, AndersonWarmStart, BudgetSchedules, ExtrapolatedWarmStart, Schedule};

/// The fewest passes an island's share of the budget must hold for the mixed sweeps of
/// [`RelaxedConfig::mix_below`]: with one kept for the solver, three map evaluations, the least
/// that lets a mixed step be evaluated. Below it the relaxed sweeps run.
pub const MIX_MIN_PASSES: u32 = 4;

/// What [`RelaxedWarmStart`]'s start left to do.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Begun {
    /// Sweep the start.
    ToSweep,
    /// The start is the output.
    Final,
}

/// Parameters of [`RelaxedWarmStart`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RelaxedConfig {
    /// Relaxation factor ω, in [1, 2) (default 1.7, tuned on seeds 100–109; 1 is plain PGS).
    pub omega: Real,
    /// Most over-relaxed sweeps per island (default 300, tuned on seeds 100–109; in
    /// 1..=[`RelaxedWarmStart::MAX_SWEEPS`]).
    pub sweeps: u32,
    /// Stop the sweeps once the ∞-norm of an iteration's impulse change is below this
    /// (N·s; default 1e-4, the world's own tolerance; ≥ 0; 0 runs every sweep).
    pub tolerance: Real,
    /// Relaxation factor of two-point manifolds (box faces), in [1, 2) (default 1: they keep
    /// the block solver's pair and are not relaxed). Above 1, and when no pass budget is set,
    /// each two-point manifold of the relaxed copy is split into two one-point rows, each
    /// over-relaxed by this factor; under a budget the pairs stay blocks (at K = 8 the split
    /// rows left a higher residual on the towers than the block solve; docs/RESEARCH.md).
    pub pairs: Real,
    /// Largest factor under a pass budget, in [1, 2] (default 2: no cap), of `omega` and of a
    /// policy's factors (not of a [`schedule`](Self::schedule)'s). With few sweeps a large ω
    /// overshoots and no sweep is left to settle it.
    pub budget_omega: Real,
    /// Islands with more contact points than this get the start without sweeps (default
    /// `usize::MAX`: every island is swept). On a pile of a thousand bodies and more the
    /// sweeps do not bring the large island under the tolerance and cost more than they save.
    pub max_points: usize,
    /// Factors for equal shares of the sweeps, in order (default [`Schedule::NONE`]: `omega`,
    /// or the policy's per-point factors, for every sweep). With a schedule every single-point
    /// manifold takes factor `j` in share `j` of the sweeps' cap (the budget's share, else
    /// `sweeps`), as given (`budget_omega` does not cap it); the sweeps stop at the tolerance
    /// as before. Each share rebuilds the relaxed copy; the later shares sweep on the solver
    /// plan of the first.
    pub schedule: Schedule,
    /// Under a pass budget, an island whose single-point manifolds (the rows relaxation
    /// reaches) hold fewer than this share of its contact points, and that is not heavy
    /// ([`heavy_ratio`](Self::heavy_ratio)), is refined
    /// by Anderson-mixed single sweeps (window 3, `anderson:sweeps=1,window=3`) instead of the
    /// relaxed sweeps, when its share of the budget holds [`MIX_MIN_PASSES`] passes or more
    /// (default 0: never; in [0, 1]). Towers of boxes hold almost no such
    /// points (under a tenth), box piles a fifth or more (docs/RESEARCH.md).
    pub mix_below: Real,
    /// An island is heavy when two of its movable bodies' masses differ more than this many
    /// times (default 10; ≥ 1). A heavy island is not mixed: under a box 100 times heavier
    /// than those it rests on the first mixed steps overshoot and a short budget does not bring
    /// them back. Under a pass budget it starts from [`heavy_alpha`](Self::heavy_alpha)'s
    /// extrapolation instead of the carried impulses.
    pub heavy_ratio: Real,
    /// Under a pass budget, a heavy island's start (when no other start is given,
    /// [`RelaxedWarmStart::with_start`]) is its carried impulses continued along their last
    /// change, `λ_t + α (λ_t − λ_{t−1})` by contact id (`extrapolate:alpha=α`), unswept: the
    /// heavy body's load reaches the bodies under it over several steps, and the carried
    /// impulses lag it (default 0: the carried impulses, swept; finite, ≥ 0).
    pub heavy_alpha: Real,
}

impl Default for RelaxedConfig {
    fn default() -> Self {
        Self {
            omega: 1.7,
            sweeps: 300,
            tolerance: 1e-4,
            pairs: 1.0,
            budget_omega: 2.0,
            max_points: usize::MAX,
            schedule: Schedule::NONE,
            mix_below: 0.0,
            heavy_ratio: 10.0,
            heavy_alpha: 0.0,
        }
    }
}

/// Per-point relaxation factors for [`RelaxedWarmStart`]: a policy that looks at an island
/// (its problem and carried impulses) and picks each point's ω_i. Only single-point
/// manifolds' factors are used (see the module docs); every factor must lie in [1, 2).
///
/// ```
/// use deepcontact_core::{Real, WarmStartContext, WarmStartError};
/// use deepcontact_warmstart::{RelaxedConfig, RelaxedWarmStart, Relaxation};
///
/// /// ω = 1.8 on points that carried an impulse, 1.2 on new ones.
/// #[derive(Debug)]
/// struct TrustCarried;
/// impl Relaxation for TrustCarried {
///     fn omegas(&mut self, ctx: &WarmStartContext<'_>, out: &mut Vec<Real>) -> Result<(), WarmStartError> {
///         out.clear();
///         out.extend(ctx.carried.iter().map(|c| if c.is_some() { 1.8 } else { 1.2 }));
///         Ok(())
///     }
/// }
///
/// let provider = RelaxedWarmStart::new(RelaxedConfig::default())
///     .unwrap()
///     .with_relaxation("trusting-sor", Box::new(TrustCarried));
/// assert_eq!(deepcontact_core::WarmStart::name(&provider), "trusting-sor");
/// ```
pub trait Relaxation: Send + std::fmt::Debug {
    /// Fills `out` (cleared first) with one factor ω_i in [1, 2) per point of `ctx.problem`,
    /// in point order.
    fn omegas(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut Vec<Real>,
    ) -> Result<(), WarmStartError>;
}

/// Carried impulses (zeros for new points) refined by over-relaxed Gauss-Seidel sweeps (see
/// the module docs). Buffers are kept between calls.
///
/// ```
/// use deepcontact_core::WarmStart;
/// use deepcontact_warmstart::{RelaxedConfig, RelaxedWarmStart};
///
/// let provider = RelaxedWarmStart::new(RelaxedConfig::default()).unwrap();
/// assert_eq!(provider.name(), "sor");
/// ```
pub struct RelaxedWarmStart {
    config: RelaxedConfig,
    /// The provider's name (`sor` unless a policy renamed it).
    name: String,
    /// Per-point factors instead of `config.omega`, if any, and their buffer.
    relaxation: Option<Box<dyn Relaxation>>,
    omegas: Vec<Real>,
    /// The start the sweeps refine; `None`: the carried impulses (zeros for new points).
    start: Option<Box<dyn WarmStart>>,
    /// The start's impulses, restored when the sweeps diverge.
    first: Vec<Impulse>,
    inner: InnerSolve,
    solver: PgsSolver,
    /// The island's problem with its effective masses scaled by ω.
    relaxed: ContactProblem,
    /// Sweeps run, in all and per island; the largest of each step (the slowest island's,
    /// comparable with the world's iterations), summed, and the step being counted.
    sweeps: u64,
    islands: u64,
    step_max_sum: u64,
    steps: u64,
    current: Option<(u64, u32)>,
    /// Islands whose sweeps diverged and were dropped.
    dropped: u64,
    /// Islands above [`RelaxedConfig::max_points`], given the start unswept.
    gated: u64,
    /// Passes of the last island: the start's (when it sweeps) and the sweeps.
    last_passes: u32,
    /// Schedules that replace [`RelaxedConfig::schedule`] under a pass budget.
    budget_schedules: BudgetSchedules,
    /// The mixed sweeps of [`RelaxedConfig::mix_below`] (`None` when it is 0).
    mixing: Option<AndersonWarmStart>,
    /// Islands refined by the mixed sweeps.
    mixed: u64,
    /// The heavy islands' start of [`RelaxedConfig::heavy_alpha`] (`None` when it is 0).
    heavy: Option<ExtrapolatedWarmStart>,
    /// Heavy islands started from the extrapolation.
    extrapolated: u64,
    /// A schedule's per-point mass factors, one run of the island's points per share.
    stage_scales: Vec<Real>,
}

impl RelaxedWarmStart {
    /// Most sweeps per island.
    pub const MAX_SWEEPS: u32 = 100_000;

    /// A provider under `config` (validated: ω in [1, 2), 1 to `MAX_SWEEPS` sweeps, a
    /// finite tolerance ≥ 0).
    pub fn new(config: RelaxedConfig) -> Result<Self, SpecError> {
        if !(1.0..=2.0).contains(&config.budget_omega) {
            return Err(SpecError::InvalidParameter {
                spec: "sor".into(),
                param: "budget_omega".into(),
                value: config.budget_omega.to_string(),
                reason: "must be in [1, 2]".into(),
            });
        }
        for (param, value) in [("omega", config.omega), ("pairs", config.pairs)] {
            if !(1.0..2.0).contains(&value) {
                return Err(SpecError::InvalidParameter {
                    spec: "sor".into(),
                    param: param.into(),
                    value: value.to_string(),
                    reason: "must be in [1, 2)".into(),
                });
            }
        }
        if !(0.0..=1.0).contains(&config.mix_below) {
            return Err(SpecError::InvalidParameter {
                spec: "sor".into(),
                param: "mix_below".into(),
                value: config.mix_below.to_string(),
                reason: "must be in [0, 1]".into(),
            });
        }
        if config.heavy_ratio.is_nan() || config.heavy_ratio < 1.0 {
            return Err(SpecError::InvalidParameter {
                spec: "sor".into(),
                param: "heavy_ratio".into(),
                value: config.heavy_ratio.to_string(),
                reason: "must be at least 1".into(),
            });
        }
        let inner = InnerSolve::new(
            "sor",
            "sweeps",
            config.sweeps,
            Self::MAX_SWEEPS,
            config.tolerance,
        )?;
        non_negative("sor", "heavy_alpha", config.heavy_alpha)?;
        let heavy = (config.heavy_alpha > 0.0)
            .then(|| ExtrapolatedWarmStart::new(config.heavy_alpha))
            .transpose()?;
        let mixing = (config.mix_below > 0.0)
            .then(|| {
                AndersonWarmStart::new(AndersonConfig {
                    sweeps: 1,
                    window: 3,
                    ..AndersonConfig::default()
                })
            })
            .transpose()?;
        Ok(Self {
            config,
            name: "sor".into(),
            relaxation: None,
            omegas: Vec::new(),
            start: None,
            first: Vec::new(),
            inner,
            solver: sweeper(),
            relaxed: ContactProblem::new(),
            sweeps: 0,
            islands: 0,
            step_max_sum: 0,
            steps: 0,
            current: None,
            dropped: 0,
            gated: 0,
            last_passes: 0,
            budget_schedules: BudgetSchedules::default(),
            mixing,
            mixed: 0,
            heavy,
            extrapolated: 0,
            stage_scales: Vec::new(),
        })
    }

    /// Whether `problem` is heavy ([`RelaxedConfig::heavy_ratio`]): the largest of its movable
    /// bodies' inverse masses over the smallest above the ratio.
    fn heavy(&self, problem: &ContactProblem) -> bool {
        let (smallest, largest) = problem
            .bodies
            .iter()
            .filter(|b| b.inv_mass > 0.0)
            .fold((Real::INFINITY, 0.0), |(lo, hi): (Real, Real), b| {
                (lo.min(b.inv_mass), hi.max(b.inv_mass))
            });
        largest > self.config.heavy_ratio * smallest
    }

    /// Whether `ctx`'s island starts from [`RelaxedConfig::heavy_alpha`]'s extrapolation: a
    /// heavy island under a pass budget, no other start given.
    fn extrapolates(&self, ctx: &WarmStartContext<'_>) -> bool {
        self.heavy.is_some()
            && self.start.is_none()
            && ctx.pass_budget.is_some()
            && self.heavy(ctx.problem)
    }

    /// Whether [`RelaxedConfig::mix_below`] sends `problem` to the mixed sweeps.
    fn mixes(&self, problem: &ContactProblem) -> bool {
        let single = problem
            .manifolds
            .iter()
            .filter(|&&(start, end)| end == start + 1)
            .count();
        (single as Real) < self.config.mix_below * problem.len() as Real && !self.heavy(problem)
    }

    /// The mixed sweeps from the start in `out` within `cap` passes (one kept for the solver,
    /// as `anderson` keeps it), counted as the relaxed sweeps are; a non-finite result is
    /// dropped for the start.
    fn mix(
        &mut self,
        step: u64,
        problem: &ContactProblem,
        cap: u32,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        let Some(mixing) = self.mixing.as_mut() else {
            return Ok(());
        };
        mixing.refine(problem, Some(cap.saturating_sub(1)), out)?;
        let sweeps = mixing.passes_spent();
        self.last_passes += sweeps;
        self.mixed += 1;
        self.count(step, sweeps);
        if out
            .iter()
            .any(|i| !(i.normal.is_finite() && i.tangent.is_finite()))
        {
            self.dropped += 1;
            out.copy_from_slice(&self.first);
        }
        Ok(())
    }

    /// The start the sweeps refine, into `out`: the given start's (its passes counted), a
    /// heavy island's extrapolation under a budget ([`RelaxedConfig::heavy_alpha`]; final,
    /// no sweeps: the solver takes the whole budget, as relaxed sweeps raise a heavy tower's
    /// residual at K = 8, docs/RESEARCH.md), or the carried impulses.
    fn begin(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<Begun, WarmStartError> {
        let extrapolates = self.extrapolates(ctx);
        match (&mut self.start, self.heavy.as_mut()) {
            (Some(start), _) => {
                start.warm_start(ctx, out)?;
                self.last_passes = start.passes_spent();
            }
            (None, Some(heavy)) if extrapolates => {
                heavy.warm_start(ctx, out)?;
                self.extrapolated += 1;
                return Ok(Begun::Final);
            }
            (None, _) => CarriedWarmStart.warm_start(ctx, out)?,
        }
        Ok(Begun::ToSweep)
    }

    /// The policy's per-point factors into `omegas` (when there is a policy), checked: one per
    /// point, each in [1, 2).
    fn policy_omegas(&mut self, ctx: &WarmStartContext<'_>) -> Result<(), WarmStartError> {
        let Some(policy) = self.relaxation.as_mut() else {
            return Ok(());
        };
        policy.omegas(ctx, &mut self.omegas)?;
        if self.omegas.len() != ctx.problem.len() {
            return Err(WarmStartError::WrongLength {
                expected: ctx.problem.len(),
                got: self.omegas.len(),
            });
        }
        if let Some((i, w)) = self
            .omegas
            .iter()
            .enumerate()
            .find(|(_, w)| !(1.0..2.0).contains(*w))
        {
            return Err(WarmStartError::Provider(format!(
                "relaxation factor {w} of point {i} is outside [1, 2)"
            )));
        }
        Ok(())
    }

    /// The same provider refining `start`'s impulses instead of the carried ones (any
    /// provider, e.g. a learned one: `sor:start=graph`). A failing start fails the call.
    pub fn with_start(mut self, start: Box<dyn WarmStart>) -> Self {
        self.start = Some(start);
        self
    }

    /// The same provider, named `name`, taking each point's factor from `relaxation` instead
    /// of [`RelaxedConfig::omega`] (a factor outside [1, 2) fails the call with
    /// [`WarmStartError::Provider`]).
    pub fn with_relaxation(mut self, name: &str, relaxation: Box<dyn Relaxation>) -> Self {
        self.name = name.into();
        self.relaxation = Some(relaxation);
        self
    }

    /// The same provider with a schedule per pass budget: under a budget it sweeps by the
    /// table's schedule for that budget ([`BudgetSchedules::for_pass_budget`]) instead of
    /// [`RelaxedConfig::schedule`] (and instead of a policy's factors); without a budget the
    /// table is not used.
    pub fn with_budget_schedules(mut self, schedules: BudgetSchedules) -> Self {
        self.budget_schedules = schedules;
        self
    }

    /// The schedule of a call offered `pass_budget` passes (see
    /// [`Self::with_budget_schedules`]).
    fn schedule(&self, pass_budget: Option<u32>) -> Schedule {
        pass_budget
            .and_then(|b| self.budget_schedules.for_pass_budget(b))
            .unwrap_or(self.config.schedule)
    }

    /// Counts `sweeps` run on an island of `step`.
    fn count(&mut self, step: u64, sweeps: u32) {
        self.sweeps += u64::from(sweeps);
        self.islands += 1;
        match &mut self.current {
            Some((s, max)) if *s == step => *max = (*max).max(sweeps),
            current => {
                if let Some((_, max)) = current.take() {
                    self.step_max_sum += u64::from(max);
                    self.steps += 1;
                }
                *current = Some((step, sweeps));
            }
        }
    }

    /// The sweeps of `schedule` from `out` (in place): each factor's share of `cap` (the
    /// budget's share; else [`RelaxedConfig::sweeps`]), the island's effective masses scaled
    /// by it, in one staged solve ([`PgsSolver::solve_stages`]: the bits of one solve per
    /// share on a copy relaxed by its factor, without the copies and the solves' ends), until
    /// a share stops at the tolerance. Returns the sweeps run and the first and last impulse
    /// changes (∞-norm) of all of them.
    fn scheduled(
        &mut self,
        schedule: &Schedule,
        problem: &ContactProblem,
        out: &mut [Impulse],
        cap: Option<u32>,
    ) -> Result<(u32, Option<Real>, Option<Real>), WarmStartError> {
        let budget = cap.is_some();
        // A schedule's factors are its own: `budget_omega` caps `omega` and a policy's.
        let config = RelaxedConfig {
            budget_omega: 2.0,
            ..self.config
        };
        // Two-point manifolds split into point rows need the split copy of the island; the
        // rest is swept on the island itself.
        let split = splits(&config, budget);
        if split {
            split_copy(&mut self.relaxed, problem, true);
        }
        let n = problem.len();
        let mut iterations = [0; Schedule::MAX];
        let mut count = 0;
        self.stage_scales.clear();
        for (omega, share) in schedule.shares(cap.unwrap_or(self.config.sweeps)) {
            let config = RelaxedConfig { omega, ..config };
            let start = self.stage_scales.len();
            self.stage_scales.resize(start + n, 1.0);
            for_each_factor(problem, &config, None, budget, |i, f| {
                self.stage_scales[start + i] = f;
            });
            iterations[count] = self.inner.iterations_within(share);
            count += 1;
        }
        let mut stages = [Stage {
            iterations: 0,
            mass_scale: &[],
        }; Schedule::MAX];
        for (j, stage) in stages.iter_mut().take(count).enumerate() {
            *stage = Stage {
                iterations: iterations[j],
                mass_scale: &self.stage_scales[j * n..(j + 1) * n],
            };
        }
        let target = if split { &self.relaxed } else { problem };
        self.inner.run_stages(
            &mut self.solver,
            target,
            out,
            "over-relaxed sweeps",
            &stages[..count],
        )?;
        let r = self.inner.report();
        Ok((
            r.iterations,
            r.residual_inf.first().copied(),
            r.residual_inf.last().copied(),
        ))
    }

    /// The config.
    pub fn config(&self) -> &RelaxedConfig {
        &self.config
    }

    /// The report of the last island's sweeps (their count is `iterations`; with a
    /// [`RelaxedConfig::schedule`], of its last share).
    pub fn last_report(&self) -> &SolveReport {
        self.inner.report()
    }
}

impl std::fmt::Debug for RelaxedWarmStart {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RelaxedWarmStart")
            .field("name", &self.name)
            .field("config", &self.config)
            .field("relaxation", &self.relaxation)
            .field("start", &self.start.as_ref().map(|s| s.name()))
            .field("dropped", &self.dropped)
            .finish_non_exhaustive()
    }
}

impl WarmStart for RelaxedWarmStart {
    fn name(&self) -> &str {
        &self.name
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.last_passes = 0;
        if self.begin(ctx, out)? == Begun::Final {
            return Ok(());
        }
        if out.is_empty() {
            return Ok(());
        }
        let problem = ctx.problem;
        if problem.len() > self.config.max_points {
            self.gated += 1;
            return Ok(());
        }
        self.first.clear();
        self.first.extend_from_slice(out);
        let schedule = self.schedule(ctx.pass_budget);
        if schedule.is_empty() {
            self.policy_omegas(ctx)?;
        }
        // Under a budget the start's own passes come out of the sweeps' share (none left: no
        // sweeps).
        let cap = ctx.pass_budget.map(|b| b.saturating_sub(self.last_passes));
        let mixable = |&cap: &u32| cap >= MIX_MIN_PASSES;
        if let Some(cap) = cap
            .filter(mixable)
            .filter(|_| self.mixing.is_some() && self.mixes(problem))
        {
            return self.mix(ctx.step, problem, cap, out);
        }
        let (sweeps, first, last) = if schedule.is_empty() {
            let omegas = self.relaxation.is_some().then_some(&self.omegas[..]);
            relaxed_copy(
                &mut self.relaxed,
                problem,
                &self.config,
                omegas,
                ctx.pass_budget.is_some(),
            );
            self.inner.run(
                &mut self.solver,
                &self.relaxed,
                out,
                "over-relaxed sweeps",
                cap,
            )?;
            let r = self.inner.report();
            (
                r.iterations,
                r.residual_inf.first().copied(),
                r.residual_inf.last().copied(),
            )
        } else {
            self.scheduled(&schedule, problem, out, cap)?
        };
        self.last_passes += sweeps;
        let diverged = match (first, last) {
            // Growing changes, or a NaN among them.
            (Some(first), Some(last)) => last > first || last.is_nan() || first.is_nan(),
            _ => false,
        };
        let dropped = diverged
            || out
                .iter()
                .any(|i| !(i.normal.is_finite() && i.tangent.is_finite()));
        self.count(ctx.step, sweeps);
        if dropped {
            self.dropped += 1;
            out.copy_from_slice(&self.first);
        }
        Ok(())
    }

    /// The start the sweeps refine sees every solve (a start that keeps history, e.g.
    /// `extrapolate`, needs it). What it is shown as the start used is the sweeps' output, the
    /// start the solver applied; the solved impulses and the report are the solve's.
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        // The observation's context carries the warm start's pass budget.
        let extrapolates = self.extrapolates(ctx);
        match (&mut self.start, self.heavy.as_mut()) {
            (Some(start), _) => start.observe(ctx, seen),
            (None, Some(heavy)) if extrapolates => heavy.observe(ctx, seen),
            (None, _) => {}
        }
    }

    fn reset(&mut self) {
        (self.sweeps, self.islands, self.step_max_sum, self.steps) = (0, 0, 0, 0);
        (self.dropped, self.gated, self.mixed, self.extrapolated) = (0, 0, 0, 0);
        if let Some(heavy) = &mut self.heavy {
            heavy.reset();
        }
        self.current = None;
        if let Some(start) = &mut self.start {
            start.reset();
        }
    }

    /// `mean_sweeps` per island, `mean_sweeps_slowest_island` (the mean over steps of the
    /// largest island count of a step — the provider's sweeps beside the world's iterations,
    /// which the comparison counts on a step's slowest island, so that the total work of a
    /// step is both), `dropped` (islands whose diverging sweeps were replaced by the
    /// carried impulses), `gated` (islands above [`RelaxedConfig::max_points`], not swept) and
    /// `mixed` (islands refined by the mixed sweeps of [`RelaxedConfig::mix_below`]) and
    /// `extrapolated` (heavy islands started from [`RelaxedConfig::heavy_alpha`]'s extrapolation);
    /// then the start's own, each name prefixed `start_`.
    fn diagnostics(&self) -> Vec<(String, Real)> {
        let (mut sum, mut steps) = (self.step_max_sum, self.steps);
        if let Some((_, max)) = self.current {
            sum += u64::from(max);
            steps += 1;
        }
        let mean = |a: u64, b: u64| if b > 0 { a as Real / b as Real } else { 0.0 };
        let own = [
            ("mean_sweeps".into(), mean(self.sweeps, self.islands)),
            ("mean_sweeps_slowest_island".into(), mean(sum, steps)),
            ("dropped".into(), self.dropped as Real),
            ("gated".into(), self.gated as Real),
            ("mixed".into(), self.mixed as Real),
            ("extrapolated".into(), self.extrapolated as Real),
        ];
        let start = self.start.iter().flat_map(|s| s.diagnostics());
        own.into_iter()
            .chain(start.map(|(k, v)| (format!("start_{k}"), v)))
            .collect()
    }

    /// The start's passes (when it sweeps) and the over-relaxed sweeps, of the last island.
    fn passes_spent(&self) -> u32 {
        self.last_passes
    }
}

/// Whether `config` splits two-point manifolds into point rows (a factor above 1 for them,
/// and no pass budget).
fn splits(config: &RelaxedConfig, budget: bool) -> bool {
    config.pairs > 1.0 && !budget
}

/// Fills `relaxed` with `problem` whose rows are over-relaxed: each single-point manifold's
/// effective masses scaled by its factor (`omegas[i]` when a policy gave them, else
/// `config.omega`); without a budget and with `config.pairs` > 1, each two-point manifold
/// split into two point rows scaled by `config.pairs`; under a budget every factor capped at
/// `config.budget_omega`.
fn relaxed_copy(
    relaxed: &mut ContactProblem,
    problem: &ContactProblem,
    config: &RelaxedConfig,
    omegas: Option<&[Real]>,
    budget: bool,
) {
    split_copy(relaxed, problem, splits(config, budget));
    for_each_factor(problem, config, omegas, budget, |i, omega| {
        let (p, q) = (&mut relaxed.points[i], &problem.points[i]);
        p.normal_mass = q.normal_mass * omega;
        p.tangent_mass = q.tangent_mass * omega;
    });
}

/// Fills `relaxed` with `problem`, each manifold of more than one point split into one-point
/// manifolds when `split` (its points keep their effective masses).
fn split_copy(relaxed: &mut ContactProblem, problem: &ContactProblem, split: bool) {
    relaxed.clear();
    relaxed.bodies.extend_from_slice(&problem.bodies);
    relaxed.points.extend_from_slice(&problem.points);
    for &(start, end) in &problem.manifolds {
        if end == start + 1 || split {
            for i in start..end {
                relaxed.points[i as usize].manifold = relaxed.manifolds.len() as u32;
                relaxed.manifolds.push((i, i + 1));
            }
        } else {
            for p in &mut relaxed.points[start as usize..end as usize] {
                p.manifold = relaxed.manifolds.len() as u32;
            }
            relaxed.manifolds.push((start, end));
        }
    }
}

/// Calls `scale(i, ω_i)` for each point `i` of `problem` that `config` relaxes, ω_i its factor:
/// a single-point manifold's `omegas[i]` when a policy gave them, else `config.omega`; a split
/// two-point manifold's `config.pairs` (the rows of one kept whole keep their masses: not
/// called); under a budget every factor capped at `config.budget_omega`. The relaxed masses
/// are the point's times ω_i, so the same products wherever they are applied.
fn for_each_factor(
    problem: &ContactProblem,
    config: &RelaxedConfig,
    omegas: Option<&[Real]>,
    budget: bool,
    mut scale: impl FnMut(usize, Real),
) {
    let split = splits(config, budget);
    let cap = if budget { config.budget_omega } else { 2.0 };
    for &(start, end) in &problem.manifolds {
        if end > start + 1 && !split {
            continue;
        }
        for i in start..end {
            let omega = match omegas {
                _ if end > start + 1 => config.pairs,
                Some(omegas) => omegas[i as usize],
                None => config.omega,
            }
            .min(cap);
            scale(i as usize, omega);
        }
    }
}
