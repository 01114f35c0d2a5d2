//! A semismooth (minimum-map) Newton method on the natural map of the frictional problem.

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
use crate::block_lu::BlockLu;
use crate::weight::{NewtonWork, island_size};
use deepcontact_core::solver::begin_solve;

/// Relative regularisation a Newton direction is recomputed with (at least) after its line
/// search failed.
pub const RETRY_REGULARIZATION: Real = 1e-6;

/// Breakpoints of the line search below this step length are ignored (a normal impulse
/// already at zero up to round-off).
const MIN_BREAKPOINT: Real = 1e-10;

/// Options of [`NewtonSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NewtonSettings {
    /// Dense or sparse storage of `W` and of the Newton matrix (default [`AssemblyMode::Auto`]).
    pub assembly: AssemblyMode,
    /// Largest number of rows handled densely in `Auto` mode (default
    /// [`DEFAULT_DENSE_THRESHOLD`] = 128 rows, i.e. 64 points).
    pub dense_threshold: usize,
    /// Relative regularisation ε of the free rows of the Newton matrix: their diagonal is
    /// `W_ii (1 + ε)` (default 1e-10). Redundant contacts make `W` singular; ε makes the step
    /// a Levenberg–Marquardt step that leaves the null space of `W` (which changes no
    /// velocity) alone. After a failed line search the direction is recomputed with ε × 100
    /// (at least [`RETRY_REGULARIZATION`]), a shorter and better-conditioned step; after a
    /// full step is accepted ε shrinks ×10 back towards this value. ≥ 0.
    pub regularization: Real,
    /// Largest ε (default 100, where the step is a heavily damped Jacobi step). When a
    /// line search fails at this ε the iteration is one projected Gauss-Seidel sweep; when
    /// the factorisation is not finite or inaccurate even at this ε the solve fails with
    /// [`LcpError::Singular`].
    pub max_regularization: Real,
    /// Armijo sufficient-decrease constant σ in (0, 0.5) of the line search on
    /// `θ = ½‖H‖²` (default 1e-4): a step α is accepted when `θ(new) ≤ (1 − 2σα) θ`.
    pub armijo: Real,
    /// Step reduction factor of the backtracking line search, in (0, 1) (default 0.5).
    pub backtrack: Real,
    /// Backtracking steps before the iteration falls back to one projected Gauss-Seidel
    /// sweep (default 8, i.e. down to α = 0.5⁸ ≈ 0.004).
    pub max_backtracks: u32,
    /// Validate the problem before solving (default true).
    pub validate: bool,
    /// Stop the solve, unconverged, at the first iteration whose Newton step (coupled and
    /// lagged) fails its line search, instead of retrying with larger regularisations and
    /// falling back to a Gauss-Seidel sweep (default false). For a bounded refinement such as
    /// the `presolve` warm start: the iterate so far is kept and the hard, slow part is left
    /// to the caller's solver.
    pub stop_on_failed_step: bool,
}

impl Default for NewtonSettings {
    fn default() -> Self {
        Self {
            assembly: AssemblyMode::Auto,
            dense_threshold: DEFAULT_DENSE_THRESHOLD,
            regularization: 1e-10,
            max_regularization: 1e2,
            armijo: 1e-4,
            backtrack: 0.5,
            max_backtracks: 8,
            validate: true,
            stop_on_failed_step: false,
        }
    }
}

impl NewtonSettings {
    /// Rejects out-of-range values.
    pub fn validate(&self) -> Result<(), LcpError> {
        let check = |name, value: Real, ok: bool, reason| {
            if ok {
                Ok(())
            } else {
                Err(LcpError::InvalidSetting {
                    name,
                    value,
                    reason,
                })
            }
        };
        check(
            "regularization",
            self.regularization,
            self.regularization.is_finite() && self.regularization >= 0.0,
            "must be finite and >= 0",
        )?;
        check(
            "max_regularization",
            self.max_regularization,
            self.max_regularization.is_finite() && self.max_regularization >= self.regularization,
            "must be finite and >= regularization",
        )?;
        check(
            "armijo",
            self.armijo,
            self.armijo > 0.0 && self.armijo < 0.5,
            "must be in (0, 0.5)",
        )?;
        check(
            "backtrack",
            self.backtrack,
            self.backtrack > 0.0 && self.backtrack < 1.0,
            "must be in (0, 1)",
        )
    }
}

