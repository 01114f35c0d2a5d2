//! The position pass: Box2D v2.4's non-linear Gauss-Seidel on the contact separations.

use deepcontact_core::math::{Pose, Real, Vector, cross, rotate};
use deepcontact_core::{
    ContactProblem, CoreError, PositionReport, PositionSettings, PositionSolver,
};

/// Non-linear Gauss-Seidel position correction (`b2ContactSolver::SolvePositionConstraints`).
///
/// The separation of a point at the current poses is estimated from its separation when
/// the contacts were computed plus the relative displacement of its two anchors along the
/// (fixed) normal, the anchors rotating with their bodies (as Box2D v3's relax step does).
#[derive(Debug, Clone, Default)]
pub struct PgsPositionSolver {
    anchors: Vec<(Vector, Vector)>,
}

impl PgsPositionSolver {
    /// A new position solver.
    pub fn new() -> Self {
        Self::default()
    }
}

impl PositionSolver for PgsPositionSolver {
    fn name(&self) -> &str {
        "ngs"
    }

    fn solve_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
    ) -> Result<PositionReport, CoreError> {
        settings.validate()?;
        if poses.len() != problem.bodies.len() {
            return Err(CoreError::LengthMismatch {
                what: "poses",
                expected: problem.bodies.len(),
                got: poses.len(),
            });
        }
        let mut report = PositionReport::default();
        if problem.points.is_empty() {
            return Ok(report);
        }
        // Anchors relative to the centres at the time the contacts were computed.
        self.anchors.clear();
        self.anchors
            .extend(problem.points.iter().map(|p| (p.r_a, p.r_b)));
        let limit = -settings.penetration_factor * settings.linear_slop;
        for it in 0..settings.max_iterations {
            let mut min_sep = Real::INFINITY;
            let mut max_corr: Real = 0.0;
            let mut max_imp: Real = 0.0;
            for (p, &(ra0, rb0)) in problem.points.iter().zip(&self.anchors) {
                let (ia, ib) = (p.body_a as usize, p.body_b as usize);
                let (a0, b0) = (&problem.bodies[ia], &problem.bodies[ib]);
                let (
                    Pose {
                        position: ca,
                        angle: ta,
                    },
                    Pose {
                        position: cb,
                        angle: tb,
                    },
                ) = (poses[ia], poses[ib]);
                let ra = rotate(&ra0, ta - a0.angle);
                let rb = rotate(&rb0, tb - b0.angle);
                // s = s0 + n · [(cB + rB) − (cA + rA) − ((cB0 + rB0) − (cA0 + rA0))]
                let d = (cb + rb - ca - ra) - (b0.position + rb0 - a0.position - ra0);
                let sep = p.separation + p.normal.dot(&d);
                min_sep = min_sep.min(sep);
                // Prevent large corrections and allow slop.
                let c = (settings.baumgarte * (sep + settings.linear_slop))
                    .clamp(-settings.max_linear_correction, 0.0);
                let (rna, rnb) = (cross(&ra, &p.normal), cross(&rb, &p.normal));
                let k = a0.inv_mass
                    + b0.inv_mass
                    + a0.inv_inertia * rna * rna
                    + b0.inv_inertia * rnb * rnb;
                let impulse = if k > 0.0 { -c / k } else { 0.0 };
                max_corr = max_corr.max(c.abs());
                max_imp = max_imp.max(impulse.abs());
                let pv = impulse * p.normal;
                poses[ia].position -= a0.inv_mass * pv;
                poses[ia].angle -= a0.inv_inertia * cross(&ra, &pv);
                poses[ib].position += b0.inv_mass * pv;
                poses[ib].angle += b0.inv_inertia * cross(&rb, &pv);
            }
            report.iterations = it + 1;
            report.min_separation = min_sep;
            report.max_correction = max_corr;
            let small = if settings.stop_on_impulse {
                max_imp <= settings.tolerance
            } else {
                max_corr < settings.tolerance
            };
            if small && min_sep >= limit {
                break;
            }
        }
        if poses
            .iter()
            .any(|p| !(p.position.x.is_finite() && p.position.y.is_finite() && p.angle.is_finite()))
        {
            return Err(CoreError::Solver {
                solver: "ngs".into(),
                reason: "position pass produced a non-finite pose".into(),
            });
        }
        Ok(report)
    }
}
