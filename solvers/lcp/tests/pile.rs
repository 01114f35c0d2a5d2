//! The solvers on recorded problems of the thesis pile (`scene::pile(12345, 100)` after
//! 150 steps of PGS with the carried warm start).

mod common;

use common::{Kind, max_diff, pile, random_problem, rows, run, scale};
use deepcontact_core::math::Real;
use deepcontact_core::{ContactProblem, Impulse, SolverSettings, VelocitySolver};
use deepcontact_lcp::{
    AssemblyMode, Delassus, NewtonSettings, NewtonSolver, PsorSettings, PsorSolver, violation,
};
use deepcontact_pgs::{PgsSettings, PgsSolver};

fn pgs_block_off() -> PgsSolver {
    PgsSolver::with_settings(PgsSettings {
        block_solver: false,
        // psor visits rows in the problem's order: compare with the same order.
        ordering: deepcontact_pgs::Ordering::Sequential,
        ..PgsSettings::default()
    })
}

#[test]
fn the_fixture_has_a_pile_worth_solving() {
    let f = pile();
    let points: usize = f.problems.iter().map(|p| p.points.len()).sum();
    assert!(
        points > 100,
        "only {points} contact points after the warm-up"
    );
    assert!(
        f.problems
            .iter()
            .any(|p| 2 * p.points.len() > deepcontact_lcp::DEFAULT_DENSE_THRESHOLD)
    );
}

/// PSOR with ω = 1 is PGS without the block solver: same row order, same projection, same
/// stop rule — so the same iterations and the same impulses.
#[test]
fn psor_matches_pgs_on_the_pile() {
    let f = pile();
    for (k, p) in f.problems.iter().enumerate() {
        for (start_name, start) in [
            ("builtin", f.carried[k].clone()),
            ("none", vec![Impulse::ZERO; p.points.len()]),
        ] {
            for settings in [
                SolverSettings::default(),
                SolverSettings {
                    max_iterations: 25,
                    tolerance: 0.0,
                    ..SolverSettings::default()
                },
            ] {
                let (a, va, ra) = run(&mut pgs_block_off(), p, &settings, &start);
                for assembly in [
                    AssemblyMode::Auto,
                    AssemblyMode::Dense,
                    AssemblyMode::Sparse,
                ] {
                    let mut psor = PsorSolver::with_settings(PsorSettings {
                        assembly,
                        ..PsorSettings::default()
                    });
                    let (b, vb, rb) = run(&mut psor, p, &settings, &start);
                    let ctx = format!(
                        "island {k} start {start_name} {assembly:?} tol {}",
                        settings.tolerance
                    );
                    assert_eq!(ra.iterations, rb.iterations, "{ctx}");
                    assert_eq!(ra.converged, rb.converged, "{ctx}");
                    let d = max_diff(&a, &b);
                    assert!(d < 1e-5, "{ctx}: impulses differ by {d}");
                    let dv = va.iter().zip(&vb).fold(0.0, |m: Real, (x, y)| {
                        m.max((x.linear - y.linear).norm())
                            .max((x.angular - y.angular).abs())
                    });
                    assert!(dv < 1e-6, "{ctx}: velocities differ by {dv}");
                    for (x, y) in ra.residual_inf.iter().zip(&rb.residual_inf) {
                        assert!((x - y).abs() < 1e-6, "{ctx}: residual curves differ");
                    }
                    assert!(
                        (ra.natural_residual - rb.natural_residual).abs() < 1e-6,
                        "{ctx}"
                    );
                }
            }
        }
    }
}

/// Over-relaxation changes the iterates but still solves the problem.
#[test]
fn over_relaxed_psor_converges_on_the_pile() {
    let f = pile();
    let settings = SolverSettings {
        max_iterations: 5000,
        tolerance: 1e-7,
        ..SolverSettings::default()
    };
    for (k, p) in f.problems.iter().enumerate() {
        let mut psor = PsorSolver::with_settings(PsorSettings {
            omega: 1.2,
            ..PsorSettings::default()
        });
        let (_, _, r) = run(&mut psor, p, &settings, &f.carried[k]);
        assert!(
            r.converged && r.natural_residual < 1e-5,
            "island {k}: {} its, res {}",
            r.iterations,
            r.natural_residual
        );
    }
}

