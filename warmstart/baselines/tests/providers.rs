//! Each baseline provider's output on a hand-built problem.

mod common;

use deepcontact_core::Velocity;

use deepcontact_core::warm_start::check_output;
use deepcontact_core::{
    ContactProblem, Impulse, SolveReport, SolverSettings, VelocitySolver, WarmStart,
    WarmStartContext, WarmStartError,
};
use deepcontact_pgs::PgsSolver;
use deepcontact_warmstart::{
    ConstantWarmStart, OracleConfig, OracleOrder, OracleWarmStart, RandomConfig, RandomWarmStart,
    Rounded,
};

fn provide(provider: &mut dyn WarmStart, problem: &ContactProblem) -> Vec<Impulse> {
    let carried = vec![None; problem.len()];
    let ctx = WarmStartContext::new(problem, &carried, 1, 0.01);
    let mut out = vec![Impulse::ZERO; problem.len()];
    provider.warm_start(&ctx, &mut out).unwrap();
    check_output(&out, problem.len()).unwrap();
    out
}

/// Solves `problem` with PGS from `start` under the world's default stop rule.
fn solve_from(problem: &ContactProblem, start: &[Impulse]) -> (Vec<Impulse>, SolveReport) {
    let mut impulses = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    PgsSolver::new()
        .solve(
            problem,
            &SolverSettings::default(),
            &mut impulses,
            &mut velocities,
            &mut report,
        )
        .unwrap();
    (impulses, report)
}

#[test]
fn random_is_in_range_seeded_and_reproducible() {
    let problem = common::column(6);
    let config = RandomConfig {
        seed: 3,
        ..RandomConfig::default()
    };
    let a = provide(&mut RandomWarmStart::new(config).unwrap(), &problem);
    let b = provide(&mut RandomWarmStart::new(config).unwrap(), &problem);
    let c = provide(
        &mut RandomWarmStart::new(RandomConfig { seed: 4, ..config }).unwrap(),
        &problem,
    );
    assert_eq!(a.len(), 6);
    assert_eq!(a, b, "same seed, same values");
    assert_ne!(a, c, "different seeds differ");
    for imp in &a {
        assert!((0.0..5.0).contains(&imp.normal), "{imp:?}");
        assert!((-2.0..2.0).contains(&imp.tangent), "{imp:?}");
    }
    // The stream advances: a second call gives new values.
    let mut p = RandomWarmStart::new(config).unwrap();
    let first = provide(&mut p, &problem);
    let second = provide(&mut p, &problem);
    assert_ne!(first, second);

    // Ranges are configurable through the registry.
    let mut p = common::registry()
        .build_provider("random:seed=9,normal_min=1,normal_max=2,tangent_max=0.5")
        .unwrap();
    for imp in provide(&mut p, &problem) {
        assert!(
            (1.0..2.0).contains(&imp.normal) && (-0.5..0.5).contains(&imp.tangent),
            "{imp:?}"
        );
    }
    assert!(
        RandomWarmStart::new(RandomConfig {
            normal_min: 3.0,
            normal_max: 1.0,
            ..config
        })
        .is_err()
    );
    assert!(
        RandomWarmStart::new(RandomConfig {
            tangent_max: -1.0,
            ..config
        })
        .is_err()
    );
}

#[test]
fn bad_is_constant_and_configurable() {
    let problem = common::column(3);
    let r = common::registry();
    let out = provide(&mut r.build_provider("bad").unwrap(), &problem);
    assert_eq!(out, vec![Impulse::new(50.0, 50.0); 3]);
    let out = provide(&mut r.build_provider("bad:value=10").unwrap(), &problem);
    assert_eq!(out, vec![Impulse::new(10.0, 10.0); 3]);
    let out = provide(
        &mut r.build_provider("bad:value=10,tangent=-1").unwrap(),
        &problem,
    );
    assert_eq!(out, vec![Impulse::new(10.0, -1.0); 3]);
    assert_eq!(
        provide(&mut ConstantWarmStart::bad(), &problem),
        vec![ConstantWarmStart::BAD; 3]
    );
    assert!(ConstantWarmStart::new("c", Impulse::new(-1.0, 0.0)).is_err());
    assert!(ConstantWarmStart::new("c", Impulse::new(1.0, f64::NAN)).is_err());
}

