//! Small islands solved together ([`VelocitySolver::solve_many`]).
//!
//! A small island's sweep is a short chain of dependent operations repeated every iteration
//! on the same few bodies, so the core idles on its latency. Small islands share nothing, so
//! their sweeps can overlap: they are packed into the lanes of shared batches
//! ([`crate::velocity::lanes`]). Each island keeps its own buffers (a solver of its own), its
//! own stop rule and iteration count, and its measures folded in its own order: each ends
//! with the bits it would have alone.
//!
//! [`VelocitySolver::solve_many`]: deepcontact_core::VelocitySolver::solve_many

use deepcontact_core::{IslandSolve, SolveReport, SolverSettings, VelocitySolver};

use crate::velocity::{PgsSolver, Sweep, Verdict, judge};

/// Islands of at most this many contact points are solved together: below it the
/// per-iteration chain, not the work, sets a sweep's time (alone, a one-point island costs
/// 40–50 ns per pass, an island of 32 points or more ≈ 7.5 ns a point, as the largest do).
pub(crate) const SMALL_POINTS: usize = 32;

impl PgsSolver {
    /// `solve_many` for PGS: islands of more than [`SMALL_POINTS`] points are solved alone,
    /// the others together ([`Self::solve_small`]); each ends with the bits of its own solve,
    /// under an over-relaxation schedule ([`crate::OverRelaxation`]) too.
    pub(crate) fn solve_islands(
        &mut self,
        settings: &SolverSettings,
        islands: &mut [IslandSolve<'_>],
    ) {
        let mut small = std::mem::take(&mut self.small_islands);
        small.clear();
        for (k, i) in islands.iter_mut().enumerate() {
            if i.problem.points.len() > SMALL_POINTS {
                i.result = self.solve(i.problem, settings, i.impulses, i.velocities, i.report);
            } else {
                small.push(k);
            }
        }
        if !small.is_empty() {
            self.solve_small(settings, islands, &small);
            self.threads_used = self.threads_used.max(1);
        }
        self.small_islands = small;
    }

    /// Whether this solver's prepared island is swept as batches only, in the plain plan (in
    /// `f64`: the packs are).
    pub(crate) fn batches_only(&self, points: usize) -> bool {
        self.settings.precision == crate::Precision::F64
            && !self.plans_chunked(points)
            && !self.segments.is_empty()
            && self.scratch.is_empty()
    }
}

/// Where one island of a pack stands: iterations run, and its verdict once it has ended.
#[derive(Default)]
pub(crate) struct Progress {
    it: u32,
    pub(crate) ended: Option<Verdict>,
}

impl Progress {
    /// Judges the island's iteration that produced `sweep`, as the one-island loop does: the
    /// stop rule, a divergence or the cap ends it.
    #[inline(always)]
    pub(crate) fn judge(
        &mut self,
        settings: &SolverSettings,
        sweep: &Sweep,
        report: &mut SolveReport,
    ) {
        self.it += 1;
        match judge(settings, self.it, sweep, Some(report)) {
            Verdict::Continue if self.it < settings.max_iterations => {}
            verdict => self.ended = Some(verdict),
        }
    }

    /// The iterations run and how the island ended (the cap: `Continue`).
    pub(crate) fn outcome(&self) -> (u32, Verdict) {
        (self.it, self.ended.unwrap_or(Verdict::Continue))
    }
}

#[cfg(test)]
mod tests {
    use deepcontact_core::{
        CarriedWarmStart, ContactProblem, Impulse, Real, ResidualNorm, Velocity, WorldSettings,
        scene,
    };

    use super::*;

    /// Every island of the first `steps` steps of a falling 100-body pile and of a pyramid
    /// (small islands of circles; two-point manifolds), step by step.
    fn islands_by_step(steps: usize) -> Vec<Vec<ContactProblem>> {
        let mut out = Vec::new();
        for mut world in [
            scene::pile(12345, 100)
                .unwrap()
                .build(WorldSettings::default())
                .unwrap(),
            scene::pyramid(4).build(WorldSettings::default()).unwrap(),
        ] {
            let (mut s, mut p) = (PgsSolver::new(), crate::PgsPositionSolver::new());
            for _ in 0..steps {
                world.step(&mut CarriedWarmStart, &mut s, &mut p).unwrap();
                out.push(world.last_problems().to_vec());
            }
        }
        out
    }

