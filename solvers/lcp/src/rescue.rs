//! PGS with a semismooth Newton finish for the islands it cannot settle.

use deepcontact_core::math::{Real, Velocity};
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, IslandSolve, ResidualNorm, SolveReport, SolverSettings,
    VelocitySolver,
};
use deepcontact_pgs::{PgsSettings, PgsSolver};

use crate::{LcpError, NewtonSettings, NewtonSolver};

/// Which islands that PGS left at its iteration cap are handed to Newton.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RescueTrigger {
    /// Every capped island (default).
    #[default]
    Capped,
    /// Only capped islands whose impulse-change curve stalled ([`stalled`]): the envelope of
    /// the last [`RescueSettings::window`] iterations is not [`RescueSettings::factor`] times
    /// below that of the window before.
    Stalled,
}

/// Where the Newton finish starts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum RescueStart {
    /// From the impulses PGS stopped at.
    Iterate,
    /// From zero impulses.
    Zeros,
    /// From PGS's impulses, and when that solve does not meet its stop rule also from zeros;
    /// the lower natural residual is kept (default).
    #[default]
    Best,
}

/// Options of [`PgsRescueSolver`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RescueSettings {
    /// The PGS solve every island gets first (default [`PgsSettings::default`]).
    pub pgs: PgsSettings,
    /// The Newton finish's options (default [`NewtonSettings::default`]).
    pub newton: NewtonSettings,
    /// Which capped islands are finished by Newton (default [`RescueTrigger::Capped`]).
    pub trigger: RescueTrigger,
    /// Iterations of the stall test's window (default 100, ≥ 1). An island capped before
    /// `2 × window` iterations is never handed to Newton: such a cap is a fixed budget of
    /// passes, not a stall.
    pub window: u32,
    /// Decrease of the impulse change's envelope over one window below which the curve
    /// counts as stalled (default 2, > 1); used by [`RescueTrigger::Stalled`].
    pub factor: Real,
    /// A capped island goes to Newton only when PGS's natural residual there is above this
    /// multiple of the stop tolerance ([`SolverSettings::tolerance`]; default 10, ≥ 0; 0 =
    /// every capped island the trigger names): with the comparison's 1e-4, the islands PGS
    /// leaves above 1e-3 N·s. Islands PGS leaves closer to a solution are not worth a Newton
    /// solve (on the 20-row pyramid and the stack under a heavy box, most of the islands a
    /// gate at 5 sent to Newton were between 5e-4 and 1e-3 N·s).
    pub above: Real,
    /// Where Newton starts (default [`RescueStart::Best`]).
    pub start: RescueStart,
    /// Iteration cap of each Newton solve (default 20, ≥ 1). Where semismooth Newton
    /// converges on a pile's island it does so within a few tens of iterations; past that it
    /// mostly wanders, at the price of a factorisation an iteration.
    pub newton_iterations: u32,
    /// Newton runs in chunks of this many iterations (≥ 1); after a chunk that did not
    /// converge it goes on only when the natural residual fell below
    /// [`Self::newton_progress`] × its value after the chunk before (after the first chunk:
    /// × PGS's). Default 300 (not below [`Self::newton_iterations`]: one solve per start). Short
    /// chunks (10) stop hopeless solves early on large islands (the 20-row pyramid), but
    /// also stop some that would have converged on the piles (Newton's natural residual does
    /// not fall monotonically) and each chunk restarts Newton's regularisation.
    pub newton_chunk: u32,
    /// Factor by which each Newton chunk after the first must lower the natural residual
    /// for the solve to go on (default 0.5, in (0, 1]).
    pub newton_progress: Real,
    /// Stop tolerance of the Newton solve on `max |Δλ|` and on the natural residual (N·s;
    /// default 1e-6, ≥ 0).
    pub newton_tolerance: Real,
    /// Iteration cap of a second round of the starts (default 300; 0 = none), run only when no
    /// start converged and the best result's natural residual is still above
    /// [`Self::escalate_above`] × the stop tolerance after the [`Self::finish`] iterations:
    /// the rare island the short solves leave far from a solution gets long ones, the others
    /// do not pay for them.
    pub escalate: u32,
    /// Multiple of the stop tolerance above which the best result of the starts gets the
    /// longer round [`Self::escalate`] (default 10, ≥ 0: with the comparison's 1e-4, a natural
    /// residual above 1e-3 N·s).
    pub escalate_above: Real,
    /// PGS iterations from the best result, kept when they lower its natural residual
    /// (default 5 000; 0 = none): first, with [`Self::sweeps_first`]; else when the short
    /// Newton solves leave the island above [`Self::escalate_above`] × the stop tolerance,
    /// before the longer round [`Self::escalate`]. On the
    /// landing steps of a pyramid of boxes semismooth Newton rarely finds a descent direction
    /// (a long round there costs ≈ 2 ms an iteration: two factorisations and a line search),
    /// while PGS only converges slowly (a few thousand iterations from builtin's start, each
    /// one sweep of the island).
    pub finish: u32,
    /// The finishing iterations run in rounds of this many (default 500, ≥ 1); after each
    /// round that another follows and that leaves the island above
    /// [`Self::escalate_above`] × the stop tolerance, a Newton solve of
    /// [`Self::newton_iterations`] starts from the round's impulses, and the next round goes
    /// on from the round's impulses (not Newton's). Semismooth Newton
    /// converges from some points of a cycling PGS trajectory and wanders from others that
    /// look alike (on a 102-point circle-pile island, from the iterates after 30 and 300
    /// sweeps but not after 10, 100 or 600), so a few starts along the trajectory finish
    /// islands that neither method finishes alone. `finish_chunk` ≥ `finish`: one round and
    /// no Newton solve in it.
    pub finish_chunk: u32,
    /// The finishing rounds ([`Self::finish`]) run before the Newton starts instead of after
    /// them (default true); the starts then run only when the rounds leave the island above
    /// [`Self::escalate_above`] × the stop tolerance. Where PGS is slow rather than cycling
    /// (the 1 000-circle pile's large island) a round of sweeps often brings the island under
    /// the gate for a fraction of one Newton start (a 20-iteration Newton solve there took
    /// ≈ 27 ms, the time of a few thousand sweeps at ≈ 5 ns a point and sweep).
    pub sweeps_first: bool,
}

