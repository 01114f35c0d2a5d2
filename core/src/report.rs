//! Reports of one solve and one step.

use crate::math::Real;

/// What a velocity solve did.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SolveReport {
    /// Iterations run.
    pub iterations: u32,
    /// Per iteration, `max |Δλ|` over all rows after clamping.
    pub residual_inf: Vec<Real>,
    /// Per iteration, `sqrt(Σ Δλ²)` over all rows after clamping.
    pub residual_l2: Vec<Real>,
    /// Natural-map residual of the final impulses: `max |λ − proj(λ − m_eff (v − bias))|`
    /// over all rows (the change one more Jacobi sweep would make), in N·s.
    pub natural_residual: Real,
    /// Whether the stop rule was met (false = the cap was hit).
    pub converged: bool,
    /// Wall time of the solve in seconds.
    pub seconds: Real,
}

impl SolveReport {
    /// Resets the report for a new solve, keeping allocations.
    pub fn clear(&mut self) {
        self.iterations = 0;
        self.residual_inf.clear();
        self.residual_l2.clear();
        self.natural_residual = 0.0;
        self.converged = false;
        self.seconds = 0.0;
    }

    /// Last ∞-norm residual (0 if no iteration ran).
    pub fn final_residual(&self) -> Real {
        self.residual_inf.last().copied().unwrap_or(0.0)
    }
}

/// What one world step did. Serialisable to JSON for scripts.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct StepReport {
    /// Index of the step (0 = the first step of the world).
    pub step: u64,
    /// Contact points solved.
    pub contacts: usize,
    /// Islands with contacts.
    pub islands: usize,
    /// Velocity iterations of the slowest island.
    pub velocity_iterations: u32,
    /// Velocity iterations summed over islands.
    pub velocity_iterations_sum: u64,
    /// Islands that hit the iteration cap.
    pub capped_islands: usize,
    /// Per iteration, the ∞-norm residual: max over the islands still iterating.
    pub residual_curve: Vec<Real>,
    /// Same with the 2-norm (root of the sum of squares over those islands).
    pub residual_curve_l2: Vec<Real>,
    /// Largest natural-map residual over islands after the solve.
    pub natural_residual: Real,
    /// Mean squared difference between warm start and final impulse, normal rows.
    pub mse_normal: Real,
    /// Same, tangent rows.
    pub mse_tangent: Real,
    /// Islands whose warm start was rejected and replaced by zeros.
    pub fallbacks: usize,
    /// Position iterations of the slowest island.
    pub position_iterations: u32,
    /// Smallest separation after the position pass (0 without contacts).
    pub min_separation: Real,
    /// Seconds spent in the warm-start provider (its `warm_start` and its `observe`).
    pub warm_start_seconds: Real,
    /// Seconds spent in the velocity solver.
    pub solve_seconds: Real,
    /// Seconds of the collide stage ([`Stage::Collide`](crate::Stage::Collide): broad phase,
    /// narrow phase, the previous step's impulses matched), wall time.
    pub collide_seconds: Real,
    /// Seconds building the islands and their problems
    /// ([`Stage::Islands`](crate::Stage::Islands)), wall time.
    pub islands_seconds: Real,
    /// Seconds of the position pass over every island
    /// ([`Stage::PositionPass`](crate::Stage::PositionPass)), wall time.
    pub position_seconds: Real,
    /// Seconds of the whole step.
    pub step_seconds: Real,
    /// Passes over their islands' contact rows that the warm-start provider spent, summed
    /// over islands (0 for providers that do not sweep; see
    /// [`WarmStart::passes_spent`](crate::WarmStart::passes_spent)).
    pub provider_passes: u64,
    /// Mean penetration depth over the contact points, `max(0, −separation)` as the narrow
    /// phase found it at the start of the step (m; 0 without contacts).
    pub penetration_mean: Real,
    /// Deepest penetration over the contact points, as [`Self::penetration_mean`] (m).
    pub penetration_max: Real,
    /// Mean normal velocity error over the contact points after the velocity solve (m/s):
    /// with `vn` the normal relative velocity and `b` the point's velocity bias,
    /// `|vn − b|` where the normal impulse is positive (a pushing contact should hold
    /// `vn = b`) and `max(0, b − vn)` where it is zero (no approach left).
    pub normal_velocity_error_mean: Real,
    /// Largest normal velocity error over the contact points (m/s), as
    /// [`Self::normal_velocity_error_mean`].
    pub normal_velocity_error_max: Real,
    /// Kinetic energy of the dynamic bodies at the end of the step (J).
    pub kinetic_energy: Real,
}

impl StepReport {
    /// Seconds of the step outside warm start and velocity solve.
    pub fn rest_seconds(&self) -> Real {
        (self.step_seconds - self.warm_start_seconds - self.solve_seconds).max(0.0)
    }

