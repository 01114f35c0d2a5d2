//! The core contracts: solvers, warm starts, the output guard, typed errors.

use deepcontact_core::math::Real;
use deepcontact_core::{
    BodyDesc, CarriedWarmStart, ContactProblem, CoreError, GuardPolicy, Impulse, Material,
    Observation, ShapeDesc, SolveReport, SolverSettings, Vector, Velocity, VelocitySolver,
    WarmStart, WarmStartContext, WarmStartError, World, WorldSettings, ZeroWarmStart, scene,
};
use deepcontact_pgs::PgsSolver;
use deepcontact_tests::{build, run};

/// A settled pile's island problems with the impulses carried into them.
fn settled_problems() -> Vec<(ContactProblem, Vec<Impulse>)> {
    struct Grab(Vec<(ContactProblem, Vec<Impulse>)>);
    impl WarmStart for Grab {
        fn name(&self) -> &str {
            "grab"
        }
        fn warm_start(
            &mut self,
            ctx: &WarmStartContext<'_>,
            out: &mut [Impulse],
        ) -> Result<(), WarmStartError> {
            if ctx.step == 160 {
                self.0.push((
                    ctx.problem.clone(),
                    ctx.carried_impulses().collect::<Vec<_>>(),
                ));
            }
            for (o, c) in out.iter_mut().zip(ctx.carried_impulses()) {
                *o = c;
            }
            Ok(())
        }
    }
    let mut world = build(&scene::pile(12345, 100).unwrap());
    let mut grab = Grab(Vec::new());
    run(&mut world, &mut grab, 161, |_, _| {}).unwrap();
    assert!(!grab.0.is_empty());
    grab.0
}

fn solve(
    problem: &ContactProblem,
    start: &[Impulse],
    settings: &SolverSettings,
) -> (Vec<Impulse>, Vec<Velocity>, SolveReport) {
    let mut solver = PgsSolver::new();
    let mut imp = start.to_vec();
    let mut vel = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    solver
        .solve(problem, settings, &mut imp, &mut vel, &mut report)
        .unwrap();
    (imp, vel, report)
}

/// Net contact impulse (linear, angular) on each body of `problem`.
fn net_impulses(problem: &ContactProblem, imp: &[Impulse]) -> Vec<Velocity> {
    let mut net = vec![Velocity::default(); problem.bodies.len()];
    for (p, l) in problem.points.iter().zip(imp) {
        let f = l.normal * p.normal + l.tangent * p.tangent();
        let (a, b) = (p.body_a as usize, p.body_b as usize);
        net[a].linear -= f;
        net[a].angular -= deepcontact_core::math::cross(&p.r_a, &f);
        net[b].linear += f;
        net[b].angular += deepcontact_core::math::cross(&p.r_b, &f);
    }
    net
}

#[test]
fn converged_solves_from_none_and_builtin_agree() {
    let settings = SolverSettings {
        tolerance: 1e-9,
        max_iterations: 200_000,
        ..SolverSettings::default()
    };
    for (problem, carried) in settled_problems() {
        let zeros = vec![Impulse::ZERO; problem.len()];
        let (a, va, ra) = solve(&problem, &zeros, &settings);
        let (b, vb, rb) = solve(&problem, &carried, &settings);
        assert!(
            ra.converged && rb.converged,
            "{} / {} iterations",
            ra.iterations,
            rb.iterations
        );
        // Velocities are unique, and so is each body's net contact impulse Jᵀλ = M(v − v*);
        // the impulses themselves are not (a circle touching three neighbours is statically
        // indeterminate), so the contract is checked on what the physics determines.
        for (v1, v2) in va.iter().zip(&vb) {
            assert!(
                (v1.linear - v2.linear).norm() < 1e-5 && (v1.angular - v2.angular).abs() < 1e-5,
                "velocities differ: {v1:?} {v2:?}"
            );
        }
        let (na, nb) = (net_impulses(&problem, &a), net_impulses(&problem, &b));
        for (i, (x, y)) in na
            .iter()
            .zip(&nb)
            .enumerate()
            .filter(|(i, _)| problem.bodies[*i].inv_mass > 0.0)
        {
            let d = (x.linear - y.linear)
                .norm()
                .max((x.angular - y.angular).abs());
            assert!(d < 1e-4, "body {i}: net impulse differs by {d}");
        }
    }
}

#[test]
fn a_converged_start_needs_one_iteration() {
    let tight = SolverSettings {
        tolerance: 1e-10,
        max_iterations: 200_000,
        ..SolverSettings::default()
    };
    for (problem, _) in settled_problems() {
        let (solution, _, _) = solve(&problem, &vec![Impulse::ZERO; problem.len()], &tight);
        let (_, _, r) = solve(&problem, &solution, &SolverSettings::default());
        assert_eq!(
            r.iterations, 1,
            "restart from the solution took {} iterations",
            r.iterations
        );
        assert!(r.natural_residual < 1e-4);
    }
}