impl Default for RescueSettings {
    fn default() -> Self {
        Self {
            pgs: PgsSettings::default(),
            newton: NewtonSettings::default(),
            trigger: RescueTrigger::Capped,
            window: 100,
            factor: 2.0,
            above: 10.0,
            start: RescueStart::Best,
            newton_iterations: 20,
            newton_chunk: 300,
            newton_progress: 0.5,
            newton_tolerance: 1e-6,
            escalate: 300,
            escalate_above: 10.0,
            finish: 5_000,
            finish_chunk: 500,
            sweeps_first: true,
        }
    }
}

impl RescueSettings {
    /// Rejects a zero window or Newton cap, a factor not above 1, a negative or non-finite
    /// Newton tolerance, and bad Newton settings.
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
            "window",
            Real::from(self.window),
            self.window >= 1,
            "must be >= 1",
        )?;
        check(
            "factor",
            self.factor,
            self.factor.is_finite() && self.factor > 1.0,
            "must be finite and > 1",
        )?;
        check(
            "above",
            self.above,
            self.above.is_finite() && self.above >= 0.0,
            "must be finite and >= 0",
        )?;
        check(
            "newton_iterations",
            Real::from(self.newton_iterations),
            self.newton_iterations >= 1,
            "must be >= 1",
        )?;
        check(
            "newton_chunk",
            Real::from(self.newton_chunk),
            self.newton_chunk >= 1,
            "must be >= 1",
        )?;
        check(
            "newton_progress",
            self.newton_progress,
            self.newton_progress > 0.0 && self.newton_progress <= 1.0,
            "must be in (0, 1]",
        )?;
        check(
            "newton_tolerance",
            self.newton_tolerance,
            self.newton_tolerance.is_finite() && self.newton_tolerance >= 0.0,
            "must be finite and >= 0",
        )?;
        check(
            "finish_chunk",
            Real::from(self.finish_chunk),
            self.finish_chunk >= 1,
            "must be >= 1",
        )?;
        check(
            "escalate_above",
            self.escalate_above,
            self.escalate_above.is_finite() && self.escalate_above >= 0.0,
            "must be finite and >= 0",
        )?;
        self.newton.validate()
    }
}