/// What the last Newton solve did besides the figures of its [`SolveReport`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NewtonStats {
    /// Newton iterations (same as the report's `iterations`).
    pub iterations: u32,
    /// Factorisations of the Newton matrix (more than the iterations when ε had to grow or
    /// the coupled step failed).
    pub factorizations: u32,
    /// Backtracking steps taken by the line search, in all.
    pub backtracks: u32,
    /// Directions recomputed with a larger regularisation after a failed line search.
    pub retries: u32,
    /// Iterations that fell back to a projected Gauss-Seidel sweep.
    pub fallback_sweeps: u32,
    /// Largest relative regularisation used.
    pub max_regularization: Real,
    /// Whether `W` was assembled dense (the Newton matrix is factorised sparse either way).
    pub dense: bool,
}

/// How the Newton matrix treats one row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RowState {
    /// `l < λ − m w < u`: the row's velocity equation `(W Δ)_i = −w_i`.
    Free,
    /// Projection active at a constant bound (a normal at 0, a row with zero mass):
    /// `Δ_i = −H_i`.
    Fixed,
    /// Tangent at `+μ λn`: `Δt − μ Δn = −H_t`.
    Upper,
    /// Tangent at `−μ λn`: `Δt + μ Δn = −H_t`.
    Lower,
}

/// Semismooth Newton on the natural map of the frictional contact problem, started from the
/// warm start.
///
/// With `w = Wλ + q` and `m` the effective masses, the natural map
/// `H(λ) = λ − proj(λ − m ∘ w)` (normal rows projected onto `[0, ∞)`, tangent rows onto
/// `[−μλn, μλn]` with the *current* `λn`) vanishes exactly at the solutions;
/// `max |H|` is the natural-map residual deepcontact-pgs reports. The start is projected onto
/// the cone, then each iteration:
///
/// 1. classifies every row (free, at a constant bound, or at a friction bound `±μλn`);
/// 2. solves the generalised-Jacobian system `K Δ = −H` of all rows at once — free rows
///    take the row of `W` (diagonal × (1 + ε)), bound rows an identity row, friction-bound
///    rows also the `∓μ` coupling to their normal (so sliding friction follows the normal
///    impulse within the step: a true Newton step for `H`, not a fixed point on the friction
///    bounds) — with a sparse LU on 2×2 point blocks with static pivots: `K` keeps the
///    block pattern of `W`, so its fill-reducing order (AMD), filled pattern and update
///    lists are worked out once per solve and each factorisation is a pass over them (no
///    pivot search, no allocation); ε grows ×100 while the solution is not finite or
///    inaccurate (residual checked against 1e-8 relative);
/// 3. line search on `θ = ½‖H‖²` along `λ ← proj(λ + αΔ)` (Armijo): α = 1, β, β², …, then
///    the first breakpoint where a normal impulse reaches zero (each trial's velocities
///    updated from `W Δ` and the columns of the projected rows; recomputed once accepted);
/// 4. if no step is accepted: the same with the friction bounds lagged (no coupling, the
///    symmetric system of a fixed point on the bounds), then with ε × 100 (a shorter
///    Levenberg–Marquardt step), and at the largest ε one projected Gauss-Seidel sweep
///    instead (so an iteration always moves). ε shrinks ×10 after every accepted step.
///
/// The iteration records `max |Δλ|` and `sqrt(Σ Δλ²)` of the change it made (the first one
/// measured from the start as given), so the stop rule of [`SolverSettings`] and every figure
/// work as for PGS; since a short line-search step can be small far from a solution, the solve
/// stops only when the natural map is below the tolerance too. The returned impulses are on the
/// friction cone and the velocities are `v_free + M⁻¹ Jᵀ λ`.
///
/// Limits: the frictional problem is not monotone; on contrived problems (several sliding
/// contacts with nearly coincident points on one body, mass ratios of 1e4) the method may
/// hit the cap with a small but non-zero residual instead of converging (see the tests).
#[derive(Debug)]
pub struct NewtonSolver {
    /// Options.
    pub settings: NewtonSettings,
    delassus: Delassus,
    order: Vec<u32>,
    x: Vec<Real>,
    prev: Vec<Real>,
    w: Vec<Real>,
    h: Vec<Real>,
    rhs: Vec<Real>,
    d: Vec<Real>,
    kd: Vec<Real>,
    trial: Vec<Real>,
    w_trial: Vec<Real>,
    state: Vec<RowState>,
    lu: BlockLu,
    stats: NewtonStats,
    /// Whether the current Newton matrix couples friction bounds to their normals.
    coupled: bool,
}

