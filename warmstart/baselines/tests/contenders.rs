//! The classical contenders (docs/RESEARCH.md) on a column of circles resting on the ground, whose
//! answer is known: point k from the top carries the weight impulse of the k bodies above
//! it and its own, `k m g dt`.

use deepcontact_core::{
    CarriedWarmStart, ContactId, ContactProblem, Impulse, Observation, PointDesc, ProblemBody,
    SolveReport, SolverSettings, Vector, Velocity, VelocitySolver, WarmStart, WarmStartContext,
    ZeroWarmStart,
};
use deepcontact_pgs::PgsSolver;
use deepcontact_warmstart::{
    AndersonConfig, AndersonWarmStart, BestOfWarmStart, CoarseConfig, CoarseWarmStart,
    ExtrapolatedWarmStart, KrylovConfig, KrylovWarmStart, MIX_MIN_PASSES, PresolveConfig,
    PresolveWarmStart, RelaxedConfig, RelaxedWarmStart, Schedule, ShockWarmStart, TailConfig,
    TailWarmStart,
};

const DT: f64 = 0.01;
const G: f64 = 9.81;
const MASS: f64 = 0.785;

/// `n` unit-diameter circles stacked on fixed ground, each falling at `g dt` before the solve.
fn column(n: usize) -> ContactProblem {
    let mut p = ContactProblem::new();
    add_column(&mut p, n, 0.0);
    p
}

/// A [`column`] of `n` circles standing at abscissa `x`, appended to `p` (its ground, bodies
/// and points after those already there).
fn add_column(p: &mut ContactProblem, n: usize, x: f64) {
    let ground = p.add_body(ProblemBody::fixed(Vector::new(x, -0.5)));
    let mut below = ground;
    for k in 0..n {
        let y = 0.5 + k as f64;
        let body = p.add_body(ProblemBody::dynamic(
            Vector::new(x, y),
            0.0,
            Vector::new(0.0, -G * DT),
            0.0,
            MASS,
            MASS / 8.0,
        ));
        p.begin_manifold();
        let desc = PointDesc::new(below, body, Vector::new(x, y - 0.5), Vector::new(0.0, 1.0))
            .id(ContactId {
                body_a: below,
                body_b: body,
                ..ContactId::default()
            })
            .friction(0.5);
        p.add_point(&desc).unwrap();
        below = body;
    }
}

/// The exact answer of [`column`]: the bottom point holds all n bodies.
fn exact(n: usize) -> Vec<Impulse> {
    (0..n)
        .map(|k| Impulse::new((n - k) as f64 * MASS * G * DT, 0.0))
        .collect()
}

fn solve(problem: &ContactProblem, start: &[Impulse]) -> (Vec<Impulse>, SolveReport) {
    let mut lambda = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    let settings = SolverSettings::default();
    PgsSolver::new()
        .solve(
            problem,
            &settings,
            &mut lambda,
            &mut velocities,
            &mut report,
        )
        .unwrap();
    (lambda, report)
}

/// Exactly `n` PGS sweeps from `start` (tolerance 0).
fn pgs_sweeps(problem: &ContactProblem, start: &[Impulse], n: u32) -> Vec<Impulse> {
    let mut lambda = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let settings = SolverSettings {
        max_iterations: n,
        tolerance: 0.0,
        ..SolverSettings::default()
    };
    PgsSolver::new()
        .solve(
            problem,
            &settings,
            &mut lambda,
            &mut velocities,
            &mut SolveReport::default(),
        )
        .unwrap();
    lambda
}

/// A column of `n` circles and carried impulses a quarter short of its load (loads from
/// before more bodies landed on top: the smooth error PGS is slow at), with the answer.
fn short_of_load(n: usize) -> (ContactProblem, Vec<Impulse>, Vec<Option<Impulse>>) {
    let answer = exact(n);
    let carried = answer
        .iter()
        .map(|i| Some(Impulse::new(0.75 * i.normal, 0.0)))
        .collect();
    (column(n), answer, carried)
}

fn start_of(
    provider: &mut dyn WarmStart,
    problem: &ContactProblem,
    carried: &[Option<Impulse>],
    step: u64,
) -> Vec<Impulse> {
    let ctx = WarmStartContext::new(problem, carried, step, DT);
    let mut out = vec![Impulse::ZERO; problem.len()];
    provider.warm_start(&ctx, &mut out).unwrap();
    out
}

fn observe(
    provider: &mut dyn WarmStart,
    problem: &ContactProblem,
    carried: &[Option<Impulse>],
    step: u64,
    start: &[Impulse],
) -> Vec<Impulse> {
    let (solved, report) = solve(problem, start);
    let ctx = WarmStartContext::new(problem, carried, step, DT);
    provider.observe(&ctx, &Observation::new(start, &solved, false, &report));
    solved
}

/// The first island of `scene` after 60 steps of carried impulses and PGS (under `budget`
/// passes): a tower at rest.
fn resting_island(scene: deepcontact_core::scene::Scene, budget: Option<u32>) -> ContactProblem {
    let settings = deepcontact_core::WorldSettings {
        budget,
        ..deepcontact_core::WorldSettings::default()
    };
    let mut world = scene.build(settings).unwrap();
    let (mut solver, mut position) = (PgsSolver::new(), deepcontact_pgs::PgsPositionSolver::new());
    for _ in 0..60 {
        world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .unwrap();
    }
    world.last_problems()[0].clone()
}

#[test]
fn shock_propagation_finds_the_loads_of_a_column_from_nothing() {
    let problem = column(6);
    let mut shock = ShockWarmStart::new(0.5).unwrap();
    let start = start_of(&mut shock, &problem, &[None; 6], 0);
    for (got, want) in start.iter().zip(exact(6)) {
        assert!(
            (got.normal - want.normal).abs() < 1e-12,
            "{got:?} vs {want:?}"
        );
    }
    // Already at the answer: PGS stops after its first sweep.
    assert_eq!(solve(&problem, &start).1.iterations, 1);
}