/// Counters of a [`PgsRescueSolver`], summed over its solves since it was made.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RescueStats {
    /// Islands solved.
    pub islands: u64,
    /// Islands PGS left at its cap.
    pub capped: u64,
    /// Capped islands whose curve the stall test marked as stalled.
    pub stalled: u64,
    /// Capped islands left as PGS ended them: the trigger did not name them, PGS's natural
    /// residual was not above [`RescueSettings::above`] × the stop tolerance, or the cap was
    /// below `2 ×` [`RescueSettings::window`].
    pub skipped: u64,
    /// Islands handed to Newton.
    pub attempted: u64,
    /// Islands whose rescue was kept: a result of Newton or of the finishing PGS iterations
    /// with a lower natural residual than PGS's.
    pub rescued: u64,
    /// Islands handed to Newton that kept PGS's result (no later stage did better, or they
    /// failed).
    pub fallbacks: u64,
    /// Islands whose starts and finishing PGS iterations left them above
    /// [`RescueSettings::escalate_above`] × the stop tolerance and that got the longer round
    /// of Newton solves.
    pub escalated: u64,
    /// Islands that got [`RescueSettings::finish`] more PGS iterations (every rescued island
    /// with [`RescueSettings::sweeps_first`]; else those the short Newton solves left above
    /// [`RescueSettings::escalate_above`] × the stop tolerance).
    pub finished: u64,
    /// Newton solves started between the finishing rounds
    /// ([`RescueSettings::finish_chunk`]).
    pub finish_newtons: u64,
    /// Newton iterations, in all.
    pub newton_iterations: u64,
    /// Wall time of the Newton solves (s).
    pub newton_seconds: Real,
}

/// Whether an impulse-change curve has stalled: with `n` its length and `w = window`, the
/// largest value of the last `w` entries is not `factor` times below the largest of the `w`
/// before them. `false` for curves shorter than `2 w`.
///
/// ```
/// use deepcontact_lcp::stalled;
/// let falling: Vec<f64> = (0..40).map(|i| 0.9f64.powi(i)).collect();
/// assert!(!stalled(&falling, 10, 2.0));
/// let cycling: Vec<f64> = (0..40).map(|i| 1.0 + 0.5 * (i as f64).sin()).collect();
/// assert!(stalled(&cycling, 10, 2.0));
/// ```
pub fn stalled(curve: &[Real], window: usize, factor: Real) -> bool {
    let n = curve.len();
    if window == 0 || n < 2 * window {
        return false;
    }
    let envelope = |s: &[Real]| s.iter().copied().fold(0.0, Real::max);
    let before = envelope(&curve[n - 2 * window..n - window]);
    let last = envelope(&curve[n - window..]);
    last * factor > before
}

/// PGS ([`PgsSolver`]) on every island; an island it leaves at its iteration cap with a
/// natural residual above [`RescueSettings::above`] × the stop tolerance, after at least
/// `2 ×` [`RescueSettings::window`] iterations (and, with
/// [`RescueTrigger::Stalled`], whose impulse-change curve stalled) is finished by more PGS
/// iterations in rounds, with a semismooth Newton solve ([`NewtonSolver`]) from the end of
/// each round ([`RescueSettings::finish`], [`RescueSettings::finish_chunk`]); where that
/// leaves it above [`RescueSettings::escalate_above`] × the stop tolerance, by Newton from
/// PGS's impulses or from zeros ([`RescueStart`]), and then by the same starts with a longer
/// cap ([`RescueSettings::escalate`]). With [`RescueSettings::sweeps_first`] off the Newton
/// starts come first and the rounds run from their best result. A result is kept only when
/// its natural residual is below
/// the best so far; when none beats PGS's, PGS's impulses and velocities stay (a counted
/// fallback, [`RescueStats::fallbacks`]).
///
/// An island PGS settles is untouched: its impulses, velocities and report are the bits of
/// [`PgsSolver`] alone (islands are handed to [`PgsSolver`]'s own
/// [`VelocitySolver::solve_many`]). The report of a finished island appends Newton's
/// iterations and per-iteration impulse changes to PGS's, its natural residual and
/// `converged` are those of the kept result, and its time includes Newton's and the
/// finishing iterations'.
#[derive(Debug)]
pub struct PgsRescueSolver {
    /// Options.
    pub settings: RescueSettings,
    pgs: PgsSolver,
    newton: NewtonSolver,
    stats: RescueStats,
    saved_impulses: Vec<Impulse>,
    saved_velocities: Vec<Velocity>,
    trial_impulses: Vec<Impulse>,
    trial_velocities: Vec<Velocity>,
    chain_impulses: Vec<Impulse>,
    newton_report: SolveReport,
    finish_report: SolveReport,
}