struct Garbage(Impulse);
impl WarmStart for Garbage {
    fn name(&self) -> &str {
        "garbage"
    }
    fn warm_start(
        &mut self,
        _: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        out.fill(self.0);
        Ok(())
    }
}

#[test]
fn garbage_warm_starts_fall_back_to_zero_and_are_counted() {
    for bad in [
        Impulse::new(Real::NAN, 0.0),
        Impulse::new(1.0, Real::INFINITY),
        Impulse::new(-1.0, 0.0),
    ] {
        let mut world = build(&scene::pile(3, 100).unwrap());
        let mut clean = build(&scene::pile(3, 100).unwrap());
        let reports = run(&mut world, &mut Garbage(bad), 120, |_, _| {}).unwrap();
        run(&mut clean, &mut ZeroWarmStart, 120, |_, _| {}).unwrap();
        let islands: usize = reports.iter().map(|r| r.islands).sum();
        let fallbacks: usize = reports.iter().map(|r| r.fallbacks).sum();
        assert!(islands > 0);
        assert_eq!(
            fallbacks, islands,
            "every island should have fallen back for {bad:?}"
        );
        // Falling back to zeros is exactly the cold start.
        assert_eq!(
            deepcontact_tests::state_bits(&world),
            deepcontact_tests::state_bits(&clean)
        );
    }
}

#[test]
fn garbage_warm_start_is_a_typed_error_under_the_error_policy() {
    let settings = WorldSettings {
        guard: GuardPolicy::Error,
        ..WorldSettings::default()
    };
    let mut world = scene::pile(3, 100).unwrap().build(settings).unwrap();
    let err = run(
        &mut world,
        &mut Garbage(Impulse::new(Real::NAN, 0.0)),
        200,
        |_, _| {},
    )
    .unwrap_err();
    match err {
        CoreError::WarmStart {
            provider,
            source: WarmStartError::NonFinite { point: 0, .. },
            ..
        } => {
            assert_eq!(provider, "garbage")
        }
        other => panic!("unexpected error {other}"),
    }
}

#[test]
fn bad_bodies_and_settings_get_typed_errors_naming_the_field() {
    let mut world = World::new(WorldSettings::default()).unwrap();
    let ball = |r: Real| BodyDesc::dynamic(ShapeDesc::Ball { radius: r }, Vector::zeros());
    let err = world.add_body(&ball(-1.0)).unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::InvalidBodyParameter {
                field: "radius",
                ..
            }
        ),
        "{err}"
    );
    let err = world
        .add_body(&ball(0.5).with_material(Material {
            density: Real::NAN,
            ..Material::default()
        }))
        .unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::InvalidBodyParameter {
                field: "density",
                ..
            }
        ),
        "{err}"
    );
    let err = world
        .add_body(&ball(0.5).with_material(Material {
            friction: -0.1,
            ..Material::default()
        }))
        .unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::InvalidBodyParameter {
                field: "friction",
                ..
            }
        ),
        "{err}"
    );
    let poly = ShapeDesc::ConvexPolygon {
        vertices: vec![
            Vector::new(0.0, 0.0),
            Vector::new(1.0, 0.0),
            Vector::new(2.0, 0.0),
        ],
    };
    let err = world
        .add_body(&BodyDesc::dynamic(poly, Vector::zeros()))
        .unwrap_err();
    assert!(matches!(err, CoreError::DegeneratePolygon { .. }), "{err}");
    for dt in [0.0, -0.01, Real::NAN] {
        let err = World::new(WorldSettings {
            dt,
            ..WorldSettings::default()
        })
        .unwrap_err();
        assert!(
            matches!(err, CoreError::InvalidSetting { name: "dt", .. }),
            "{err}"
        );
    }
    for (settings, setting) in [
        (
            WorldSettings {
                island_threads: 0,
                ..WorldSettings::default()
            },
            "island_threads",
        ),
        (
            WorldSettings {
                collide_threads: 0,
                ..WorldSettings::default()
            },
            "collide_threads",
        ),
    ] {
        let err = World::new(settings).unwrap_err();
        assert!(
            matches!(err, CoreError::InvalidSetting { name, .. } if name == setting),
            "{err}"
        );
    }
    let s = SolverSettings {
        max_iterations: 0,
        ..SolverSettings::default()
    };
    assert!(matches!(
        s.validate(),
        Err(CoreError::InvalidSetting {
            name: "max_iterations",
            ..
        })
    ));
    let s = SolverSettings {
        tolerance: -1.0,
        ..SolverSettings::default()
    };
    assert!(matches!(
        s.validate(),
        Err(CoreError::InvalidSetting {
            name: "tolerance",
            ..
        })
    ));
}