    /// Everything a solve leaves, as bits: impulses, velocities, iterations, verdict,
    /// residual curves, natural residual (not the time).
    fn bits(impulses: &[Impulse], velocities: &[Velocity], r: &SolveReport) -> Vec<u64> {
        let mut v: Vec<u64> = impulses
            .iter()
            .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
            .collect();
        v.extend(
            velocities
                .iter()
                .flat_map(|x| [x.linear.x, x.linear.y, x.angular].map(Real::to_bits)),
        );
        v.extend([u64::from(r.iterations), u64::from(r.converged)]);
        v.extend(
            r.residual_inf
                .iter()
                .chain(&r.residual_l2)
                .map(|x| x.to_bits()),
        );
        v.push(r.natural_residual.to_bits());
        v
    }

    /// [`bits`] of every island of `problems` solved through `solve_many` from `start`
    /// (`None` for an island whose solve failed).
    fn solve_many_bits(
        solver: &mut PgsSolver,
        problems: &[ContactProblem],
        stop: &SolverSettings,
        start: impl Fn(&ContactProblem) -> Vec<Impulse>,
    ) -> Vec<Option<Vec<u64>>> {
        let mut impulses: Vec<Vec<Impulse>> = problems.iter().map(start).collect();
        let mut velocities: Vec<Vec<Velocity>> = problems
            .iter()
            .map(|p| vec![Velocity::default(); p.bodies.len()])
            .collect();
        let mut reports = vec![SolveReport::default(); problems.len()];
        let mut islands: Vec<IslandSolve<'_>> = problems
            .iter()
            .zip(&mut impulses)
            .zip(&mut velocities)
            .zip(&mut reports)
            .map(|(((p, i), v), r)| IslandSolve::new(p, i, v, r))
            .collect();
        solver.solve_many(stop, &mut islands);
        let ok: Vec<bool> = islands.iter().map(|i| i.result.is_ok()).collect();
        drop(islands);
        (0..problems.len())
            .map(|k| ok[k].then(|| bits(&impulses[k], &velocities[k], &reports[k])))
            .collect()
    }

    /// [`solve_many_bits`] where every island must succeed.
    fn solved_many(
        solver: &mut PgsSolver,
        problems: &[ContactProblem],
        stop: &SolverSettings,
        start: impl Fn(&ContactProblem) -> Vec<Impulse>,
    ) -> Vec<Vec<u64>> {
        solve_many_bits(solver, problems, stop, start)
            .into_iter()
            .map(|b| b.expect("every island solved"))
            .collect()
    }

    /// [`bits`] of every island of `problems` solved alone from `start`.
    fn solved_alone(
        solver: &mut PgsSolver,
        problems: &[ContactProblem],
        stop: &SolverSettings,
        start: impl Fn(&ContactProblem) -> Vec<Impulse>,
    ) -> Vec<Vec<u64>> {
        problems
            .iter()
            .map(|p| {
                let (mut imp, mut vel) = (start(p), vec![Velocity::default(); p.bodies.len()]);
                let mut report = SolveReport::default();
                solver
                    .solve(p, stop, &mut imp, &mut vel, &mut report)
                    .unwrap();
                bits(&imp, &vel, &report)
            })
            .collect()
    }