impl Default for NewtonSolver {
    fn default() -> Self {
        Self::with_settings(NewtonSettings::default())
    }
}

impl NewtonSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options.
    pub fn with_settings(settings: NewtonSettings) -> Self {
        Self {
            settings,
            delassus: Delassus::new(),
            order: Vec::new(),
            x: Vec::new(),
            prev: Vec::new(),
            w: Vec::new(),
            h: Vec::new(),
            rhs: Vec::new(),
            d: Vec::new(),
            kd: Vec::new(),
            trial: Vec::new(),
            w_trial: Vec::new(),
            state: Vec::new(),
            lu: BlockLu::default(),
            stats: NewtonStats::default(),
            coupled: true,
        }
    }

    /// The system assembled by the last solve.
    pub fn delassus(&self) -> &Delassus {
        &self.delassus
    }

    /// Counters of the last solve.
    pub fn last_stats(&self) -> NewtonStats {
        self.stats
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
        self.set_up(problem)?;
        self.start_from(impulses)?;
        report.iterations = self.iterate(settings, report)?;
        self.stats.iterations = report.iterations;
        self.finish(impulses, velocities, report);
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// One full Newton step from `start` on the active set of `reference`: every row is
    /// classified (separating, sticking, sliding up or down) as the method would classify it
    /// at `reference`, the generalised-Jacobian system of that classification is solved at
    /// `start` (coupled friction bounds, relative regularisation
    /// [`NewtonSettings::regularization`], grown ×100 until the solution is accurate), and
    /// `start + Δ`, projected onto the friction cone, is written to `out`. No line search.
    ///
    /// With `reference` the answer, this is what a predictor of the active set alone would
    /// buy: the values then follow from one linear solve (docs/RESEARCH.md, the diagnosis). With
    /// `reference = start` it is Newton's first step without its line search. Returns the
    /// regularisation used; `out` must have the problem's length.
    pub fn step_on_active_set(
        &mut self,
        problem: &ContactProblem,
        reference: &[Impulse],
        start: &[Impulse],
        out: &mut [Impulse],
    ) -> Result<Real, LcpError> {
        let points = problem.points.len();
        for (what, len) in [
            ("reference", reference.len()),
            ("start", start.len()),
            ("out", out.len()),
        ] {
            if len != points {
                return Err(CoreError::LengthMismatch {
                    what,
                    expected: points,
                    got: len,
                }
                .into());
            }
        }
        if self.settings.validate {
            problem.validate()?;
        }
        self.set_up(problem)?;
        self.start_from(reference)?;
        self.classify();
        self.coupled = true;
        self.start_from(start)?;
        for (p, &mu) in self.delassus.friction().iter().enumerate() {
            let (n, t) = (2 * p, 2 * p + 1);
            let (ln, lt) = (self.x[n], self.x[t]);
            self.rhs[n] = match self.state[n] {
                RowState::Free => -self.w[n],
                _ => -ln,
            };
            self.rhs[t] = match self.state[t] {
                RowState::Free => -self.w[t],
                RowState::Upper => -(lt - mu * ln),
                RowState::Lower => -(lt + mu * ln),
                RowState::Fixed => -lt,
            };
        }
        let scale = self
            .delassus
            .diagonal()
            .iter()
            .fold(0.0, |m: Real, &v| m.max(v));
        let scale = if scale > 0.0 { scale } else { 1.0 };
        let reg = self.newton_direction(0, self.settings.regularization, scale)?;
        for ((x, d), o) in self
            .x
            .chunks_exact(2)
            .zip(self.d.chunks_exact(2))
            .zip(out.iter_mut())
        {
            *o = Impulse::new(x[0] + d[0], x[1] + d[1]);
        }
        for (o, &friction) in out.iter_mut().zip(self.delassus.friction()) {
            let normal = o.normal.max(0.0);
            let bound = friction * normal;
            *o = Impulse::new(normal, o.tangent.clamp(-bound, bound));
        }
        Ok(reg)
    }

    /// The structure of one iteration on `problem`, from the points and the bodies they touch
    /// (without assembling `W`; the analysis of the factors is kept, and a solve of the same
    /// contact graph after it reuses it).
    pub fn work(&mut self, problem: &ContactProblem) -> Result<NewtonWork, LcpError> {
        self.work_within(problem, None)
    }

    /// [`Self::work`], or, when even a lower bound of one iteration's weight exceeds
    /// `budget`, that bound (the factors' blocks counted as `W`'s, no update counted: fill-in
    /// only adds to both) without analysing the factors.
    fn work_within(
        &mut self,
        problem: &ContactProblem,
        budget: Option<u32>,
    ) -> Result<NewtonWork, LcpError> {
        let blocks = self.lu.structure(problem)?;
        let (points, paired_points, w_entries) = island_size(
            problem,
            self.settings.assembly,
            self.settings.dense_threshold,
            blocks,
        );
        let mut work = NewtonWork {
            points,
            paired_points,
            w_entries,
            filled_blocks: blocks,
            updates: 0,
        };
        if budget.is_some_and(|b| work.pass_cost().passes(1) > b) {
            return Ok(work);
        }
        self.lu.analyse_structure()?;
        work.filled_blocks = self.lu.filled_blocks();
        work.updates = self.lu.updates();
        Ok(work)
    }

    /// Assembles the problem, sizes the buffers and analyses the Newton matrix's pattern.
    fn set_up(&mut self, problem: &ContactProblem) -> Result<(), LcpError> {
        self.delassus.assemble(
            problem,
            self.settings.assembly,
            self.settings.dense_threshold,
        )?;
        sweep_order(problem, &mut self.order);
        self.stats = NewtonStats {
            dense: self.delassus.is_dense(),
            ..NewtonStats::default()
        };
        let n = self.delassus.rows();
        for v in [
            &mut self.w,
            &mut self.h,
            &mut self.rhs,
            &mut self.d,
            &mut self.kd,
            &mut self.trial,
            &mut self.w_trial,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
        self.state.clear();
        self.state.resize(n, RowState::Free);
        self.lu.analyse(&self.delassus)
    }

    /// The first iterate: the start projected onto the friction cone, and its velocities.
    fn start_from(&mut self, impulses: &[Impulse]) -> Result<(), LcpError> {
        impulses_to_rows(impulses, &mut self.prev);
        if let Some(row) = self.prev.iter().position(|v| !v.is_finite()) {
            return Err(LcpError::NonFinite {
                what: "start impulse",
                row,
                iteration: 0,
            });
        }
        self.x.clear();
        self.x.extend_from_slice(&self.prev);
        self.delassus.project(&mut self.x);
        self.delassus.velocity_of(&self.x, &mut self.w);
        Ok(())
    }

    /// Newton iterations until the stop rule holds or the cap; returns the iterations run.
    fn iterate(
        &mut self,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> Result<u32, LcpError> {
        let scale = self
            .delassus
            .diagonal()
            .iter()
            .fold(0.0, |m: Real, &v| m.max(v));
        let scale = if scale > 0.0 { scale } else { 1.0 };
        let mut reg = self.settings.regularization;
        let mut it = 0;
        while it < settings.max_iterations {
            it += 1;
            let theta = self.classify();
            if theta > 0.0 {
                match self.newton_step(it, reg, scale, theta)? {
                    Some(next) => reg = next,
                    // Gave up (`stop_on_failed_step`): this iteration made no change.
                    None => break,
                }
            }
            if self.record_change(it, settings, report)? {
                report.converged = true;
                break;
            }
        }
        Ok(it)
    }

    /// One iteration's move from `x` at merit `theta`: the Newton step (coupled, then with
    /// the friction bounds lagged, then with a growing regularisation), or a projected
    /// Gauss-Seidel sweep when none is accepted. Returns the regularisation to go on with, or
    /// `None` when the step failed and `stop_on_failed_step` is set (nothing moved).
    fn newton_step(
        &mut self,
        it: u32,
        mut reg: Real,
        scale: Real,
        theta: Real,
    ) -> Result<Option<Real>, LcpError> {
        let (base, max_reg) = (
            self.settings.regularization,
            self.settings.max_regularization,
        );
        loop {
            // The exact generalised Jacobian first; if its step fails, the one with the
            // friction bounds lagged (held at ±μλn of this iterate).
            for coupled in [true, false] {
                self.coupled = coupled;
                reg = self.newton_direction(it, reg, scale)?;
                if self.line_search(theta).is_some() {
                    self.accept_trial();
                    // The line search updated the velocities; recompute them exactly, so
                    // that no round-off accumulates over the iterations.
                    self.delassus.velocity_of(&self.x, &mut self.w);
                    return Ok(Some((reg * 0.1).max(base)));
                }
            }
            if self.settings.stop_on_failed_step {
                return Ok(None);
            }
            if reg >= max_reg {
                break;
            }
            // Levenberg–Marquardt: a shorter, better-conditioned step.
            self.stats.retries += 1;
            reg = (reg * 100.0).max(RETRY_REGULARIZATION).min(max_reg);
        }
        self.fallback_sweep(it)?;
        self.accept_trial();
        Ok(Some(reg))
    }

    /// One projected Gauss-Seidel sweep from `x` into `trial` / `w_trial`.
    fn fallback_sweep(&mut self, it: u32) -> Result<(), LcpError> {
        self.stats.fallback_sweeps += 1;
        self.trial.copy_from_slice(&self.x);
        let (_, _, finite) = sor_sweep(&self.delassus, &self.order, &mut self.trial, 1.0);
        if !finite {
            let row = self.trial.iter().position(|v| !v.is_finite()).unwrap_or(0);
            return Err(LcpError::NonFinite {
                what: "impulse",
                row,
                iteration: it,
            });
        }
        self.delassus.velocity_of(&self.trial, &mut self.w_trial);
        Ok(())
    }

    /// Makes `trial` / `w_trial` the current iterate.
    fn accept_trial(&mut self) {
        std::mem::swap(&mut self.x, &mut self.trial);
        std::mem::swap(&mut self.w, &mut self.w_trial);
    }

    /// Records iteration `it`'s change (`max |Δλ|`, `sqrt(Σ Δλ²)`) in the report and
    /// returns whether the solve has converged: the change and the natural map both under
    /// the tolerance (a short line-search step can make a tiny change far from a solution).
    fn record_change(
        &mut self,
        it: u32,
        settings: &SolverSettings,
        report: &mut SolveReport,
    ) -> Result<bool, LcpError> {
        let mut max_d: Real = 0.0;
        let mut sum_sq: Real = 0.0;
        for (p, &x) in self.prev.iter_mut().zip(&self.x) {
            let d = x - *p;
            max_d = max_d.max(d.abs());
            sum_sq += d * d;
            *p = x;
        }
        let l2 = sum_sq.sqrt();
        report.residual_inf.push(max_d);
        report.residual_l2.push(l2);
        if !(max_d.is_finite() && l2.is_finite()) {
            let row = self.x.iter().position(|v| !v.is_finite()).unwrap_or(0);
            return Err(LcpError::NonFinite {
                what: "impulse",
                row,
                iteration: it,
            });
        }
        let (h_inf, h_l2) = self.natural_norms();
        Ok(settings.converged(it, max_d, l2, Real::INFINITY)
            && settings.converged(it, h_inf, h_l2, Real::INFINITY))
    }

    /// The result: impulses projected onto the final cone (iterates are admissible except
    /// after a fallback sweep, whose friction was clamped against the normal of its sweep),
    /// the body velocities and the natural residual.
    fn finish(
        &mut self,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) {
        self.delassus.project(&mut self.x);
        self.delassus.velocity_of(&self.x, &mut self.w);
        rows_to_impulses(&self.x, impulses);
        self.delassus.body_velocities(&self.x, velocities);
        report.natural_residual = self.delassus.natural_residual(&self.x, &self.w);
    }

    /// Classifies the rows at the current iterate, fills `h = H(x)` and the Newton
    /// right-hand side, and returns `θ = ½‖H‖²`.
    #[allow(clippy::needless_range_loop)] // rows 2p and 2p + 1 of several arrays
    fn classify(&mut self) -> Real {
        let del = &self.delassus;
        let (m, mu) = (del.effective_mass(), del.friction());
        let mut theta = 0.0;
        for p in 0..del.points() {
            let (n, t) = (2 * p, 2 * p + 1);
            let (ln, lt) = (self.x[n], self.x[t]);
            let yn = ln - m[n] * self.w[n];
            let hn = ln - yn.max(0.0);
            self.h[n] = hn;
            if m[n] > 0.0 && yn > 0.0 {
                self.state[n] = RowState::Free;
                self.rhs[n] = -self.w[n];
            } else {
                self.state[n] = RowState::Fixed;
                self.rhs[n] = -hn;
            }
            let bound = (mu[p] * ln).max(0.0);
            let yt = lt - m[t] * self.w[t];
            let ht = lt - yt.max(-bound).min(bound);
            self.h[t] = ht;
            self.rhs[t] = -ht;
            self.state[t] = if m[t] <= 0.0 {
                RowState::Fixed
            } else if yt >= bound {
                RowState::Upper
            } else if yt <= -bound {
                RowState::Lower
            } else {
                self.rhs[t] = -self.w[t];
                RowState::Free
            };
            theta += hn * hn + ht * ht;
        }
        0.5 * theta
    }

    /// Solves `K d = rhs` into `self.d` with relative regularisation `reg`, growing it
    /// until the solution is finite and accurate; returns the regularisation used.
    fn newton_direction(
        &mut self,
        iteration: u32,
        mut reg: Real,
        scale: Real,
    ) -> Result<Real, LcpError> {
        loop {
            self.stats.factorizations += 1;
            self.stats.max_regularization = self.stats.max_regularization.max(reg);
            self.d.copy_from_slice(&self.rhs);
            if self.factor_and_solve(reg, scale) && self.step_is_accurate(reg, scale) {
                return Ok(reg);
            }
            if reg >= self.settings.max_regularization {
                return Err(LcpError::Singular {
                    rows: self.delassus.rows(),
                    regularization: reg,
                    iteration,
                });
            }
            reg = (reg * 100.0)
                .max(1e-12)
                .min(self.settings.max_regularization);
        }
    }

    /// Regularised diagonal entry of a free row: `W_ii (1 + reg)` (at least `reg × 1e-12 ×
    /// scale` above `W_ii`, for a row whose diagonal vanishes).
    #[inline(always)]
    fn regularized(w_ii: Real, reg: Real, scale: Real) -> Real {
        w_ii + reg * w_ii.max(1e-12 * scale)
    }

    /// The coupling `K_{r, r−1}` of a bound tangent row `r` to its normal: `∓μ` at `±μλn`
    /// when the friction bounds are coupled, else 0 (also for normal rows).
    #[inline(always)]
    fn coupling(&self, r: usize) -> Real {
        if !self.coupled {
            return 0.0;
        }
        let mu = self.delassus.friction()[r / 2];
        match self.state[r] {
            RowState::Upper => -mu,
            RowState::Lower => mu,
            RowState::Free | RowState::Fixed => 0.0,
        }
    }

    /// Loads `K` into the block LU (rows of `W` with the regularised diagonal for free
    /// rows, identity rows with their coupling for bound rows), factorises it and solves
    /// for `d` in place; `false` when a pivot is singular.
    fn factor_and_solve(&mut self, reg: Real, scale: Real) -> bool {
        self.lu.load_w();
        for r in 0..self.delassus.rows() {
            if self.state[r] == RowState::Free {
                let w_ii = self.delassus.diagonal()[r];
                self.lu.set_diagonal(r, Self::regularized(w_ii, reg, scale));
            } else {
                let c = self.coupling(r);
                self.lu.set_bound_row(r, c);
            }
        }
        if !self.lu.factor() {
            return false;
        }
        self.lu.solve(&mut self.d);
        true
    }

    /// Whether `d` is finite and solves `K d = rhs` to a relative accuracy of 1e-8.
    fn step_is_accurate(&mut self, reg: Real, scale: Real) -> bool {
        if self.d.iter().any(|v| !v.is_finite()) {
            return false;
        }
        self.kd.fill(0.0);
        self.delassus.mul_add(&self.d, &mut self.kd);
        let mu = self.delassus.friction();
        let mut res: Real = 0.0;
        let mut rhs_max: Real = 0.0;
        let mut d_max: Real = 0.0;
        for r in 0..self.d.len() {
            let kd = match self.state[r] {
                RowState::Free => {
                    let w_ii = self.delassus.diagonal()[r];
                    self.kd[r] + (Self::regularized(w_ii, reg, scale) - w_ii) * self.d[r]
                }
                RowState::Fixed => self.d[r],
                RowState::Upper if self.coupled => self.d[r] - mu[r / 2] * self.d[r - 1],
                RowState::Lower if self.coupled => self.d[r] + mu[r / 2] * self.d[r - 1],
                RowState::Upper | RowState::Lower => self.d[r],
            };
            res = res.max((kd - self.rhs[r]).abs());
            rhs_max = rhs_max.max(self.rhs[r].abs());
            d_max = d_max.max(self.d[r].abs());
        }
        res <= 1e-8 * (rhs_max + scale.max(1.0) * d_max) || res == 0.0
    }

    /// Projected backtracking line search along `d`; leaves the accepted point in `trial`
    /// and its velocities in `w_trial`. Returns the accepted step, or `None`.
    ///
    /// Tries α = 1, β, β², … and then the first breakpoint (the largest α at which no
    /// normal impulse has crossed zero yet) when it is shorter: near-redundant contacts give
    /// Newton steps that are long along a nearly singular direction of `W`, and it is the
    /// first contact leaving (λn reaching 0) that makes progress there.
    fn line_search(&mut self, theta: Real) -> Option<Real> {
        let (sigma, beta) = (self.settings.armijo, self.settings.backtrack);
        let mut alpha = 1.0;
        for k in 0..=self.settings.max_backtracks {
            if self.try_step(alpha, theta, sigma) {
                self.stats.backtracks += k;
                return Some(alpha);
            }
            alpha *= beta;
        }
        self.stats.backtracks += self.settings.max_backtracks;
        let breakpoint = self
            .x
            .iter()
            .zip(&self.d)
            .step_by(2)
            .filter(|&(&x, &d)| x > 0.0 && d < 0.0 && x > MIN_BREAKPOINT * -d)
            .fold(Real::INFINITY, |m: Real, (&x, &d)| m.min(x / -d));
        (breakpoint < alpha / beta && self.try_step(breakpoint, theta, sigma)).then_some(breakpoint)
    }

    /// Evaluates `proj(x + αd)` into `trial` / `w_trial`; true if it passes the Armijo test.
    ///
    /// The velocities are updated, not recomputed: `w + α W d` (`W d` is `kd`, from the
    /// accuracy check of `d`) plus the columns of `W` of the rows the projection moved.
    fn try_step(&mut self, alpha: Real, theta: Real, sigma: Real) -> bool {
        for ((t, &x), &d) in self.trial.iter_mut().zip(&self.x).zip(&self.d) {
            *t = x + alpha * d;
        }
        for ((wt, &w), &kd) in self.w_trial.iter_mut().zip(&self.w).zip(&self.kd) {
            *wt = w + alpha * kd;
        }
        for p in 0..self.delassus.points() {
            let (n, t) = (2 * p, 2 * p + 1);
            let (un, ut) = (self.trial[n], self.trial[t]);
            let pn = un.max(0.0);
            let bound = self.delassus.friction()[p] * pn;
            let pt = ut.max(-bound).min(bound);
            self.trial[n] = pn;
            self.trial[t] = pt;
            if pn != un {
                self.delassus.add_column(n, pn - un, &mut self.w_trial);
            }
            if pt != ut {
                self.delassus.add_column(t, pt - ut, &mut self.w_trial);
            }
        }
        let theta_t = self.merit();
        theta_t.is_finite() && theta_t <= (1.0 - 2.0 * sigma * alpha) * theta
    }

    /// `(max |H|, ‖H‖₂)` at the current iterate.
    fn natural_norms(&self) -> (Real, Real) {
        let (inf, sq) = self.delassus.natural_norms(&self.x, &self.w);
        (inf, sq.sqrt())
    }

    /// `½‖H‖²` at `trial` (with `w_trial`).
    fn merit(&self) -> Real {
        0.5 * self.delassus.natural_norms(&self.trial, &self.w_trial).1
    }
}

impl VelocitySolver for NewtonSolver {
    fn name(&self) -> &str {
        "newton"
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
            .map_err(|e| e.into_core("newton"))
    }

    /// A fresh solver with the same settings (its own buffers and analysis).
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        Some(Box::new(NewtonSolver::with_settings(self.settings)))
    }

    /// [`NewtonWork::pass_cost`] of `problem` (from its structure; the solve after it reuses
    /// the analysis), or a lower bound above `budget` when one iteration cannot fit it.
    fn pass_cost(
        &mut self,
        problem: &ContactProblem,
        budget: Option<u32>,
    ) -> Result<PassCost, CoreError> {
        self.work_within(problem, budget)
            .map(|w| w.pass_cost())
            .map_err(|e| e.into_core("newton"))
    }
}
