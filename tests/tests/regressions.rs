//! Regression tests of the bugs found by fuzzing and property testing (one test per bug,
//! named after it). A fuzz crash is rebuilt by hand as a valid problem that meets the same
//! arithmetic: the crash bytes themselves build problems that `ContactProblem::add_point` now
//! refuses, so they would never reach the solver whose guard the test pins.

use std::path::Path;

use deepcontact_core::math::Real;
use deepcontact_core::{
    ContactId, ContactProblem, Impulse, PointDesc, ProblemBody, ResidualNorm, SolveReport,
    SolverSettings, Vector, Velocity, VelocitySolver,
};
use deepcontact_pgs::{Ordering, PgsSettings, PgsSolver};

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

/// A body of a hand-built problem, at rest unless `velocity` says otherwise.
fn body(x: Real, y: Real, inv_mass: Real, inv_inertia: Real, velocity: Vector) -> ProblemBody {
    ProblemBody {
        world_index: u32::MAX,
        position: Vector::new(x, y),
        angle: 0.0,
        linear_velocity: velocity,
        angular_velocity: 0.0,
        inv_mass,
        inv_inertia,
    }
}

/// Adds a one-point manifold between bodies `a` and `b` of `p`.
fn add_contact(
    p: &mut ContactProblem,
    a: u32,
    b: u32,
    point: Vector,
    normal: Vector,
    friction: Real,
) {
    p.begin_manifold();
    p.add_point(&PointDesc {
        id: ContactId {
            body_a: a,
            body_b: b,
            feature_a: p.len() as u64,
            feature_b: 0,
        },
        body_a: a,
        body_b: b,
        point,
        normal,
        separation: -0.01,
        friction,
        restitution: 0.0,
        restitution_threshold: 1.0,
    })
    .expect("a valid point");
}