#[test]
fn shock_splits_a_bridges_weight_between_the_columns_it_rests_on() {
    // Two columns of 3 circles, then a bridge resting on both tops: each top circle's points
    // (its support, then the bridge's, after the other column's) are apart in the list.
    let (n, x) = (3, 2.0);
    let mut problem = ContactProblem::new();
    add_column(&mut problem, n, 0.0);
    add_column(&mut problem, n, x);
    let tops = [n as u32, 2 * n as u32 + 1];
    let bridge = problem.add_body(ProblemBody::dynamic(
        Vector::new(0.5 * x, n as f64 + 0.5),
        0.0,
        Vector::new(0.0, -G * DT),
        0.0,
        MASS,
        MASS / 8.0,
    ));
    for (k, top) in tops.into_iter().enumerate() {
        problem.begin_manifold();
        let at = Vector::new(k as f64 * x, n as f64);
        let id = ContactId {
            body_a: top,
            body_b: bridge,
            feature_a: k as u64,
            ..ContactId::default()
        };
        let desc = PointDesc::new(top, bridge, at, Vector::new(0.0, 1.0))
            .id(id)
            .friction(0.5);
        problem.add_point(&desc).unwrap();
    }
    let start = start_of(
        &mut ShockWarmStart::new(0.5).unwrap(),
        &problem,
        &vec![None; problem.len()],
        0,
    );
    // Point k of a column (0 at the bottom) holds the n − k circles above it and half the
    // bridge; each of the bridge's points, half the bridge.
    let load = |bodies: f64| bodies * MASS * G * DT;
    let mut want: Vec<f64> = (0..n).map(|k| load((n - k) as f64 + 0.5)).collect();
    want.extend_from_within(..);
    want.extend([load(0.5); 2]);
    assert_eq!(start.len(), want.len());
    for (got, want) in start.iter().zip(want) {
        assert!((got.normal - want).abs() < 1e-12, "{got:?} vs {want}");
    }
}

#[test]
fn shock_blends_with_carried_impulses() {
    let problem = column(2);
    let carried = [Some(Impulse::ZERO), Some(Impulse::ZERO)];
    let start = start_of(
        &mut ShockWarmStart::new(0.25).unwrap(),
        &problem,
        &carried,
        1,
    );
    assert!((start[0].normal - 0.25 * exact(2)[0].normal).abs() < 1e-12);
    assert!(ShockWarmStart::new(1.5).is_err());
}

#[test]
fn extrapolate_continues_each_contact_linearly_and_alpha_zero_is_builtin() {
    let problem = column(3);
    let mut ex = ExtrapolatedWarmStart::new(0.5).unwrap();
    let old = [Some(Impulse::new(0.01, 0.0)); 3];
    let start = start_of(&mut ex, &problem, &old, 0);
    let solved = observe(&mut ex, &problem, &old, 0, &start);
    let carried: Vec<_> = solved.iter().map(|s| Some(*s)).collect();
    let next = start_of(&mut ex, &problem, &carried, 1);
    for ((n, s), o) in next.iter().zip(&solved).zip(old) {
        let want = s.normal + 0.5 * (s.normal - o.unwrap().normal);
        assert!((n.normal - want).abs() < 1e-15);
    }
    let mut zero_alpha = ExtrapolatedWarmStart::new(0.0).unwrap();
    let start = start_of(&mut zero_alpha, &problem, &old, 0);
    observe(&mut zero_alpha, &problem, &old, 0, &start);
    assert_eq!(
        start_of(&mut zero_alpha, &problem, &carried, 1),
        start_of(&mut CarriedWarmStart, &problem, &carried, 1)
    );
    assert!(ExtrapolatedWarmStart::new(f64::NAN).is_err());
}

#[test]
fn krylov_corrects_a_carried_start_that_misses_the_load() {
    let (problem, answer, carried) = short_of_load(8);
    let mut krylov = KrylovWarmStart::new(KrylovConfig::default()).unwrap();
    let start = start_of(&mut krylov, &problem, &carried, 1);
    let from_carried = solve(
        &problem,
        &start_of(&mut CarriedWarmStart, &problem, &carried, 1),
    );
    let from_krylov = solve(&problem, &start);
    for (got, want) in start.iter().zip(&answer) {
        assert!(
            (got.normal - want.normal).abs() < 1e-9,
            "{got:?} vs {want:?}"
        );
    }
    assert!(from_krylov.1.iterations < from_carried.1.iterations);
    for (iterations, rounds) in [(0, 1), (10_001, 1), (10, 0), (10, 101)] {
        let config = KrylovConfig {
            iterations,
            rounds,
            ..KrylovConfig::default()
        };
        assert!(KrylovWarmStart::new(config).is_err());
    }
    // A second round from the corrected start keeps the exact answer.
    let two = KrylovConfig {
        rounds: 2,
        ..KrylovConfig::default()
    };
    let again = start_of(
        &mut KrylovWarmStart::new(two).unwrap(),
        &problem,
        &carried,
        1,
    );
    for (got, want) in again.iter().zip(&answer) {
        assert!((got.normal - want.normal).abs() < 1e-9);
    }
}

#[test]
fn best_of_keeps_the_candidate_with_the_smaller_residual() {
    let problem = column(4);
    let carried: Vec<_> = exact(4).into_iter().map(Some).collect();
    let mut best =
        BestOfWarmStart::new(vec![Box::new(ZeroWarmStart), Box::new(CarriedWarmStart)]).unwrap();
    let start = start_of(&mut best, &problem, &carried, 1);
    assert_eq!(start, exact(4));
    let shares = best.diagnostics();
    assert_eq!(shares[1], ("share_builtin".to_string(), 1.0));
    assert!(BestOfWarmStart::new(Vec::new()).is_err());
}

#[test]
fn tail_without_extrapolation_carries_the_converged_answer() {
    let problem = column(5);
    let config = TailConfig {
        sweeps: 2000,
        extrapolate: false,
        ..TailConfig::default()
    };
    let mut tail = TailWarmStart::new(Box::new(PgsSolver::new()), config).unwrap();
    let none = [None; 5];
    let start = start_of(&mut tail, &problem, &none, 0);
    observe(&mut tail, &problem, &none, 0, &start);
    let carried = [Some(Impulse::ZERO); 5];
    let next = start_of(&mut tail, &problem, &carried, 1);
    for (got, want) in next.iter().zip(exact(5)) {
        assert!(
            (got.normal - want.normal).abs() < 1e-9,
            "{got:?} vs {want:?}"
        );
    }
    let bad = TailConfig {
        max_rate: 1.0,
        ..TailConfig::default()
    };
    assert!(TailWarmStart::new(Box::new(PgsSolver::new()), bad).is_err());
    let endless = TailConfig {
        sweeps: 4_000_000_000,
        ..TailConfig::default()
    };
    assert!(TailWarmStart::new(Box::new(PgsSolver::new()), endless).is_err());
}

