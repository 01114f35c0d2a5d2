//! The solver on hand-built problems.

use deepcontact_core::math::{Pose, Real, Vector, Velocity};
use deepcontact_core::{
    ContactProblem, Impulse, PointDesc, ProblemBody, SolveReport, SolverSettings, VelocitySolver,
};

use crate::{SoftSettings, SoftSolver};

const DT: Real = 0.01;
const G: Real = -9.81;

/// A unit box (mass 1, inertia 1/6) centred at `(0, y)` moving at `v` (before this step's
/// gravity) on a fixed ground whose top is `y = 0`: two points at x = ±0.5, normal up.
fn box_on_ground(y: Real, v: Vector, w: Real) -> ContactProblem {
    let mut p = ContactProblem::new();
    p.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
    let v = v + Vector::new(0.0, DT * G);
    p.add_body(ProblemBody::dynamic(
        Vector::new(0.0, y),
        0.0,
        v,
        w,
        1.0,
        1.0 / 6.0,
    ));
    p.begin_manifold();
    for x in [-0.5, 0.5] {
        let desc = PointDesc::new(0, 1, Vector::new(x, 0.0), Vector::new(0.0, 1.0))
            .separation(y - 0.5)
            .friction(0.6);
        p.add_point(&desc).unwrap();
    }
    p
}

struct Out {
    impulses: Vec<Impulse>,
    velocities: Vec<Velocity>,
    displacements: Vec<Pose>,
    report: SolveReport,
}

fn solve(
    solver: &mut SoftSolver,
    problem: &ContactProblem,
    settings: &SolverSettings,
    start: &[Impulse],
) -> Out {
    let mut out = Out {
        impulses: start.to_vec(),
        velocities: vec![Velocity::default(); problem.bodies.len()],
        displacements: vec![Pose::default(); problem.bodies.len()],
        report: SolveReport::default(),
    };
    solver
        .solve_step(
            problem,
            settings,
            &mut out.impulses,
            &mut out.velocities,
            &mut out.displacements,
            &mut out.report,
        )
        .unwrap();
    out
}

/// Steps the box on the ground `steps` times as a world would: the displacements move it,
/// the impulses warm-start the next step. Returns the last solve and the box's state (height, velocity, angular velocity).
fn settle(solver: &mut SoftSolver, steps: usize) -> (Out, (Real, Vector, Real)) {
    let (mut y, mut v, mut w) = (0.5, Vector::zeros(), 0.0);
    let mut start = vec![Impulse::ZERO; 2];
    let settings = SolverSettings::default();
    let mut last = None;
    for _ in 0..steps {
        let problem = box_on_ground(y, v, w);
        let out = solve(solver, &problem, &settings, &start);
        y += out.displacements[1].position.y;
        (v, w) = (out.velocities[1].linear, out.velocities[1].angular);
        start.clone_from(&out.impulses);
        last = Some(out);
    }
    (last.unwrap(), (y, v, w))
}

#[test]
fn a_resting_box_carries_m_g_dt_per_step() {
    let mut solver = SoftSolver::new();
    let (out, (y, _, _)) = settle(&mut solver, 200);
    let total: Real = out.impulses.iter().map(|i| i.normal).sum();
    let m_g_dt = 1.0 * 9.81 * DT;
    assert!(
        (total - m_g_dt).abs() < 1e-3 * m_g_dt,
        "normal impulse {total} N·s per step, m g dt = {m_g_dt}"
    );
    // Symmetric: each point carries half, no friction.
    assert!((out.impulses[0].normal - out.impulses[1].normal).abs() < 1e-9);
    assert!(out.impulses.iter().all(|i| i.tangent.abs() < 1e-12));
    // At rest, a little into the ground (soft contact), not through it.
    assert!(
        out.velocities[1].linear.norm() < 1e-4,
        "{:?}",
        out.velocities[1]
    );
    assert!(y < 0.5 && y > 0.5 - 0.005, "y = {y}");
}

