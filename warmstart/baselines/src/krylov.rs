//! The `krylov` provider: carried impulses plus a conjugate-gradient correction of their
//! smooth error.
//!
//! What PGS is slow at is the smooth part of the start's error: a load change that has to
//! travel through the whole pile, one contact per sweep. Conjugate gradients on the same
//! equations reach such modes in √κ rather than κ steps. The provider takes the carried
//! impulses λc, assumes their active set (normal rows with λn > 0, friction rows of those
//! points inside the cone), and runs `iterations` Jacobi-preconditioned CG steps on
//! `W_AA Δ = −(J v(λc) − b)_A`, where `W = J M⁻¹ Jᵀ` is applied matrix-free (two passes over
//! the points per step, no matrix), `v(λc)` are the velocities after λc and `b` the rows'
//! targets (restitution bias for normal rows, 0 for friction rows). The start is
//! `λc + Δ`, projected onto the friction cone; PGS then handles what the active set got
//! wrong.

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, Real, SpecError, Velocity, WarmStart,
    WarmStartContext, WarmStartError,
};

use crate::rows::{apply_jt, in_cone, row, row_velocity, velocities_after};

/// Directions whose Rayleigh quotient `pᵀWp / pᵀDp` (D the diagonal of W) is below this lie
/// in W's null space up to round-off: conjugate gradients stop there.
const NULL_SPACE: Real = 1e-9;

/// Parameters of [`KrylovWarmStart`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KrylovConfig {
    /// Conjugate-gradient steps per island (default 10, in 1..=[`KrylovWarmStart::MAX_ITERATIONS`];
    /// fewer where a pass budget leaves room for fewer).
    pub iterations: u32,
    /// Whether friction rows of sticking points join the system (default true).
    pub friction: bool,
    /// Rounds of (active set of the current start → CG → projection) (default 1, in
    /// 1..=[`KrylovWarmStart::MAX_ROUNDS`]).
    pub rounds: u32,
    /// Relative regularisation ε: CG runs on `W_AA + ε D_AA` (D the diagonal of W), which
    /// keeps the correction out of W's null space (default 0).
    pub regularization: Real,
}

impl Default for KrylovConfig {
    fn default() -> Self {
        Self {
            iterations: 10,
            friction: true,
            rounds: 1,
            regularization: 0.0,
        }
    }
}

/// Carried impulses corrected by a few conjugate-gradient steps on their active set (see
/// the module docs). Buffers are kept between calls.
///
/// ```
/// use deepcontact_core::WarmStart;
/// use deepcontact_warmstart::{KrylovConfig, KrylovWarmStart};
///
/// let provider = KrylovWarmStart::new(KrylovConfig::default()).unwrap();
/// assert_eq!(provider.name(), "krylov");
/// ```
#[derive(Debug, Clone)]
pub struct KrylovWarmStart {
    config: KrylovConfig,
    /// Per row (2 per point: normal, friction): whether it is in the active set.
    active: Vec<bool>,
    x: Vec<Real>,
    r: Vec<Real>,
    z: Vec<Real>,
    p: Vec<Real>,
    q: Vec<Real>,
    dv: Vec<Velocity>,
    /// Passes over the rows on the last island (see `passes_spent`).
    last_passes: u32,
}

impl KrylovWarmStart {
    /// Most conjugate-gradient steps per island (each costs about two PGS iterations).
    pub const MAX_ITERATIONS: u32 = 10_000;

    /// Most rounds per island.
    pub const MAX_ROUNDS: u32 = 100;

    /// A provider under `config` (validated: 1 to `MAX_ITERATIONS` steps, 1 to `MAX_ROUNDS`
    /// rounds).
    pub fn new(config: KrylovConfig) -> Result<Self, SpecError> {
        if !(1..=Self::MAX_ROUNDS).contains(&config.rounds) {
            return Err(SpecError::InvalidParameter {
                spec: "krylov".into(),
                param: "rounds".into(),
                value: config.rounds.to_string(),
                reason: "must be in 1..=100".into(),
            });
        }
        if !(1..=Self::MAX_ITERATIONS).contains(&config.iterations) {
            return Err(SpecError::InvalidParameter {
                spec: "krylov".into(),
                param: "iterations".into(),
                value: config.iterations.to_string(),
                reason: "must be in 1..=10000".into(),
            });
        }
        Ok(Self {
            config,
            active: Vec::new(),
            x: Vec::new(),
            r: Vec::new(),
            z: Vec::new(),
            p: Vec::new(),
            q: Vec::new(),
            dv: Vec::new(),
            last_passes: 0,
        })
    }

    /// The config.
    pub fn config(&self) -> &KrylovConfig {
        &self.config
    }

