//! Regression tests of the bugs found by fuzzing and property testing (one test per bug,
//! named after it). The harness is the fuzzers' own (`deepcontact-fuzz-harness`, `fuzz/harness/`).

use std::path::Path;

use deepcontact_core::math::Real;
use deepcontact_core::{
    ContactId, ContactProblem, Impulse, PointDesc, ProblemBody, SolveReport, SolverSettings,
    Vector, Velocity, VelocitySolver,
};
use deepcontact_pgs::PgsSolver;

use deepcontact_core::{CoreError, scene};
use deepcontact_onnx::{ModelCard, OnnxError};

fn models() -> &'static Path {
    Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/../models"))
}

/// `peak.onnx` loaded with `pressure.json` ran without complaint: both have the same input and
/// output shapes, so the card's shape checks passed. Cards now pin their file by SHA-256.
#[test]
fn regression_card_of_another_model_was_accepted() {
    let card = ModelCard::load(&models().join("pressure.json")).unwrap();
    let own = std::fs::read(models().join("pressure.onnx")).unwrap();
    card.check_model_bytes(&own, Path::new("pressure.onnx"))
        .unwrap();
    let other = std::fs::read(models().join("peak.onnx")).unwrap();
    let err = card
        .check_model_bytes(&other, Path::new("peak.onnx"))
        .unwrap_err();
    assert!(
        matches!(&err, OnnxError::ModelHashMismatch { card, .. } if card == "pressure"),
        "{err}"
    );
    // Every committed card pins its model.
    for name in ["pressure", "peak"] {
        let card = ModelCard::load(&models().join(format!("{name}.json"))).unwrap();
        assert!(
            card.model_sha256.is_some(),
            "{name}.json has no model_sha256"
        );
        let bytes = std::fs::read(models().join(format!("{name}.onnx"))).unwrap();
        card.check_model_bytes(&bytes, Path::new(name)).unwrap();
    }
}

/// `--scene nosuch` printed "invalid setting scene = NaN: unknown scene name".
#[test]
fn regression_unknown_scene_was_reported_as_a_nan_setting() {
    let err = scene::by_name("nosuch", 1, 100).unwrap_err();
    assert!(
        matches!(&err, CoreError::UnknownScene { name, known } if name == "nosuch" && known.contains("pile")),
        "{err}"
    );
}

/// `--bodies 0` blamed the circle radius ("pile.radius = 0.5: must be > 0 and fit the box").
#[test]
fn regression_empty_pile_blamed_the_radius() {
    let err = scene::pile(1, 0).unwrap_err();
    assert!(
        matches!(
            err,
            CoreError::InvalidSetting {
                name: "pile.bodies",
                ..
            }
        ),
        "{err}"
    );
}

/// cargo-fuzz `solve_problem` (crash-41447d4d…): PGS started from a finite negative normal
/// impulse panicked in `clamp` (friction bound μ λn < 0). Starts are now projected onto the
/// cone first.
#[test]
fn regression_pgs_panicked_on_a_negative_normal_start() {
    const CRASH: &[u8] = &[
        25, 53, 53, 53, 53, 53, 53, 53, 49, 53, 52, 210, 65, 51, 51, 51, 51, 51, 51, 51, 51, 51,
        51, 51, 51, 48, 48, 48, 50, 48, 51, 51, 51, 179, 51, 51, 51, 51, 19, 19, 51, 51, 51, 51,
        53, 53, 49, 53, 52, 210, 65, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 48, 48, 208,
        205, 48, 51, 51, 51, 179, 51, 51, 51, 51, 19, 19, 49, 52, 56, 56, 54, 53, 56, 57, 50, 53,
        57, 54, 50, 51, 55, 56, 49, 55, 49, 56, 244, 103, 254, 255, 255, 224, 255, 255, 0, 0, 152,
        152, 152, 152, 1, 0, 0, 0, 0, 0, 0, 31, 152, 152, 52, 152, 152, 152,
    ];
    deepcontact_fuzz_harness::solve_problem(CRASH);

    // The same bug on a hand-built problem: one ball resting on the ground.
    let mut p = ContactProblem::new();
    let body = |y: Real, inv_mass: Real| ProblemBody {
        world_index: u32::MAX,
        position: Vector::new(0.0, y),
        angle: 0.0,
        linear_velocity: Vector::new(0.0, -0.1),
        angular_velocity: 0.0,
        inv_mass,
        inv_inertia: 2.0 * inv_mass,
    };
    let ground = p.add_body(body(-0.5, 0.0));
    let ball = p.add_body(body(0.5, 1.0));
    p.begin_manifold();
    let id = ContactId {
        body_a: 0,
        body_b: 1,
        feature_a: 0,
        feature_b: 0,
    };
    p.add_point(&PointDesc {
        id,
        body_a: ground,
        body_b: ball,
        point: Vector::zeros(),
        normal: Vector::new(0.0, 1.0),
        separation: -0.01,
        friction: 0.5,
        restitution: 0.0,
        restitution_threshold: 1.0,
    })
    .unwrap();
    let mut imp = vec![Impulse::new(-1.0, 0.3)];
    let mut vel = vec![Velocity::default(); 2];
    PgsSolver::new()
        .solve(
            &p,
            &SolverSettings::default(),
            &mut imp,
            &mut vel,
            &mut SolveReport::default(),
        )
        .unwrap();
    assert!(
        imp[0].normal >= 0.0 && imp[0].tangent.abs() <= 0.5 * imp[0].normal + 1e-12,
        "{:?}",
        imp[0]
    );
}