/// A box on the ground on three collinear points, spinning so that only one point is fast
/// enough for restitution: `W_AA` is singular (six rows, three velocities) and the restitution
/// bias is not a velocity of the box, so `W_AA Δ = r` has no solution.
fn spinning_box_on_three_points() -> ContactProblem {
    let mut p = ContactProblem::new();
    let ground = p.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
    let body = p.add_body(ProblemBody::dynamic(
        Vector::new(0.0, 0.5),
        0.0,
        Vector::new(0.0, -1.0),
        2.0,
        1.0,
        1.0 / 6.0,
    ));
    for (k, x) in [-0.5, 0.0, 0.5].into_iter().enumerate() {
        p.begin_manifold();
        let desc = PointDesc::new(ground, body, Vector::new(x, 0.0), Vector::new(0.0, 1.0))
            .id(ContactId {
                body_a: ground,
                body_b: body,
                feature_a: k as u64,
                feature_b: 0,
            })
            .friction(0.5)
            .restitution(0.5, 1.5);
        p.add_point(&desc).unwrap();
    }
    p
}

#[test]
fn regression_krylov_blew_up_to_1e26_on_a_singular_island_without_a_solution() {
    let problem = spinning_box_on_three_points();
    let biased = problem
        .points
        .iter()
        .filter(|p| p.velocity_bias > 0.0)
        .count();
    assert_eq!(biased, 1, "the bias must not be a velocity of the box");
    let carried = vec![Some(Impulse::new(0.1, 0.0)); 3];
    for config in [
        KrylovConfig::default(),
        KrylovConfig {
            iterations: 100,
            ..KrylovConfig::default()
        },
    ] {
        let start = start_of(
            &mut KrylovWarmStart::new(config).unwrap(),
            &problem,
            &carried,
            1,
        );
        // The box's momentum change is at most a few N·s: so is any sensible start.
        for s in &start {
            assert!(s.normal.abs() < 10.0 && s.tangent.abs() < 10.0, "{start:?}");
        }
    }
}

#[test]
fn presolve_with_newton_reaches_the_column_answer_and_pgs_stops_at_once() {
    let (problem, answer, carried) = short_of_load(8);
    let mut presolve = PresolveWarmStart::new(
        Box::new(deepcontact_lcp::NewtonSolver::new()),
        PresolveConfig::default(),
    )
    .unwrap();
    let start = start_of(&mut presolve, &problem, &carried, 1);
    assert!(presolve.last_report().iterations <= PresolveConfig::default().iterations);
    for (got, want) in start.iter().zip(&answer) {
        assert!(
            (got.normal - want.normal).abs() < 1e-9,
            "{got:?} vs {want:?}"
        );
    }
    let from_carried = solve(
        &problem,
        &start_of(&mut CarriedWarmStart, &problem, &carried, 1),
    );
    let from_presolve = solve(&problem, &start);
    assert!(from_presolve.1.iterations <= 2, "{:?}", from_presolve.1);
    assert!(from_carried.1.iterations > 10 * from_presolve.1.iterations);
}

#[test]
fn presolve_spends_at_most_its_iterations_and_rejects_bad_settings() {
    let problem = column(8);
    let carried = vec![None; 8];
    // One PGS sweep from zeros as the inner solve: exactly one sweep, never more.
    let config = PresolveConfig {
        iterations: 1,
        tolerance: 0.0,
    };
    let mut presolve = PresolveWarmStart::new(Box::new(PgsSolver::new()), config).unwrap();
    let start = start_of(&mut presolve, &problem, &carried, 0);
    assert_eq!(presolve.last_report().iterations, 1);
    assert_eq!(start, pgs_sweeps(&problem, &[Impulse::ZERO; 8], 1));
    // An empty island costs nothing.
    let empty = ContactProblem::new();
    assert!(start_of(&mut presolve, &empty, &[], 0).is_empty());
    for (iterations, tolerance) in [(0, 1e-6), (10_001, 1e-6), (3, -1.0), (3, f64::NAN)] {
        let config = PresolveConfig {
            iterations,
            tolerance,
        };
        assert!(PresolveWarmStart::new(Box::new(PgsSolver::new()), config).is_err());
    }
}

/// Over-relaxed sweeps (`sor`) move the smooth load error of a column faster than
/// Gauss-Seidel: from a start that misses a quarter of the load, the world's PGS needs far
/// fewer iterations after them, and fewer sweeps in all (provider's and world's) than from
/// the carried start; with ω = 1 they are plain PGS sweeps, bit for bit.
#[test]
fn over_relaxed_sweeps_cut_the_world_iterations_and_the_total() {
    let (problem, _, carried) = short_of_load(12);
    let from_carried = solve(
        &problem,
        &start_of(&mut CarriedWarmStart, &problem, &carried, 1),
    );
    let mut sor = RelaxedWarmStart::new(RelaxedConfig::default()).unwrap();
    let start = start_of(&mut sor, &problem, &carried, 1);
    let sweeps = sor.last_report().iterations;
    let from_sor = solve(&problem, &start);
    assert!(
        from_sor.1.iterations * 4 < from_carried.1.iterations,
        "{} after sor vs {} from carried",
        from_sor.1.iterations,
        from_carried.1.iterations
    );
    assert!(sweeps + from_sor.1.iterations < from_carried.1.iterations);
    let diagnostics = sor.diagnostics();
    assert_eq!(
        diagnostics[0],
        ("mean_sweeps".to_string(), f64::from(sweeps))
    );

    // ω = 1: the same as the world's own sweeps.
    let plain = RelaxedConfig {
        omega: 1.0,
        sweeps: 7,
        tolerance: 0.0,
        pairs: 1.0,
        budget_omega: 2.0,
        max_points: usize::MAX,
        schedule: Schedule::NONE,
        ..RelaxedConfig::default()
    };
    let start = start_of(
        &mut RelaxedWarmStart::new(plain).unwrap(),
        &problem,
        &carried,
        1,
    );
    let carried_start: Vec<Impulse> = carried.iter().map(|c| c.unwrap()).collect();
    assert_eq!(start, pgs_sweeps(&problem, &carried_start, 7));
    assert!(start_of(&mut sor, &ContactProblem::new(), &[], 2).is_empty());
    for (omega, sweeps, tolerance, pairs) in [
        (0.9, 10, 1e-4, 1.0),
        (2.0, 10, 1e-4, 1.0),
        (f64::NAN, 10, 1e-4, 1.0),
        (1.5, 0, 1e-4, 1.0),
        (1.5, 100_001, 1e-4, 1.0),
        (1.5, 10, -1.0, 1.0),
        (1.5, 10, 1e-4, 0.9),
        (1.5, 10, 1e-4, 2.0),
        (1.5, 10, 1e-4, f64::NAN),
    ] {
        let config = RelaxedConfig {
            omega,
            sweeps,
            tolerance,
            pairs,
            budget_omega: 2.0,
            max_points: usize::MAX,
            schedule: Schedule::NONE,
            ..RelaxedConfig::default()
        };
        assert!(RelaxedWarmStart::new(config).is_err(), "{config:?}");
    }
}

