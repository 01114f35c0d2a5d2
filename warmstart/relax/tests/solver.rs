//! `learned-pgs`: the learned schedules inside the world's own PGS solve.

use deepcontact_core::{
    CarriedWarmStart, ContactProblem, Impulse, Registry, SolveReport, SolverSettings, Velocity,
    VelocitySolver, WarmStart, WarmStartContext, WarmStartError, WorldSettings, scene,
};
use deepcontact_pgs::{OverRelaxation, PgsPositionSolver, PgsSettings, PgsSolver};
use deepcontact_relax::{ScheduledPgs, shipped_schedules};

fn registry() -> Registry {
    let mut registry = Registry::empty();
    deepcontact_pgs::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    deepcontact_relax::register(&mut registry);
    registry
}

/// Carried impulses, keeping the largest island's problem and start of the last step.
#[derive(Default)]
struct Capture {
    largest: Option<(ContactProblem, Vec<Impulse>)>,
}

impl WarmStart for Capture {
    fn name(&self) -> &str {
        "capture"
    }

    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        CarriedWarmStart.warm_start(ctx, out)?;
        let larger = self
            .largest
            .as_ref()
            .is_none_or(|(p, _)| ctx.island == 0 || p.len() < ctx.problem.len());
        if larger {
            self.largest = Some((ctx.problem.clone(), out.to_vec()));
        }
        Ok(())
    }
}

/// The settled 100-circle pile's largest island at step 200 (seed 12345) and its carried
/// impulses.
fn pile_island() -> (ContactProblem, Vec<Impulse>) {
    let mut world = scene::pile(12345, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let (mut s, mut p) = (PgsSolver::new(), PgsPositionSolver::new());
    let mut capture = Capture::default();
    for _ in 0..200 {
        world.step(&mut capture, &mut s, &mut p).unwrap();
    }
    let (problem, start) = capture.largest.unwrap();
    assert!(problem.len() > 100, "the settled pile's island");
    (problem, start)
}

/// Impulses and velocities (as bits) and the natural residual of `solver`'s solve of `problem` from `start`
/// in `passes` sweeps.
fn solve(
    solver: &mut dyn VelocitySolver,
    problem: &ContactProblem,
    start: &[Impulse],
    passes: u32,
) -> (Vec<u64>, f64) {
    let stop = SolverSettings {
        max_iterations: passes,
        tolerance: 0.0,
        ..SolverSettings::default()
    };
    let mut impulses = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    solver
        .solve(problem, &stop, &mut impulses, &mut velocities, &mut report)
        .unwrap();
    assert_eq!(report.iterations, passes, "the budget ran");
    let bits = impulses
        .iter()
        .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
        .chain(velocities.iter().flat_map(|v| {
            [
                v.linear.x.to_bits(),
                v.linear.y.to_bits(),
                v.angular.to_bits(),
            ]
        }))
        .collect();
    (bits, report.natural_residual)
}

#[test]
fn learned_pgs_picks_the_learned_schedule_of_its_pass_budget() {
    let table = shipped_schedules().unwrap();
    let solver = ScheduledPgs::new(PgsSettings::default(), table.clone());
    for (k, schedule) in table.entries() {
        assert_eq!(
            solver.schedule_for(*k).factors(),
            schedule.factors(),
            "K = {k}"
        );
    }
    let largest = table.entries().last().unwrap();
    assert_eq!(
        solver.schedule_for(2 * largest.0).factors(),
        largest.1.factors()
    );
    // A tolerance solve's cap, and a single sweep, are swept plain.
    for cap in [2 * largest.0 + 1, 1000, 1] {
        assert!(solver.schedule_for(cap).is_none(), "cap {cap}");
    }
}

/// The mean natural residual over the contact steps of a 100-circle pile (seed 100, 200
/// steps) under a budget of `budget` passes, carried impulses and `solver`.
fn mean_residual(solver: &mut dyn VelocitySolver, budget: u32) -> f64 {
    let settings = WorldSettings {
        budget: Some(budget),
        ..WorldSettings::default()
    };
    let mut world = scene::pile(100, 100).unwrap().build(settings).unwrap();
    let mut position = PgsPositionSolver::new();
    let (mut sum, mut steps) = (0.0, 0);
    for _ in 0..200 {
        let r = world
            .step(&mut CarriedWarmStart, solver, &mut position)
            .unwrap();
        if r.contacts > 0 {
            sum += r.natural_residual;
            steps += 1;
        }
    }
    assert!(steps > 100, "{steps} steps with contacts");
    sum / f64::from(steps)
}

#[test]
fn learned_pgs_ends_a_budget_nearer_a_solution_than_pgs() {
    for budget in [4, 8, 16] {
        let mut learned = registry().build_solver("learned-pgs").unwrap();
        let plain = mean_residual(&mut PgsSolver::new(), budget);
        let relaxed = mean_residual(learned.as_mut(), budget);
        assert!(
            relaxed < 0.8 * plain,
            "K = {budget}: {relaxed} against {plain}"
        );
    }
}

#[test]
fn learned_pgs_is_pgs_under_the_schedule_of_the_budget() {
    let (problem, start) = pile_island();
    let mut learned = registry().build_solver("learned-pgs").unwrap();
    assert_eq!(learned.name(), "learned-pgs");
    for passes in [4, 8, 16] {
        let (plain_bits, _) = solve(&mut PgsSolver::new(), &problem, &start, passes);
        let (bits, _) = solve(learned.as_mut(), &problem, &start, passes);
        assert_ne!(
            bits, plain_bits,
            "K = {passes}: the schedule changed nothing"
        );
        let schedule = ScheduledPgs::new(PgsSettings::default(), shipped_schedules().unwrap())
            .schedule_for(passes);
        assert!(!schedule.is_none());
        let mut pgs = PgsSolver::with_settings(PgsSettings {
            over_relaxation: schedule,
            ..PgsSettings::default()
        });
        assert_eq!(
            solve(&mut pgs, &problem, &start, passes).0,
            bits,
            "K = {passes}"
        );
    }
    // Its fork solves to the same bits.
    let mut fork = learned.fork().unwrap();
    assert_eq!(
        solve(fork.as_mut(), &problem, &start, 8).0,
        solve(learned.as_mut(), &problem, &start, 8).0
    );
}

#[test]
fn learned_pgs_refuses_bad_parameters_with_typed_errors() {
    let r = registry();
    for (spec, names) in [
        ("learned-pgs:threads=0", "threads"),
        (
            "learned-pgs:schedules=/no/such/schedules.json",
            "/no/such/schedules.json",
        ),
        ("pgs:sor=2.1", "factor 2.1 is not in [1, 2)"),
        ("pgs:sor=1.8/x", "`x`"),
    ] {
        let e = r
            .build_solver(spec)
            .err()
            .unwrap_or_else(|| panic!("{spec}"));
        assert!(e.to_string().contains(names), "{spec}: {e}");
    }
    assert!(r.build_solver("pgs:sor=1.8/1.4/1.1").is_ok());
    assert_eq!(
        OverRelaxation::new(&[1.8, 1.4, 1.1]).unwrap().factors(),
        [1.8, 1.4, 1.1]
    );
}
