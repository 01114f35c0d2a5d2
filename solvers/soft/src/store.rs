//! **Store**: the step's impulses, velocities and displacements written out (Box2D v3's
//! `b2StoreImpulses`), and the natural-map residual of the result.

use deepcontact_core::math::{Pose, Real, Vector, Velocity};
use deepcontact_core::{ContactProblem, Impulse};

use crate::prepare::Island;

/// Writes the step's impulses (the substeps' accumulated impulses summed: N·s over the step,
/// the world's units), the final velocities and the displacements over the step.
pub(crate) fn store(
    island: &Island,
    impulses: &mut [Impulse],
    velocities: &mut [Velocity],
    displacements: &mut [Pose],
) {
    for (out, p) in impulses.iter_mut().zip(&island.points) {
        *out = Impulse::new(p.total_normal, p.total_tangent);
    }
    for ((v, d), b) in velocities
        .iter_mut()
        .zip(displacements.iter_mut())
        .zip(&island.bodies)
    {
        *v = Velocity::new(b.v, b.w);
        *d = Pose::new(b.dp, b.dq);
    }
}

/// The natural-map residual of the step's impulses at the final velocities, against the
/// rigid problem (its effective masses and restitution targets), as `pgs` measures it:
/// `max |λ − proj(λ − m (v − bias))|` over the rows, N·s.
pub(crate) fn natural_residual(
    problem: &ContactProblem,
    impulses: &[Impulse],
    velocities: &[Velocity],
) -> Real {
    let mut res: Real = 0.0;
    for (i, (p, imp)) in problem.points.iter().zip(impulses).enumerate() {
        let dv: Vector = problem
            .relative_velocity_with(i, velocities)
            .unwrap_or_default();
        let vn = dv.dot(&p.normal);
        let vt = dv.dot(&p.tangent());
        let rn = imp.normal - (imp.normal - p.normal_mass * (vn - p.velocity_bias)).max(0.0);
        let bound = p.friction * imp.normal;
        let rt = imp.tangent - (imp.tangent - p.tangent_mass * vt).max(-bound).min(bound);
        res = res.max(rn.abs()).max(rt.abs());
    }
    res
}