impl Default for PgsRescueSolver {
    fn default() -> Self {
        Self::with_settings(RescueSettings::default())
    }
}

impl PgsRescueSolver {
    /// A solver with default options.
    pub fn new() -> Self {
        Self::default()
    }

    /// A solver with the given options (checked at each solve).
    pub fn with_settings(settings: RescueSettings) -> Self {
        Self {
            settings,
            pgs: PgsSolver::with_settings(settings.pgs),
            newton: NewtonSolver::with_settings(settings.newton),
            stats: RescueStats::default(),
            saved_impulses: Vec::new(),
            saved_velocities: Vec::new(),
            trial_impulses: Vec::new(),
            trial_velocities: Vec::new(),
            chain_impulses: Vec::new(),
            newton_report: SolveReport::default(),
            finish_report: SolveReport::default(),
        }
    }

    /// Counters since the solver was made (a fork from [`VelocitySolver::fork`] counts its
    /// own).
    pub fn stats(&self) -> RescueStats {
        self.stats
    }

    /// The stop rule of a Newton chunk of `iterations`.
    fn newton_stop(&self, iterations: u32) -> SolverSettings {
        SolverSettings {
            max_iterations: iterations,
            tolerance: self.settings.newton_tolerance,
            norm: ResidualNorm::Infinity,
            min_iterations: 1,
        }
    }

    /// Whether an island PGS has solved goes to Newton (and counts it).
    fn wants_rescue(&mut self, settings: &SolverSettings, report: &SolveReport) -> bool {
        self.stats.islands += 1;
        if report.converged {
            return false;
        }
        self.stats.capped += 1;
        let window = self.settings.window as usize;
        let is_stalled = stalled(&report.residual_inf, window, self.settings.factor);
        self.stats.stalled += u64::from(is_stalled);
        let named = match self.settings.trigger {
            RescueTrigger::Capped => true,
            RescueTrigger::Stalled => is_stalled,
        };
        let far = report.natural_residual > self.settings.above * settings.tolerance;
        let long = report.iterations as usize >= 2 * window;
        let wanted = named && far && long;
        self.stats.skipped += u64::from(!wanted);
        wanted
    }

    /// One Newton solve of at most `iterations` from `self.trial_impulses`; its natural
    /// residual, or `None` when it failed. The result is left in the trial buffers and
    /// `self.newton_report`.
    fn newton_from_trial(&mut self, problem: &ContactProblem, iterations: u32) -> Option<Real> {
        let stop = self.newton_stop(iterations);
        let outcome = self.newton.solve_lcp(
            problem,
            &stop,
            &mut self.trial_impulses,
            &mut self.trial_velocities,
            &mut self.newton_report,
        );
        self.stats.newton_iterations += u64::from(self.newton_report.iterations);
        self.stats.newton_seconds += self.newton_report.seconds;
        match outcome {
            Ok(()) if self.newton_report.natural_residual.is_finite() => {
                Some(self.newton_report.natural_residual)
            }
            _ => None,
        }
    }

    /// Keeps the last Newton solve's result (the trial buffers) as the island's when its
    /// natural residual `residual` is below `best` (which it lowers).
    fn keep_newton(
        &self,
        residual: Option<Real>,
        best: &mut Real,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) {
        if let Some(r) = residual
            && r < *best
        {
            *best = r;
            impulses.copy_from_slice(&self.trial_impulses);
            velocities.copy_from_slice(&self.trial_velocities);
            report.converged = self.newton_report.converged;
        }
    }

