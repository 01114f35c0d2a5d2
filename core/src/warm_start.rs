//! The [`WarmStart`] plug-in point: the first iterate of the velocity solver.

use crate::contact::Impulse;
use crate::math::{Real, Vector};
use crate::problem::ContactProblem;
use crate::report::SolveReport;

/// What a provider learns after the solve of an island ([`WarmStart::observe`]).
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub struct Observation<'a> {
    /// The start the solver actually used: the provider's output (or zeros after a fallback)
    /// as the solver applied it, projected onto each point's friction cone
    /// ([`project_start`]; the tangent only where the solver projects it, see
    /// [`crate::VelocitySolver::projects_start`]).
    pub start: &'a [Impulse],
    /// The impulses the solver ended with, one per point (N·s).
    pub solved: &'a [Impulse],
    /// Whether the provider's output was rejected and replaced by zeros.
    pub fell_back: bool,
    /// The solve's report (iterations, residuals per iteration, natural residual).
    pub report: &'a SolveReport,
}

impl<'a> Observation<'a> {
    /// An observation of a solve that started from `start` and ended at `solved`.
    pub fn new(
        start: &'a [Impulse],
        solved: &'a [Impulse],
        fell_back: bool,
        report: &'a SolveReport,
    ) -> Self {
        Self {
            start,
            solved,
            fell_back,
            report,
        }
    }
}

/// What a provider sees when asked for a warm start. Borrowed, so new data can be
/// added as new fields without changing the trait's signature.
#[derive(Debug, Clone, Copy)]
#[non_exhaustive]
pub struct WarmStartContext<'a> {
    /// The island's contact problem (bodies, points, manifolds).
    pub problem: &'a ContactProblem,
    /// Per point of `problem`, the impulse carried over from the previous step by
    /// [`ContactId`](crate::ContactId) (N·s), or `None` where the point is new.
    pub carried: &'a [Option<Impulse>],
    /// Index of the step being solved (the first step of a world is 0).
    pub step: u64,
    /// Index of the island within the step (islands are ordered by their smallest body).
    pub island: usize,
    /// Number of islands in this step.
    pub island_count: usize,
    /// Time step in seconds.
    pub dt: Real,
    /// Gravity in m/s² (the world's; `(0, -9.81)` for a context made with [`Self::new`]
    /// until [`Self::with_gravity`]).
    pub gravity: Vector,
    /// The world being stepped, if the problem comes from one (`None` for hand-built problems).
    pub world: Option<&'a crate::World>,
    /// Under a fixed budget ([`WorldSettings::budget`](crate::WorldSettings::budget)), the
    /// most passes over this island's contact rows the provider may spend, in
    /// [`WarmStart::warm_start`] and [`WarmStart::observe`] together (both get the same
    /// value); the solver gets the rest. `None` (the default): no budget, the provider spends
    /// what it likes.
    pub pass_budget: Option<u32>,
}

impl<'a> WarmStartContext<'a> {
    /// A context for a problem without a world (hand-built problems, tests, foreign engines).
    pub fn new(
        problem: &'a ContactProblem,
        carried: &'a [Option<Impulse>],
        step: u64,
        dt: Real,
    ) -> Self {
        Self {
            problem,
            carried,
            step,
            island: 0,
            island_count: 1,
            dt,
            gravity: Vector::new(0.0, -9.81),
            world: None,
            pass_budget: None,
        }
    }

    /// Sets the most passes the provider may spend ([`Self::pass_budget`]).
    pub fn with_pass_budget(mut self, passes: u32) -> Self {
        self.pass_budget = Some(passes);
        self
    }

    /// `own` passes capped by [`Self::pass_budget`]: what a provider that sweeps `own` times
    /// by its own settings may run here.
    pub fn passes_allowed(&self, own: u32) -> u32 {
        self.pass_budget.map_or(own, |b| own.min(b))
    }

    /// The impulse carried to point `i`, zero where the point is new (or out of range).
    pub fn carried_or_zero(&self, i: usize) -> Impulse {
        self.carried
            .get(i)
            .copied()
            .flatten()
            .unwrap_or(Impulse::ZERO)
    }

    /// The carried impulses, zero where a point is new: what Box2D warm-starts from.
    pub fn carried_impulses(&self) -> impl Iterator<Item = Impulse> + '_ {
        self.carried.iter().map(|c| c.unwrap_or(Impulse::ZERO))
    }

    /// Sets the gravity (m/s²).
    pub fn with_gravity(mut self, gravity: Vector) -> Self {
        self.gravity = gravity;
        self
    }

    /// Attaches the world and island position (used by [`World::step`](crate::World::step)).
    pub fn with_world(
        mut self,
        world: &'a crate::World,
        island: usize,
        island_count: usize,
    ) -> Self {
        self.world = Some(world);
        self.island = island;
        self.island_count = island_count;
        self
    }
}