    /// Adds one island's solve: iterations, cap, residual curves (∞-norm as the max over
    /// islands, 2-norm as a running sum of squares until [`Self::finish_islands`]) and the
    /// squared start error of each row (summed until [`Self::finish_islands`]).
    pub fn add_island(
        &mut self,
        r: &SolveReport,
        start: &[crate::Impulse],
        solved: &[crate::Impulse],
    ) {
        self.contacts += solved.len();
        self.velocity_iterations = self.velocity_iterations.max(r.iterations);
        self.velocity_iterations_sum += u64::from(r.iterations);
        self.capped_islands += usize::from(!r.converged);
        self.natural_residual = self.natural_residual.max(r.natural_residual);
        for (i, (&ri, &r2)) in r.residual_inf.iter().zip(&r.residual_l2).enumerate() {
            if i < self.residual_curve.len() {
                self.residual_curve[i] = self.residual_curve[i].max(ri);
                self.residual_curve_l2[i] += r2 * r2;
            } else {
                self.residual_curve.push(ri);
                self.residual_curve_l2.push(r2 * r2);
            }
        }
        for (w, f) in start.iter().zip(solved) {
            self.mse_normal += (w.normal - f.normal).powi(2);
            self.mse_tangent += (w.tangent - f.tangent).powi(2);
        }
    }

    /// Adds one island's contact measures after its solve: penetration depths (from the
    /// points' separations) and normal velocity errors (from the solved body `velocities`,
    /// one per body of `problem`, and the `solved` impulses, one per point), summed until
    /// [`Self::finish_islands`].
    pub fn add_contact_errors(
        &mut self,
        problem: &crate::ContactProblem,
        velocities: &[crate::Velocity],
        solved: &[crate::Impulse],
    ) {
        for (i, (p, imp)) in problem.points.iter().zip(solved).enumerate() {
            let depth = (-p.separation).max(0.0);
            self.penetration_mean += depth;
            self.penetration_max = self.penetration_max.max(depth);
            let Some(dv) = problem.relative_velocity_with(i, velocities) else {
                continue;
            };
            let vn = dv.dot(&p.normal);
            let error = if imp.normal > 0.0 {
                (vn - p.velocity_bias).abs()
            } else {
                (p.velocity_bias - vn).max(0.0)
            };
            self.normal_velocity_error_mean += error;
            self.normal_velocity_error_max = self.normal_velocity_error_max.max(error);
        }
    }

    /// Turns the sums of [`Self::add_island`] and [`Self::add_contact_errors`] into the
    /// 2-norm curve, the mean squared errors and the means over points.
    pub fn finish_islands(&mut self) {
        for v in &mut self.residual_curve_l2 {
            *v = v.sqrt();
        }
        if self.contacts > 0 {
            let n = self.contacts as Real;
            self.mse_normal /= n;
            self.mse_tangent /= n;
            self.penetration_mean /= n;
            self.normal_velocity_error_mean /= n;
        }
    }

    /// Residual at the end of the step's velocity solve (last value of the curve).
    pub fn final_residual(&self) -> Real {
        self.residual_curve.last().copied().unwrap_or(0.0)
    }
}

#[cfg(test)]
mod contact_error_tests {
    use super::*;
    use crate::problem::{ContactProblem, PointDesc, ProblemBody};
    use crate::{Impulse, Vector, Velocity};

    #[test]
    fn contact_errors_measure_penetration_and_the_normal_velocity_left() {
        // A ball 2 mm into the ground: one point, normal +y from the ground (A) to the ball (B).
        let mut p = ContactProblem::new();
        let ground = p.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
        let ball = p.add_body(ProblemBody::dynamic(
            Vector::new(0.0, 0.498),
            0.0,
            Vector::zeros(),
            0.0,
            1.0,
            1.0,
        ));
        p.begin_manifold();
        let desc = PointDesc::new(ground, ball, Vector::zeros(), Vector::new(0.0, 1.0));
        p.add_point(&desc.separation(-0.002)).unwrap();
        let still = [Velocity::default(); 2];
        let falling = [
            Velocity::default(),
            Velocity::new(Vector::new(0.0, -0.3), 0.0),
        ];
        let cases = [
            // Pushing and at rest: no error. Pushing and approaching: the approach.
            (Impulse::new(1.0, 0.0), still, 0.0),
            (Impulse::new(1.0, 0.0), falling, 0.3),
            // Idle and approaching: the approach; idle and separating: none.
            (Impulse::ZERO, falling, 0.3),
            (
                Impulse::ZERO,
                [
                    Velocity::default(),
                    Velocity::new(Vector::new(0.0, 0.3), 0.0),
                ],
                0.0,
            ),
        ];
        for (impulse, velocities, error) in cases {
            let mut r = StepReport::default();
            r.add_island(&SolveReport::default(), &[impulse], &[impulse]);
            r.add_contact_errors(&p, &velocities, &[impulse]);
            r.finish_islands();
            assert!(
                (r.normal_velocity_error_max - error).abs() < 1e-12,
                "{impulse:?}"
            );
            assert!((r.normal_velocity_error_mean - error).abs() < 1e-12);
            assert!((r.penetration_max - 0.002).abs() < 1e-12);
            assert!((r.penetration_mean - 0.002).abs() < 1e-12);
        }
    }
}