/// Relaxing the friction rows of box faces (two-point manifolds, whose normals go through the
/// block solver) made the first step of a box pyramid diverge to 1e74 N·s and the pyramid
/// fly apart. Only single-point manifolds are relaxed now, and diverging sweeps are dropped.
#[test]
fn regression_sor_blew_up_a_box_pyramid() {
    use deepcontact_core::{WorldSettings, scene};
    use deepcontact_pgs::PgsPositionSolver;
    let mut world = scene::pyramid(10).build(WorldSettings::default()).unwrap();
    let mut sor = RelaxedWarmStart::new(RelaxedConfig::default()).unwrap();
    let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
    let mut contacts = 0;
    for _ in 0..40 {
        let report = world.step(&mut sor, &mut solver, &mut position).unwrap();
        assert!(
            report.natural_residual < 1e-2,
            "step {}: natural residual {:e}",
            report.step,
            report.natural_residual
        );
        contacts = report.contacts;
    }
    // Still a pyramid resting on its 55 box faces and the ground (not scattered bodies).
    assert!(contacts > 150, "{contacts} contacts left");
}

/// `sor` refines any provider's start (`sor:start=…`): with ω = 1 from zeros it is plain PGS
/// from zeros, whatever was carried; from `shock`'s exact loads of a column with nothing
/// carried, the sweeps stop after their first and hand those loads on.
#[test]
fn sor_refines_the_start_of_another_provider() {
    let (problem, _, carried) = short_of_load(12);
    let plain = RelaxedConfig {
        omega: 1.0,
        sweeps: 7,
        tolerance: 0.0,
        pairs: 1.0,
        budget_omega: 2.0,
        max_points: usize::MAX,
        schedule: Schedule::NONE,
        ..RelaxedConfig::default()
    };
    let mut from_zeros = RelaxedWarmStart::new(plain)
        .unwrap()
        .with_start(Box::new(ZeroWarmStart));
    assert_eq!(
        start_of(&mut from_zeros, &problem, &carried, 1),
        pgs_sweeps(&problem, &[Impulse::ZERO; 12], 7)
    );
    assert!(format!("{from_zeros:?}").contains("none"));

    let column = column(6);
    let mut from_shock = RelaxedWarmStart::new(RelaxedConfig::default())
        .unwrap()
        .with_start(Box::new(ShockWarmStart::new(0.5).unwrap()));
    let start = start_of(&mut from_shock, &column, &[None; 6], 0);
    assert_eq!(from_shock.last_report().iterations, 1);
    for (got, want) in start.iter().zip(exact(6)) {
        assert!(
            (got.normal - want.normal).abs() < 1e-9,
            "{got:?} vs {want:?}"
        );
    }
}

/// `pairs` relaxes box faces: split into over-relaxed point rows, a settling box pyramid's
/// world solve needs a third fewer iterations (at least) than from the block-kept sweeps, every step ends
/// near a solution and the pyramid stands. Under a pass budget the pairs stay blocks: the
/// same bits as `pairs = 1`.
#[test]
fn sor_pairs_relax_box_faces_and_keep_a_pyramid_standing() {
    use deepcontact_core::{StepReport, WorldSettings, scene};
    use deepcontact_pgs::PgsPositionSolver;
    let run = |pairs: f64, budget: Option<u32>| -> Vec<StepReport> {
        let settings = WorldSettings {
            budget,
            ..WorldSettings::default()
        };
        let mut world = scene::pyramid(10).build(settings).unwrap();
        let config = RelaxedConfig {
            pairs,
            ..RelaxedConfig::default()
        };
        let mut sor = RelaxedWarmStart::new(config).unwrap();
        let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
        (0..60)
            .map(|_| world.step(&mut sor, &mut solver, &mut position).unwrap())
            .collect()
    };
    let iterations = |reports: &[StepReport]| -> u64 {
        reports
            .iter()
            .map(|r| u64::from(r.velocity_iterations))
            .sum()
    };
    let (blocks, split) = (run(1.0, None), run(1.3, None));
    for r in &split {
        assert!(
            r.natural_residual < 1e-2,
            "step {}: natural residual {:e}",
            r.step,
            r.natural_residual
        );
    }
    let contacts = split.last().unwrap().contacts;
    assert!(contacts > 150, "{contacts} contacts left");
    let (b, s) = (iterations(&blocks), iterations(&split));
    assert!(
        3 * s < 2 * b,
        "world iterations: {s} after split pairs against {b} after blocks (3 704 against 6 986 when written)"
    );
    let (b8, s8) = (run(1.0, Some(8)), run(1.3, Some(8)));
    let bits = |reports: &[StepReport]| -> Vec<u64> {
        reports
            .iter()
            .map(|r| r.natural_residual.to_bits())
            .collect()
    };
    assert_eq!(bits(&b8), bits(&s8), "under a budget the pairs stay blocks");
}