/// cargo-fuzz `solve_problem` (crash-181ce052…): PGS returned `Ok` with a NaN tangent
/// impulse. Its divergence check looked at `max |Δλ|` only, and `f64::max` skips NaN; it now
/// checks the sum of squares too, and every impulse and velocity before returning.
#[test]
fn regression_pgs_returned_ok_with_a_nan_impulse() {
    const CRASH: &[u8] = &[
        25, 53, 53, 53, 53, 53, 53, 53, 49, 53, 52, 210, 4, 5, 51, 51, 6, 4, 65, 4, 6, 6, 51, 51,
        51, 51, 51, 51, 51, 48, 48, 48, 50, 48, 51, 49, 51, 51, 51, 51, 51, 51, 51, 19, 19, 51, 51,
        51, 51, 51, 51, 5, 4, 65, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 255, 8, 51,
        4, 152, 1, 0, 0, 25, 53, 53, 53, 53, 53, 53, 53, 49, 53, 52, 210, 4, 5, 51, 51, 6, 4, 65,
        4, 6, 6, 51, 51, 51, 51, 51, 51, 51, 48, 48, 48, 50, 48, 51, 49, 51, 51, 51, 51, 51, 51,
        51, 19, 19, 51, 51, 51, 51, 51, 51, 5, 4, 65, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51,
        51, 51, 255, 8, 51, 4, 152, 1, 0, 0, 31, 0, 0, 152, 0, 4, 4, 4, 65, 4, 4, 0, 42, 0, 0, 0,
        0, 31, 152, 152, 52, 152, 152, 152, 31, 0, 0, 152, 0, 4, 4, 4, 65, 4, 4, 0, 42, 0, 0, 0, 0,
        31, 152, 152, 52, 152, 152, 152,
    ];
    deepcontact_fuzz_harness::solve_problem(CRASH);
}

/// cargo-fuzz `solve_problem` (crash-07ff248e…): a sweep that overflowed to λn = ∞ gave the
/// friction bound μ λn = NaN and `f64::clamp` panicked on it. The solver loop now clamps
/// without the panic and reports the divergence as `PgsError::Diverged`.
#[test]
fn regression_pgs_panicked_on_a_nan_friction_bound() {
    const CRASH: &[u8] = &[
        25, 53, 53, 53, 53, 53, 49, 48, 51, 48, 56, 210, 4, 5, 51, 51, 6, 4, 122, 65, 4, 6, 6, 51,
        51, 51, 51, 51, 51, 51, 48, 48, 48, 50, 48, 51, 49, 51, 51, 51, 51, 51, 51, 51, 19, 19, 51,
        51, 51, 51, 51, 51, 5, 4, 65, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 51, 255, 8,
        51, 4, 152, 1, 0, 0, 31, 0, 0, 152, 0, 4, 4, 4, 4, 65, 0, 42, 4, 0, 0, 0, 0, 31, 152, 152,
        52, 152, 152, 152,
    ];
    deepcontact_fuzz_harness::solve_problem(CRASH);
}
