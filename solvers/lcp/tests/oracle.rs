//! The solvers against the exact (enumerating) solver on seeded random small problems:
//! well conditioned, badly conditioned and with redundant contacts.

mod common;

use common::{Kind, random_problem, rows, run, scale};
use deepcontact_core::math::Real;
use deepcontact_core::{Impulse, SolverSettings};
use deepcontact_lcp::{
    AssemblyMode, Delassus, NewtonSettings, NewtonSolver, PsorSettings, PsorSolver, solve_exact,
    violation,
};

const SEEDS: u64 = 40;

fn tight(max_iterations: u32) -> SolverSettings {
    SolverSettings {
        max_iterations,
        tolerance: 1e-12,
        ..SolverSettings::default()
    }
}

fn assembled(problem: &deepcontact_core::ContactProblem) -> Delassus {
    let mut d = Delassus::new();
    d.assemble(problem, AssemblyMode::Dense, usize::MAX)
        .unwrap();
    d
}

/// Relative velocities `Wλ + q` of the rows.
fn velocities(d: &Delassus, lambda: &[Impulse]) -> Vec<Real> {
    let mut w = vec![0.0; d.rows()];
    d.velocity_of(&rows(lambda), &mut w);
    w
}

#[test]
fn exact_solutions_are_complementary_and_in_the_cone() {
    for kind in [Kind::Well, Kind::Bad, Kind::Redundant] {
        for seed in 0..SEEDS {
            let p = random_problem(seed, kind);
            let exact =
                solve_exact(&p, 1e-9).unwrap_or_else(|e| panic!("{kind:?} seed {seed}: {e}"));
            let d = assembled(&p);
            let v = violation(&d, &rows(&exact.impulses));
            let tol = 1e-7 * scale(&exact.impulses) * p.points.len() as Real;
            assert!(
                v.max() < tol,
                "{kind:?} seed {seed}: exact solution violates {v:?}"
            );
        }
    }
}

#[test]
fn exact_solver_rejects_large_and_invalid_problems() {
    let mut p = random_problem(1, Kind::Well);
    while p.points.len() <= deepcontact_lcp::EXACT_MAX_POINTS {
        let q = p.points[0];
        p.begin_manifold();
        p.points.push(q);
        let n = p.points.len() as u32;
        *p.manifolds.last_mut().unwrap() = (n - 1, n);
    }
    assert!(matches!(
        solve_exact(&p, 1e-9),
        Err(deepcontact_lcp::LcpError::TooManyPointsForExact { .. })
    ));
    let mut p = random_problem(2, Kind::Well);
    p.points[0].friction = Real::NAN;
    assert!(matches!(
        solve_exact(&p, 1e-9),
        Err(deepcontact_lcp::LcpError::InvalidProblem(_))
    ));
}

/// Newton (dense and sparse) reaches a solution of every problem; where the velocities of
/// the solution are unique it reproduces the oracle's, and where `W` is regular its impulses.
#[test]
fn newton_matches_the_exact_solver() {
    for kind in [Kind::Well, Kind::Bad, Kind::Redundant] {
        for seed in 0..SEEDS {
            let p = random_problem(seed, kind);
            let exact = solve_exact(&p, 1e-9).unwrap();
            let d = assembled(&p);
            let s = scale(&exact.impulses) * p.points.len() as Real;
            for assembly in [AssemblyMode::Dense, AssemblyMode::Sparse] {
                let mut newton = NewtonSolver::with_settings(NewtonSettings {
                    assembly,
                    ..NewtonSettings::default()
                });
                let zeros = vec![Impulse::ZERO; p.points.len()];
                let (imp, _, report) = run(&mut newton, &p, &tight(200), &zeros);
                let ctx = format!(
                    "{kind:?} seed {seed} {assembly:?}: {report:?} {:?}",
                    newton.last_stats()
                );
                assert!(report.converged, "{ctx}");
                let v = violation(&d, &rows(&imp));
                assert!(v.max() < 1e-8 * s, "{ctx}: violation {v:?}");
                assert!(report.natural_residual < 1e-8 * s, "{ctx}");
                // Normal velocities of touching points agree with the oracle.
                let (w, we) = (velocities(&d, &imp), &exact.velocity);
                let dv = w
                    .iter()
                    .zip(we)
                    .fold(0.0, |m: Real, (a, b)| m.max((a - b).abs()));
                let vs = we.iter().fold(1.0, |m: Real, v| m.max(v.abs()));
                assert!(
                    dv < 1e-6 * vs,
                    "{ctx}: velocities differ by {dv}: {w:?} vs {we:?}"
                );
                if kind == Kind::Well {
                    let di = common::max_diff(&imp, &exact.impulses);
                    assert!(
                        di < 1e-6 * s,
                        "{ctx}: impulses differ by {di}: {imp:?} vs {:?}",
                        exact.impulses
                    );
                }
            }
        }
    }
}

