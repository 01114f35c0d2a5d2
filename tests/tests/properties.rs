//! Property tests of every velocity solver on random small contact problems built through
//! the public builders (`ContactProblem::add_body` / `begin_manifold` / `add_point`):
//!
//! * the impulses are admissible: `λn ≥ 0`, `|λt| ≤ μ λn`;
//! * a solve that reports convergence met its stop rule, and its natural-map residual is small;
//! * the converged **velocities** do not depend on the warm start (impulses may: redundant
//!   contacts make them indeterminate, but the velocities of a monotone problem are unique).
//!
//! Solvers: PGS (coloured and sequential order), PSOR and semismooth Newton.

use deepcontact_core::Velocity;

use deepcontact_core::math::Real;
use deepcontact_core::{
    ContactId, ContactProblem, Impulse, PointDesc, ProblemBody, SolveReport, SolverSettings,
    Vector, VelocitySolver,
};
use deepcontact_lcp::{NewtonSolver, PsorSolver};
use deepcontact_pgs::{Ordering, PgsSettings, PgsSolver};
use proptest::prelude::*;

/// One dynamic body: position, velocity, angular velocity, log10 of inverse mass and inertia.
#[derive(Debug, Clone)]
struct BodyGen {
    pos: (Real, Real),
    vel: (Real, Real),
    omega: Real,
    log_inv_mass: Real,
    log_inv_inertia: Real,
}

/// One point: body selectors, normal angle, anchor offset from body B, friction, and whether
/// it joins the previous point's manifold (same pair, same normal) as a second point.
#[derive(Debug, Clone)]
struct PointGen {
    a: usize,
    b: usize,
    angle: Real,
    offset: (Real, Real),
    friction: Real,
    restitution: Real,
    second: bool,
}

fn body_gen() -> impl Strategy<Value = BodyGen> {
    (
        (-2.0..2.0, -2.0..2.0),
        (-3.0..3.0, -3.0..3.0),
        -3.0..3.0,
        -0.5..0.5,
        -0.5..0.5,
    )
        .prop_map(|(pos, vel, omega, log_inv_mass, log_inv_inertia)| BodyGen {
            pos,
            vel,
            omega,
            log_inv_mass,
            log_inv_inertia,
        })
}

fn point_gen(max_friction: Real) -> impl Strategy<Value = PointGen> {
    (
        0usize..64,
        0usize..64,
        0.0..std::f64::consts::TAU,
        (-0.6..0.6, -0.6..0.6),
        0.0..=max_friction,
        prop_oneof![3 => Just(0.0), 1 => 0.0..1.0],
        any::<bool>(),
    )
        .prop_map(
            |(a, b, angle, offset, friction, restitution, second)| PointGen {
                a,
                b,
                angle,
                offset,
                friction,
                restitution,
                second,
            },
        )
}

/// 2–6 bodies (body 0 static), 1–8 points.
fn problem_gen(max_friction: Real) -> impl Strategy<Value = ContactProblem> {
    (
        prop::collection::vec(body_gen(), 1..=5),
        prop::collection::vec(point_gen(max_friction), 1..=8),
    )
        .prop_map(|(bodies, points)| build_problem(&bodies, &points))
}

fn build_problem(bodies: &[BodyGen], points: &[PointGen]) -> ContactProblem {
    let mut p = ContactProblem::new();
    p.add_body(ProblemBody {
        world_index: u32::MAX,
        position: Vector::new(0.0, -1.0),
        angle: 0.0,
        linear_velocity: Vector::zeros(),
        angular_velocity: 0.0,
        inv_mass: 0.0,
        inv_inertia: 0.0,
    });
    for b in bodies {
        p.add_body(ProblemBody {
            world_index: u32::MAX,
            position: Vector::new(b.pos.0, b.pos.1),
            angle: 0.0,
            linear_velocity: Vector::new(b.vel.0, b.vel.1),
            angular_velocity: b.omega,
            inv_mass: 10f64.powf(b.log_inv_mass),
            inv_inertia: 10f64.powf(b.log_inv_inertia),
        });
    }
    let n = p.bodies.len();
    let mut prev: Option<(u32, u32, Vector, Real)> = None;
    let mut in_manifold = 0;
    for (k, g) in points.iter().enumerate() {
        let (a, b, normal, friction) = match prev {
            Some(prev) if g.second && in_manifold == 1 => prev,
            _ => {
                // B is dynamic; A is any other body (static or dynamic).
                let b = 1 + g.b % (n - 1);
                let mut a = g.a % n;
                if a == b {
                    a = 0;
                }
                p.begin_manifold();
                in_manifold = 0;
                let normal = Vector::new(g.angle.cos(), g.angle.sin());
                (a as u32, b as u32, normal, g.friction)
            }
        };
        let at = p.bodies[b as usize].position + Vector::new(g.offset.0, g.offset.1);
        let id = ContactId {
            body_a: a.min(b),
            body_b: a.max(b),
            feature_a: k as u64,
            feature_b: 0,
        };
        p.add_point(&PointDesc {
            id,
            body_a: a,
            body_b: b,
            point: at,
            normal,
            separation: -0.01,
            friction,
            restitution: g.restitution,
            restitution_threshold: 1.0,
        })
        .unwrap();
        in_manifold += 1;
        prev = Some((a, b, normal, friction));
    }
    p.validate().expect("generated problems are valid");
    p
}