/// The start is N·s over a step: the first substep warm-starts with a substep's share of
/// it (`start / substeps`), and a settled box's returned impulses, fed back as the next
/// step's start, come back unchanged (a fixed point of the world's carry-over).
#[test]
fn the_start_is_per_step_and_split_among_the_substeps() {
    let mut solver = SoftSolver::new();
    let problem = box_on_ground(0.5, Vector::zeros(), 0.0);
    let start = [Impulse::new(0.08, 0.02), Impulse::new(0.04, -0.01)];
    let softness = crate::ContactSoftness::new(30.0, 10.0, DT / 4.0);
    solver
        .island
        .prepare(&problem, &start, 4, DT, Vector::new(0.0, G), &softness)
        .unwrap();
    for (p, s) in solver.island.points.iter().zip(&start) {
        assert_eq!((p.normal, p.tangent), (s.normal / 4.0, s.tangent / 4.0));
    }
    let (settled, state) = settle(&mut solver, 300);
    let (y, v, w) = state;
    let again = solve(
        &mut solver,
        &box_on_ground(y, v, w),
        &SolverSettings::default(),
        &settled.impulses,
    );
    for (a, b) in again.impulses.iter().zip(&settled.impulses) {
        assert!(
            (a.normal - b.normal).abs() < 1e-6 * b.normal,
            "{a:?} vs {b:?}"
        );
    }
}

/// Far above the ground (a speculative point 1 m away) the box falls freely: the solver takes
/// the world's `dt g` out and puts `h g` back each substep, so the velocity is `v + dt g`
/// and the displacement `Σ h v_k = dt v + h² g (1 + … + n)`.
#[test]
fn free_fall_inside_the_step_is_symplectic_euler_over_the_substeps() {
    let mut solver = SoftSolver::new();
    let v0 = Vector::new(0.3, -0.2);
    let problem = box_on_ground(1.5, v0, 0.0);
    let out = solve(
        &mut solver,
        &problem,
        &SolverSettings::default(),
        &[Impulse::ZERO; 2],
    );
    assert_eq!(out.impulses, vec![Impulse::ZERO; 2]);
    let h = DT / 4.0;
    let v = out.velocities[1].linear;
    assert!(
        (v - (v0 + Vector::new(0.0, DT * G))).norm() < 1e-12,
        "{v:?}"
    );
    let dy = DT * v0.y + h * h * G * 10.0;
    let d = out.displacements[1].position;
    assert!((d - Vector::new(DT * v0.x, dy)).norm() < 1e-12, "{d:?}");
    assert_eq!(out.displacements[0], Pose::default());
}

/// A box hitting the ground at 3 m/s with restitution 0.5 bounces, after the substeps, by one
/// restitution pass towards the problem's target `−e vn` (measured by the world after the
/// step's gravity).
#[test]
fn restitution_bounces_the_box_in_one_pass_towards_the_target() {
    let mut p = ContactProblem::new();
    p.add_body(ProblemBody::fixed(Vector::new(0.0, -0.5)));
    let v = Vector::new(0.0, -3.0 + DT * G);
    p.add_body(ProblemBody::dynamic(
        Vector::new(0.0, 0.5),
        0.0,
        v,
        0.0,
        1.0,
        1.0 / 6.0,
    ));
    p.begin_manifold();
    for x in [-0.5, 0.5] {
        let desc =
            PointDesc::new(0, 1, Vector::new(x, 0.0), Vector::new(0.0, 1.0)).restitution(0.5, 1.0);
        p.add_point(&desc).unwrap();
    }
    let target = p.points[0].velocity_bias;
    assert!((target - 0.5 * (3.0 - DT * G)).abs() < 1e-12);
    let out = solve(
        &mut SoftSolver::new(),
        &p,
        &SolverSettings::default(),
        &[Impulse::ZERO; 2],
    );
    // One Gauss-Seidel pass over the two corners from rest, as Box2D's single restitution
    // pass: the corner mass is 1 / (1 + 6 × 0.5²) = 0.4; the first corner's impulse turns
    // the box (ω = −3 λ1), the second corner then closes at −λ1 / 2.
    let k = 2.5;
    let l1 = target / k;
    let l2 = (target + 0.5 * l1) / k;
    let expected = l1 + l2;
    let vy = out.velocities[1].linear.y;
    assert!(
        (vy - expected).abs() < 0.01 * expected,
        "vy = {vy}, one pass from rest gives {expected} (target {target})"
    );
}