/// PSOR (ω = 1 and over-relaxed) converges to a solution of the well-conditioned problems.
#[test]
fn psor_matches_the_exact_solver_on_well_conditioned_problems() {
    for seed in 0..SEEDS {
        let p = random_problem(seed, Kind::Well);
        let exact = solve_exact(&p, 1e-9).unwrap();
        let d = assembled(&p);
        let s = scale(&exact.impulses) * p.points.len() as Real;
        for omega in [1.0, 1.3] {
            let mut psor = PsorSolver::with_settings(PsorSettings {
                omega,
                ..PsorSettings::default()
            });
            let zeros = vec![Impulse::ZERO; p.points.len()];
            let (imp, _, report) = run(&mut psor, &p, &tight(100_000), &zeros);
            let ctx = format!(
                "seed {seed} omega {omega}: its {} res {}",
                report.iterations, report.natural_residual
            );
            assert!(report.converged, "{ctx}");
            let v = violation(&d, &rows(&imp));
            assert!(v.max() < 1e-7 * s, "{ctx}: violation {v:?}");
            let di = common::max_diff(&imp, &exact.impulses);
            assert!(
                di < 1e-5 * s,
                "{ctx}: impulses differ by {di}: {imp:?} vs {:?}",
                exact.impulses
            );
        }
    }
}

/// Starting Newton at the exact solution stops after one iteration with no change.
#[test]
fn newton_from_the_exact_solution_stops_at_once() {
    for kind in [Kind::Well, Kind::Redundant] {
        for seed in 0..SEEDS {
            let p = random_problem(seed, kind);
            let exact = solve_exact(&p, 1e-12).unwrap();
            let mut newton = NewtonSolver::new();
            let (imp, _, report) =
                run(&mut newton, &p, &SolverSettings::default(), &exact.impulses);
            assert_eq!(report.iterations, 1, "{kind:?} seed {seed}: {report:?}");
            assert!(
                common::max_diff(&imp, &exact.impulses) < 1e-4,
                "{kind:?} seed {seed}"
            );
        }
    }
}