#[test]
fn non_finite_state_entering_a_step_is_reported_with_the_body() {
    let mut world = build(&scene::resting_ball());
    world
        .body_mut(deepcontact_core::BodyHandle(1))
        .unwrap()
        .linear_velocity
        .x = Real::NAN;
    let err = run(&mut world, &mut CarriedWarmStart, 1, |_, _| {}).unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::NonFiniteState {
                body: 1,
                field: "linear velocity",
                step: 0
            }
        ),
        "{err}"
    );
}

#[test]
fn malformed_problems_are_rejected_by_the_solver() {
    let (mut problem, _) = settled_problems().swap_remove(0);
    let body_b = problem.points[0].body_b;
    problem.points[0].body_b = 10_000;
    let mut imp = vec![Impulse::ZERO; problem.len()];
    let mut vel = vec![Velocity::default(); problem.bodies.len()];
    let err = PgsSolver::new()
        .solve(
            &problem,
            &SolverSettings::default(),
            &mut imp,
            &mut vel,
            &mut SolveReport::default(),
        )
        .unwrap_err();
    assert!(matches!(err, CoreError::InvalidProblem(_)), "{err}");
    // The problem valid again, the impulses one long: only the length is wrong.
    let mut short = vec![Impulse::ZERO; 1];
    problem.points[0].body_b = body_b;
    problem.validate().unwrap();
    let err = PgsSolver::new()
        .solve(
            &problem,
            &SolverSettings::default(),
            &mut short,
            &mut vel,
            &mut SolveReport::default(),
        )
        .unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::LengthMismatch {
                what: "impulses",
                expected,
                got: 1,
            } if expected == problem.len()
        ),
        "{err}"
    );
}

/// A provider that writes NaN (so every island falls back) and records what the world tells it.
#[derive(Default)]
struct Probe {
    resets: usize,
    gravity: Option<Vector>,
    fell_back: Vec<bool>,
    zero_starts: bool,
}

impl WarmStart for Probe {
    fn name(&self) -> &str {
        "probe"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        self.gravity = Some(ctx.gravity);
        out.fill(Impulse::new(Real::NAN, 0.0));
        Ok(())
    }
    fn observe(&mut self, _ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        self.fell_back.push(seen.fell_back);
        self.zero_starts &= seen.start.iter().all(|i| *i == Impulse::ZERO);
    }
    fn reset(&mut self) {
        self.resets += 1;
    }
}

#[test]
fn observe_sees_the_zero_start_of_a_fallback_and_the_world_resets_the_provider_once() {
    let mut world = build(&scene::pile(12345, 100).unwrap());
    let mut probe = Probe {
        zero_starts: true,
        ..Probe::default()
    };
    let reports = run(&mut world, &mut probe, 45, |_, _| {}).unwrap();
    let fallbacks: usize = reports.iter().map(|r| r.fallbacks).sum();
    assert!(fallbacks > 0, "the pile touches before step 45");
    assert_eq!(probe.fell_back.len(), fallbacks);
    assert!(probe.fell_back.iter().all(|&f| f));
    assert!(
        probe.zero_starts,
        "the start used after a fallback is zeros"
    );
    assert_eq!(probe.resets, 1, "reset before the first step only");
    assert_eq!(probe.gravity, Some(world.settings().gravity));
}

#[test]
fn the_contact_stop_rule_is_pgs_only_and_stops_a_settled_pile() {
    use deepcontact_core::ResidualNorm;
    let contact = SolverSettings {
        norm: ResidualNorm::Contact,
        ..SolverSettings::default()
    };
    let (problem, carried) = settled_problems().into_iter().next().unwrap();
    let (_, _, report) = solve(&problem, &carried, &contact);
    assert!(report.converged && report.iterations >= 1);
    for mut solver in [
        Box::new(deepcontact_lcp::PsorSolver::new()) as Box<dyn VelocitySolver>,
        Box::new(deepcontact_lcp::NewtonSolver::new()),
    ] {
        let mut imp = carried.clone();
        let mut vel = vec![Velocity::default(); problem.bodies.len()];
        let mut r = SolveReport::default();
        let err = solver
            .solve(&problem, &contact, &mut imp, &mut vel, &mut r)
            .unwrap_err();
        assert!(err.to_string().contains("pgs only"), "{err}");
    }
}