#[test]
fn copy_is_the_converged_solution_and_the_next_solve_is_nearly_free() {
    let problem = common::column(8);
    let mut oracle = OracleWarmStart::pgs();
    let start = provide(&mut oracle, &problem);
    assert!(oracle.last_report().converged);
    assert!(oracle.last_report().final_residual() < 1e-6);

    let (cold_solution, cold) = solve_from(&problem, &vec![Impulse::ZERO; problem.len()]);
    let (warm_solution, warm) = solve_from(&problem, &start);
    assert!(
        warm.iterations <= 3,
        "copy start took {} iterations",
        warm.iterations
    );
    assert!(
        cold.iterations > warm.iterations,
        "cold {} vs copy {}",
        cold.iterations,
        warm.iterations
    );
    for ((s, w), c) in start.iter().zip(&warm_solution).zip(&cold_solution) {
        assert!((s.normal - w.normal).abs() < 1e-5 && (s.tangent - w.tangent).abs() < 1e-5);
        assert!((s.normal - c.normal).abs() < 1e-2, "{s:?} vs {c:?}");
    }
    // The column's weight is carried: the bottom point holds the most.
    assert!(start[0].normal > start[7].normal && start[7].normal > 0.0);
    assert!(
        start[7].tangent.abs() > 0.0,
        "the sliding top ball has friction"
    );

    // A tiny cap is honoured (the oracle does not converge, but still answers).
    let solver = Box::new(PgsSolver::new());
    let mut capped = OracleWarmStart::new(
        solver,
        OracleConfig {
            tolerance: 0.0,
            max_iterations: 2,
            ..OracleConfig::default()
        },
    )
    .unwrap();
    provide(&mut capped, &problem);
    assert_eq!(capped.last_report().iterations, 2);
    let solver = Box::new(PgsSolver::new());
    assert!(
        OracleWarmStart::new(
            solver,
            OracleConfig {
                tolerance: -1.0,
                max_iterations: 2,
                ..OracleConfig::default()
            }
        )
        .is_err()
    );
}

#[test]
fn copy_in_another_order_answers_each_point_for_itself() {
    // A column is statically determinate: every order reaches the same impulses, so a
    // point answered with another point's impulse would show.
    let problem = common::column(8);
    let registry = baseline_registry();
    let world = provide(&mut OracleWarmStart::pgs(), &problem);
    for spec in ["copy:order=reversed", "copy:order=shuffled,order_seed=3"] {
        let mut oracle = registry.build_provider(spec).unwrap();
        let out = provide(oracle.as_mut(), &problem);
        assert_ne!(out, world, "{spec}: the same order");
        for (o, w) in out.iter().zip(&world) {
            assert!((o.normal - w.normal).abs() < 1e-4, "{spec}: {o:?} vs {w:?}");
        }
        // Deterministic: after a reset (a new world) the same answers again.
        oracle.reset();
        assert_eq!(provide(oracle.as_mut(), &problem), out, "{spec}");
    }
    let config = OracleConfig {
        order: OracleOrder::Shuffled(3),
        ..OracleConfig::default()
    };
    let mut oracle = OracleWarmStart::new(Box::new(PgsSolver::new()), config).unwrap();
    assert_eq!(oracle.config().order, OracleOrder::Shuffled(3));
    // Shuffles are drawn afresh per solve: the second differs from the first.
    let first = provide(&mut oracle, &problem);
    let second = provide(&mut oracle, &problem);
    assert_ne!(first, second);
    assert!(registry.build_provider("copy:order=sideways").is_err());
}

/// The baseline providers and the PGS solver.
fn baseline_registry() -> deepcontact_core::Registry {
    let mut registry = deepcontact_core::Registry::empty();
    deepcontact_pgs::register(&mut registry);
    deepcontact_warmstart::register(&mut registry);
    registry
}

#[test]
fn copy_rejects_a_wrong_output_length() {
    let problem = common::column(2);
    let ctx = WarmStartContext::new(&problem, &[], 0, 0.01);
    let mut out = vec![Impulse::ZERO; 1];
    let err = OracleWarmStart::pgs()
        .warm_start(&ctx, &mut out)
        .unwrap_err();
    assert_eq!(
        err,
        WarmStartError::WrongLength {
            expected: 2,
            got: 1
        }
    );
}

/// Writes fixed values, to test the rounding wrapper on awkward inputs.
struct Fixed(Vec<Impulse>);

impl WarmStart for Fixed {
    fn name(&self) -> &str {
        "fixed"
    }
    fn warm_start(
        &mut self,
        _ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        out.copy_from_slice(&self.0);
        Ok(())
    }
}

