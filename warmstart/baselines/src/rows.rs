//! The contact rows as a matrix-free operator: `M⁻¹ Jᵀ` and `J`, shared by the providers
//! that look at the velocity equations (`krylov`, `best`, `shock`).
//!
//! Row `2i` is point i's normal, row `2i + 1` its friction along `t = (−n.y, n.x)`; an
//! impulse `y` on a row pushes body B along the row's direction and body A against it.

use deepcontact_core::math::{cross, cross_sv};
use deepcontact_core::{ContactProblem, Impulse, Real, Vector, Velocity};

/// `(normal, tangent)` projected onto the friction cone of coefficient `friction`:
/// `λn ≥ 0`, `|λt| ≤ μ λn`.
pub(crate) fn in_cone(normal: Real, tangent: Real, friction: Real) -> Impulse {
    let normal = normal.max(0.0);
    let bound = friction * normal;
    Impulse::new(normal, tangent.clamp(-bound, bound))
}

/// Row `k`'s direction, bodies A and B, anchors and effective mass.
pub(crate) fn row(
    problem: &ContactProblem,
    k: usize,
) -> (Vector, usize, usize, Vector, Vector, Real) {
    let p = &problem.points[k / 2];
    let (dir, mass) = if k % 2 == 0 {
        (p.normal, p.normal_mass)
    } else {
        (p.tangent(), p.tangent_mass)
    };
    (
        dir,
        p.body_a as usize,
        p.body_b as usize,
        p.r_a,
        p.r_b,
        mass,
    )
}

/// `dv = M⁻¹ Jᵀ y` over the rows (rows with y = 0 are skipped).
pub(crate) fn apply_jt(problem: &ContactProblem, y: &[Real], dv: &mut [Velocity]) {
    dv.fill(Velocity::default());
    for (k, &yk) in y.iter().enumerate() {
        if yk == 0.0 {
            continue;
        }
        let (d, a, b, ra, rb, _) = row(problem, k);
        let imp = d * yk;
        let (ba, bb) = (&problem.bodies[a], &problem.bodies[b]);
        dv[a].linear -= imp * ba.inv_mass;
        dv[a].angular -= ba.inv_inertia * cross(&ra, &imp);
        dv[b].linear += imp * bb.inv_mass;
        dv[b].angular += bb.inv_inertia * cross(&rb, &imp);
    }
}

/// Row `k`'s relative velocity `J_k v`.
pub(crate) fn row_velocity(problem: &ContactProblem, k: usize, v: &[Velocity]) -> Real {
    let (d, a, b, ra, rb, _) = row(problem, k);
    let va = v[a].linear + cross_sv(v[a].angular, &ra);
    let vb = v[b].linear + cross_sv(v[b].angular, &rb);
    (vb - va).dot(&d)
}

/// The body velocities after `start`: free velocities + `M⁻¹ Jᵀ λ` (`flat` is scratch).
pub(crate) fn velocities_after(
    problem: &ContactProblem,
    start: &[Impulse],
    flat: &mut Vec<Real>,
    v: &mut Vec<Velocity>,
) {
    flat.clear();
    flat.extend(start.iter().flat_map(|i| [i.normal, i.tangent]));
    v.clear();
    v.resize(problem.bodies.len(), Velocity::default());
    apply_jt(problem, flat, v);
    for (v, b) in v.iter_mut().zip(&problem.bodies) {
        v.linear += b.linear_velocity;
        v.angular += b.angular_velocity;
    }
}

/// Squared 2-norm of the natural-map residual of `start` (the change one Jacobi sweep from it
/// would make), given the velocities `v` after it.
pub(crate) fn natural_residual_sq(
    problem: &ContactProblem,
    start: &[Impulse],
    v: &[Velocity],
) -> Real {
    let mut sum = 0.0;
    for (i, (p, s)) in problem.points.iter().zip(start).enumerate() {
        let vn = row_velocity(problem, 2 * i, v);
        let n = (s.normal - p.normal_mass * (vn - p.velocity_bias)).max(0.0);
        let vt = row_velocity(problem, 2 * i + 1, v);
        let bound = p.friction * s.normal;
        let t = (s.tangent - p.tangent_mass * vt).clamp(-bound, bound);
        sum += (n - s.normal).powi(2) + (t - s.tangent).powi(2);
    }
    sum
}
