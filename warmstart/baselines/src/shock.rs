//! The `shock` provider: normal loads propagated down the contact graph, blended with the
//! carried impulses.

use deepcontact_core::{
    Impulse, Real, SpecError, Vector, WarmStart, WarmStartContext, WarmStartError,
};

use crate::rows::in_cone;

/// A static load estimate in the spirit of shock propagation (Guendelman et al. 2003):
/// bodies are visited from the top down (along −gravity); each must lose its downward free
/// momentum `m max(0, −v_free·up)` plus the load the bodies above pass to it, and hands that
/// load to its supporting points (those whose impulse on it points up) in equal vertical
/// shares, `λn = load / Σ (n·up)` over them; the body below receives `λn (n·up)`.
/// The start is `(1 − blend) λ_carried + blend λ_estimate` on normal rows of carried points,
/// the estimate on new points, and the carried tangent (clamped to the new cone).
/// Buffers are kept between calls.
///
/// ```
/// use deepcontact_core::WarmStart;
/// use deepcontact_warmstart::ShockWarmStart;
///
/// let shock = ShockWarmStart::new(0.5).unwrap();
/// assert_eq!(shock.name(), "shock");
/// ```
#[derive(Debug, Clone)]
pub struct ShockWarmStart {
    blend: Real,
    order: Vec<usize>,
    load: Vec<Real>,
    /// Per body: Σ (n·up) over its supporting points.
    support: Vec<Real>,
    estimate: Vec<Real>,
    /// Per body, where its points start in `points_of`, then the end (`bodies + 1` entries).
    first: Vec<u32>,
    /// The points of each body, body by body, each body's in ascending order.
    points_of: Vec<u32>,
}

impl ShockWarmStart {
    /// A provider with weight `blend` of the estimate on carried points (in [0, 1]).
    pub fn new(blend: Real) -> Result<Self, SpecError> {
        if !(0.0..=1.0).contains(&blend) {
            return Err(SpecError::InvalidParameter {
                spec: "shock".into(),
                param: "blend".into(),
                value: blend.to_string(),
                reason: "must be in [0, 1]".into(),
            });
        }
        Ok(Self {
            blend,
            order: Vec::new(),
            load: Vec::new(),
            support: Vec::new(),
            estimate: Vec::new(),
            first: Vec::new(),
            points_of: Vec::new(),
        })
    }

    /// The weight of the estimate on carried points.
    pub fn blend(&self) -> Real {
        self.blend
    }

    /// The upward component of point `i`'s normal impulse on `body` (≤ 0: not a support).
    fn lift(ctx: &WarmStartContext<'_>, i: usize, body: usize, up: &Vector) -> Real {
        let p = &ctx.problem.points[i];
        let side = if p.body_b as usize == body { 1.0 } else { -1.0 };
        side * p.normal.dot(up)
    }

    /// Fills `estimate` with the propagated normal loads.
    fn propagate(&mut self, ctx: &WarmStartContext<'_>) {
        let problem = ctx.problem;
        let g = ctx.gravity.norm();
        self.estimate.clear();
        self.estimate.resize(problem.points.len(), 0.0);
        if g == 0.0 {
            return;
        }
        let up = -ctx.gravity / g;
        let nb = problem.bodies.len();
        self.load.clear();
        self.load.extend(problem.bodies.iter().map(|b| {
            if b.inv_mass > 0.0 {
                (-b.linear_velocity.dot(&up)).max(0.0) / b.inv_mass
            } else {
                0.0
            }
        }));
        self.support.clear();
        self.support.resize(nb, 0.0);
        for (i, p) in problem.points.iter().enumerate() {
            for body in [p.body_a as usize, p.body_b as usize] {
                let lift = Self::lift(ctx, i, body, &up);
                if lift > 0.0 {
                    self.support[body] += lift;
                }
            }
        }
        // Each body's points, ascending (a counting sort by body): the visit below reads a
        // body's own points instead of scanning every point for each body. `first[b]` counts
        // up to the end of body b's run, then the fill, from the last point down, moves it back
        // to the run's start.
        self.first.clear();
        self.first.resize(nb + 1, 0);
        for p in &problem.points {
            self.first[p.body_a as usize] += 1;
            self.first[p.body_b as usize] += 1;
        }
        for b in 1..=nb {
            self.first[b] += self.first[b - 1];
        }
        self.points_of.clear();
        self.points_of.resize(2 * problem.points.len(), 0);
        for (i, p) in problem.points.iter().enumerate().rev() {
            for body in [p.body_a as usize, p.body_b as usize] {
                self.first[body] -= 1;
                self.points_of[self.first[body] as usize] = i as u32;
            }
        }
        self.order.clear();
        self.order.extend(0..nb);
        let height = |b: usize| problem.bodies[b].position.dot(&up);
        self.order
            .sort_by(|&a, &b| height(b).total_cmp(&height(a)).then(a.cmp(&b)));
        // Visiting from the top, each body's load is complete when it is reached: every
        // point that loads it comes from a body above.
        for k in 0..nb {
            let body = self.order[k];
            if problem.bodies[body].inv_mass == 0.0 || self.support[body] <= 0.0 {
                continue;
            }
            let per_lift = self.load[body] / self.support[body];
            let own = self.first[body] as usize..self.first[body + 1] as usize;
            for &i in &self.points_of[own] {
                let (i, p) = (i as usize, &problem.points[i as usize]);
                let lift = Self::lift(ctx, i, body, &up);
                if lift <= 0.0 {
                    continue;
                }
                self.estimate[i] += per_lift;
                let other = if p.body_a as usize == body {
                    p.body_b
                } else {
                    p.body_a
                };
                self.load[other as usize] += per_lift * lift;
            }
        }
    }
}

impl WarmStart for ShockWarmStart {
    fn name(&self) -> &str {
        "shock"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.propagate(ctx);
        let points = ctx.problem.points.iter().zip(&self.estimate);
        for (i, (o, (p, &estimate))) in out.iter_mut().zip(points).enumerate() {
            *o = match ctx.carried.get(i).copied().flatten() {
                Some(c) => in_cone(
                    (1.0 - self.blend) * c.normal + self.blend * estimate,
                    c.tangent,
                    p.friction,
                ),
                None => Impulse::new(estimate, 0.0),
            };
        }
        Ok(())
    }
}