/// `budget_omega` caps the factors under a pass budget only: capped at 1, ω = 1.7's sweeps
/// are plain PGS's (the bits of ω = 1) at K = 8, and without a budget the cap is not applied.
#[test]
fn sor_budget_omega_caps_the_factors_under_a_budget_only() {
    use deepcontact_core::{WorldSettings, scene};
    use deepcontact_pgs::PgsPositionSolver;
    let run = |omega: f64, budget_omega: f64, budget: Option<u32>| -> Vec<u64> {
        let settings = WorldSettings {
            budget,
            ..WorldSettings::default()
        };
        let mut world = scene::pile(100, 100).unwrap().build(settings).unwrap();
        let config = RelaxedConfig {
            omega,
            budget_omega,
            ..RelaxedConfig::default()
        };
        let mut sor = RelaxedWarmStart::new(config).unwrap();
        let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
        let mut contact_steps = 0;
        let bits = (0..80)
            .map(|_| {
                let r = world.step(&mut sor, &mut solver, &mut position).unwrap();
                contact_steps += usize::from(r.contacts > 0);
                r.natural_residual.to_bits()
            })
            .collect();
        assert!(contact_steps > 30, "{contact_steps} steps with contacts");
        bits
    };
    assert_eq!(run(1.7, 1.0, Some(8)), run(1.0, 2.0, Some(8)));
    assert_ne!(run(1.7, 2.0, Some(8)), run(1.0, 2.0, Some(8)));
    assert_eq!(run(1.7, 1.0, None), run(1.7, 2.0, None));
}

/// Under a pass budget `mix_below` hands the towers' islands (boxes on boxes: no single-point
/// rows) to Anderson-mixed single sweeps, the bits of `anderson:sweeps=1,window=3`; the
/// island of a tower under a box 100 times heavier than the rest (`heavy_ratio`) and the
/// tolerance mode keep the relaxed sweeps, bit for bit.
#[test]
fn sor_mix_below_mixes_the_towers_under_a_budget_and_spares_the_heavy_box() {
    use deepcontact_core::{WorldSettings, scene};
    use deepcontact_pgs::PgsPositionSolver;
    let tower = |heavy: bool| {
        let params = scene::StackParams {
            count: if heavy { 5 } else { 10 },
            ratio: 100.0,
            jitter: 0.01,
            ..scene::StackParams::default()
        };
        if heavy {
            scene::ratio_stack(100, &params).unwrap()
        } else {
            scene::stack_with(100, &params).unwrap()
        }
    };
    let run = |provider: &mut dyn WarmStart, heavy: bool, budget: Option<u32>| -> Vec<u64> {
        let settings = WorldSettings {
            budget,
            ..WorldSettings::default()
        };
        let mut world = tower(heavy).build(settings).unwrap();
        let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
        let mut contact_steps = 0;
        let bits = (0..60)
            .map(|_| {
                let r = world.step(provider, &mut solver, &mut position).unwrap();
                contact_steps += usize::from(r.contacts > 0);
                r.natural_residual.to_bits()
            })
            .collect();
        assert!(contact_steps > 30, "{contact_steps} steps with contacts");
        bits
    };
    let sor = |mix_below: f64| {
        RelaxedWarmStart::new(RelaxedConfig {
            mix_below,
            ..RelaxedConfig::default()
        })
        .unwrap()
    };
    let mixed = |provider: &RelaxedWarmStart| {
        provider
            .diagnostics()
            .into_iter()
            .find(|(name, _)| name == "mixed")
            .map(|(_, v)| v)
            .unwrap()
    };
    let mut mixing = sor(0.15);
    assert_ne!(
        run(&mut mixing, false, Some(8)),
        run(&mut sor(0.0), false, Some(8))
    );
    assert!(mixed(&mixing) > 30.0, "{} islands mixed", mixed(&mixing));
    // The resting towers' islands: every point in a box face. The even tower's start is
    // Anderson's; under the heavy box the island keeps the relaxed sweeps.
    let resting = |heavy: bool| {
        let island = resting_island(tower(heavy), Some(8));
        assert!(
            island.manifolds.iter().all(|&(a, b)| b == a + 2),
            "box faces only"
        );
        island
    };
    let budgeted = |provider: &mut dyn WarmStart, island: &ContactProblem, passes: u32| {
        let carried = vec![None; island.len()];
        let ctx = WarmStartContext::new(island, &carried, 1, DT).with_pass_budget(passes);
        let mut out = vec![Impulse::ZERO; island.len()];
        provider.warm_start(&ctx, &mut out).unwrap();
        let bits: Vec<u64> = out
            .iter()
            .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
            .collect();
        (bits, provider.passes_spent())
    };
    let mut anderson = AndersonWarmStart::new(AndersonConfig {
        sweeps: 1,
        window: 3,
        ..AndersonConfig::default()
    })
    .unwrap();
    let even = resting(false);
    let (ours, theirs) = (
        budgeted(&mut sor(0.15), &even, 7),
        budgeted(&mut anderson, &even, 7),
    );
    assert!(ours.1 > 1, "{} mixed sweeps", ours.1);
    assert_eq!(ours, theirs);
    // Three passes leave no room for a mixed step: the relaxed sweeps run.
    let mut short = sor(0.15);
    assert_eq!(
        budgeted(&mut short, &even, MIX_MIN_PASSES - 1),
        budgeted(&mut sor(0.0), &even, MIX_MIN_PASSES - 1)
    );
    assert_eq!(mixed(&short), 0.0);
    let heavy = resting(true);
    let mut spared = sor(0.15);
    assert_eq!(
        budgeted(&mut spared, &heavy, 7),
        budgeted(&mut sor(0.0), &heavy, 7)
    );
    assert_eq!(mixed(&spared), 0.0);
    // Without a budget nothing is mixed.
    let mut unmixed = sor(0.15);
    assert_eq!(
        run(&mut unmixed, false, None),
        run(&mut sor(0.0), false, None)
    );
    assert_eq!(mixed(&unmixed), 0.0);
    for config in [
        RelaxedConfig {
            mix_below: 1.5,
            ..RelaxedConfig::default()
        },
        RelaxedConfig {
            heavy_ratio: 0.5,
            ..RelaxedConfig::default()
        },
    ] {
        assert!(RelaxedWarmStart::new(config).is_err(), "{config:?}");
    }
}

