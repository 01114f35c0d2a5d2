//! **Solve** and **relax**: one pass over the island's contact rows (Box2D
//! v3's `b2SolveContact`, `useBias = true` for the solve pass, `false` for a relax pass).
//!
//! Per manifold, as Box2D v3.1 does it (`src/contact_solver.c`): first the normal rows, then
//! the friction rows, each friction row bounded by `μ λn` of the normal impulse just solved.
//!
//! Normal row at the current separation `s` (m, negative = overlap; see
//! [`crate::prepare::Point::base_separation`]):
//! * `s > 0` (the points drifted apart within the step): speculative, `bias = s / h`, rigid
//!   mass, so the row only stops the bodies from closing the gap faster than one substep;
//! * `s ≤ 0` in a solve pass: soft, `bias = max(bias_rate · s, −push)` (push-out capped at
//!   `push` m/s), `λ = −m · mass_scale · (vn + bias) − impulse_scale · λ_acc`;
//! * `s ≤ 0` in a relax pass: rigid and without bias, `λ = −m vn` (removes the velocity the
//!   soft push-out added, so that it does not turn into bounce).
//!
//! Then `λ_acc ← max(λ_acc + λ, 0)`. Friction: `λt_acc ← clamp(λt_acc − mt vt, ±μ λn_acc)`.

use deepcontact_core::math::{Real, Vector};

use crate::prepare::{BodyState, Island, Point};

/// What one pass measures of its impulse changes (N·s per substep).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct PassMeasure {
    /// `max |Δλ|` over the rows.
    pub(crate) max: Real,
    /// `Σ Δλ²` over the rows.
    pub(crate) sum_sq: Real,
}

impl PassMeasure {
    #[inline(always)]
    fn add(&mut self, delta: Real) {
        self.max = self.max.max(delta.abs());
        self.sum_sq += delta * delta;
    }
}

/// The parameters of one pass.
#[derive(Debug, Clone, Copy)]
pub(crate) struct PassParams {
    /// `1 / h` (1/s).
    pub(crate) inv_h: Real,
    /// Largest push-out speed (m/s).
    pub(crate) push: Real,
    /// Solve pass (soft bias) or relax pass (none).
    pub(crate) use_bias: bool,
}

/// Velocity of B's anchor against A's (m/s).
#[inline(always)]
fn relative_velocity(a: &BodyState, b: &BodyState, p: &Point) -> Vector {
    let va = a.v + Vector::new(-a.w * p.r_a.y, a.w * p.r_a.x);
    let vb = b.v + Vector::new(-b.w * p.r_b.y, b.w * p.r_b.x);
    vb - va
}

/// Applies impulse `lambda` along `dir` (with the anchors' cross terms `ra`, `rb`) to A
/// (negatively) and B.
#[inline(always)]
pub(crate) fn apply(
    a: &mut BodyState,
    b: &mut BodyState,
    dir: Vector,
    ra: Real,
    rb: Real,
    lambda: Real,
) {
    a.v -= (a.inv_mass * lambda) * dir;
    a.w -= a.inv_inertia * ra * lambda;
    b.v += (b.inv_mass * lambda) * dir;
    b.w += b.inv_inertia * rb * lambda;
}

/// The current separation of `p` from its bodies' displacements (m).
#[inline(always)]
pub(crate) fn separation(a: &BodyState, b: &BodyState, p: &Point) -> Real {
    let ds = (b.dp - a.dp) + (b.turned(&p.r_b) - a.turned(&p.r_a));
    p.base_separation + ds.dot(&p.normal_dir)
}

/// One pass over every manifold in the problem's order (a sequential Gauss-Seidel sweep;
/// Box2D v3 sweeps graph colours, another order of the same rows).
pub(crate) fn pass(island: &mut Island, params: PassParams) -> PassMeasure {
    let Island {
        bodies,
        points,
        manifolds,
    } = island;
    let mut measure = PassMeasure::default();
    for m in manifolds.iter() {
        let (mut a, mut b) = (bodies[m.a as usize], bodies[m.b as usize]);
        let rows = &mut points[m.start as usize..m.end as usize];
        for p in rows.iter_mut() {
            let s = separation(&a, &b, p);
            let (bias, mass_scale, impulse_scale) = if s > 0.0 {
                (s * params.inv_h, 1.0, 0.0)
            } else if params.use_bias {
                let soft = &m.softness;
                (
                    (soft.bias_rate * s).max(-params.push),
                    soft.mass_scale,
                    soft.impulse_scale,
                )
            } else {
                (0.0, 1.0, 0.0)
            };
            let vn = relative_velocity(&a, &b, p).dot(&p.normal_dir);
            let lambda = -p.normal_mass * mass_scale * (vn + bias) - impulse_scale * p.normal;
            let new = (p.normal + lambda).max(0.0);
            let delta = new - p.normal;
            p.normal = new;
            measure.add(delta);
            apply(&mut a, &mut b, p.normal_dir, p.rn_a, p.rn_b, delta);
        }
        for p in rows.iter_mut() {
            let vt = relative_velocity(&a, &b, p).dot(&p.tangent_dir);
            let bound = p.friction * p.normal;
            let new = (p.tangent - p.tangent_mass * vt).max(-bound).min(bound);
            let delta = new - p.tangent;
            p.tangent = new;
            measure.add(delta);
            apply(&mut a, &mut b, p.tangent_dir, p.rt_a, p.rt_b, delta);
        }
        bodies[m.a as usize] = a;
        bodies[m.b as usize] = b;
    }
    measure
}
