//! Bad input gives typed errors (never a panic), and the trivial inputs work.

mod common;

use common::{Kind, random_problem, run};
use deepcontact_core::Velocity;
use deepcontact_core::math::Real;
use deepcontact_core::{
    ContactProblem, CoreError, Impulse, SolveReport, SolverSettings, VelocitySolver,
};
use deepcontact_lcp::{
    AssemblyMode, LcpError, NewtonSettings, NewtonSolver, PsorSettings, PsorSolver,
};

fn solvers() -> Vec<Box<dyn VelocitySolver>> {
    vec![Box::new(PsorSolver::new()), Box::new(NewtonSolver::new())]
}

fn solve(
    solver: &mut dyn VelocitySolver,
    p: &ContactProblem,
    settings: &SolverSettings,
    imp: &mut [Impulse],
    bodies: usize,
) -> Result<SolveReport, CoreError> {
    let mut vel = vec![Velocity::default(); bodies];
    let mut report = SolveReport::default();
    solver
        .solve(p, settings, imp, &mut vel, &mut report)
        .map(|_| report)
}

#[test]
fn wrong_buffer_lengths_are_errors() {
    let p = random_problem(3, Kind::Well);
    for mut s in solvers() {
        let mut short = vec![Impulse::ZERO; p.points.len() - 1];
        let e = solve(
            s.as_mut(),
            &p,
            &SolverSettings::default(),
            &mut short,
            p.bodies.len(),
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                CoreError::LengthMismatch {
                    what: "impulses",
                    ..
                }
            ),
            "{e:?}"
        );
        let mut imp = vec![Impulse::ZERO; p.points.len()];
        let e = solve(
            s.as_mut(),
            &p,
            &SolverSettings::default(),
            &mut imp,
            p.bodies.len() + 1,
        )
        .unwrap_err();
        assert!(
            matches!(
                e,
                CoreError::LengthMismatch {
                    what: "velocities",
                    ..
                }
            ),
            "{e:?}"
        );
    }
}

#[test]
fn invalid_problems_and_settings_are_errors() {
    let mut p = random_problem(4, Kind::Well);
    p.points[0].normal.x = Real::NAN;
    for mut s in solvers() {
        let mut imp = vec![Impulse::ZERO; p.points.len()];
        let e = solve(
            s.as_mut(),
            &p,
            &SolverSettings::default(),
            &mut imp,
            p.bodies.len(),
        )
        .unwrap_err();
        assert!(matches!(e, CoreError::InvalidProblem(_)), "{e:?}");
    }
    let p = random_problem(4, Kind::Well);
    let bad = SolverSettings {
        max_iterations: 0,
        ..SolverSettings::default()
    };
    for mut s in solvers() {
        let mut imp = vec![Impulse::ZERO; p.points.len()];
        assert!(solve(s.as_mut(), &p, &bad, &mut imp, p.bodies.len()).is_err());
    }
    for omega in [0.0, 2.0, Real::NAN, -1.0] {
        let mut s = PsorSolver::with_settings(PsorSettings {
            omega,
            ..PsorSettings::default()
        });
        let mut imp = vec![Impulse::ZERO; p.points.len()];
        let e = solve(
            &mut s,
            &p,
            &SolverSettings::default(),
            &mut imp,
            p.bodies.len(),
        )
        .unwrap_err();
        assert!(
            matches!(e, CoreError::InvalidSetting { name: "omega", .. }),
            "{e:?}"
        );
    }
    let bad = [
        NewtonSettings {
            regularization: -1.0,
            ..NewtonSettings::default()
        },
        NewtonSettings {
            max_regularization: 1e-20,
            ..NewtonSettings::default()
        },
        NewtonSettings {
            armijo: 0.7,
            ..NewtonSettings::default()
        },
        NewtonSettings {
            backtrack: 1.0,
            ..NewtonSettings::default()
        },
    ];
    for settings in bad {
        let mut s = NewtonSolver::with_settings(settings);
        let mut imp = vec![Impulse::ZERO; p.points.len()];
        assert!(matches!(
            solve(
                &mut s,
                &p,
                &SolverSettings::default(),
                &mut imp,
                p.bodies.len()
            ),
            Err(CoreError::InvalidSetting { .. })
        ));
    }
}