/// Under a pass budget `heavy_alpha` starts a heavy island (masses more than `heavy_ratio`
/// apart) from the extrapolated impulses and leaves the whole budget to the solver: on the
/// resting island of a tower under a box 100 times heavier, the start of `extrapolate` at the
/// same weight, no sweeps; in a world, other bits than without it under a budget, and the same
/// bits without a budget.
#[test]
fn sor_heavy_alpha_starts_heavy_towers_from_the_extrapolation_under_a_budget() {
    use deepcontact_core::{WorldSettings, scene};
    use deepcontact_pgs::PgsPositionSolver;
    let tower = || {
        let params = scene::StackParams {
            count: 5,
            ratio: 100.0,
            jitter: 0.01,
            ..scene::StackParams::default()
        };
        scene::ratio_stack(100, &params).unwrap()
    };
    let sor = |heavy_alpha: f64| {
        RelaxedWarmStart::new(RelaxedConfig {
            heavy_alpha,
            ..RelaxedConfig::default()
        })
        .unwrap()
    };
    let count = |provider: &RelaxedWarmStart, what: &str| {
        provider
            .diagnostics()
            .into_iter()
            .find(|(name, _)| name == what)
            .map(|(_, v)| v)
            .unwrap()
    };
    // The resting island, two steps of starts and solves.
    let island = resting_island(tower(), None);
    assert_eq!(island.bodies.iter().filter(|b| b.inv_mass > 0.0).count(), 5);
    let starts = |provider: &mut dyn WarmStart| {
        let mut carried = vec![None; island.len()];
        let mut all = Vec::new();
        for step in 1..4 {
            let ctx = WarmStartContext::new(&island, &carried, step, DT).with_pass_budget(7);
            let mut out = vec![Impulse::ZERO; island.len()];
            provider.warm_start(&ctx, &mut out).unwrap();
            assert_eq!(provider.passes_spent(), 0, "no sweeps");
            all.extend(
                out.iter()
                    .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()]),
            );
            // The next step carries a tenth more load than this one's solve; the solve is
            // observed under the same budget, as the world observes it.
            let (solved, report) = solve(&island, &out);
            provider.observe(&ctx, &Observation::new(&out, &solved, false, &report));
            carried = solved
                .iter()
                .map(|i| Some(Impulse::new(1.1 * i.normal, i.tangent)))
                .collect();
        }
        all
    };
    let mut heavy = sor(0.25);
    let ours = starts(&mut heavy);
    assert_eq!(ours, starts(&mut ExtrapolatedWarmStart::new(0.25).unwrap()));
    assert_ne!(ours, starts(&mut CarriedWarmStart));
    assert_eq!(count(&heavy, "extrapolated"), 3.0);
    // In the world: under a budget it changes the run, without one it does not.
    let run = |provider: &mut dyn WarmStart, budget: Option<u32>| -> Vec<u64> {
        let settings = WorldSettings {
            budget,
            ..WorldSettings::default()
        };
        let mut world = tower().build(settings).unwrap();
        let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
        (0..60)
            .map(|_| {
                let r = world.step(provider, &mut solver, &mut position).unwrap();
                r.natural_residual.to_bits()
            })
            .collect()
    };
    let mut budgeted = sor(0.25);
    assert_ne!(run(&mut budgeted, Some(8)), run(&mut sor(0.0), Some(8)));
    assert!(count(&budgeted, "extrapolated") > 30.0);
    let mut unbudgeted = sor(0.25);
    assert_eq!(run(&mut unbudgeted, None), run(&mut sor(0.0), None));
    assert_eq!(count(&unbudgeted, "extrapolated"), 0.0);
    for heavy_alpha in [-0.5, f64::NAN] {
        let config = RelaxedConfig {
            heavy_alpha,
            ..RelaxedConfig::default()
        };
        assert!(RelaxedWarmStart::new(config).is_err(), "{config:?}");
    }
}

/// A schedule's factors run in equal shares of the sweeps: one factor is the constant factor bit
/// for bit; under a budget of 8 two factors spend the provider's 7 passes (3 at the first, 4 at
/// the second, one relaxed copy each), and a schedule that ends at ω = 1 leaves other bits than
/// either constant.
#[test]
fn sor_schedule_runs_its_factors_in_equal_shares_of_the_sweeps() {
    use deepcontact_core::{WorldSettings, scene};
    use deepcontact_pgs::PgsPositionSolver;
    let run = |omega: f64, schedule: &[f64]| -> (Vec<u64>, Vec<u32>) {
        let settings = WorldSettings {
            budget: Some(8),
            ..WorldSettings::default()
        };
        let mut world = scene::pile(100, 100).unwrap().build(settings).unwrap();
        let config = RelaxedConfig {
            omega,
            tolerance: 0.0,
            schedule: if schedule.is_empty() {
                Schedule::NONE
            } else {
                Schedule::new("sor", schedule).unwrap()
            },
            ..RelaxedConfig::default()
        };
        let mut sor = RelaxedWarmStart::new(config).unwrap();
        let (mut solver, mut position) = (PgsSolver::new(), PgsPositionSolver::new());
        let (mut bits, mut passes) = (Vec::new(), Vec::new());
        for _ in 0..80 {
            let r = world.step(&mut sor, &mut solver, &mut position).unwrap();
            bits.push(r.natural_residual.to_bits());
            if r.contacts > 0 {
                passes.push(sor.passes_spent());
            }
        }
        assert!(passes.len() > 30, "{} steps with contacts", passes.len());
        (bits, passes)
    };
    let constant = run(1.5, &[]);
    assert_eq!(
        run(1.9, &[1.5]),
        constant,
        "one factor is the constant factor"
    );
    let (bits, passes) = run(1.5, &[1.8, 1.0]);
    assert!(passes.iter().all(|&p| p == 7), "{passes:?}");
    assert_ne!(bits, constant.0);
    assert_ne!(bits, run(1.8, &[]).0);
    // The shares' edges: the sweeps of 1.8 then 1.0 are those of a 3-sweep ω = 1.8 provider
    // followed by 4 plain PGS sweeps.
    let (problem, _, carried) = short_of_load(12);
    let scheduled = RelaxedConfig {
        tolerance: 0.0,
        sweeps: 7,
        schedule: Schedule::new("sor", &[1.8, 1.0]).unwrap(),
        ..RelaxedConfig::default()
    };
    let first = RelaxedConfig {
        omega: 1.8,
        tolerance: 0.0,
        sweeps: 3,
        ..RelaxedConfig::default()
    };
    let mut sor = RelaxedWarmStart::new(scheduled).unwrap();
    let start = start_of(&mut sor, &problem, &carried, 1);
    assert_eq!(sor.passes_spent(), 7);
    let three = start_of(
        &mut RelaxedWarmStart::new(first).unwrap(),
        &problem,
        &carried,
        1,
    );
    assert_eq!(start, pgs_sweeps(&problem, &three, 4));
}