    #[test]
    fn small_islands_packed_under_an_over_relaxation_schedule_end_with_the_bits_of_their_own_solves()
     {
        // A step's islands (small ones packed, the rest alone) and 19 one-point islands (two
        // full packs and part of a third), under a schedule of three factors, from starts that
        // stop them at different sweeps: inside a share, at the cap, after a one-sweep cap.
        let steps = islands_by_step(61);
        let ones: Vec<ContactProblem> = steps
            .iter()
            .flatten()
            .filter(|p| p.len() == 1)
            .take(19)
            .cloned()
            .collect();
        assert_eq!(ones.len(), 19);
        let problems = &steps[60];
        assert!(
            problems.iter().filter(|p| p.len() <= SMALL_POINTS).count() >= 2,
            "small islands to pack"
        );
        let settings = crate::PgsSettings {
            over_relaxation: crate::OverRelaxation::new(&[1.8, 1.5, 1.2]).unwrap(),
            ..crate::PgsSettings::default()
        };
        let start = |p: &ContactProblem| -> Vec<Impulse> {
            (0..p.len())
                .map(|i| {
                    let x = p.bodies[p.points[i].body_b as usize].position.x;
                    Impulse::new(0.3 * (7.0 * x).fract().abs(), 0.01 * (50.0 * x).sin())
                })
                .collect()
        };
        let cap = |max_iterations, tolerance| SolverSettings {
            max_iterations,
            tolerance,
            ..SolverSettings::default()
        };
        // Least iterations (20) spanning shares of 13: counted from the solve's first sweep.
        let least = SolverSettings {
            min_iterations: 20,
            ..cap(40, 1e3)
        };
        let mut stops = std::collections::BTreeSet::new();
        for stop in [
            cap(1, 0.0),
            cap(2, 0.0),
            cap(7, 0.0),
            cap(12, 1e-3),
            cap(40, 1e-5),
            least,
        ] {
            for islands in [&problems[..], &ones[..]] {
                let mut many = PgsSolver::with_settings(settings);
                let mut alone = PgsSolver::with_settings(settings);
                let together = solved_many(&mut many, islands, &stop, start);
                assert_eq!(
                    together,
                    solved_alone(&mut alone, islands, &stop, start),
                    "{stop:?}"
                );
                // `bits` holds the iterations after the impulses and velocities.
                stops.extend(
                    islands
                        .iter()
                        .zip(&together)
                        .map(|(p, b)| b[2 * p.len() + 3 * p.bodies.len()]),
                );
            }
        }
        assert!(
            stops.iter().filter(|&&it| it > 2 && it < 12).count() >= 3,
            "stops inside the shares: {stops:?}"
        );
        assert!(stops.contains(&20), "the least iterations' stop: {stops:?}");
        // The schedule reached the packed islands: plain PGS ends elsewhere on them.
        let stop = cap(7, 0.0);
        let scheduled = solved_many(&mut PgsSolver::with_settings(settings), &ones, &stop, start);
        let plain = solved_many(&mut PgsSolver::new(), &ones, &stop, start);
        let differ = scheduled.iter().zip(&plain).filter(|(a, b)| a != b).count();
        assert!(
            differ >= 15,
            "{differ} of 19 one-point islands over-relaxed"
        );
    }

    #[test]
    fn small_islands_solved_together_end_with_the_bits_of_their_own_solves() {
        let steps = islands_by_step(60);
        let start = |p: &ContactProblem| -> Vec<Impulse> {
            (0..p.len())
                .map(|i| Impulse::new(0.02 * (i % 5) as Real, 0.003 * (i % 3) as Real))
                .collect()
        };
        let mut shared_steps = 0;
        for stop in [
            SolverSettings::default(),
            SolverSettings {
                norm: ResidualNorm::Contact,
                ..SolverSettings::default()
            },
            SolverSettings {
                tolerance: 0.0,
                max_iterations: 30,
                ..SolverSettings::default()
            },
        ] {
            // One solver for the whole run, as the world keeps one.
            let (mut many, mut alone) = (PgsSolver::new(), PgsSolver::new());
            for problems in &steps {
                let small = problems.iter().filter(|p| p.len() <= SMALL_POINTS).count();
                shared_steps += usize::from(small >= 2);
                let many_bits = solved_many(&mut many, problems, &stop, start);
                let alone_bits = solved_alone(&mut alone, problems, &stop, start);
                for (k, p) in problems.iter().enumerate() {
                    assert_eq!(
                        many_bits[k],
                        alone_bits[k],
                        "island {k} of {} ({} points), {stop:?}",
                        problems.len(),
                        p.len()
                    );
                }
            }
        }
        assert!(
            shared_steps > 50,
            "{shared_steps} steps with two small islands"
        );
    }