/// On problems that may be non-monotone (many sliding points on one body, nearly coincident
/// points, masses over 1e4) the solvers need not converge, but they return finite impulses,
/// an honest report and no error; most of them do converge.
#[test]
fn hostile_problems_fail_gracefully() {
    let mut converged = 0;
    for seed in 0..SEEDS {
        let p = random_problem(seed, Kind::Hostile);
        let d = assembled(&p);
        let zeros = vec![Impulse::ZERO; p.points.len()];
        let mut newton = NewtonSolver::new();
        let mut psor = PsorSolver::new();
        for solver in [
            &mut newton as &mut dyn deepcontact_core::VelocitySolver,
            &mut psor,
        ] {
            let (imp, vel, report) = run(solver, &p, &tight(300), &zeros);
            assert!(
                imp.iter().all(|i| i.is_finite())
                    && vel
                        .iter()
                        .all(|v| v.linear.x.is_finite() && v.angular.is_finite())
            );
            assert_eq!(report.residual_inf.len(), report.iterations as usize);
            // The reported natural residual is the one of the returned impulses.
            let mut w = vec![0.0; d.rows()];
            d.velocity_of(&rows(&imp), &mut w);
            assert!((report.natural_residual - d.natural_residual(&rows(&imp), &w)).abs() < 1e-9);
            if report.converged && solver.name() == "newton" {
                converged += 1;
                assert!(
                    violation(&d, &rows(&imp)).max() < 1e-8 * scale(&imp) * p.points.len() as Real
                );
            }
        }
    }
    assert!(
        converged >= SEEDS * 3 / 4,
        "newton converged on only {converged} of {SEEDS}"
    );
}

/// Where `W` is regular the dense and sparse Newton paths make the same iterates.
#[test]
fn dense_and_sparse_newton_make_the_same_iterates() {
    for seed in 0..SEEDS {
        let p = random_problem(seed, Kind::Well);
        let (mut dense, mut sparse) = (Delassus::new(), Delassus::new());
        dense.assemble(&p, AssemblyMode::Dense, 0).unwrap();
        sparse
            .assemble(&p, AssemblyMode::Sparse, usize::MAX)
            .unwrap();
        let (a, b) = (dense.to_dense(), sparse.to_dense());
        for j in 0..dense.rows() {
            for i in 0..dense.rows() {
                assert!(
                    (a[(i, j)] - b[(i, j)]).abs() < 1e-12,
                    "seed {seed}: W({i},{j})"
                );
            }
        }
        let zeros = vec![Impulse::ZERO; p.points.len()];
        for its in 1..6 {
            let settings = SolverSettings {
                max_iterations: its,
                tolerance: 0.0,
                ..SolverSettings::default()
            };
            let mut out = Vec::new();
            for assembly in [AssemblyMode::Dense, AssemblyMode::Sparse] {
                let mut newton = NewtonSolver::with_settings(NewtonSettings {
                    assembly,
                    ..NewtonSettings::default()
                });
                out.push(run(&mut newton, &p, &settings, &zeros).0);
            }
            let d = common::max_diff(&out[0], &out[1]);
            assert!(
                d < 1e-9 * scale(&out[0]),
                "seed {seed} after {its} iterations: {d}"
            );
        }
    }
}

/// Given the answer's active set, the frictional problem is linear: one Newton step on it
/// lands on the answer from any start (well-conditioned problems, where the answer is
/// unique); on its own active set it is Newton's first step. Wrong lengths are typed errors.
#[test]
fn one_step_on_the_answers_active_set_reaches_the_answer() {
    let mut newton = NewtonSolver::new();
    for seed in 0..SEEDS {
        let p = random_problem(seed, Kind::Well);
        let exact = solve_exact(&p, 1e-9).unwrap();
        let s = scale(&exact.impulses) * p.points.len() as Real;
        let n = p.points.len();
        for start in [vec![Impulse::ZERO; n], vec![Impulse::new(1.0, -0.5); n]] {
            let mut out = vec![Impulse::ZERO; n];
            newton
                .step_on_active_set(&p, &exact.impulses, &start, &mut out)
                .unwrap();
            let di = common::max_diff(&out, &exact.impulses);
            assert!(
                di < 1e-6 * s,
                "seed {seed}: {out:?} vs {:?}",
                exact.impulses
            );
        }
    }
    let p = random_problem(0, Kind::Well);
    let n = p.points.len();
    let mut out = vec![Impulse::ZERO; n + 1];
    let e = newton
        .step_on_active_set(
            &p,
            &vec![Impulse::ZERO; n],
            &vec![Impulse::ZERO; n],
            &mut out,
        )
        .unwrap_err();
    assert!(e.to_string().contains("out"), "{e}");
}