#[test]
fn anderson_loads_a_column_in_fewer_passes_than_pgs_from_the_carried_start() {
    // A 20-circle column a quarter short of its load: PGS from the carried impulses moves
    // the missing load down one contact a sweep; the accelerated sweeps find it sooner, and
    // PGS from their start stops at once.
    let (problem, answer, carried) = short_of_load(20);
    let mut anderson = AndersonWarmStart::new(AndersonConfig::default()).unwrap();
    let start = start_of(&mut anderson, &problem, &carried, 1);
    let passes = anderson.passes_spent();
    let from_carried = solve(
        &problem,
        &start_of(&mut CarriedWarmStart, &problem, &carried, 1),
    );
    let from_anderson = solve(&problem, &start);
    assert!(
        passes > AndersonConfig::default().sweeps,
        "{passes} passes: no mixing ran"
    );
    let total = passes + from_anderson.1.iterations;
    assert!(
        total < from_carried.1.iterations,
        "{passes} + {} passes vs {} from the carried start",
        from_anderson.1.iterations,
        from_carried.1.iterations
    );
    // Ends at least as close to the column's answer as PGS from the carried start does.
    let error = |solved: &[Impulse]| {
        solved
            .iter()
            .zip(&answer)
            .map(|(got, want)| (got.normal - want.normal).abs())
            .fold(0.0, f64::max)
    };
    let (ours, theirs) = (error(&from_anderson.0), error(&from_carried.0));
    assert!(
        ours <= theirs,
        "error {ours:e} vs {theirs:e} from the carried start"
    );
    println!(
        "passes {passes} + {}, carried {}, error {ours:e} vs {theirs:e}",
        from_anderson.1.iterations, from_carried.1.iterations
    );
    for config in [
        AndersonConfig {
            window: 0,
            ..AndersonConfig::default()
        },
        AndersonConfig {
            window: 17,
            ..AndersonConfig::default()
        },
        AndersonConfig {
            sweeps: 0,
            ..AndersonConfig::default()
        },
        AndersonConfig {
            rounds: 0,
            ..AndersonConfig::default()
        },
        AndersonConfig {
            tolerance: f64::NAN,
            ..AndersonConfig::default()
        },
        AndersonConfig {
            omega: 0.0,
            ..AndersonConfig::default()
        },
        AndersonConfig {
            omega: 2.0,
            ..AndersonConfig::default()
        },
    ] {
        assert!(AndersonWarmStart::new(config).is_err(), "{config:?}");
    }
}

#[test]
fn anderson_omega_sweeps_the_single_point_rows_over_relaxed() {
    // One evaluation of G (one sweep, one round): the start is that sweep's image, which with
    // ω = 1.5 is one plain sweep of the island whose point rows carry 1.5 × their effective
    // masses, and not one plain sweep of the island itself. The bodies slide at different
    // speeds, so that the friction rows work too.
    let (mut problem, _, carried) = short_of_load(12);
    for (k, b) in problem.bodies.iter_mut().enumerate() {
        if b.inv_mass > 0.0 {
            b.linear_velocity.x = 0.02 * k as f64;
        }
    }
    let carried_start: Vec<Impulse> = carried.iter().map(|c| c.unwrap()).collect();
    let one_sweep = |omega: f64| {
        let mut anderson = AndersonWarmStart::new(AndersonConfig {
            sweeps: 1,
            rounds: 1,
            omega,
            ..AndersonConfig::default()
        })
        .unwrap();
        let start = start_of(&mut anderson, &problem, &carried, 1);
        assert_eq!(anderson.passes_spent(), 1, "one sweep ran");
        start
    };
    let mut relaxed = problem.clone();
    assert!(
        problem.manifolds.iter().all(|&(s, e)| e == s + 1),
        "a column of single-point manifolds"
    );
    for p in &mut relaxed.points {
        p.normal_mass *= 1.5;
        p.tangent_mass *= 1.5;
    }
    let bits = |v: &[Impulse]| -> Vec<u64> {
        v.iter()
            .flat_map(|i| [i.normal.to_bits(), i.tangent.to_bits()])
            .collect()
    };
    let over = one_sweep(1.5);
    assert_eq!(bits(&over), bits(&pgs_sweeps(&relaxed, &carried_start, 1)));
    assert_ne!(bits(&over), bits(&pgs_sweeps(&problem, &carried_start, 1)));
    assert_eq!(
        bits(&one_sweep(1.0)),
        bits(&pgs_sweeps(&problem, &carried_start, 1))
    );

    // A box face (one two-point manifold, swept as a block) is left as it is.
    let mut face = ContactProblem::new();
    let ground = face.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
    let body = face.add_body(ProblemBody::dynamic(
        Vector::new(0.0, 0.5),
        0.0,
        Vector::new(0.01, -1.0),
        0.0,
        1.0,
        1.0 / 6.0,
    ));
    face.begin_manifold();
    for (k, x) in [-0.5, 0.5].into_iter().enumerate() {
        let desc = PointDesc::new(ground, body, Vector::new(x, 0.0), Vector::new(0.0, 1.0))
            .id(ContactId {
                body_a: ground,
                body_b: body,
                feature_a: k as u64,
                feature_b: 0,
            })
            .friction(0.5);
        face.add_point(&desc).unwrap();
    }
    assert_eq!(face.manifolds, vec![(0, 2)], "one two-point manifold");
    let none = vec![Some(Impulse::new(0.1, 0.0)); 2];
    let mut anderson = AndersonWarmStart::new(AndersonConfig {
        sweeps: 1,
        rounds: 1,
        omega: 1.5,
        ..AndersonConfig::default()
    })
    .unwrap();
    let start = start_of(&mut anderson, &face, &none, 1);
    assert_eq!(
        bits(&start),
        bits(&pgs_sweeps(&face, &[Impulse::new(0.1, 0.0); 2], 1))
    );
}

