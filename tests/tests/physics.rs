//! Physical behaviour of the core + PGS pipeline on the shared scenes.

use deepcontact_core::math::Real;
use deepcontact_core::{BodyKind, CarriedWarmStart, Vector, ZeroWarmStart, scene};
use deepcontact_tests::{build, run, state_bits};

const SLOP: Real = 0.0005;

#[test]
fn circle_resting_on_ground_stays_within_slop_for_1000_steps() {
    let mut world = build(&scene::resting_ball());
    run(&mut world, &mut CarriedWarmStart, 1000, |w, r| {
        let ball = &w.bodies()[1];
        // Ground top at y = 0, radius 0.5: penetration = 0.5 - y.
        let penetration = 0.5 - ball.position.y;
        assert!(
            penetration <= 3.0 * SLOP + 1e-9,
            "step {}: penetration {penetration}",
            r.step
        );
        assert!(
            penetration >= -1e-3,
            "step {}: ball bounced to {}",
            r.step,
            ball.position.y
        );
        assert!(
            ball.position.x.abs() < 1e-6,
            "ball drifted to x = {}",
            ball.position.x
        );
    })
    .unwrap();
}

#[test]
fn ten_box_stack_stands_for_500_steps() {
    let mut world = build(&scene::stack(10));
    run(&mut world, &mut CarriedWarmStart, 500, |_, _| {}).unwrap();
    for (i, b) in world.bodies().iter().enumerate().skip(1) {
        let expected_y = 0.5 + (i - 1) as Real;
        assert!(
            b.position.x.abs() < 0.05,
            "box {i} slid sideways to x = {}",
            b.position.x
        );
        assert!(
            (b.position.y - expected_y).abs() < 0.05,
            "box {i} at y = {} (expected {expected_y})",
            b.position.y
        );
        assert!(b.angle.abs() < 0.02, "box {i} tilted by {}", b.angle);
    }
}

fn slide_distance(degrees: Real) -> Real {
    let mut world = build(&scene::slope(degrees, 0.5));
    let start = world.bodies()[1].position;
    run(&mut world, &mut CarriedWarmStart, 200, |_, _| {}).unwrap();
    (world.bodies()[1].position - start).norm()
}

#[test]
fn box_on_20_degree_slope_stays_and_slides_at_35() {
    // tan 20° = 0.36 < μ = 0.5 < tan 35° = 0.70.
    let stay = slide_distance(20.0);
    assert!(stay < 0.01, "box moved {stay} m on a 20° slope");
    let slide = slide_distance(35.0);
    // a = g (sin θ − μ cos θ) = 1.61 m/s²; in 2 s: ~3.2 m.
    assert!(slide > 2.0, "box moved only {slide} m on a 35° slope");
}

#[test]
fn pile_impulses_are_admissible_and_bodies_stay_in_the_box() {
    let mut world = build(&scene::pile(12345, 100).unwrap());
    let side = 15.0;
    let mut deepest: Real = 0.0;
    run(&mut world, &mut CarriedWarmStart, 250, |w, r| {
        for (id, imp) in w.contacts() {
            assert!(
                imp.is_finite(),
                "step {}: non-finite impulse at {id:?}",
                r.step
            );
            assert!(
                imp.normal >= 0.0,
                "step {}: negative normal impulse {}",
                r.step,
                imp.normal
            );
            // μ = sqrt(0.5 · 0.5) = 0.5 for every pair of the pile (1e-12: μ computed by sqrt).
            assert!(
                imp.tangent.abs() <= 0.5 * imp.normal * (1.0 + 1e-12),
                "step {}: friction cone violated {imp:?}",
                r.step
            );
        }
        for (i, b) in w
            .bodies()
            .iter()
            .enumerate()
            .filter(|(_, b)| b.kind == BodyKind::Dynamic)
        {
            assert!(
                b.position.x.is_finite() && b.position.y.is_finite(),
                "step {}: body {i} NaN",
                r.step
            );
            assert!(
                (0.0..=side).contains(&b.position.x) && (0.0..=side).contains(&b.position.y),
                "step {}: body {i} escaped to {:?}",
                r.step,
                b.position
            );
        }
        deepest = deepest.min(r.min_separation);
    })
    .unwrap();
    assert!(deepest > -0.05, "penetration reached {deepest} m");
}

