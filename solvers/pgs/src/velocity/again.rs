//! One island solved again from another start, on the plan its last solve built.
//!
//! A provider that refines a start by sweeps it mixes or restarts (Anderson acceleration,
//! the shares of an over-relaxation schedule) solves one island many times from different
//! starts, or with its rows' effective masses scaled. Each [`VelocitySolver::solve`] builds
//! the island's plan afresh: its rows, manifolds and block factors, the colouring and the
//! batches, and checks the problem, a few passes' worth of work before the first sweep.
//! [`PgsSolver::solve_again`] keeps the plan and resets only what a sweep changes (the rows'
//! and batches' impulses, the velocities) and what an over-relaxed copy of the island changes
//! (the rows' effective masses; the colouring and the block factors do not depend on them).
//! The result is the bits of a fresh solve.

use std::time::Instant;

use deepcontact_core::{
    ContactProblem, CoreError, Impulse, SolveReport, SolverSettings, Velocity, VelocitySolver,
};

use super::{LANES, PgsSolver, Real, Row, Vel};
use crate::PgsError;

impl PgsSolver {
    /// Solves `problem` from the start in `impulses`, as [`VelocitySolver::solve`] does and
    /// to its bits, on the plan this solver's last solve built for the same island, whose
    /// points' effective masses may since have been scaled (an over-relaxed copy). An
    /// island of [`PgsSettings::parallel_min_points`](crate::PgsSettings::parallel_min_points)
    /// points or more, whose plan is built in the sweep, is solved afresh.
    ///
    /// # Errors
    /// [`PgsError::NotPlanned`] (as [`CoreError::Solver`]) when the last solve was not of this
    /// island: another count of points, manifolds or bodies, or a point's normal, friction or
    /// bias, or a manifold's bodies or their inverse masses, that differ (bit for bit). Otherwise what [`VelocitySolver::solve`] returns for the start.
    pub fn solve_again(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        if self.plans_chunked(problem.points.len()) {
            return self.solve(problem, settings, impulses, velocities, report);
        }
        let t0 = Instant::now();
        report.clear();
        settings.validate()?;
        deepcontact_core::solver::check_solve_buffers(problem, impulses, velocities)?;
        if !self.planned_for(problem) {
            return Err(PgsError::NotPlanned.into());
        }
        self.restart(problem, impulses, None);
        self.warm_start();
        let (it, verdict) = self.run_scheduled(problem, settings, report);
        self.end(it, verdict, impulses, velocities, report)?;
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// Whether the plan held is `problem`'s (what the sweeps read from it, bit for bit, but
    /// the points' effective masses).
    fn planned_for(&self, problem: &ContactProblem) -> bool {
        let same = |a: f64, b: f64| a.to_bits() == b.to_bits();
        let points = &problem.points;
        if self.planned_bodies != Some(problem.bodies.len())
            || self.rows.len() != points.len()
            || self.bodies.is_active()
        {
            return false;
        }
        let rows_match = self.rows.iter().zip(points).all(|(r, p)| {
            same(r.nx, p.normal.x)
                && same(r.ny, p.normal.y)
                && same(r.friction, p.friction)
                && same(r.bias, p.velocity_bias)
        });
        let manifolds = problem.manifolds.iter().filter(|(s, e)| e > s).count();
        rows_match
            && self.manifolds.len() == manifolds
            && self.manifolds.iter().all(|m| {
                let p = &points[m.start as usize];
                let (a, b) = (
                    &problem.bodies[p.body_a as usize],
                    &problem.bodies[p.body_b as usize],
                );
                problem.manifolds.get(p.manifold as usize) == Some(&(m.start, m.start + m.count))
                    && (m.a, m.b) == (p.body_a, p.body_b)
                    && same(m.ma, a.inv_mass)
                    && same(m.ia, a.inv_inertia)
                    && same(m.mb, b.inv_mass)
                    && same(m.ib, b.inv_inertia)
            })
    }

    /// The state a fresh plan of `problem` starts from: the start and the points' effective
    /// masses (multiplied by `scale`'s factors when given, as [`Self::prepare`] does) in the
    /// rows and the batches' lanes (padding lanes' impulses at zero), the bodies' free
    /// velocities, and the dummy body and sink after them at zero.
    pub(super) fn restart(
        &mut self,
        problem: &ContactProblem,
        start: &[Impulse],
        scale: Option<&[Real]>,
    ) {
        let raw = self.settings.raw_start;
        for (i, ((row, p), s)) in self
            .rows
            .iter_mut()
            .zip(&problem.points)
            .zip(start)
            .enumerate()
        {
            (row.ln, row.lt) = Row::start(s, p.friction, raw);
            (row.normal_mass, row.tangent_mass) = (p.normal_mass, p.tangent_mass);
            if let Some(scale) = scale {
                row.normal_mass *= scale[i];
                row.tangent_mass *= scale[i];
            }
        }
        for batch in &mut self.batches {
            for lane in 0..LANES {
                match self.rows.get(batch.row[lane] as usize) {
                    Some(r) => {
                        (batch.ln[lane], batch.lt[lane]) = (r.ln, r.lt);
                        batch.normal_mass[lane] = r.normal_mass;
                        batch.tangent_mass[lane] = r.tangent_mass;
                    }
                    None => (batch.ln[lane], batch.lt[lane]) = (0.0, 0.0),
                }
            }
        }
        for (v, b) in self.vel.iter_mut().zip(&problem.bodies) {
            *v = Vel {
                vx: b.linear_velocity.x,
                vy: b.linear_velocity.y,
                w: b.angular_velocity,
            };
        }
        for v in self.vel.iter_mut().skip(problem.bodies.len()) {
            *v = Vel::default();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PgsSettings, Precision};
    use deepcontact_core::scene;

    /// The largest islands of `scene` after `steps` steps (up to three, of more than 8 points).
    fn islands(scene: scene::Scene, steps: usize) -> Vec<ContactProblem> {
        let mut problems = super::super::test_support::islands(scene, steps);
        problems.truncate(3);
        problems.retain(|p| p.len() > 8);
        assert!(!problems.is_empty(), "an island with contacts");
        problems
    }

    /// A start for `problem` that differs from point to point (`k` picks the pattern).
    fn start(problem: &ContactProblem, k: u64) -> Vec<Impulse> {
        (0..problem.len())
            .map(|i| {
                let x = ((i as u64 * 7 + k * 13) % 11) as f64;
                Impulse::new(0.01 * x, 0.002 * (x - 5.0))
            })
            .collect()
    }

    /// The bits of a solve: impulses, velocities, iterations and natural residual.
    fn solved(
        solver: &mut PgsSolver,
        problem: &ContactProblem,
        from: &[Impulse],
        again: bool,
    ) -> Vec<u64> {
        let settings = SolverSettings {
            max_iterations: 7,
            tolerance: 0.0,
            ..SolverSettings::default()
        };
        let mut impulses = from.to_vec();
        let mut velocities = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        let run = if again {
            solver.solve_again(
                problem,
                &settings,
                &mut impulses,
                &mut velocities,
                &mut report,
            )
        } else {
            solver.solve(
                problem,
                &settings,
                &mut impulses,
                &mut velocities,
                &mut report,
            )
        };
        run.unwrap();
        assert_eq!(report.iterations, 7, "the sweeps ran");
        let mut bits = super::super::test_support::solution_bits(&impulses, &velocities);
        bits.push(report.natural_residual.to_bits());
        bits
    }

    #[test]
    fn solve_again_gives_the_bits_of_a_fresh_solve_from_each_start() {
        let circles = islands(scene::pile(12345, 100).unwrap(), 130);
        let boxes = islands(
            scene::box_pile(12345, &scene::ShapePileParams::default()).unwrap(),
            150,
        );
        let faces: usize = boxes
            .iter()
            .map(|p| p.manifolds.iter().filter(|(s, e)| e - s == 2).count())
            .sum();
        assert!(faces > 0, "the box pile's islands hold two-point manifolds");
        for precision in [Precision::F64, Precision::F32] {
            let settings = PgsSettings {
                precision,
                ..PgsSettings::default()
            };
            for problem in circles.iter().chain(&boxes) {
                let mut kept = PgsSolver::with_settings(settings);
                solved(&mut kept, problem, &start(problem, 0), false);
                for k in 1..4 {
                    // Every other start on a copy whose point rows are over-relaxed by k / 2.
                    let mut copy = problem.clone();
                    if k % 2 == 0 {
                        for p in &mut copy.points {
                            p.normal_mass *= 1.0 + 0.25 * k as f64;
                            p.tangent_mass *= 1.0 + 0.25 * k as f64;
                        }
                    }
                    let from = start(&copy, k);
                    let fresh =
                        solved(&mut PgsSolver::with_settings(settings), &copy, &from, false);
                    assert_eq!(solved(&mut kept, &copy, &from, true), fresh, "start {k}");
                }
            }
        }
    }

    #[test]
    fn solve_again_refuses_an_island_it_has_no_plan_for() {
        let a = &islands(scene::pile(12345, 100).unwrap(), 130)[0];
        let b = &islands(
            scene::box_pile(12345, &scene::ShapePileParams::default()).unwrap(),
            150,
        )[0];
        let settings = SolverSettings::default();
        let attempt = |solver: &mut PgsSolver, problem: &ContactProblem| {
            let mut impulses = vec![Impulse::ZERO; problem.len()];
            let mut velocities = vec![Velocity::default(); problem.bodies.len()];
            solver.solve_again(
                problem,
                &settings,
                &mut impulses,
                &mut velocities,
                &mut SolveReport::default(),
            )
        };
        let not_planned = CoreError::from(PgsError::NotPlanned).to_string();
        let mut solver = PgsSolver::new();
        assert_eq!(
            attempt(&mut solver, a).unwrap_err().to_string(),
            not_planned
        );
        solved(&mut solver, a, &start(a, 0), false);
        assert_eq!(
            attempt(&mut solver, b).unwrap_err().to_string(),
            not_planned
        );
        // The same island with one point's bias changed.
        let mut moved = a.clone();
        moved.points[0].velocity_bias += 0.01;
        assert_eq!(
            attempt(&mut solver, &moved).unwrap_err().to_string(),
            not_planned
        );
        attempt(&mut solver, a).unwrap();
    }
}
