//! The `anderson` provider: carried impulses refined by Anderson-accelerated Gauss-Seidel.
//!
//! Let `G(λ)` be `sweeps` PGS sweeps from the impulses λ. PGS iterates `λ ← G(λ)`; on a big
//! pile the error's slow, load-redistributing modes shrink by `1 − O(μ)` per sweep
//! (docs/RESEARCH.md). Anderson acceleration (type II, window `m`) keeps the last `m + 1`
//! images `g_i = G(λ_i)` and residuals `f_i = g_i − λ_i`, finds the combination of the
//! residual differences closest to cancelling the newest one,
//! `γ = argmin ‖f_k − ΔF γ‖₂`, and steps to `λ_{k+1} = g_k − ΔG γ`, projected onto each
//! point's friction cone (`λn ≥ 0`, `|λt| ≤ μ λn`). On a linear map this is GMRES on
//! `λ = G(λ)`; the projections make it a heuristic, so a safeguard restarts the history (and
//! takes the plain `g_k`) whenever a residual grows past the last one. The image with the
//! smallest residual is returned; PGS then finishes from it. The sweeps are provider time
//! and count as its passes.

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, Real, SpecError, WarmStart, WarmStartContext,
    WarmStartError,
};
use deepcontact_pgs::PgsSolver;

use crate::inner::{InnerSolve, in_range, non_negative, sweeper};
use crate::rows::in_cone;

/// Parameters of [`AndersonWarmStart`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AndersonConfig {
    /// Residual differences kept, `m` (default 5, in 1..=[`AndersonWarmStart::MAX_WINDOW`]).
    pub window: u32,
    /// PGS sweeps per map evaluation `G` (default 4, in 1..=1000).
    pub sweeps: u32,
    /// Most evaluations of `G` per island (default 40, in 1..=10 000).
    pub rounds: u32,
    /// Stop once the ∞-norm of a residual `G(λ) − λ` is below this (N·s; default 1e-4, the
    /// world's tolerance; ≥ 0).
    pub tolerance: Real,
    /// Over-relaxation of the sweeps `G` (default 1: plain PGS; in (0, 2)): each single-point
    /// manifold's effective masses scaled by it, as `sor` does; two-point manifolds, swept as
    /// blocks, are left as they are.
    pub omega: Real,
}

impl Default for AndersonConfig {
    fn default() -> Self {
        Self {
            window: 5,
            sweeps: 4,
            rounds: 40,
            tolerance: 1e-4,
            omega: 1.0,
        }
    }
}

/// Carried impulses refined by Anderson-accelerated PGS sweeps (see the module docs).
/// Buffers are kept between calls.
#[derive(Debug)]
pub struct AndersonWarmStart {
    config: AndersonConfig,
    inner: InnerSolve,
    solver: PgsSolver,
    /// The island with over-relaxed single-point rows (`omega` ≠ 1 only).
    relaxed: ContactProblem,
    /// The current iterate λ_k and its image g_k (impulses).
    x: Vec<Impulse>,
    g: Vec<Impulse>,
    /// The image with the smallest residual so far, and that residual's ∞-norm.
    best: Vec<Impulse>,
    /// History, `window + 1` slots of `2n` reals each (ring): images and residuals.
    images: Vec<Real>,
    residuals: Vec<Real>,
    /// Normal equations of the least-squares problem (`m × m` and `m`).
    gram: Vec<Real>,
    rhs: Vec<Real>,
    /// The residual differences `ΔF` of a mixing step, column after column (`m × 2n`).
    columns: Vec<Real>,
    /// Passes of the last island.
    last_passes: u32,
    /// Restarts of the history (a residual grew), in all.
    restarts: u64,
}

impl AndersonWarmStart {
    /// Largest window.
    pub const MAX_WINDOW: u32 = 16;