/// `coarse`'s start from `carried` after one round of one sweep, the correction and one sweep,
/// its groups cells `width` wide (infinite: whole layers).
fn one_coarse_round(
    width: f64,
    problem: &ContactProblem,
    carried: &[Option<Impulse>],
) -> Vec<Impulse> {
    let config = CoarseConfig {
        rounds: 1,
        sweeps: 1,
        width,
        ..CoarseConfig::default()
    };
    let mut coarse = CoarseWarmStart::new(config).unwrap();
    let start = start_of(&mut coarse, problem, carried, 1);
    assert_eq!(coarse.passes_spent(), 3, "a sweep, the correction, a sweep");
    start
}

#[test]
fn coarse_layers_carry_a_column_its_missing_load_in_one_correction() {
    // One contact a layer (unit spacing, 1 m layers): the coarse problem is the column's
    // whole normal system, so one correction finds the loads and PGS from there stops at
    // once (to the coarse solve's regularisation, 1e-9 of the diagonal); from the carried
    // start PGS needs hundreds of sweeps.
    let (problem, answer, carried) = short_of_load(20);
    let start = one_coarse_round(f64::INFINITY, &problem, &carried);
    for (got, want) in start.iter().zip(&answer) {
        assert!(
            (got.normal - want.normal).abs() < 1e-6,
            "{got:?} vs {want:?}"
        );
    }
    let from_coarse = solve(&problem, &start);
    let from_carried = solve(
        &problem,
        &start_of(&mut CarriedWarmStart, &problem, &carried, 1),
    );
    assert_eq!(from_coarse.1.iterations, 1);
    assert!(
        from_carried.1.iterations > 100,
        "{}",
        from_carried.1.iterations
    );
    for config in [
        CoarseConfig {
            layer: 0.0,
            ..CoarseConfig::default()
        },
        CoarseConfig {
            layer: f64::NAN,
            ..CoarseConfig::default()
        },
        CoarseConfig {
            sweeps: 0,
            ..CoarseConfig::default()
        },
        CoarseConfig {
            rounds: 0,
            ..CoarseConfig::default()
        },
    ] {
        assert!(CoarseWarmStart::new(config).is_err(), "{config:?}");
    }
}

/// Two [`column`]s of `n` bodies, 3 m apart, in one problem (the second's points after the
/// first's), the first carried a quarter short of its load and the second a quarter over.
fn two_columns_short_and_over(n: usize) -> (ContactProblem, Vec<Impulse>, Vec<Option<Impulse>>) {
    let mut p = ContactProblem::new();
    let mut carried = Vec::new();
    for (x, share) in [(0.0, 0.75), (3.0, 1.25)] {
        add_column(&mut p, n, x);
        carried.extend(
            exact(n)
                .iter()
                .map(|i| Some(Impulse::new(share * i.normal, 0.0))),
        );
    }
    let answer = [exact(n), exact(n)].concat();
    (p, answer, carried)
}

#[test]
fn coarse_cells_carry_two_columns_their_loads_where_layers_cannot() {
    // One layer spans both columns, one short and one over: its one unknown cannot correct
    // both. Cells 1 m wide give each column's layer its own unknown: one correction finds
    // both columns' loads (to the coarse solve's regularisation).
    let (problem, answer, carried) = two_columns_short_and_over(10);
    let worst = |width| {
        one_coarse_round(width, &problem, &carried)
            .iter()
            .zip(&answer)
            .map(|(got, want)| (got.normal - want.normal).abs())
            .fold(0.0, f64::max)
    };
    let (cells, layers) = (worst(1.0), worst(f64::INFINITY));
    assert!(cells < 1e-6, "cells leave an error of {cells:e}");
    assert!(layers > 1e-3, "layers leave an error of only {layers:e}");
    for width in [0.0, -1.0, f64::NAN] {
        let config = CoarseConfig {
            width,
            ..CoarseConfig::default()
        };
        assert!(CoarseWarmStart::new(config).is_err(), "{config:?}");
    }
}

#[test]
fn coarse_cells_far_narrower_than_the_island_do_not_overflow_the_cell_count() {
    // 3 m of island over 1e-300 m cells: 3e300 columns, beyond any integer; the cells grow
    // until at most 256 fit (the build before counted them in `usize`, wrapped to none and
    // panicked on an empty cell index).
    let (problem, _, carried) = two_columns_short_and_over(4);
    let start = one_coarse_round(1e-300, &problem, &carried);
    assert!(
        start
            .iter()
            .all(|i| i.normal.is_finite() && i.normal >= 0.0)
    );
}

#[test]
fn sor_gives_islands_above_max_points_the_start_unswept() {
    // An 8-point column: with room for 8 points the sweeps run; with room for 7 the island
    // gets the carried impulses as they are, no pass spent, and the gate is counted.
    let (problem, _, carried) = short_of_load(8);
    let with = |max_points| {
        let config = RelaxedConfig {
            max_points,
            ..RelaxedConfig::default()
        };
        let mut sor = RelaxedWarmStart::new(config).unwrap();
        let start = start_of(&mut sor, &problem, &carried, 1);
        let gated = sor
            .diagnostics()
            .into_iter()
            .find(|(k, _)| k == "gated")
            .map(|(_, v)| v);
        (start, sor.passes_spent(), gated)
    };
    let (swept, passes, gated) = with(8);
    assert!(passes > 0, "no sweep ran");
    assert_eq!(gated, Some(0.0));
    let carried_start: Vec<Impulse> = carried.iter().map(|c| c.unwrap()).collect();
    assert_ne!(swept, carried_start, "the sweeps changed nothing");
    let (kept, passes, gated) = with(7);
    assert_eq!(passes, 0);
    assert_eq!(gated, Some(1.0));
    assert_eq!(kept, carried_start);
}