#[test]
fn a_clone_taken_mid_run_steps_on_in_the_same_bits() {
    // `World` promises that a clone steps bit-identically to the original (a snapshot to
    // branch experiments from). The clone is taken in the piling phase (contacts and carried
    // impulses alive) and stepped by fresh solvers, so state the clone drops or state a solver
    // keeps between steps shows up as different bits.
    let mut whole = build(&scene::pile(7, 100).unwrap());
    run(&mut whole, &mut CarriedWarmStart, 150, |_, _| {}).unwrap();

    let mut first = build(&scene::pile(7, 100).unwrap());
    let reports = run(&mut first, &mut CarriedWarmStart, 75, |_, _| {}).unwrap();
    let touching = reports.last().unwrap().contacts;
    assert!(
        touching > 20,
        "the clone is taken with contacts alive: {touching}"
    );
    let mut snapshot = first.clone();
    drop(first);
    run(&mut snapshot, &mut CarriedWarmStart, 75, |_, _| {}).unwrap();
    let (branch, straight) = (state_bits(&snapshot), state_bits(&whole));
    let differ = branch.iter().zip(&straight).filter(|(a, b)| a != b).count();
    assert_eq!(differ, 0, "{differ} of {} bodies differ", branch.len());
}

#[test]
fn residual_curve_is_nonempty_and_ends_under_tolerance_unless_capped() {
    let mut world = build(&scene::pile(12345, 100).unwrap());
    let tol = world.settings().solver.tolerance;
    let reports = run(&mut world, &mut ZeroWarmStart, 120, |_, _| {}).unwrap();
    let mut seen = 0;
    for r in reports.iter().filter(|r| r.contacts > 0) {
        seen += 1;
        assert!(
            !r.residual_curve.is_empty(),
            "step {} has contacts but no residual curve",
            r.step
        );
        assert_eq!(r.residual_curve.len(), r.velocity_iterations as usize);
        if r.capped_islands == 0 {
            assert!(
                r.final_residual() < tol,
                "step {}: final residual {}",
                r.step,
                r.final_residual()
            );
        }
    }
    assert!(
        seen > 20,
        "pile should have contacts for many steps, had {seen}"
    );
}

#[test]
fn builtin_needs_fewer_iterations_than_none_once_settled() {
    let late_mean = |warm: &mut dyn deepcontact_core::WarmStart| {
        let mut world = build(&scene::pile(12345, 100).unwrap());
        let reports = run(&mut world, warm, 200, |_, _| {}).unwrap();
        reports[150..]
            .iter()
            .map(|r| r.velocity_iterations as Real)
            .sum::<Real>()
            / 50.0
    };
    let none = late_mean(&mut ZeroWarmStart);
    let builtin = late_mean(&mut CarriedWarmStart);
    assert!(builtin < 0.9 * none, "builtin {builtin} vs none {none}");
}

#[test]
fn kinematic_body_moves_at_its_velocity_and_pushes() {
    use deepcontact_core::{BodyDesc, ShapeDesc, World, WorldSettings};
    let mut desc = BodyDesc::dynamic(
        ShapeDesc::Cuboid {
            half_width: 0.5,
            half_height: 0.5,
        },
        Vector::new(0.0, 0.0),
    );
    desc.kind = BodyKind::Kinematic;
    desc.linear_velocity = Vector::new(1.0, 0.0);
    let ball = BodyDesc::dynamic(ShapeDesc::Ball { radius: 0.5 }, Vector::new(1.2, 0.0));
    let settings = WorldSettings {
        gravity: Vector::zeros(),
        ..WorldSettings::default()
    };
    let mut world = World::with_bodies(settings, &[desc, ball]).unwrap();
    run(&mut world, &mut CarriedWarmStart, 100, |_, _| {}).unwrap();
    let k = &world.bodies()[0];
    assert!(
        (k.position.x - 1.0).abs() < 1e-9,
        "kinematic body at {}",
        k.position.x
    );
    assert!(
        world.bodies()[1].position.x > 1.9,
        "ball was not pushed: {}",
        world.bodies()[1].position.x
    );
}