    /// A provider under `config` (validated).
    pub fn new(config: AndersonConfig) -> Result<Self, SpecError> {
        in_range("anderson", "window", config.window, 1..=Self::MAX_WINDOW)?;
        in_range("anderson", "rounds", config.rounds, 1..=10_000)?;
        non_negative("anderson", "tolerance", config.tolerance)?;
        if !(config.omega > 0.0 && config.omega < 2.0) {
            return Err(SpecError::InvalidParameter {
                spec: "anderson".into(),
                param: "omega".into(),
                value: config.omega.to_string(),
                reason: "must be in (0, 2)".into(),
            });
        }
        // Every evaluation of G runs all its sweeps (the mixing needs whole images).
        let inner = InnerSolve::new("anderson", "sweeps", config.sweeps, 1000, 0.0)?;
        Ok(Self {
            config,
            inner,
            solver: sweeper(),
            relaxed: ContactProblem::default(),
            x: Vec::new(),
            g: Vec::new(),
            best: Vec::new(),
            images: Vec::new(),
            residuals: Vec::new(),
            gram: Vec::new(),
            rhs: Vec::new(),
            columns: Vec::new(),
            last_passes: 0,
            restarts: 0,
        })
    }

    /// `g = G(x)`: the sweeps from `x`; their count is added to the passes.
    /// The island's first image builds the solver's plan; the others sweep on it.
    fn image(
        &mut self,
        problem: &ContactProblem,
        cap: u32,
        first: bool,
    ) -> Result<(), WarmStartError> {
        self.g.clear();
        self.g.extend_from_slice(&self.x);
        let swept = if self.config.omega == 1.0 {
            problem
        } else {
            &self.relaxed
        };
        let what = "Anderson's sweeps";
        if first {
            self.inner
                .run(&mut self.solver, swept, &mut self.g, what, Some(cap))?;
        } else {
            self.inner
                .run_again(&mut self.solver, swept, &mut self.g, what, Some(cap))?;
        }
        self.last_passes += self.inner.passes();
        Ok(())
    }

    /// Writes `g` and `g − x` into history slot `slot`; the residual's ∞-norm.
    fn record(&mut self, slot: usize) -> Real {
        let n = 2 * self.x.len();
        let (images, residuals) = (
            &mut self.images[slot * n..(slot + 1) * n],
            &mut self.residuals[slot * n..(slot + 1) * n],
        );
        let mut norm: Real = 0.0;
        for (i, (g, x)) in self.g.iter().zip(&self.x).enumerate() {
            images[2 * i] = g.normal;
            images[2 * i + 1] = g.tangent;
            residuals[2 * i] = g.normal - x.normal;
            residuals[2 * i + 1] = g.tangent - x.tangent;
            norm = norm
                .max(residuals[2 * i].abs())
                .max(residuals[2 * i + 1].abs());
        }
        norm
    }

    /// The accelerated iterate from the `count` newest slots ending at `newest` into `x`,
    /// projected onto the cones; `false` (and `x` untouched) if the least-squares problem
    /// is singular.
    fn mix(&mut self, problem: &ContactProblem, newest: usize, count: usize) -> bool {
        let n = 2 * self.x.len();
        let slots = self.config.window as usize + 1;
        let m = count - 1;
        // Where history entry j (0: the newest) starts, j = 0..=m.
        let mut at = [0; AndersonWarmStart::MAX_WINDOW as usize + 1];
        for (j, at) in at.iter_mut().enumerate().take(m + 1) {
            *at = (newest + slots - j) % slots * n;
        }
        // ΔF column j = f_{newest−j} − f_{newest−j−1}, j = 0..m, one after another.
        self.columns.clear();
        for j in 0..m {
            let (new, old) = (
                &self.residuals[at[j]..at[j] + n],
                &self.residuals[at[j + 1]..at[j + 1] + n],
            );
            self.columns
                .extend(new.iter().zip(old).map(|(new, old)| new - old));
        }
        let column = |j: usize| &self.columns[j * n..(j + 1) * n];
        let dot = |u: &[Real], v: &[Real]| u.iter().zip(v).fold(0.0, |acc, (u, v)| acc + u * v);
        let f = &self.residuals[at[0]..at[0] + n];
        self.gram.clear();
        self.gram.resize(m * m, 0.0);
        self.rhs.clear();
        for a in 0..m {
            self.rhs.push(dot(column(a), f));
            for b in a..m {
                let g = dot(column(a), column(b));
                self.gram[a * m + b] = g;
                self.gram[b * m + a] = g;
            }
        }
        // The differences are nearly parallel once the iterates settle: a light ridge.
        if !crate::spd::solve_spd(&mut self.gram, &mut self.rhs, m, 1e-10, 1e-14) {
            return false;
        }
        let images = &self.images;
        for (i, (x, p)) in self.x.iter_mut().zip(&problem.points).enumerate() {
            let mut v = [0.0; 2];
            for (c, value) in v.iter_mut().enumerate() {
                let r = 2 * i + c;
                *value = images[at[0] + r];
                for (a, gamma) in self.rhs.iter().enumerate() {
                    *value -= gamma * (images[at[a] + r] - images[at[a + 1] + r]);
                }
            }
            *x = in_cone(v[0], v[1], p.friction);
        }
        true
    }
}