    /// The active set of `start`: loaded normal rows, and the friction rows of loaded points
    /// strictly inside the cone (when friction joins).
    fn select_active(&mut self, problem: &ContactProblem, start: &[Impulse]) {
        let friction = self.config.friction;
        self.active.clear();
        self.active.extend((0..2 * start.len()).map(|k| {
            let (imp, p) = (start[k / 2], &problem.points[k / 2]);
            let loaded = imp.normal > 0.0;
            if k % 2 == 0 {
                loaded
            } else {
                friction && loaded && imp.tangent.abs() < p.friction * imp.normal
            }
        }));
    }

    /// The preconditioned residual at `start` on the active rows, `r = −(J v(start) − b)`,
    /// `z = D⁻¹ r` with D the rows' own `W_kk`, `p = z`; returns `rᵀz`. Clears `x`.
    fn residual(&mut self, problem: &ContactProblem, start: &[Impulse]) -> Real {
        let rows = 2 * start.len();
        for buf in [&mut self.r, &mut self.z, &mut self.p, &mut self.q] {
            buf.clear();
            buf.resize(rows, 0.0);
        }
        velocities_after(problem, start, &mut self.x, &mut self.dv);
        let mut rz = 0.0;
        for k in (0..rows).filter(|&k| self.active[k]) {
            let target = if k % 2 == 0 {
                problem.points[k / 2].velocity_bias
            } else {
                0.0
            };
            self.r[k] = target - row_velocity(problem, k, &self.dv);
            self.z[k] = row(problem, k).5 * self.r[k];
            self.p[k] = self.z[k];
            rz += self.r[k] * self.z[k];
        }
        self.x.clear();
        self.x.resize(rows, 0.0);
        rz
    }

    /// At most `iterations` Jacobi-preconditioned CG steps on `W_AA x = r` from `x = 0`;
    /// returns the steps taken.
    fn conjugate_gradient(
        &mut self,
        problem: &ContactProblem,
        mut rz: Real,
        iterations: u32,
    ) -> u32 {
        let rows = self.x.len();
        let mut steps = 0;
        for _ in 0..iterations {
            if rz <= 0.0 {
                break;
            }
            steps += 1;
            apply_jt(problem, &self.p, &mut self.dv);
            let (mut pq, mut pdp) = (0.0, 0.0);
            for k in 0..rows {
                let mass = row(problem, k).5;
                let w_kk = if mass > 0.0 { 1.0 / mass } else { 0.0 };
                self.q[k] = if self.active[k] {
                    row_velocity(problem, k, &self.dv)
                        + self.config.regularization * w_kk * self.p[k]
                } else {
                    0.0
                };
                pq += self.p[k] * self.q[k];
                pdp += w_kk * self.p[k] * self.p[k];
            }
            // A direction in W's null space (Rayleigh quotient against the diagonal at
            // round-off level): the rest of the residual has no solution there (a
            // restitution bias that no velocity of the island produces), and a step along it
            // would be unbounded.
            if pq <= NULL_SPACE * pdp {
                break;
            }
            let alpha = rz / pq;
            let mut rz_new = 0.0;
            for k in (0..rows).filter(|&k| self.active[k]) {
                self.x[k] += alpha * self.p[k];
                self.r[k] -= alpha * self.q[k];
                self.z[k] = row(problem, k).5 * self.r[k];
                rz_new += self.r[k] * self.z[k];
            }
            let beta = rz_new / rz;
            rz = rz_new;
            for k in (0..rows).filter(|&k| self.active[k]) {
                self.p[k] = self.z[k] + beta * self.p[k];
            }
        }
        steps
    }
}

impl WarmStart for KrylovWarmStart {
    fn name(&self) -> &str {
        "krylov"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        CarriedWarmStart.warm_start(ctx, out)?;
        self.last_passes = 0;
        if out.is_empty() {
            return Ok(());
        }
        // The residual is one pass over the rows, a CG step two (W applied matrix-free); under
        // a pass budget a round runs only if at least one step fits, with as many as fit.
        let mut left = ctx.pass_budget.unwrap_or(u32::MAX);
        for _ in 0..self.config.rounds {
            let iterations = self.config.iterations.min(left.saturating_sub(1) / 2);
            if iterations == 0 {
                break;
            }
            self.select_active(ctx.problem, out);
            let rz = self.residual(ctx.problem, out);
            let spent = 1 + 2 * self.conjugate_gradient(ctx.problem, rz, iterations);
            self.last_passes += spent;
            left -= spent;
            for (i, (o, p)) in out.iter_mut().zip(&ctx.problem.points).enumerate() {
                *o = in_cone(
                    o.normal + self.x[2 * i],
                    o.tangent + self.x[2 * i + 1],
                    p.friction,
                );
            }
        }
        Ok(())
    }

    /// One pass per round for its residual and two per conjugate-gradient step (each an
    /// application of W over the rows), on the last island; never more than the context's
    /// [`WarmStartContext::pass_budget`] (the steps and rounds that do not fit are not run).
    fn passes_spent(&self) -> u32 {
        self.last_passes
    }
}