/// Newton converges from zeros, from the carried impulses and from the "bad" (50, 50)
/// start, to a solution of the problem; restarted from its own solution it stops at once.
#[test]
fn newton_converges_from_every_start_on_the_pile() {
    let f = pile();
    let settings = SolverSettings::default();
    let tight = SolverSettings {
        tolerance: 1e-9,
        ..SolverSettings::default()
    };
    for (k, p) in f.problems.iter().enumerate() {
        let mut d = Delassus::new();
        d.assemble(p, AssemblyMode::Sparse, 0).unwrap();
        let n = p.points.len();
        let starts = [
            ("none", vec![Impulse::ZERO; n]),
            ("builtin", f.carried[k].clone()),
            ("bad", vec![Impulse::new(50.0, 50.0); n]),
        ];
        let mut newton = NewtonSolver::new();
        for (name, start) in &starts {
            let (imp, _, r) = run(&mut newton, p, &settings, start);
            let stats = newton.last_stats();
            let ctx = format!(
                "island {k} ({n} points) start {name}: {} its, {stats:?}",
                r.iterations
            );
            assert!(r.converged, "{ctx}");
            assert!(r.iterations <= 60, "{ctx}");
            let v = violation(&d, &rows(&imp));
            assert!(v.max() < 1e-6 * scale(&imp), "{ctx}: {v:?}");
            assert!(
                r.natural_residual < 1e-6,
                "{ctx}: natural residual {}",
                r.natural_residual
            );
        }
        // Copy start: the converged solution.
        let (copy, _, _) = run(&mut newton, p, &tight, &starts[0].1);
        let (again, _, r) = run(&mut newton, p, &settings, &copy);
        assert!(
            r.converged && r.iterations <= 2,
            "island {k} copy start: {} its",
            r.iterations
        );
        assert!(max_diff(&again, &copy) < 1e-6, "island {k}");
        // PGS's own (1e-4) solution is a copy-ish start too.
        let (_, _, r) = run(&mut newton, p, &settings, &f.solved[k]);
        assert!(
            r.converged && r.iterations <= 3,
            "island {k} PGS-solution start: {} its",
            r.iterations
        );
    }
}

/// Newton reaches the same velocities as a tightly converged PGS (the impulses of the pile
/// are not unique: more rows than degrees of freedom).
#[test]
fn newton_and_pgs_agree_on_velocities() {
    let f = pile();
    let tight = SolverSettings {
        max_iterations: 100_000,
        tolerance: 1e-10,
        ..SolverSettings::default()
    };
    for (k, p) in f.problems.iter().enumerate() {
        let (_, va, ra) = run(&mut pgs_block_off(), p, &tight, &f.carried[k]);
        assert!(ra.converged, "island {k}: PGS did not converge tightly");
        let (_, vb, rb) = run(&mut NewtonSolver::new(), p, &tight, &f.carried[k]);
        assert!(rb.converged, "island {k}");
        let dv = va.iter().zip(&vb).fold(0.0, |m: Real, (x, y)| {
            m.max((x.linear - y.linear).norm())
                .max((x.angular - y.angular).abs())
        });
        assert!(dv < 1e-5, "island {k}: velocities differ by {dv}");
    }
}