    /// Appends the last Newton solve's figures to `report`.
    fn append_newton(&self, report: &mut SolveReport) {
        let n = &self.newton_report;
        report.iterations += n.iterations;
        report.residual_inf.extend_from_slice(&n.residual_inf);
        report.residual_l2.extend_from_slice(&n.residual_l2);
        report.seconds += n.seconds;
    }

    /// Newton from each start [`RescueStart`] names, at most `cap` iterations each (in chunks
    /// of [`RescueSettings::newton_chunk`]), until one converges; a result replaces the
    /// island's impulses and velocities when its natural residual is below `best` (which it
    /// lowers). Returns whether a start converged.
    fn run_starts(
        &mut self,
        problem: &ContactProblem,
        cap: u32,
        best: &mut Real,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> bool {
        let pgs_residual = report.natural_residual;
        let starts: &[bool] = match self.settings.start {
            RescueStart::Iterate => &[false],
            RescueStart::Zeros => &[true],
            RescueStart::Best => &[false, true],
        };
        for &zeros in starts {
            self.trial_impulses.clear();
            if zeros {
                self.trial_impulses
                    .resize(self.saved_impulses.len(), Impulse::default());
            } else {
                self.trial_impulses.extend_from_slice(&self.saved_impulses);
            }
            self.trial_velocities.clear();
            self.trial_velocities
                .resize(self.saved_velocities.len(), Velocity::default());
            let mut left = cap;
            let mut last = pgs_residual;
            let mut residual = None;
            while left > 0 {
                let chunk = left.min(self.settings.newton_chunk);
                left -= chunk;
                residual = self.newton_from_trial(problem, chunk);
                self.append_newton(report);
                match residual {
                    Some(r)
                        if !self.newton_report.converged
                            && r < last * self.settings.newton_progress =>
                    {
                        last = r;
                    }
                    _ => break,
                }
            }
            self.keep_newton(residual, best, impulses, velocities, report);
            if self.newton_report.converged {
                return true;
            }
        }
        false
    }

    /// Finishes an island PGS left at its cap: the finishing rounds
    /// ([`RescueSettings::finish`]) from PGS's result, then, while the best result is above
    /// [`RescueSettings::escalate_above`] × the stop tolerance, Newton from the starts
    /// [`RescueStart`] names and the same starts with the longer cap
    /// [`RescueSettings::escalate`]; each result kept when its natural residual is below the
    /// best so far. With [`RescueSettings::sweeps_first`] off the rounds come after the first
    /// starts (when none converged) and run from their best result.
    fn rescue(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) {
        self.stats.attempted += 1;
        let tolerance = settings.tolerance;
        let pgs_residual = report.natural_residual;
        let mut best = pgs_residual;
        self.saved_impulses.clear();
        self.saved_impulses.extend_from_slice(impulses);
        self.saved_velocities.clear();
        self.saved_velocities.extend_from_slice(velocities);
        let cap = self.settings.newton_iterations;
        let gate = self.settings.escalate_above * tolerance;
        let sweeps_first = self.settings.sweeps_first && self.settings.finish > 0;
        if sweeps_first {
            self.finish(
                problem, settings, gate, &mut best, impulses, velocities, report,
            );
        }
        let converged = if best > gate {
            self.run_starts(problem, cap, &mut best, impulses, velocities, report)
        } else {
            false
        };
        if !sweeps_first && !converged && self.settings.finish > 0 && best > gate {
            self.finish(
                problem, settings, gate, &mut best, impulses, velocities, report,
            );
        }
        if !converged && self.settings.escalate > 0 && best > gate {
            self.stats.escalated += 1;
            let cap = self.settings.escalate;
            self.run_starts(problem, cap, &mut best, impulses, velocities, report);
        }
        report.natural_residual = best;
        if best < pgs_residual {
            self.stats.rescued += 1;
        } else {
            self.stats.fallbacks += 1;
        }
    }

    /// [`RescueSettings::finish`] PGS iterations from `impulses` (the best result so far),
    /// under the stop rule of `settings`, in rounds of [`RescueSettings::finish_chunk`]; a
    /// round's result is kept when its natural residual is below `best` (which it lowers).
    /// After a round that neither met the stop rule nor brought `best` to `gate`, and that
    /// another round follows, Newton ([`RescueSettings::newton_iterations`]) from the round's
    /// impulses, kept likewise; the rounds end when Newton converges. A failed solve keeps the best result.
    #[allow(clippy::too_many_arguments)]
    fn finish(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        gate: Real,
        best: &mut Real,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) {
        self.stats.finished += 1;
        self.chain_impulses.clear();
        self.chain_impulses.extend_from_slice(impulses);
        let mut left = self.settings.finish;
        while left > 0 {
            let chunk = left.min(self.settings.finish_chunk);
            left -= chunk;
            // The round's velocities are kept at once or not at all, so the trial buffer
            // (which the Newton solve after the round overwrites) holds them.
            self.trial_velocities.clear();
            self.trial_velocities
                .resize(velocities.len(), Velocity::default());
            let stop = SolverSettings {
                max_iterations: chunk,
                ..*settings
            };
            let solved = self.pgs.solve(
                problem,
                &stop,
                &mut self.chain_impulses,
                &mut self.trial_velocities,
                &mut self.finish_report,
            );
            let f = &self.finish_report;
            report.iterations += f.iterations;
            report.residual_inf.extend_from_slice(&f.residual_inf);
            report.residual_l2.extend_from_slice(&f.residual_l2);
            report.seconds += f.seconds;
            if solved.is_err() {
                return;
            }
            if f.natural_residual < *best {
                *best = f.natural_residual;
                impulses.copy_from_slice(&self.chain_impulses);
                velocities.copy_from_slice(&self.trial_velocities);
                report.converged = f.converged;
            }
            if f.converged || *best <= gate || left == 0 {
                return;
            }
            self.stats.finish_newtons += 1;
            self.trial_impulses.clear();
            self.trial_impulses.extend_from_slice(&self.chain_impulses);
            self.trial_velocities.clear();
            self.trial_velocities
                .resize(velocities.len(), Velocity::default());
            let residual = self.newton_from_trial(problem, self.settings.newton_iterations);
            self.append_newton(report);
            self.keep_newton(residual, best, impulses, velocities, report);
            if self.newton_report.converged {
                return;
            }
        }
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
        self.settings.validate()?;
        self.pgs.settings = self.settings.pgs;
        self.newton.settings = self.settings.newton;
        self.pgs
            .solve(problem, settings, impulses, velocities, report)?;
        if self.wants_rescue(settings, report) {
            self.rescue(problem, settings, impulses, velocities, report);
        }
        Ok(())
    }
}

impl VelocitySolver for PgsRescueSolver {
    fn name(&self) -> &str {
        "pgs-rescue"
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
            .map_err(|e| e.into_core("pgs-rescue"))
    }

