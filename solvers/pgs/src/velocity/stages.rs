//! One island solved in stages, each with its rows' effective masses scaled by its own factors.
//!
//! Scaling a row's effective mass by ω is the over-relaxed Gauss-Seidel update (the `sor`
//! provider's derivation), so a relaxation schedule — one factor for each share of the sweeps —
//! is a solve in stages. Solving a scaled copy of the island per stage costs, per stage, the
//! copy, the checks of the problem and of the plan, and the end of a solve (the checks and the
//! copies out), where the sweeps of a small island under a pass budget are a few passes.
//! [`PgsSolver::solve_stages`] builds the plan once and, between stages, does to the state
//! exactly what a fresh solve of the next stage from the last one's impulses would: the final
//! friction projection, the start's projection onto each point's cone, the bodies' free
//! velocities with those impulses applied. So the bits are those of the stage-by-stage solves.

use std::time::Instant;

use deepcontact_core::{ContactProblem, CoreError, Impulse, SolveReport, SolverSettings, Velocity};

use super::measures::Verdict;
use super::{PgsSolver, Real};
use crate::PgsError;

/// A stage of [`PgsSolver::solve_stages`].
#[derive(Debug, Clone, Copy)]
pub struct Stage<'a> {
    /// Most sweeps of the stage (0: the stage is skipped).
    pub iterations: u32,
    /// One factor per contact point of the island, multiplying the point's normal and tangent
    /// effective masses for the stage (1: the point as given; ω ∈ (1, 2): over-relaxed by ω);
    /// finite and > 0. Under the block solver a two-point manifold's normals do not read them.
    pub mass_scale: &'a [Real],
}

impl PgsSolver {
    /// Solves `problem` from the start in `impulses` in `stages`, in order, until a stage
    /// meets the stop rule of `settings` (whose `max_iterations` each stage's
    /// [`Stage::iterations`] replaces): the bits of solving, stage by stage, a copy of the
    /// island whose points' effective masses are multiplied by the stage's factors, the first
    /// with [`VelocitySolver::solve`](deepcontact_core::VelocitySolver::solve) and each later
    /// one with [`Self::solve_again`] from the impulses the one before ended with. `report`
    /// holds the stages together: their iterations summed, every iteration's residuals in
    /// order, the verdict of the last stage run; `impulses`, `velocities` and the natural
    /// residual are those the last stage ended with. Without a stage that sweeps, nothing is
    /// solved: `impulses` and `velocities` are left as given and the report is empty. The
    /// stages are the schedule: [`PgsSettings::over_relaxation`](crate::PgsSettings) is not
    /// applied.
    ///
    /// # Errors
    /// [`PgsError::StageScale`] (as [`CoreError::Solver`]) when a stage's factors are not one
    /// per point, or one is not finite and positive; otherwise what a solve returns.
    pub fn solve_stages(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        stages: &[Stage<'_>],
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let t0 = Instant::now();
        report.clear();
        check_stages(problem, stages)?;
        let mut sweeping = stages.iter().filter(|s| s.iterations > 0);
        let Some(first) = sweeping.next() else {
            return Ok(());
        };
        let stage = |s: &Stage<'_>| SolverSettings {
            max_iterations: s.iterations,
            ..*settings
        };
        let scale = Some(first.mass_scale);
        self.begin_scaled(problem, &stage(first), impulses, velocities, report, scale)?;
        let points = problem.points.len();
        let (mut iterations, mut verdict) = self.run(points, &stage(first), report);
        for next in sweeping {
            if verdict != Verdict::Continue {
                break;
            }
            // The end of a solve, but for its checks and copies: the batches' impulses in
            // the rows, the final friction projection; then the next stage's start from them.
            // A start is projected onto the cone anyway, and the velocities are rebuilt from
            // it, unless the solver takes the start as given.
            self.sync_rows();
            if self.settings.raw_start {
                self.project_friction();
            }
            for (out, r) in impulses.iter_mut().zip(&self.rows) {
                *out = Impulse::new(r.ln, r.lt);
            }
            let scale = Some(next.mass_scale);
            if self.plans_chunked(points) {
                // The chunked and domain plans are built in the sweep (as `solve_again`
                // solves such an island afresh).
                self.prepare(problem, impulses, scale);
            } else {
                self.restart(problem, impulses, scale);
            }
            self.warm_start();
            let (it, v) = self.run(points, &stage(next), report);
            (iterations, verdict) = (iterations + it, v);
        }
        self.end(iterations, verdict, impulses, velocities, report)?;
        report.seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }
}