impl WarmStart for AndersonWarmStart {
    fn name(&self) -> &str {
        "anderson"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        CarriedWarmStart.warm_start(ctx, out)?;
        // Under a budget the provider keeps one pass for the solver at least.
        self.refine(
            ctx.problem,
            ctx.pass_budget.map(|b| b.saturating_sub(1)),
            out,
        )
    }

    fn passes_spent(&self) -> u32 {
        self.last_passes
    }

    fn diagnostics(&self) -> Vec<(String, Real)> {
        vec![("restarts".into(), self.restarts as Real)]
    }
}

impl AndersonWarmStart {
    /// The mixed sweeps from the start in `out` (in place), at most `budget` sweeps when
    /// given; their count is [`WarmStart::passes_spent`]. The start is projected onto the
    /// friction cones first; `out` is left as it is when no sweep ran.
    pub(crate) fn refine(
        &mut self,
        problem: &ContactProblem,
        budget: Option<u32>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.last_passes = 0;
        if out.is_empty() {
            return Ok(());
        }
        let (sweeps, window) = (self.config.sweeps, self.config.window as usize);
        let n = out.len();
        if self.config.omega != 1.0 {
            relax_single_points(&mut self.relaxed, problem, self.config.omega);
        }
        self.x.clear();
        self.x.extend(
            out.iter()
                .zip(&problem.points)
                .map(|(s, p)| in_cone(s.normal, s.tangent, p.friction)),
        );
        self.images.clear();
        self.images.resize((window + 1) * 2 * n, 0.0);
        self.residuals.clear();
        self.residuals.resize((window + 1) * 2 * n, 0.0);
        let (mut newest, mut count) = (0, 0);
        let mut best_norm = Real::INFINITY;
        let mut last_norm = Real::INFINITY;
        for _ in 0..self.config.rounds {
            let cap = match budget {
                Some(b) if self.last_passes >= b => break,
                Some(b) => sweeps.min(b - self.last_passes),
                None => sweeps,
            };
            self.image(problem, cap, self.last_passes == 0)?;
            let slot = if count == 0 {
                0
            } else {
                (newest + 1) % (window + 1)
            };
            let norm = self.record(slot);
            if norm < best_norm {
                best_norm = norm;
                self.best.clear();
                self.best.extend_from_slice(&self.g);
            }
            if norm <= self.config.tolerance || self.inner.passes() < cap {
                break;
            }
            if norm > last_norm {
                // The mixed step made things worse: forget the history, go on from g.
                self.restarts += 1;
                (newest, count) = (0, 0);
                self.images.copy_within(slot * 2 * n..(slot + 1) * 2 * n, 0);
                self.residuals
                    .copy_within(slot * 2 * n..(slot + 1) * 2 * n, 0);
            } else {
                newest = slot;
            }
            count = (count + 1).min(window + 1);
            last_norm = norm;
            if count < 2 || !self.mix(problem, newest, count) {
                self.x.clear();
                self.x.extend_from_slice(&self.g);
            }
        }
        if best_norm.is_finite() {
            out.copy_from_slice(&self.best);
        }
        Ok(())
    }
}

/// Fills `relaxed` with `problem`, each single-point manifold's effective masses scaled by
/// `omega` (a sweep of that row then moves it `omega` times its Gauss-Seidel step).
fn relax_single_points(relaxed: &mut ContactProblem, problem: &ContactProblem, omega: Real) {
    relaxed.clone_from(problem);
    for &(start, end) in &problem.manifolds {
        if end == start + 1 {
            let p = &mut relaxed.points[start as usize];
            p.normal_mass *= omega;
            p.tangent_mass *= omega;
        }
    }
}