    /// PGS's [`VelocitySolver::solve_many`] on all islands (so small islands share lanes as
    /// with plain PGS), then the rescue of the capped ones, one after another.
    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        if let Err(e) = self.settings.validate() {
            let e = e.into_core("pgs-rescue");
            for island in islands {
                island.result = Err(e.clone());
            }
            return;
        }
        self.pgs.settings = self.settings.pgs;
        self.newton.settings = self.settings.newton;
        self.pgs.solve_many(settings, islands);
        for island in islands {
            if island.result.is_ok() && self.wants_rescue(settings, island.report) {
                self.rescue(
                    island.problem,
                    settings,
                    island.impulses,
                    island.velocities,
                    island.report,
                );
            }
        }
    }

    /// The same settings, PGS on one thread (the result does not depend on the thread count).
    fn fork(&self) -> Option<Box<dyn VelocitySolver>> {
        Some(Box::new(PgsRescueSolver::with_settings(RescueSettings {
            pgs: PgsSettings {
                threads: 1,
                ..self.settings.pgs
            },
            ..self.settings
        })))
    }

    /// PGS's threads for the island (a rescue runs on the calling thread).
    fn threads_for(&self, points: usize) -> usize {
        self.settings.pgs.threads_for(points)
    }

    /// As PGS's: `false` when its settings apply a start's tangents as given
    /// ([`PgsSettings::raw_start`]).
    fn projects_start(&self) -> bool {
        !self.settings.pgs.raw_start
    }
}