#[test]
fn rounding_wrapper_rounds_clamps_and_drops_negative_zero() {
    let problem = common::column(4);
    let values = vec![
        Impulse::new(1.23456, -0.98765),
        Impulse::new(0.4, -0.3),
        Impulse::new(2.5, 2.5),
        Impulse::new(0.0, -0.0),
    ];
    let carried = vec![None; 4];
    let ctx = WarmStartContext::new(&problem, &carried, 0, 0.01);
    let mut out = vec![Impulse::ZERO; 4];

    let mut two = Rounded::new(Fixed(values.clone()), 2).unwrap();
    assert_eq!(two.name(), "fixed2");
    two.warm_start(&ctx, &mut out).unwrap();
    assert_eq!(out[0], Impulse::new(1.23, -0.99));
    assert_eq!(out[1], Impulse::new(0.4, -0.3));

    let mut zero = Rounded::new(Fixed(values), 0).unwrap();
    zero.warm_start(&ctx, &mut out).unwrap();
    assert_eq!(
        out,
        vec![
            Impulse::new(1.0, -1.0),
            Impulse::new(0.0, 0.0),
            Impulse::new(3.0, 3.0),
            Impulse::ZERO
        ]
    );
    for imp in &out {
        assert!(
            imp.normal.is_sign_positive() && imp.tangent.is_sign_positive() || imp.tangent < 0.0,
            "{imp:?}"
        );
    }
    assert!(
        out[1].tangent.is_sign_positive(),
        "-0.3 rounds to +0, not -0"
    );
    check_output(&out, 4).unwrap();

    // A slightly negative normal (e.g. from a learned model) is clamped to zero.
    let mut neg = Rounded::new(Fixed(vec![Impulse::new(-0.7, 0.0); 4]), 0).unwrap();
    neg.warm_start(&ctx, &mut out).unwrap();
    assert!(
        out.iter()
            .all(|i| i.normal == 0.0 && i.normal.is_sign_positive())
    );
    // NaN is not hidden: the world's check still sees it.
    let mut nan = Rounded::new(Fixed(vec![Impulse::new(f64::NAN, 0.0); 4]), 2).unwrap();
    nan.warm_start(&ctx, &mut out).unwrap();
    assert!(check_output(&out, 4).is_err());
    assert!(Rounded::new(Fixed(vec![]), 16).is_err());
}

#[test]
fn copy2_and_copy0_are_rounded_copies() {
    let problem = common::column(8);
    let r = common::registry();
    let exact = provide(&mut r.build_provider("copy").unwrap(), &problem);
    for (spec, name, decimals) in [
        ("copy2", "copy2", 2),
        ("copy:decimals=2", "copy2", 2),
        ("copy0", "copy0", 0),
    ] {
        let mut p = r.build_provider(spec).unwrap();
        assert_eq!(p.name(), name);
        let out = provide(&mut p, &problem);
        let scale = 10f64.powi(decimals);
        for (o, e) in out.iter().zip(&exact) {
            assert!(
                (o.normal * scale - (o.normal * scale).round()).abs() < 1e-9,
                "{spec}: {o:?}"
            );
            assert!(
                (o.normal - e.normal).abs() <= 0.5 / scale + 1e-12,
                "{spec}: {o:?} vs {e:?}"
            );
            assert!(
                (o.tangent - e.tangent).abs() <= 0.5 / scale + 1e-12,
                "{spec}: {o:?} vs {e:?}"
            );
        }
    }
}

#[test]
fn copy_in_a_world_makes_every_solve_nearly_free() {
    use deepcontact_core::{WorldSettings, scene};
    let r = common::registry();
    let mut world = scene::pile(7, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    let mut copy = r.build_provider("copy").unwrap();
    let mut solver = r.build_solver("pgs").unwrap();
    let mut position = deepcontact_pgs::PgsPositionSolver::new();
    let mut contact_steps = 0;
    for _ in 0..60 {
        let report = world.step(&mut copy, &mut solver, &mut position).unwrap();
        assert_eq!(report.fallbacks, 0);
        if report.contacts > 0 {
            contact_steps += 1;
            assert!(
                report.velocity_iterations <= 3,
                "step {}: {} iterations",
                report.step,
                report.velocity_iterations
            );
        }
    }
    assert!(
        contact_steps > 10,
        "the pile settles within 60 steps ({contact_steps} contact steps)"
    );
}