/// Unvalidated foreign input with a body index out of range: an error, not a panic.
#[test]
fn unvalidated_out_of_range_indices_are_errors() {
    let mut p = random_problem(5, Kind::Well);
    p.points[0].body_b = 99;
    let mut psor = PsorSolver::with_settings(PsorSettings {
        validate: false,
        ..PsorSettings::default()
    });
    let mut newton = NewtonSolver::with_settings(NewtonSettings {
        validate: false,
        ..NewtonSettings::default()
    });
    for s in [&mut psor as &mut dyn VelocitySolver, &mut newton] {
        let mut imp = vec![Impulse::ZERO; p.points.len()];
        let e = solve(s, &p, &SolverSettings::default(), &mut imp, p.bodies.len()).unwrap_err();
        assert!(matches!(e, CoreError::InvalidProblem(_)), "{e:?}");
    }
}

/// Starts outside the cone (negative normals, huge tangents) are fine; non-finite ones are
/// a typed error for Newton and a non-finite error for PSOR (never a panic).
#[test]
fn odd_starts() {
    let p = random_problem(6, Kind::Well);
    let n = p.points.len();
    for mut s in solvers() {
        let mut imp = vec![Impulse::new(-3.0, 40.0); n];
        let r = solve(
            s.as_mut(),
            &p,
            &SolverSettings::default(),
            &mut imp,
            p.bodies.len(),
        )
        .unwrap();
        assert!(r.converged, "{}", s.name());
        assert!(
            imp.iter()
                .all(|i| i.normal >= 0.0 && i.tangent.abs() <= 1.0 * i.normal + 1e-12)
        );
        let mut imp = vec![Impulse::new(Real::NAN, 0.0); n];
        let e = solve(
            s.as_mut(),
            &p,
            &SolverSettings::default(),
            &mut imp,
            p.bodies.len(),
        )
        .unwrap_err();
        assert!(matches!(e, CoreError::Solver { .. }), "{}: {e:?}", s.name());
    }
    let mut newton = NewtonSolver::new();
    let mut imp = vec![Impulse::new(Real::INFINITY, 0.0); n];
    let mut vel = vec![Velocity::default(); p.bodies.len()];
    let e = newton
        .solve_lcp(
            &p,
            &SolverSettings::default(),
            &mut imp,
            &mut vel,
            &mut SolveReport::default(),
        )
        .unwrap_err();
    assert!(
        matches!(
            e,
            LcpError::NonFinite {
                what: "start impulse",
                row: 0,
                iteration: 0
            }
        ),
        "{e:?}"
    );
}

#[test]
fn empty_problems_take_one_iteration() {
    let p = ContactProblem::new();
    for mut s in solvers() {
        let r = solve(s.as_mut(), &p, &SolverSettings::default(), &mut [], 0).unwrap();
        assert_eq!(
            (r.iterations, r.converged, r.natural_residual),
            (1, true, 0.0),
            "{}",
            s.name()
        );
    }
}

/// Buffers are reused: solving different problems (growing and shrinking) one after the
/// other with the same solver, dense or sparse, gives the same answers as fresh solvers.
#[test]
fn reuse_between_solves() {
    let problems: Vec<_> = (0..6)
        .map(|s| {
            random_problem(
                s,
                if s % 2 == 0 {
                    Kind::Well
                } else {
                    Kind::Redundant
                },
            )
        })
        .collect();
    let settings = SolverSettings {
        tolerance: 1e-10,
        ..SolverSettings::default()
    };
    let sparse = || -> Vec<Box<dyn VelocitySolver>> {
        vec![
            Box::new(PsorSolver::with_settings(PsorSettings {
                assembly: AssemblyMode::Sparse,
                ..PsorSettings::default()
            })),
            Box::new(NewtonSolver::with_settings(NewtonSettings {
                assembly: AssemblyMode::Sparse,
                ..NewtonSettings::default()
            })),
        ]
    };
    let mut reused: Vec<Box<dyn VelocitySolver>> = solvers().into_iter().chain(sparse()).collect();
    for p in problems.iter().chain(problems.iter().rev()) {
        let zeros = vec![Impulse::ZERO; p.points.len()];
        for (k, fresh) in solvers().iter_mut().chain(sparse().iter_mut()).enumerate() {
            let (a, _, ra) = run(fresh.as_mut(), p, &settings, &zeros);
            let (b, _, rb) = run(reused[k].as_mut(), p, &settings, &zeros);
            assert_eq!(ra.iterations, rb.iterations);
            assert_eq!(a, b);
        }
    }
}
