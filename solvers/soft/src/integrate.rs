//! **Integrate velocities** and **integrate positions** of a substep (Box2D v3's
//! `b2IntegrateVelocitiesTask`, `b2IntegratePositionsTask`), symplectic Euler: gravity into
//! the velocities first, the new velocities into the displacements after the solve pass.

use deepcontact_core::math::{Real, Vector};

use crate::prepare::BodyState;

/// `v += h g` for every body gravity acts on (a positive inverse mass). No damping, as the
/// world's own IntegrateVelocities stage.
pub(crate) fn integrate_velocities(bodies: &mut [BodyState], h: Real, gravity: Vector) {
    let dv = h * gravity;
    for b in bodies.iter_mut().filter(|b| b.gravity) {
        b.v += dv;
    }
}

/// `Δp += h v`, `Δθ += h ω` for every body (immovable ones keep their velocity, zero for a
/// static body), and the sine and cosine of `Δθ` for the next separations.
pub(crate) fn integrate_positions(bodies: &mut [BodyState], h: Real) {
    for b in bodies.iter_mut() {
        b.dp += h * b.v;
        b.dq += h * b.w;
        (b.dq_sin, b.dq_cos) = b.dq.sin_cos();
    }
}