/// Why a warm start could not be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WarmStartError {
    /// The provider wrote a NaN or infinite value.
    #[error("non-finite impulse ({normal}, {tangent}) at point {point}")]
    NonFinite {
        /// Point index.
        point: usize,
        /// Normal value written.
        normal: Real,
        /// Tangent value written.
        tangent: Real,
    },
    /// The provider wrote a negative normal impulse.
    #[error("negative normal impulse {normal} at point {point}")]
    NegativeNormal {
        /// Point index.
        point: usize,
        /// Normal value written.
        normal: Real,
    },
    /// The context carries a different number of impulses than the problem has points (a
    /// [`WarmStartContext::new`] given the wrong `carried` slice): the caller's mistake, not
    /// the provider's.
    #[error(
        "the context carries {carried} impulses for {points} contact points (WarmStartContext::new needs one per point)"
    )]
    CarriedLength {
        /// Points of the problem.
        points: usize,
        /// Carried impulses in the context.
        carried: usize,
    },
    /// The provider produced the wrong number of impulses.
    #[error("provider produced {got} impulses for {expected} contact points")]
    WrongLength {
        /// Number of points.
        expected: usize,
        /// Number produced.
        got: usize,
    },
    /// The provider itself failed (model error, solver error, ...).
    #[error("provider failure: {0}")]
    Provider(String),
}

/// Projects a start onto the friction cones of `points` (one per impulse) as the solvers apply
/// it: a negative normal impulse is raised to 0, and with `tangent` the tangent impulse is
/// clamped to `|λt| ≤ μ λn` (μ the point's friction). The world measures a start's error
/// ([`crate::StepReport::mse_normal`]) and hands [`Observation::start`] to the provider after
/// this projection, so two starts the solver treats alike are measured alike.
pub fn project_start(points: &[crate::ContactPoint], start: &mut [Impulse], tangent: bool) {
    for (p, s) in points.iter().zip(start.iter_mut()) {
        if s.normal < 0.0 {
            s.normal = 0.0;
        }
        if tangent {
            let bound = p.friction * s.normal;
            if s.tangent > bound {
                s.tangent = bound;
            } else if s.tangent < -bound {
                s.tangent = -bound;
            }
        }
    }
}

/// Checks a provider's output: finite everywhere, normal ≥ 0.
pub fn check_output(out: &[Impulse], expected: usize) -> Result<(), WarmStartError> {
    if out.len() != expected {
        return Err(WarmStartError::WrongLength {
            expected,
            got: out.len(),
        });
    }
    for (point, imp) in out.iter().enumerate() {
        if !imp.is_finite() {
            return Err(WarmStartError::NonFinite {
                point,
                normal: imp.normal,
                tangent: imp.tangent,
            });
        }
        if imp.normal < 0.0 {
            return Err(WarmStartError::NegativeNormal {
                point,
                normal: imp.normal,
            });
        }
    }
    Ok(())
}

/// What the world does when a provider fails or writes garbage.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum GuardPolicy {
    /// Start that island from zeros and count it in [`StepReport::fallbacks`](crate::StepReport::fallbacks) (default).
    #[default]
    FallbackToZero,
    /// Abort the step with [`CoreError::WarmStart`](crate::CoreError::WarmStart).
    Error,
}

/// Supplies the initial impulses of the velocity solver.
///
/// Object safe: use it as `Box<dyn WarmStart>` or generically. Implementors
/// write one [`Impulse`] per contact point of `ctx.problem` into `out` (which
/// arrives zeroed, so doing nothing is a cold start) and may learn from the
/// solved impulses in [`WarmStart::observe`].
///
/// Call order within a [`crate::World`] step: `warm_start` for every island in island order
/// (`ctx.island` = 0, 1, …), then the solves (side by side with
/// [`crate::WorldSettings::island_threads`]), then `observe` for every island in island order;
/// always on the stepping thread, whatever the thread count. Keep per-island state by
/// `ctx.island`, not "the last call".
///
/// ```
/// use deepcontact_core::{Impulse, WarmStart, WarmStartContext, WarmStartError};
///
/// /// Last step's impulses, damped: a typical first experiment.
/// struct Scaled(f64);
///
/// impl WarmStart for Scaled {
///     fn name(&self) -> &str { "scaled" }
///     fn warm_start(&mut self, ctx: &WarmStartContext<'_>, out: &mut [Impulse]) -> Result<(), WarmStartError> {
///         for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) {
///             *o = Impulse::new(self.0 * c.normal, self.0 * c.tangent);
///         }
///         Ok(())
///     }
/// }
///
/// let mut provider: Box<dyn WarmStart> = Box::new(Scaled(0.9));
/// let problem = deepcontact_core::ContactProblem::new();
/// let ctx = WarmStartContext::new(&problem, &[], 0, 0.01);
/// provider.warm_start(&ctx, &mut []).unwrap();
/// assert_eq!(provider.name(), "scaled");
/// ```
pub trait WarmStart: Send {
    /// Short name used in reports and tables.
    fn name(&self) -> &str;