    #[test]
    fn one_point_islands_packed_in_lanes_end_with_the_bits_of_their_own_solves() {
        // The one-point islands of both runs, handed over in calls of 1 to 19 islands (full
        // packs, partial packs, a lone island), from starts that make them stop at different
        // iterations, under three stop rules; one island in each call starts from NaN and
        // fails.
        let ones: Vec<ContactProblem> = islands_by_step(60)
            .into_iter()
            .flatten()
            .filter(|p| p.len() == 1)
            .collect();
        assert!(ones.len() >= 52, "{} one-point islands", ones.len());
        let start = |p: &ContactProblem| -> Vec<Impulse> {
            let x = p.bodies[p.points[0].body_b as usize].position.x;
            let f = (7.0 * x).fract().abs();
            vec![Impulse::new(
                10.0_f64.powf(4.0 * f) - 1.0,
                (50.0 * x).sin() * f,
            )]
        };
        for stop in [
            SolverSettings::default(),
            SolverSettings {
                norm: ResidualNorm::Contact,
                tolerance: 1e-9,
                ..SolverSettings::default()
            },
            SolverSettings {
                tolerance: 0.0,
                max_iterations: 7,
                ..SolverSettings::default()
            },
        ] {
            let (mut many, mut alone) = (PgsSolver::new(), PgsSolver::new());
            let mut iterations = std::collections::BTreeSet::new();
            let mut at = 0;
            for size in [1, 3, 8, 9, 12, 19] {
                let call = &ones[at..at + size];
                at += size;
                let nan = size / 2;
                let start_of = |p: &ContactProblem| {
                    let mut s = start(p);
                    if std::ptr::eq(p, &call[nan]) {
                        s[0].normal = Real::NAN;
                    }
                    s
                };
                let many_bits = solve_many_bits(&mut many, call, &stop, start_of);
                let alone_bits = solved_alone(&mut alone, call, &stop, start);
                for (k, p) in call.iter().enumerate() {
                    if k == nan {
                        assert!(many_bits[k].is_none(), "a NaN start fails");
                        continue;
                    }
                    let alone = &alone_bits[k];
                    // `bits` holds the iterations after the impulses and velocities.
                    iterations.insert(alone[2 * p.len() + 3 * p.bodies.len()]);
                    assert_eq!(
                        many_bits[k].as_ref(),
                        Some(alone),
                        "island {k} of {size}, {stop:?}"
                    );
                }
            }
            if stop.tolerance > 0.0 {
                assert!(iterations.len() >= 2, "stops at {iterations:?}");
            }
        }
    }

    #[test]
    fn regression_empty_islands_shared_a_nan_time() {
        // The group's time was shared in proportion to points × iterations: islands without
        // points made it 0 / 0.
        let empty = ContactProblem::new();
        let (mut i0, mut i1) = (Vec::new(), Vec::new());
        let (mut v0, mut v1) = (Vec::new(), Vec::new());
        let (mut r0, mut r1) = (SolveReport::default(), SolveReport::default());
        let mut islands = [
            IslandSolve::new(&empty, &mut i0, &mut v0, &mut r0),
            IslandSolve::new(&empty, &mut i1, &mut v1, &mut r1),
        ];
        PgsSolver::new().solve_many(&SolverSettings::default(), &mut islands);
        for island in &islands {
            assert!(island.report.seconds.is_finite() && island.report.seconds >= 0.0);
        }
    }

    #[test]
    fn regression_pairs_kept_the_options_of_their_first_solve() {
        // The partner solver was made with the options of the first pair and kept them: a
        // later change (here: starts taken as given, outside the friction cone) reached only
        // one island of each pair. The packs' solvers take the options of every call too.
        let problems = islands_by_step(60)
            .into_iter()
            .find(|p| p.iter().filter(|p| p.len() <= SMALL_POINTS).count() >= 2)
            .expect("a step with two small islands");
        let start = |p: &ContactProblem| vec![Impulse::new(0.05, 0.2); p.len()];
        let stop = SolverSettings::default();
        let mut reused = PgsSolver::new();
        solved_many(&mut reused, &problems, &stop, start);
        reused.settings.raw_start = true;
        let mut alone = PgsSolver::with_settings(reused.settings);
        assert_eq!(
            solved_many(&mut reused, &problems, &stop, start),
            solved_alone(&mut alone, &problems, &stop, start)
        );
    }

    #[test]
    fn a_failing_small_island_leaves_the_others_solved() {
        let problems = islands_by_step(60)
            .into_iter()
            .find(|p| p.iter().filter(|p| p.len() <= SMALL_POINTS).count() >= 2);
        let problems = problems.expect("a step with two small islands");
        let small: Vec<&ContactProblem> = problems
            .iter()
            .filter(|p| p.len() <= SMALL_POINTS)
            .take(2)
            .collect();
        let mut bad = vec![Impulse::default(); small[0].len()];
        bad[0] = Impulse::new(Real::NAN, 0.0);
        let mut good = vec![Impulse::default(); small[1].len()];
        let mut v0 = vec![Velocity::default(); small[0].bodies.len()];
        let mut v1 = vec![Velocity::default(); small[1].bodies.len()];
        let (mut r0, mut r1) = (SolveReport::default(), SolveReport::default());
        let mut islands = [
            IslandSolve::new(small[0], &mut bad, &mut v0, &mut r0),
            IslandSolve::new(small[1], &mut good, &mut v1, &mut r1),
        ];
        PgsSolver::new().solve_many(&SolverSettings::default(), &mut islands);
        assert!(islands[0].result.is_err(), "a NaN start is an error");
        assert!(islands[1].result.is_ok());
        assert!(r1.iterations >= 1);
    }
}