/// PGS in each of its sweeps: coloured with lanes (the default), one manifold at a time,
/// the problem's order, and every island in the chunked plan and in the domain plan.
fn pgs_plans() -> [(&'static str, PgsSettings); 5] {
    let d = PgsSettings::default();
    [
        ("default", d),
        ("no lanes", PgsSettings { lanes: false, ..d }),
        (
            "sequential",
            PgsSettings {
                ordering: Ordering::Sequential,
                ..d
            },
        ),
        (
            "chunked",
            PgsSettings {
                parallel_min_points: 0,
                domains: 0,
                chunk: 1,
                ..d
            },
        ),
        (
            "domains",
            PgsSettings {
                parallel_min_points: 0,
                domains: 2,
                ..d
            },
        ),
    ]
}

/// Solves `problem` from `start` with every plan of [`pgs_plans`] under every norm, and
/// checks that each solve is refused as diverged in iteration `iteration` (the sweep whose
/// result first held a non-finite value, or the iteration after which one was returned).
fn assert_diverges_in(problem: &ContactProblem, start: &[Impulse], iteration: u32) {
    problem.validate().expect("the problem is valid");
    for (plan, pgs) in pgs_plans() {
        for norm in [
            ResidualNorm::Infinity,
            ResidualNorm::L2,
            ResidualNorm::Contact,
        ] {
            let settings = SolverSettings {
                norm,
                max_iterations: 50,
                ..SolverSettings::default()
            };
            let mut impulses = start.to_vec();
            let mut velocities = vec![Velocity::default(); problem.bodies.len()];
            let result = PgsSolver::with_settings(pgs).solve(
                problem,
                &settings,
                &mut impulses,
                &mut velocities,
                &mut SolveReport::default(),
            );
            let expected = format!("in iteration {iteration}");
            match &result {
                Err(CoreError::Solver { solver, reason })
                    if solver == "pgs"
                        && reason.starts_with("non-finite impulse")
                        && reason.ends_with(&expected) => {}
                other => panic!(
                    "{plan}, {norm:?}: expected a divergence {expected}, got {other:?} \
                     (impulses {impulses:?}, velocities {velocities:?})"
                ),
            }
        }
    }
}

/// cargo-fuzz `solve_problem` (crash-41447d4d…): PGS started from a finite negative normal
/// impulse panicked in `clamp` (friction bound μ λn < 0). Starts are now projected onto the
/// cone first, so that start is the same as a start of zero.
#[test]
fn regression_pgs_panicked_on_a_negative_normal_start() {
    // One ball resting on the ground.
    let mut p = ContactProblem::new();
    let down = Vector::new(0.0, -0.1);
    let ground = p.add_body(body(0.0, -0.5, 0.0, 0.0, down));
    let ball = p.add_body(body(0.0, 0.5, 1.0, 2.0, down));
    add_contact(
        &mut p,
        ground,
        ball,
        Vector::new(0.1, 0.0),
        Vector::new(0.0, 1.0),
        0.5,
    );
    let solve = |pgs: PgsSettings, start: Impulse| {
        let mut imp = vec![start];
        let mut vel = vec![Velocity::default(); 2];
        PgsSolver::with_settings(pgs)
            .solve(
                &p,
                &SolverSettings::default(),
                &mut imp,
                &mut vel,
                &mut SolveReport::default(),
            )
            .unwrap();
        (imp[0], vel)
    };
    for (plan, pgs) in pgs_plans() {
        let (imp, vel) = solve(pgs, Impulse::new(-1.0, 0.3));
        assert!(
            imp.normal >= 0.0 && imp.tangent.abs() <= 0.5 * imp.normal + 1e-12,
            "{plan}: {imp:?}"
        );
        // The projected start is (0, 0): the very same solve, bit for bit.
        let (zero, zero_vel) = solve(pgs, Impulse::ZERO);
        assert_eq!(
            (imp, vel),
            (zero, zero_vel),
            "{plan}: start (-1, 0.3) and (0, 0)"
        );
    }
}

/// cargo-fuzz `solve_problem` (crash-181ce052…): PGS returned `Ok` with a NaN tangent
/// impulse. Its divergence check looked at `max |Δλ|` only, and `f64::max` skips NaN; it now
/// checks the sum of squares too, and every impulse and velocity before returning.
#[test]
fn regression_pgs_returned_ok_with_a_nan_impulse() {
    // A light ball (inverse mass 1e300) whose start of 1e10 N·s throws it up at ∞ m/s: the
    // first sweep's tangent velocity is ∞ · 0 = NaN, so are its impulse changes. The sum of
    // squares sees them in that sweep, whatever the stop rule's norm.
    let mut p = ContactProblem::new();
    let ground = p.add_body(body(0.0, -0.5, 0.0, 0.0, Vector::zeros()));
    let ball = p.add_body(body(0.0, 0.5, 1e300, 0.0, Vector::zeros()));
    add_contact(
        &mut p,
        ground,
        ball,
        Vector::zeros(),
        Vector::new(0.0, 1.0),
        0.5,
    );
    assert_diverges_in(&p, &[Impulse::new(1e10, 0.0)], 1);

    // The same ball with a finite start and a spin of ∞ rad/s from two contacts whose
    // starts are each finite: every impulse change stays finite (each sweep cancels a finite
    // part of the spin, ∞ − 1.2e308 = ∞), so only the last check of the velocities sees it,
    // once the second sweep has changed nothing (converged).
    let mut p = ContactProblem::new();
    let ground = p.add_body(body(0.0, -0.5, 0.0, 0.0, Vector::zeros()));
    let wall = p.add_body(body(-1.0, 0.5, 0.0, 0.0, Vector::zeros()));
    let ball = p.add_body(body(0.0, 0.5, 1.0, 1e298, Vector::zeros()));
    // r × n = 0.3 at both points, so both starts spin the ball the same way.
    add_contact(
        &mut p,
        ground,
        ball,
        Vector::new(0.3, 0.0),
        Vector::new(0.0, 1.0),
        0.0,
    );
    add_contact(
        &mut p,
        wall,
        ball,
        Vector::new(-0.5, 0.2),
        Vector::new(1.0, 0.0),
        0.0,
    );
    let start = [Impulse::new(4e10, 0.0); 2];
    assert_diverges_in(&p, &start, 2);
}

/// cargo-fuzz `solve_problem` (crash-07ff248e…): a sweep that overflowed to λn = ∞ gave the
/// friction bound μ λn = NaN and `f64::clamp` panicked on it. The solver loop now clamps
/// without the panic and reports the divergence as `PgsError::Diverged`.
#[test]
fn regression_pgs_panicked_on_a_nan_friction_bound() {
    // A heavy ball (inverse mass 1e-300: effective mass 1e300) falling at 1e10 m/s on a
    // frictionless ground: the first sweep's normal impulse is 1e300 · 1e10 = ∞, which makes
    // the next sweep's friction bound 0 · ∞ = NaN. The divergence is refused in the sweep that
    // made it, before any bound of NaN.
    let mut p = ContactProblem::new();
    let ground = p.add_body(body(0.0, -0.5, 0.0, 0.0, Vector::zeros()));
    let ball = p.add_body(body(0.0, 0.5, 1e-300, 0.0, Vector::new(0.0, -1e10)));
    add_contact(
        &mut p,
        ground,
        ball,
        Vector::zeros(),
        Vector::new(0.0, 1.0),
        0.0,
    );
    assert_diverges_in(&p, &[Impulse::ZERO], 1);
}

/// Records, at one step, the island the solver it wraps leaves farthest from a solution: its
/// problem, the start it was given and the natural residual it was left at.
struct WorstIsland {
    inner: Box<dyn VelocitySolver>,
    recording: bool,
    worst: Option<(ContactProblem, Vec<Impulse>, Real)>,
}

impl VelocitySolver for WorstIsland {
    fn name(&self) -> &str {
        "worst-island"
    }

    fn solve(
        &mut self,
        problem: &ContactProblem,
        settings: &SolverSettings,
        impulses: &mut [Impulse],
        velocities: &mut [Velocity],
        report: &mut SolveReport,
    ) -> Result<(), CoreError> {
        let start = impulses.to_vec();
        self.inner
            .solve(problem, settings, impulses, velocities, report)?;
        let left = report.natural_residual;
        if self.recording && self.worst.as_ref().is_none_or(|w| left > w.2) {
            self.worst = Some((problem.clone(), start, left));
        }
        Ok(())
    }

    fn begin_step(&mut self, dt: Real, gravity: Vector) {
        self.inner.begin_step(dt, gravity);
    }

    fn projects_start(&self) -> bool {
        self.inner.projects_start()
    }
}

/// Circle pile, seed 1315, step 116, `learned-sor`'s start: `pgs-rescue` left a 102-point
/// island at 1.9e-3 N·s, above its 1e-3 target. PGS cycles there; Newton from PGS's last
/// iterate, from zeros and after the 5 000 finishing iterations all wander, while Newton from
/// some of the iterates along the finishing iterations converges. The finishing iterations now
/// run in rounds with a Newton solve between them.
#[test]
fn regression_rescue_left_a_cycling_island_above_its_target() {
    use deepcontact_core::{PositionSolver, WorldSettings};
    use deepcontact_lcp::{PgsRescueSolver, RescueSettings};
    let registry = deepcontact_experiments::full_registry();
    let one_round = RescueSettings {
        finish_chunk: 5_000,
        sweeps_first: false,
        ..RescueSettings::default()
    };
    let mut provider = registry.build_provider("learned-sor").unwrap();
    // The trajectory of the rescue before the rounds (one round of 5 000, no Newton in it,
    // after the Newton starts).
    let mut solver = WorstIsland {
        inner: Box::new(PgsRescueSolver::with_settings(one_round)),
        recording: false,
        worst: None,
    };
    let mut position = deepcontact_pgs::PgsPositionSolver::new();
    let position: &mut dyn PositionSolver = &mut position;
    let mut world = scene::pile(1315, 100)
        .unwrap()
        .build(WorldSettings::default())
        .unwrap();
    for step in 0..=116 {
        solver.recording = step == 116;
        world
            .step(provider.as_mut(), &mut solver, &mut *position)
            .unwrap();
    }
    let (problem, start, left) = solver.worst.unwrap();
    assert!(left > 1e-3, "the recorded island was left at {left:e}");
    let run = |settings: RescueSettings| {
        let mut rescue = PgsRescueSolver::with_settings(settings);
        let mut impulses = start.clone();
        let mut velocities = vec![Velocity::default(); problem.bodies.len()];
        let mut report = SolveReport::default();
        rescue
            .solve(
                &problem,
                &SolverSettings::default(),
                &mut impulses,
                &mut velocities,
                &mut report,
            )
            .unwrap();
        (report.natural_residual, rescue.stats())
    };
    let (before, stats) = run(one_round);
    assert_eq!(before.to_bits(), left.to_bits());
    assert_eq!((stats.finished, stats.finish_newtons), (1, 0), "{stats:?}");
    let (after, stats) = run(RescueSettings::default());
    assert!(stats.finish_newtons >= 1, "{stats:?}");
    assert!(after < 1e-3, "the rounds left the island at {after:e}");
}

/// cargo-fuzz `solve_problem` (crash-f5967ebb…): `add_point` after the last manifold's range
/// was edited by hand to end before it starts subtracted with overflow (a panic where overflow
/// is checked, elsewhere the wrong error); an edited range that started earlier, such as
/// `(0, 0)` after one point, took the new point in and ran over the points before it. The open
/// manifold must now end at the new point.
#[test]
fn regression_add_point_overflowed_on_an_edited_manifold_range() {
    let mut p = ContactProblem::new();
    let ground = p.add_body(body(0.0, -0.5, 0.0, 0.0, Vector::zeros()));
    let ball = p.add_body(body(0.0, 0.5, 1.0, 1.0, Vector::zeros()));
    let (point, up) = (Vector::new(0.0, 0.0), Vector::new(0.0, 1.0));
    add_contact(&mut p, ground, ball, point, up, 0.5);
    let desc = PointDesc {
        id: ContactId {
            body_a: ground,
            body_b: ball,
            feature_a: 1,
            feature_b: 0,
        },
        body_a: ground,
        body_b: ball,
        point,
        normal: up,
        separation: -0.01,
        friction: 0.5,
        restitution: 0.0,
        restitution_threshold: 1.0,
    };
    for edited in [(3, 1), (0, 0), (1, 2)] {
        let mut q = p.clone();
        q.manifolds.push(edited);
        let expected = format!(
            "range {}..{} does not end at this point",
            edited.0, edited.1
        );
        match q.add_point(&desc) {
            Err(CoreError::InvalidProblem(why)) if why.contains(&expected) => {}
            other => panic!("{edited:?}: expected a refusal naming the range, got {other:?}"),
        }
        assert_eq!(q.points.len(), 1, "{edited:?}: no point added");
    }
    // The manifold begun as the API asks still takes its point.
    p.begin_manifold();
    assert_eq!(p.add_point(&desc).expect("an open manifold"), 1);
}