    /// Writes the initial impulses, one per point of `ctx.problem`, into `out` (zeroed on entry).
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError>;

    /// Sees the island after the solve: the start used, the solved impulses, whether a
    /// fallback replaced the output, the solve report. Default: nothing.
    fn observe(&mut self, _ctx: &WarmStartContext<'_>, _seen: &Observation<'_>) {}

    /// A new world begins (a [`crate::World`] calls it before its first step): forget what
    /// does not carry over from the previous world (per-contact history, step counters).
    /// Default: nothing.
    fn reset(&mut self) {}

    /// Named numbers describing the provider's learned or adapted state (e.g. an online
    /// scale factor), for reports. Default: none.
    fn diagnostics(&self) -> Vec<(String, Real)> {
        Vec::new()
    }

    /// Passes over the island's contact rows (sweeps of a solver, each costing about one
    /// solver iteration) that the last [`Self::warm_start`] call spent. Under a fixed budget
    /// ([`WarmStartContext::pass_budget`]) the world gives the solver what is left, so a
    /// provider that sweeps must say so here. Default: 0 (the provider does not sweep).
    fn passes_spent(&self) -> u32 {
        0
    }
}

impl<W: WarmStart + ?Sized> WarmStart for Box<W> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        (**self).warm_start(ctx, out)
    }
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        (**self).observe(ctx, seen)
    }
    fn reset(&mut self) {
        (**self).reset()
    }
    fn diagnostics(&self) -> Vec<(String, Real)> {
        (**self).diagnostics()
    }
    fn passes_spent(&self) -> u32 {
        (**self).passes_spent()
    }
}

/// The no-op provider: every solve starts from zero ("none" in the thesis).
#[derive(Debug, Clone, Copy, Default)]
pub struct ZeroWarmStart;

impl WarmStart for ZeroWarmStart {
    fn name(&self) -> &str {
        "none"
    }
    fn warm_start(
        &mut self,
        _ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        out.fill(Impulse::ZERO);
        Ok(())
    }
}

/// Box2D's own warm start: the impulses carried from the previous step ("builtin").
#[derive(Debug, Clone, Copy, Default)]
pub struct CarriedWarmStart;

impl WarmStart for CarriedWarmStart {
    fn name(&self) -> &str {
        "builtin"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        if ctx.carried.len() != ctx.problem.len() {
            return Err(WarmStartError::CarriedLength {
                points: ctx.problem.len(),
                carried: ctx.carried.len(),
            });
        }
        if out.len() != ctx.problem.len() {
            return Err(WarmStartError::WrongLength {
                expected: ctx.problem.len(),
                got: out.len(),
            });
        }
        for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) {
            *o = c;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::problem::{PointDesc, ProblemBody};

    /// A ball resting on the ground: one point.
    fn one_point() -> ContactProblem {
        let mut p = ContactProblem::new();
        let ground = p.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
        let ball = p.add_body(ProblemBody::dynamic(
            Vector::new(0.0, 0.5),
            0.0,
            Vector::zeros(),
            0.0,
            1.0,
            1.0,
        ));
        p.begin_manifold();
        p.add_point(&PointDesc::new(
            ground,
            ball,
            Vector::new(0.0, 0.0),
            Vector::new(0.0, 1.0),
        ))
        .unwrap();
        p
    }

    #[test]
    fn a_context_carrying_the_wrong_count_blames_the_context_not_the_provider() {
        let problem = one_point();
        let mut out = [Impulse::ZERO];
        let ctx = WarmStartContext::new(&problem, &[], 0, 0.01);
        let err = CarriedWarmStart.warm_start(&ctx, &mut out).unwrap_err();
        assert_eq!(
            err,
            WarmStartError::CarriedLength {
                points: 1,
                carried: 0
            }
        );
        assert!(err.to_string().contains("WarmStartContext::new"), "{err}");
        // The right count, a wrong output buffer: the output's length is named.
        let carried = [Some(Impulse::new(2.0, 0.5))];
        let ctx = WarmStartContext::new(&problem, &carried, 0, 0.01);
        let err = CarriedWarmStart.warm_start(&ctx, &mut []).unwrap_err();
        assert_eq!(
            err,
            WarmStartError::WrongLength {
                expected: 1,
                got: 0
            }
        );
        CarriedWarmStart.warm_start(&ctx, &mut out).unwrap();
        assert_eq!(out, [Impulse::new(2.0, 0.5)]);
    }
}