const SOLVERS: [&str; 4] = [
    "pgs:order=coloured",
    "pgs:order=sequential",
    "psor",
    "newton",
];

fn solver(name: &str) -> Box<dyn VelocitySolver> {
    match name {
        "pgs:order=coloured" => Box::new(PgsSolver::new()),
        "pgs:order=sequential" => Box::new(PgsSolver::with_settings(PgsSettings {
            ordering: Ordering::Sequential,
            ..Default::default()
        })),
        "psor" => Box::new(PsorSolver::new()),
        "newton" => Box::new(NewtonSolver::new()),
        _ => unreachable!(),
    }
}

/// The warm starts: none, an admissible random one (like `builtin` after a step), an
/// inadmissible random one (like `random`), and `bad` (50, 50).
fn starts(problem: &ContactProblem, u: &[Real]) -> [(&'static str, Vec<Impulse>); 4] {
    let n = problem.len();
    let r = |i: usize| u[i % u.len()];
    let admissible = (0..n)
        .map(|i| {
            let normal = 5.0 * r(2 * i);
            let mu = problem.points[i].friction;
            Impulse::new(normal, (2.0 * r(2 * i + 1) - 1.0) * mu * normal)
        })
        .collect();
    let random = (0..n)
        .map(|i| Impulse::new(5.0 * r(3 * i + 7), 4.0 * r(3 * i + 8) - 2.0))
        .collect();
    [
        ("none", vec![Impulse::ZERO; n]),
        ("builtin-like", admissible),
        ("random", random),
        ("bad", vec![Impulse::new(50.0, 50.0); n]),
    ]
}

struct Outcome {
    impulses: Vec<Impulse>,
    velocities: Vec<Velocity>,
    report: SolveReport,
}

fn solve(
    name: &str,
    problem: &ContactProblem,
    settings: &SolverSettings,
    start: &[Impulse],
) -> Outcome {
    let mut impulses = start.to_vec();
    let mut velocities = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    solver(name)
        .solve(
            problem,
            settings,
            &mut impulses,
            &mut velocities,
            &mut report,
        )
        .unwrap_or_else(|e| panic!("{name}: {e}"));
    Outcome {
        impulses,
        velocities,
        report,
    }
}

fn check_admissible(
    name: &str,
    start: &str,
    problem: &ContactProblem,
    out: &Outcome,
) -> Result<(), TestCaseError> {
    for (i, (imp, p)) in out.impulses.iter().zip(&problem.points).enumerate() {
        prop_assert!(imp.is_finite(), "{name}/{start}: point {i} {imp:?}");
        prop_assert!(
            imp.normal >= 0.0,
            "{name}/{start}: point {i} λn = {}",
            imp.normal
        );
        prop_assert!(
            imp.tangent.abs() <= p.friction * imp.normal * (1.0 + 1e-9) + 1e-12,
            "{name}/{start}: point {i} |λt| = {} > μ λn = {}",
            imp.tangent.abs(),
            p.friction * imp.normal
        );
    }
    for (b, v) in out.velocities.iter().enumerate() {
        prop_assert!(
            v.linear.x.is_finite() && v.linear.y.is_finite() && v.angular.is_finite(),
            "{name}/{start}: body {b} velocity {v:?}"
        );
    }
    Ok(())
}

fn check_report(
    name: &str,
    start: &str,
    settings: &SolverSettings,
    r: &SolveReport,
) -> Result<(), TestCaseError> {
    prop_assert!(r.iterations >= 1 && r.iterations <= settings.max_iterations);
    prop_assert_eq!(r.residual_inf.len(), r.iterations as usize);
    prop_assert_eq!(r.residual_l2.len(), r.iterations as usize);
    prop_assert!(r.natural_residual.is_finite() && r.natural_residual >= 0.0);
    if r.converged {
        prop_assert!(
            r.final_residual() < settings.tolerance,
            "{name}/{start}: converged with residual {}",
            r.final_residual()
        );
    } else {
        prop_assert_eq!(r.iterations, settings.max_iterations, "{}/{}", name, start);
    }
    Ok(())
}

/// Largest velocity difference over the bodies, relative to the size of the velocities.
fn velocity_gap(a: &[Velocity], b: &[Velocity]) -> Real {
    a.iter()
        .zip(b)
        .map(|(x, y)| {
            (x.linear - y.linear)
                .norm()
                .max((x.angular - y.angular).abs())
        })
        .fold(0.0, Real::max)
}

fn uniform_list() -> impl Strategy<Value = Vec<Real>> {
    prop::collection::vec(0.0..1.0, 24)
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: 32,
        max_shrink_iters: 64,
        // A fixed seed: CI sees the same cases every run (failures are still persisted).
        rng_seed: proptest::test_runner::RngSeed::Fixed(0x5eed_d33c),
        ..ProptestConfig::default()
    })]

    /// Every solver, from every start, under the default stop rule (cap 1000, 1e-4):
    /// admissible impulses, a consistent report.
    #[test]
    fn impulses_are_admissible_from_every_start(problem in problem_gen(1.0), u in uniform_list()) {
        let settings = SolverSettings::default();
        for name in SOLVERS {
            for (start, warm) in starts(&problem, &u) {
                let out = solve(name, &problem, &settings, &warm);
                check_admissible(name, start, &problem, &out)?;
                check_report(name, start, &settings, &out.report)?;
            }
        }
    }

    /// Solved tightly, every solver reaches the same velocities from every start.
    /// Frictionless (μ = 0) problems: a convex QP, unique velocities. With friction
    /// (even μ ≤ 0.3) the velocities are NOT unique in general: proptest found PGS
    /// (coloured) converged to 1e-9 from `bad` and from `none` with velocities 0.043 m/s
    /// apart on a 6-point problem — the Coulomb problem is not monotone.
    #[test]
    fn converged_velocities_do_not_depend_on_the_warm_start(
        problem in problem_gen(0.0),
        u in uniform_list(),
    ) {
        let settings = SolverSettings { max_iterations: 2_000, tolerance: 1e-9, ..Default::default() };
        let scale = problem
            .bodies
            .iter()
            .map(|b| b.linear_velocity.norm().max(b.angular_velocity.abs()))
            .fold(1.0, Real::max);
        let tol = 1e-6 * scale * (1.0 + problem.len() as Real);
        let mut reference: Option<(String, Vec<Velocity>)> = None;
        for name in SOLVERS {
            // Newton converges in a few iterations or not at all: a small cap keeps it cheap.
            let settings = if name == "newton" {
                SolverSettings { max_iterations: 50, ..settings }
            } else {
                settings
            };
            for (start, warm) in starts(&problem, &u) {
                let out = solve(name, &problem, &settings, &warm);
                check_admissible(name, start, &problem, &out)?;
                check_report(name, start, &settings, &out.report)?;
                if !out.report.converged {
                    continue;
                }
                prop_assert!(
                    out.report.natural_residual < 1e-6,
                    "{name}/{start}: converged but natural residual {}",
                    out.report.natural_residual
                );
                match &reference {
                    None => reference = Some((format!("{name}/{start}"), out.velocities)),
                    Some((who, v)) => {
                        let gap = velocity_gap(v, &out.velocities);
                        prop_assert!(
                            gap <= tol,
                            "{name}/{start} vs {who}: velocities differ by {gap:e} (tolerance {tol:e})"
                        );
                    }
                }
            }
        }
        // Badly conditioned draws may converge for no solver within the caps; they say
        // nothing about uniqueness, so they are discarded rather than failed.
        prop_assume!(reference.is_some(), "no solver converged from any start");
    }
}