/// Dense and sparse assembly give the same `W` and `q`, and Newton the same velocities on both.
#[test]
fn dense_and_sparse_assembly_agree() {
    let f = pile();
    for (k, p) in f.problems.iter().enumerate() {
        let (mut dense, mut sparse) = (Delassus::new(), Delassus::new());
        dense.assemble(p, AssemblyMode::Dense, 0).unwrap();
        sparse
            .assemble(p, AssemblyMode::Sparse, usize::MAX)
            .unwrap();
        assert!(dense.is_dense() && !sparse.is_dense());
        let (a, b) = (dense.to_dense(), sparse.to_dense());
        let n = dense.rows();
        let mut max: Real = 0.0;
        for j in 0..n {
            for i in 0..n {
                max = max.max((a[(i, j)] - b[(i, j)]).abs());
            }
        }
        assert!(max < 1e-12, "island {k}: W differs by {max}");
        assert_eq!(dense.q(), sparse.q());
        // W is symmetric and its diagonal is the inverse of the problem's effective masses.
        for i in 0..n {
            let m = if i % 2 == 0 {
                p.points[i / 2].normal_mass
            } else {
                p.points[i / 2].tangent_mass
            };
            assert!((a[(i, i)] * m - 1.0).abs() < 1e-12, "island {k} row {i}");
            for j in 0..i {
                assert!((a[(i, j)] - a[(j, i)]).abs() < 1e-12);
            }
        }
        let settings = SolverSettings {
            tolerance: 1e-10,
            ..SolverSettings::default()
        };
        let mut out = Vec::new();
        for assembly in [AssemblyMode::Dense, AssemblyMode::Sparse] {
            let mut newton = NewtonSolver::with_settings(NewtonSettings {
                assembly,
                ..NewtonSettings::default()
            });
            out.push(run(&mut newton, p, &settings, &f.carried[k]));
            assert_eq!(newton.last_stats().dense, assembly == AssemblyMode::Dense);
            assert!(out.last().unwrap().2.converged, "island {k} {assembly:?}");
        }
        // W is singular (more rows than degrees of freedom): the two LU pivot orders leave
        // round-off of different size in its null space, which can steer the iterates to
        // different impulses — but not to different velocities.
        let dv = out[0].1.iter().zip(&out[1].1).fold(0.0, |m: Real, (x, y)| {
            m.max((x.linear - y.linear).norm())
                .max((x.angular - y.angular).abs())
        });
        assert!(
            dv < 1e-8,
            "island {k}: dense and sparse Newton velocities differ by {dv}"
        );
    }
}

/// The trait objects report their registry names.
#[test]
fn names() {
    assert_eq!(PsorSolver::new().name(), "psor");
    assert_eq!(NewtonSolver::new().name(), "newton");
}

/// `stop_on_failed_step` (the bounded refinement of the `presolve` warm start) never retries
/// nor falls back to a sweep: it stops where the plain solver would have retried, with the
/// same iterates up to there; a fork solves exactly like its parent. On the pile's islands
/// and on hostile random problems (where the plain solver does retry).
#[test]
fn newton_stopping_on_a_failed_step_never_retries_and_forks_agree() {
    let f = pile();
    let settings = SolverSettings::default();
    let stopping = NewtonSettings {
        stop_on_failed_step: true,
        ..NewtonSettings::default()
    };
    let mut cases: Vec<(ContactProblem, Vec<Impulse>)> = Vec::new();
    for (k, p) in f.problems.iter().enumerate() {
        cases.push((p.clone(), vec![Impulse::new(50.0, 50.0); p.points.len()]));
        cases.push((p.clone(), f.carried[k].clone()));
    }
    for seed in 0..40 {
        let p = random_problem(seed, Kind::Hostile);
        let zeros = vec![Impulse::ZERO; p.points.len()];
        cases.push((p, zeros));
    }
    let mut stopped = 0;
    for (k, (p, start)) in cases.iter().enumerate() {
        let mut plain = NewtonSolver::new();
        let (full, _, full_report) = run(&mut plain, p, &settings, start);
        let plain_stats = plain.last_stats();
        let mut bounded = NewtonSolver::with_settings(stopping);
        let (imp, _, r) = run(&mut bounded, p, &settings, start);
        let stats = bounded.last_stats();
        assert_eq!((stats.retries, stats.fallback_sweeps), (0, 0), "case {k}");
        assert!(r.iterations <= full_report.iterations, "case {k}");
        if plain_stats.retries == 0 && plain_stats.fallback_sweeps == 0 {
            assert_eq!(r.iterations, full_report.iterations, "case {k}");
            assert!(imp.iter().zip(&full).all(|(a, b)| a == b), "case {k}");
        } else if !r.converged {
            stopped += 1;
        }
        let mut fork = bounded.fork().expect("newton forks");
        let (forked, _, fr) = run(&mut fork, p, &settings, start);
        assert_eq!(fr.iterations, r.iterations);
        assert!(forked.iter().zip(&imp).all(|(a, b)| a == b));
    }
    assert!(stopped > 0, "no case made the plain solver retry");
}
