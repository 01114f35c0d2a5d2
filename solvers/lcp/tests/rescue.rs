//! `pgs-rescue` on a recorded island where PGS cycles, on one it settles, and with bad
//! parameters.

use deepcontact_core::math::Real;
use deepcontact_core::registry::{Registry, SpecError};
use deepcontact_core::{
    CarriedWarmStart, ContactProblem, CoreError, Impulse, IslandSolve, SolveReport, SolverSettings,
    Velocity, VelocitySolver, WorldSettings, scene,
};
use deepcontact_lcp::{
    LcpError, NewtonSettings, PgsRescueSolver, RescueSettings, RescueStart, stalled,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// PGS that keeps a copy of the largest island of each step and its start.
struct Recorder {
    pgs: PgsSolver,
    largest: Option<(ContactProblem, Vec<Impulse>)>,
}

impl VelocitySolver for Recorder {
    fn name(&self) -> &str {
        "recorder"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        self.solve_many(
            settings,
            &mut [IslandSolve::new(problem, impulses, velocities, report)],
        );
        Ok(())
    }

    fn solve_many(&mut self, settings: &SolverSettings, islands: &mut [IslandSolve<'_>]) {
        self.largest = islands
            .iter()
            .max_by_key(|i| i.problem.len())
            .map(|i| (i.problem.clone(), i.impulses.to_vec()));
        self.pgs.solve_many(settings, islands);
    }
}

/// The largest island of step `step` of the 100-circle pile of `seed`, stepped with PGS and
/// the carried warm start, with its start.
fn island(seed: u64, step: u64) -> (ContactProblem, Vec<Impulse>) {
    let mut world = scene::pile(seed, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let mut recorder = Recorder {
        pgs: PgsSolver::new(),
        largest: None,
    };
    let mut position = PgsPositionSolver::new();
    for _ in 0..=step {
        world
            .step(&mut CarriedWarmStart, &mut recorder, &mut position)
            .unwrap();
    }
    recorder.largest.unwrap()
}

fn solve(
    solver: &mut dyn VelocitySolver,
    problem: &ContactProblem,
    start: &[Impulse],
) -> (Vec<Impulse>, Vec<Velocity>, SolveReport) {
    solve_under(solver, problem, start, &SolverSettings::default())
}

fn solve_under(
    solver: &mut dyn VelocitySolver,
    problem: &ContactProblem,
    start: &[Impulse],
    settings: &SolverSettings,
) -> (Vec<Impulse>, Vec<Velocity>, SolveReport) {
    let mut impulses = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    solver
        .solve(
            problem,
            settings,
            &mut impulses,
            &mut velocities,
            &mut report,
        )
        .unwrap();
    (impulses, velocities, report)
}

fn bits(impulses: &[Impulse], velocities: &[Velocity]) -> Vec<u64> {
    impulses
        .iter()
        .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
        .chain(velocities.iter().flat_map(|v| {
            [
                v.linear.x.to_bits(),
                v.linear.y.to_bits(),
                v.angular.to_bits(),
            ]
        }))
        .collect()
}

/// Seed 313, step 149 of the carried start's world: PGS cycles there from every start and
/// stops at its cap far from a solution; the rescue finishes it below 1e-6.
#[test]
fn a_cycling_island_is_finished_by_newton() {
    let (problem, start) = island(313, 149);
    let (_, _, plain) = solve(&mut PgsSolver::new(), &problem, &start);
    assert!(!plain.converged, "PGS settles the recorded island");
    assert!(
        plain.natural_residual > 1e-3,
        "PGS ends close to a solution: {:e}",
        plain.natural_residual
    );
    assert!(stalled(&plain.residual_inf, 100, 2.0), "the curve falls");
    let mut rescue = PgsRescueSolver::new();
    let (_, _, report) = solve(&mut rescue, &problem, &start);
    let stats = rescue.stats();
    assert_eq!((stats.attempted, stats.rescued), (1, 1), "{stats:?}");
    assert!(report.converged);
    assert!(
        report.natural_residual < 1e-6,
        "natural residual {:e} after the rescue",
        report.natural_residual
    );
    assert!(report.iterations > plain.iterations);
    assert_eq!(report.residual_inf.len(), report.iterations as usize);
}

/// A cap below two windows is a fixed budget of passes: the island stays as PGS left it.
#[test]
fn a_fixed_budget_is_not_rescued() {
    let (problem, start) = island(313, 149);
    let budget = SolverSettings {
        max_iterations: 16,
        ..SolverSettings::default()
    };
    let mut rescue = PgsRescueSolver::new();
    let (_, _, report) = solve_under(&mut rescue, &problem, &start, &budget);
    assert!(!report.converged && report.natural_residual > 1e-3);
    assert_eq!(report.iterations, 16);
    let stats = rescue.stats();
    assert_eq!((stats.capped, stats.skipped, stats.attempted), (1, 1, 0));
}

/// An island PGS settles keeps PGS's bits and report; no Newton solve runs.
#[test]
fn a_converging_island_keeps_the_bits_of_plain_pgs() {
    let (problem, start) = island(313, 60);
    let (pi, pv, plain) = solve(&mut PgsSolver::new(), &problem, &start);
    assert!(plain.converged && plain.iterations > 1, "{plain:?}");
    let mut rescue = PgsRescueSolver::new();
    let (ri, rv, report) = solve(&mut rescue, &problem, &start);
    assert_eq!(rescue.stats().attempted, 0);
    assert_eq!(bits(&pi, &pv), bits(&ri, &rv));
    assert_eq!(report.iterations, plain.iterations);
    assert_eq!(report.residual_inf, plain.residual_inf);
    assert_eq!(
        report.natural_residual.to_bits(),
        plain.natural_residual.to_bits()
    );
}

/// The gate: a capped island whose natural residual PGS left below `above` × the stop
/// tolerance keeps PGS's bits and report (no Newton solve); just above it, Newton runs.
#[test]
fn a_capped_island_below_the_gate_keeps_the_bits_of_plain_pgs() {
    let (problem, start) = island(313, 149);
    let tolerance = SolverSettings::default().tolerance;
    let (pi, pv, plain) = solve(&mut PgsSolver::new(), &problem, &start);
    assert!(!plain.converged, "PGS settles the recorded island");
    let left = plain.natural_residual;
    let run = |above: f64| {
        let mut rescue = PgsRescueSolver::with_settings(RescueSettings {
            above,
            ..RescueSettings::default()
        });
        let (ri, rv, report) = solve(&mut rescue, &problem, &start);
        (bits(&ri, &rv), report, rescue.stats())
    };
    let (kept, report, stats) = run(2.0 * left / tolerance);
    assert_eq!((stats.capped, stats.attempted), (1, 0), "{stats:?}");
    assert_eq!(kept, bits(&pi, &pv));
    assert_eq!(report.natural_residual.to_bits(), left.to_bits());
    let (_, report, stats) = run(0.5 * left / tolerance);
    assert_eq!((stats.capped, stats.attempted), (1, 1), "{stats:?}");
    assert!(report.natural_residual < left);
}

/// An island PGS converges on in 37 iterations, capped at 20 (two windows of 10) and handed to
/// one heavily damped Newton step without the longer round: the finishing PGS iterations from the best
/// result end it converged, below what Newton left; without them it stays there.
#[test]
fn an_island_newton_leaves_is_finished_by_more_pgs_iterations() {
    let (problem, start) = island(313, 60);
    let (_, _, plain) = solve(&mut PgsSolver::new(), &problem, &start);
    assert!(plain.converged && plain.iterations > 20, "{plain:?}");
    let capped = SolverSettings {
        max_iterations: 20,
        ..SolverSettings::default()
    };
    let run = |finish: u32| {
        let mut rescue = PgsRescueSolver::with_settings(RescueSettings {
            window: 10,
            above: 0.0,
            // One heavily damped step (a Jacobi step, at the largest regularisation).
            newton: NewtonSettings {
                regularization: 100.0,
                ..NewtonSettings::default()
            },
            newton_iterations: 1,
            escalate: 0,
            escalate_above: 0.0,
            finish,
            ..RescueSettings::default()
        });
        let (_, _, report) = solve_under(&mut rescue, &problem, &start, &capped);
        (report, rescue.stats())
    };
    let (left, stats) = run(0);
    assert_eq!((stats.attempted, stats.finished), (1, 0), "{stats:?}");
    assert!(!left.converged);
    let (finished, stats) = run(5_000);
    assert_eq!((stats.attempted, stats.finished), (1, 1), "{stats:?}");
    assert!(finished.converged, "{finished:?}");
    assert!(
        finished.natural_residual < left.natural_residual,
        "{:e} after the finish, {:e} before",
        finished.natural_residual,
        left.natural_residual
    );
    assert_eq!(finished.residual_inf.len(), finished.iterations as usize);
}

#[test]
fn bad_parameters_give_typed_errors() {
    let bad = [
        RescueSettings {
            window: 0,
            ..RescueSettings::default()
        },
        RescueSettings {
            factor: 1.0,
            ..RescueSettings::default()
        },
        RescueSettings {
            above: -1.0,
            ..RescueSettings::default()
        },
        RescueSettings {
            newton_iterations: 0,
            ..RescueSettings::default()
        },
        RescueSettings {
            newton_chunk: 0,
            ..RescueSettings::default()
        },
        RescueSettings {
            newton_progress: 1.5,
            ..RescueSettings::default()
        },
        RescueSettings {
            newton_tolerance: Real::NAN,
            start: RescueStart::Zeros,
            ..RescueSettings::default()
        },
        RescueSettings {
            escalate_above: Real::INFINITY,
            ..RescueSettings::default()
        },
        RescueSettings {
            finish_chunk: 0,
            ..RescueSettings::default()
        },
    ];
    for (settings, name) in bad.iter().zip([
        "window",
        "factor",
        "above",
        "newton_iterations",
        "newton_chunk",
        "newton_progress",
        "newton_tolerance",
        "escalate_above",
        "finish_chunk",
    ]) {
        match settings.validate() {
            Err(LcpError::InvalidSetting { name: n, .. }) => assert_eq!(n, name),
            other => panic!("{name}: {other:?}"),
        }
        let mut solver = PgsRescueSolver::with_settings(*settings);
        let problem = ContactProblem::new();
        let err = solver
            .solve(
                &problem,
                &SolverSettings::default(),
                &mut [],
                &mut [],
                &mut SolveReport::default(),
            )
            .unwrap_err();
        assert!(
            matches!(err, CoreError::InvalidSetting { name: n, .. } if n == name),
            "{err:?}"
        );
    }
    let mut registry = Registry::empty();
    deepcontact_lcp::register(&mut registry);
    assert!(registry.build_solver("pgs-rescue").is_ok());
    for (spec, param) in [
        ("pgs-rescue:window=0", "window"),
        ("pgs-rescue:factor=0.5", "factor"),
        ("pgs-rescue:above=-2", "above"),
        ("pgs-rescue:newton_iterations=0", "newton_iterations"),
        ("pgs-rescue:newton_tolerance=-1", "newton_tolerance"),
        ("pgs-rescue:newton_chunk=0", "newton_chunk"),
        ("pgs-rescue:escalate_above=-1", "escalate_above"),
        ("pgs-rescue:newton_progress=0", "newton_progress"),
        ("pgs-rescue:start=middle", "start"),
        ("pgs-rescue:trigger=never", "trigger"),
    ] {
        match registry.build_solver(spec) {
            Err(SpecError::InvalidParameter { param: p, .. }) => assert_eq!(p, param, "{spec}"),
            Err(e) => panic!("{spec}: {e:?}"),
            Ok(_) => panic!("{spec} accepted"),
        }
    }
}

/// Starts too short to finish the cycling island (two Newton iterations each) leave it off a
/// solution; the starts again with the longer cap finish it, but only when their best result
/// is above the gate.
#[test]
fn an_island_the_short_starts_leave_above_the_gate_gets_the_longer_round() {
    let (problem, start) = island(313, 149);
    let tolerance = SolverSettings::default().tolerance;
    // No finishing PGS iterations: they would bring the island under the gate first.
    let short = RescueSettings {
        newton_iterations: 2,
        finish: 0,
        ..RescueSettings::default()
    };
    let run = |settings: RescueSettings| {
        let mut rescue = PgsRescueSolver::with_settings(settings);
        let (_, _, report) = solve(&mut rescue, &problem, &start);
        (report, rescue.stats())
    };
    let (alone, stats) = run(RescueSettings {
        escalate: 0,
        ..short
    });
    assert_eq!((stats.attempted, stats.escalated), (1, 0), "{stats:?}");
    let left = alone.natural_residual;
    assert!(
        !alone.converged && left > 1e-5,
        "two Newton iterations a start already end at {left:e}"
    );
    // The gate just below where the starts ended: the longer round runs and finishes it.
    let (escalated, stats) = run(RescueSettings {
        escalate_above: 0.5 * left / tolerance,
        ..short
    });
    assert_eq!((stats.attempted, stats.escalated), (1, 1), "{stats:?}");
    assert!(
        escalated.converged && escalated.natural_residual < 1e-6,
        "natural residual {:e} after the longer round",
        escalated.natural_residual
    );
    assert!(escalated.iterations > alone.iterations);
    // The gate above it: no longer round, the starts. result stays.
    let (kept, stats) = run(RescueSettings {
        escalate_above: 2.0 * left / tolerance,
        ..short
    });
    assert_eq!(stats.escalated, 0, "{stats:?}");
    assert_eq!(kept.natural_residual.to_bits(), left.to_bits());
}

/// `pgs-rescue` over PGS with `raw_start` said it projected the start (the trait's default), so
/// the world measured the start it observed projected while PGS applied it as given.
#[test]
fn regression_rescue_claimed_to_project_a_raw_start() {
    let projected = PgsRescueSolver::with_settings(RescueSettings::default());
    assert!(projected.projects_start());
    let d = RescueSettings::default();
    let raw = PgsRescueSolver::with_settings(RescueSettings {
        pgs: deepcontact_pgs::PgsSettings {
            raw_start: true,
            ..d.pgs
        },
        ..d
    });
    assert!(!raw.projects_start());
    assert_eq!(
        raw.projects_start(),
        PgsSolver::with_settings(raw.settings.pgs).projects_start()
    );
}

/// With the finishing rounds first, an island that one round of PGS settles never pays for a
/// Newton start; with the starts first it does. The island of the test above (PGS converges
/// in 37 iterations), capped at 20.
#[test]
fn a_slow_island_the_first_round_settles_gets_no_newton_start() {
    let (problem, start) = island(313, 60);
    let capped = SolverSettings {
        max_iterations: 20,
        ..SolverSettings::default()
    };
    let run = |sweeps_first: bool| {
        let mut rescue = PgsRescueSolver::with_settings(RescueSettings {
            window: 10,
            above: 0.0,
            sweeps_first,
            ..RescueSettings::default()
        });
        let (_, _, report) = solve_under(&mut rescue, &problem, &start, &capped);
        (report, rescue.stats())
    };
    let (first, stats) = run(true);
    assert_eq!((stats.attempted, stats.finished), (1, 1), "{stats:?}");
    assert_eq!(stats.newton_iterations, 0, "{stats:?}");
    assert!(first.converged, "{first:?}");
    let (after, stats) = run(false);
    assert_eq!(stats.attempted, 1, "{stats:?}");
    assert!(stats.newton_iterations > 0, "{stats:?}");
    assert!(
        after.natural_residual <= capped.tolerance * 10.0,
        "{after:?}"
    );
}