/// Under a fixed budget of K passes the solve spends at most K, one residual each.
#[test]
fn a_fixed_budget_of_k_passes_is_respected() {
    let problem = box_on_ground(0.49, Vector::new(0.5, -1.0), 0.3);
    for relax in [0, 1, 3] {
        let mut solver = SoftSolver::with_settings(SoftSettings {
            relax,
            ..SoftSettings::default()
        });
        for k in 1..=24 {
            let settings = SolverSettings {
                tolerance: 0.0,
                max_iterations: k,
                ..SolverSettings::default()
            };
            let out = solve(&mut solver, &problem, &settings, &[Impulse::ZERO; 2]);
            let r = &out.report;
            assert!(
                r.iterations <= k,
                "K = {k}, relax = {relax}: {}",
                r.iterations
            );
            assert!(
                r.iterations >= k.min(1 + relax),
                "K = {k}: {}",
                r.iterations
            );
            assert_eq!(r.residual_inf.len(), r.iterations as usize);
            assert_eq!(r.residual_l2.len(), r.iterations as usize);
            assert!(!r.converged);
        }
    }
}

/// The friction cone holds for the returned impulses, a sliding box slows down, and a fork
/// solves to the same bits.
#[test]
fn friction_is_bounded_and_forks_agree_to_the_bit() {
    let problem = box_on_ground(0.499, Vector::new(2.0, 0.0), 0.0);
    let mut solver = SoftSolver::new();
    let start = [Impulse::new(0.05, 0.02), Impulse::new(0.05, -0.01)];
    let out = solve(&mut solver, &problem, &SolverSettings::default(), &start);
    for i in &out.impulses {
        assert!(
            i.normal >= 0.0 && i.tangent.abs() <= 0.6 * i.normal + 1e-15,
            "{i:?}"
        );
    }
    assert!(out.velocities[1].linear.x < 2.0);
    // t = (−n.y, n.x) = (−1, 0): slowing a box that slides along +x is a positive λt.
    assert!(out.impulses.iter().all(|i| i.tangent > 0.0));
    let mut fork = solver.fork().unwrap();
    let mut impulses = start.to_vec();
    let mut velocities = vec![Velocity::default(); 2];
    let mut report = SolveReport::default();
    fork.solve(
        &problem,
        &SolverSettings::default(),
        &mut impulses,
        &mut velocities,
        &mut report,
    )
    .unwrap();
    let bits = |i: &[Impulse]| -> Vec<(u64, u64)> {
        i.iter()
            .map(|i| (i.normal.to_bits(), i.tangent.to_bits()))
            .collect()
    };
    assert_eq!(bits(&impulses), bits(&out.impulses));
    assert_eq!(velocities, out.velocities);
    assert_eq!(report.iterations, out.report.iterations);
}

#[test]
fn bad_input_is_an_error_not_a_panic() {
    let problem = box_on_ground(0.5, Vector::zeros(), 0.0);
    let mut solver = SoftSolver::new();
    let mut velocities = vec![Velocity::default(); 2];
    let mut report = SolveReport::default();
    let mut nan = [Impulse::new(Real::NAN, 0.0), Impulse::ZERO];
    let settings = SolverSettings::default();
    assert!(
        solver
            .solve(&problem, &settings, &mut nan, &mut velocities, &mut report)
            .is_err()
    );
    let mut short = [Impulse::ZERO];
    assert!(
        solver
            .solve(
                &problem,
                &settings,
                &mut short,
                &mut velocities,
                &mut report
            )
            .is_err()
    );
    let contact_norm = SolverSettings {
        norm: deepcontact_core::ResidualNorm::Contact,
        ..settings
    };
    let mut ok = [Impulse::ZERO; 2];
    assert!(
        solver
            .solve(
                &problem,
                &contact_norm,
                &mut ok,
                &mut velocities,
                &mut report
            )
            .is_err()
    );
    let mut bad = SoftSolver::with_settings(SoftSettings {
        substeps: 0,
        ..SoftSettings::default()
    });
    assert!(
        bad.solve(&problem, &settings, &mut ok, &mut velocities, &mut report)
            .is_err()
    );
}