/// Starts outside the friction cone: carried normal (0.1 N·s for a new point), tangent
/// `10 λn + 1`, far beyond `μ λn`. Checks in `observe` that the start it sees is the one the
/// solver applied and sums, per step, the squared errors the world's MSE must average.
struct OutsideCone {
    /// Whether the solver clamps the tangent (the start observed must then be clamped).
    projected: bool,
    /// Points whose output tangent left the cone (the case under test was reached).
    outside: usize,
    /// Per step: Σ (start − solved)² of the tangents and the number of points.
    sums: std::collections::BTreeMap<u64, (Real, usize)>,
}

impl OutsideCone {
    fn output(ctx: &WarmStartContext<'_>) -> Vec<Impulse> {
        ctx.carried
            .iter()
            .map(|c| {
                let n = c.map_or(0.1, |c| c.normal);
                Impulse::new(n, 10.0 * n + 1.0)
            })
            .collect()
    }
}

impl WarmStart for OutsideCone {
    fn name(&self) -> &str {
        "outside-cone"
    }
    fn warm_start(
        &mut self,
        ctx: &WarmStartContext<'_>,
        out: &mut [Impulse],
    ) -> Result<(), WarmStartError> {
        out.copy_from_slice(&Self::output(ctx));
        Ok(())
    }
    fn observe(&mut self, ctx: &WarmStartContext<'_>, seen: &Observation<'_>) {
        let sum = self.sums.entry(ctx.step).or_default();
        for ((given, used), (p, solved)) in Self::output(ctx)
            .iter()
            .zip(seen.start)
            .zip(ctx.problem.points.iter().zip(seen.solved))
        {
            let bound = p.friction * given.normal;
            self.outside += usize::from(given.tangent > bound);
            let expected = if self.projected {
                given.tangent.min(bound)
            } else {
                given.tangent
            };
            assert_eq!(used.normal, given.normal);
            assert_eq!(used.tangent, expected, "the start as the solver applied it");
            sum.0 += (used.tangent - solved.tangent).powi(2);
            sum.1 += 1;
        }
    }
}

#[test]
fn the_start_observed_and_measured_is_the_start_projected_onto_the_friction_cone() {
    use deepcontact_pgs::{PgsPositionSolver, PgsSettings};
    for raw_start in [false, true] {
        let mut world = build(&scene::pile(12345, 100).unwrap());
        let mut probe = OutsideCone {
            projected: !raw_start,
            outside: 0,
            sums: Default::default(),
        };
        let mut solvers = (
            PgsSolver::with_settings(PgsSettings {
                raw_start,
                ..PgsSettings::default()
            }),
            PgsPositionSolver::new(),
        );
        let reports =
            deepcontact_tests::run_with(&mut world, &mut probe, &mut solvers, 60, |_, _| {})
                .unwrap();
        assert!(
            probe.outside > 0,
            "starts left the cone (raw_start {raw_start})"
        );
        // The MSE column averages the same starts' errors over the step's points.
        let mut measured = 0;
        for (step, r) in reports.iter().enumerate() {
            let Some(&(sum, points)) = probe.sums.get(&(step as u64)) else {
                continue;
            };
            assert_eq!(r.contacts, points);
            let mse = sum / points as Real;
            assert!(
                (r.mse_tangent - mse).abs() <= 1e-12 * mse.max(1.0),
                "step {step}: mse_tangent {} against {mse} (raw_start {raw_start})",
                r.mse_tangent
            );
            measured += 1;
        }
        assert!(
            measured > 10,
            "steps with contacts were measured: {measured}"
        );
    }
}

#[test]
fn a_step_report_times_its_stages_within_the_step() {
    let mut world = build(&scene::pile(12345, 100).unwrap());
    let mut with_contacts = 0;
    run(&mut world, &mut CarriedWarmStart, 160, |_, r| {
        let stages = [
            ("collide", r.collide_seconds),
            ("islands", r.islands_seconds),
            ("warm start", r.warm_start_seconds),
            ("solve", r.solve_seconds),
            ("position", r.position_seconds),
        ];
        for (stage, seconds) in stages {
            assert!(seconds >= 0.0, "step {}: {stage} {seconds}", r.step);
        }
        assert!(r.collide_seconds > 0.0, "step {}: no collide time", r.step);
        let sum: Real = stages.iter().map(|s| s.1).sum();
        assert!(
            sum <= r.step_seconds,
            "step {}: stages {sum} s in a step of {} s",
            r.step,
            r.step_seconds
        );
        if r.contacts > 0 {
            with_contacts += 1;
            assert!(
                r.islands_seconds > 0.0 && r.position_seconds > 0.0,
                "step {}",
                r.step
            );
        }
    })
    .unwrap();
    assert!(with_contacts > 50, "{with_contacts} steps with contacts");
}