/// [`PgsError::StageScale`] for the first stage of `stages` whose factors do not fit
/// `problem`.
fn check_stages(problem: &ContactProblem, stages: &[Stage<'_>]) -> Result<(), PgsError> {
    for (stage, s) in stages.iter().enumerate() {
        let fail = |reason: String| PgsError::StageScale { stage, reason };
        if s.mass_scale.len() != problem.points.len() {
            return Err(fail(format!(
                "{} mass factors for {} contact points",
                s.mass_scale.len(),
                problem.points.len()
            )));
        }
        if let Some((i, f)) = s
            .mass_scale
            .iter()
            .enumerate()
            .find(|(_, f)| !(f.is_finite() && **f > 0.0))
        {
            return Err(fail(format!(
                "mass factor {f} of point {i} is not finite and positive"
            )));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{PgsSettings, Precision};
    use deepcontact_core::{VelocitySolver, scene};

    /// The largest island of `scene` after `steps` steps of carried impulses.
    fn island(scene: scene::Scene, steps: usize) -> ContactProblem {
        let problem = super::super::test_support::islands(scene, steps).remove(0);
        assert!(problem.len() > 8, "an island with contacts");
        problem
    }

    /// Per stage, a factor for each point: single-point manifolds over-relaxed by the
    /// stage's ω, the rest as given.
    fn scales(problem: &ContactProblem, omegas: &[Real]) -> Vec<Vec<Real>> {
        omegas
            .iter()
            .map(|&w| {
                let mut f = vec![1.0; problem.len()];
                for &(s, e) in &problem.manifolds {
                    if e == s + 1 {
                        f[s as usize] = w;
                    }
                }
                f
            })
            .collect()
    }

    /// A start that differs from point to point.
    fn start(problem: &ContactProblem) -> Vec<Impulse> {
        (0..problem.len())
            .map(|i| {
                let x = (i * 7 % 11) as f64;
                Impulse::new(0.01 * x, 0.002 * (x - 5.0))
            })
            .collect()
    }

    /// The bits of impulses, velocities and the summed iterations.
    fn bits(impulses: &[Impulse], velocities: &[Velocity], iterations: u32) -> Vec<u64> {
        let mut bits = super::super::test_support::solution_bits(impulses, velocities);
        bits.push(u64::from(iterations));
        bits
    }

    /// The stages solved one by one on scaled copies (`solve`, then `solve_again`).
    fn chained(
        settings: PgsSettings,
        problem: &ContactProblem,
        stages: &[Stage<'_>],
        tolerance: Real,
    ) -> Vec<u64> {
        let mut solver = PgsSolver::with_settings(settings);
        let mut impulses = start(problem);
        let mut velocities = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        let mut iterations = 0;
        for (k, stage) in stages.iter().enumerate() {
            let mut copy = problem.clone();
            for (p, f) in copy.points.iter_mut().zip(stage.mass_scale) {
                p.normal_mass *= f;
                p.tangent_mass *= f;
            }
            let s = SolverSettings {
                max_iterations: stage.iterations,
                tolerance,
                ..SolverSettings::default()
            };
            let (i, v, r) = (&mut impulses, &mut velocities, &mut report);
            if k == 0 {
                solver.solve(&copy, &s, i, v, r).unwrap();
            } else {
                solver.solve_again(&copy, &s, i, v, r).unwrap();
            }
            iterations += report.iterations;
            if report.converged {
                break;
            }
        }
        bits(&impulses, &velocities, iterations)
    }

    /// The stages in one [`PgsSolver::solve_stages`].
    fn staged(
        settings: PgsSettings,
        problem: &ContactProblem,
        stages: &[Stage<'_>],
        tolerance: Real,
    ) -> (Vec<u64>, SolveReport) {
        let mut impulses = start(problem);
        let mut velocities = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        let s = SolverSettings {
            tolerance,
            ..SolverSettings::default()
        };
        PgsSolver::with_settings(settings)
            .solve_stages(
                problem,
                &s,
                stages,
                &mut impulses,
                &mut velocities,
                &mut report,
            )
            .unwrap();
        (bits(&impulses, &velocities, report.iterations), report)
    }

    #[test]
    fn stages_give_the_bits_of_one_solve_per_stage_on_scaled_copies() {
        let circles = island(scene::pile(12345, 100).unwrap(), 130);
        let boxes = island(
            scene::box_pile(12345, &scene::ShapePileParams::default()).unwrap(),
            150,
        );
        assert!(
            boxes.manifolds.iter().any(|(s, e)| e - s == 2),
            "the box pile's island holds two-point manifolds"
        );
        // Every island in the chunked domain plan too.
        let chunked = PgsSettings {
            parallel_min_points: 1,
            ..PgsSettings::default()
        };
        let f32 = PgsSettings {
            precision: Precision::F32,
            ..PgsSettings::default()
        };
        // With the start taken as given (the friction projection between stages is then the
        // only one).
        let raw = PgsSettings {
            raw_start: true,
            ..PgsSettings::default()
        };
        for settings in [PgsSettings::default(), f32, chunked, raw] {
            for problem in [&circles, &boxes] {
                let factors = scales(problem, &[1.8, 1.4, 1.0]);
                let stages: Vec<Stage<'_>> = factors
                    .iter()
                    .zip([3, 0, 4])
                    .map(|(f, iterations)| Stage {
                        iterations,
                        mass_scale: f,
                    })
                    .collect();
                let sweeping: Vec<Stage<'_>> = stages
                    .iter()
                    .copied()
                    .filter(|s| s.iterations > 0)
                    .collect();
                let (got, report) = staged(settings, problem, &stages, 0.0);
                assert_eq!(report.iterations, 7, "both sweeping stages ran in full");
                assert_eq!(report.residual_inf.len(), 7, "every iteration's residual");
                assert_eq!(got, chained(settings, problem, &sweeping, 0.0));
                // A stop in the first stage ends the solve there.
                let (got, report) = staged(settings, problem, &stages, 1e3);
                assert_eq!((report.iterations, report.converged), (1, true));
                assert_eq!(got, chained(settings, problem, &sweeping, 1e3));
            }
        }
    }

    #[test]
    fn stages_with_factors_that_do_not_fit_are_a_typed_error() {
        let problem = island(scene::pile(12345, 100).unwrap(), 130);
        let n = problem.len();
        let good = vec![1.5; n];
        let mut nan = good.clone();
        nan[3] = Real::NAN;
        let short = vec![1.5; n - 1];
        let mut solver = PgsSolver::new();
        for (bad, expected) in [
            (
                &nan,
                "stage 1: mass factor NaN of point 3 is not finite and positive".to_string(),
            ),
            (
                &short,
                format!("stage 1: {} mass factors for {n} contact points", n - 1),
            ),
        ] {
            let stages = [
                Stage {
                    iterations: 2,
                    mass_scale: &good,
                },
                Stage {
                    iterations: 2,
                    mass_scale: bad,
                },
            ];
            let mut impulses = vec![Impulse::ZERO; n];
            let mut velocities = vec![Velocity::default(); problem.bodies.len()];
            let e = solver
                .solve_stages(
                    &problem,
                    &SolverSettings::default(),
                    &stages,
                    &mut impulses,
                    &mut velocities,
                    &mut SolveReport::default(),
                )
                .unwrap_err();
            assert!(e.to_string().contains(&expected), "{e}");
            assert!(
                impulses.iter().all(|i| *i == Impulse::ZERO),
                "nothing solved"
            );
        }
        // Without a stage that sweeps, nothing is solved.
        let mut report = SolveReport::default();
        let mut impulses = vec![Impulse::new(1.0, 0.0); n];
        solver
            .solve_stages(
                &problem,
                &SolverSettings::default(),
                &[Stage {
                    iterations: 0,
                    mass_scale: &good,
                }],
                &mut impulses,
                &mut vec![Velocity::default(); problem.bodies.len()],
                &mut report,
            )
            .unwrap();
        assert_eq!(report.iterations, 0);
        assert!(impulses.iter().all(|i| *i == Impulse::new(1.0, 0.0)));
    }
}
