//! Fuzz harnesses of deepcontact, shared by the cargo-fuzz targets in `fuzz/fuzz_targets/` and
//! by the stable "fuzz-lite" test `tests/tests/fuzz_lite.rs` (a dev-dependency of the tests
//! crate). Each harness turns arbitrary bytes into input of a public API and panics only
//! when that API breaks its contract (a panic, or an `Ok` with a non-finite or inadmissible
//! result).

use std::path::Path;

use deepcontact_core::Velocity;

use deepcontact_core::math::Real;
use deepcontact_core::registry::{Registry, Spec, split_spec_list};
use deepcontact_core::{
    ContactId, ContactProblem, Impulse, Observation, PointDesc, ProblemBody, ResidualNorm,
    SolveReport, SolverSettings, Vector, VelocitySolver, WarmStartContext,
};
use deepcontact_lcp::{NewtonSolver, PsorSettings, PsorSolver};
use deepcontact_pgs::{Ordering, PgsSettings, PgsSolver};

/// Reads the fuzz input as a stream; past the end it yields zeros.
#[derive(Debug)]
pub struct Bytes<'a> {
    data: &'a [u8],
    pos: usize,
}

impl<'a> Bytes<'a> {
    /// A reader over `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data, pos: 0 }
    }

    /// Next byte (0 past the end).
    pub fn byte(&mut self) -> u8 {
        let b = self.data.get(self.pos).copied().unwrap_or(0);
        self.pos += 1;
        b
    }

    /// A small value in [-32.768, 32.767].
    pub fn small(&mut self) -> Real {
        Real::from(i16::from_le_bytes([self.byte(), self.byte()])) / 1000.0
    }

    /// A real, mostly small, sometimes special: NaN, ±inf, ±0, ±1e300, the smallest
    /// subnormal, or any bit pattern.
    pub fn real(&mut self) -> Real {
        match self.byte() {
            0 => Real::NAN,
            1 => Real::INFINITY,
            2 => Real::NEG_INFINITY,
            3 => 0.0,
            4 => -0.0,
            5 => 1e300,
            6 => -1e300,
            7 => 5e-324,
            8 => Real::from_bits(u64::from_le_bytes(std::array::from_fn(|_| self.byte()))),
            _ => self.small(),
        }
    }
}

/// A problem built from `bytes` through the public builders, plus some direct edits of its
/// public fields (bad manifold ranges, body indices out of range).
pub fn problem_from(bytes: &mut Bytes<'_>) -> ContactProblem {
    let mut p = ContactProblem::new();
    let bodies = 1 + bytes.byte() % 6;
    for _ in 0..bodies {
        p.add_body(ProblemBody {
            world_index: u32::MAX,
            position: Vector::new(bytes.real(), bytes.real()),
            angle: bytes.real(),
            linear_velocity: Vector::new(bytes.real(), bytes.real()),
            angular_velocity: bytes.real(),
            inv_mass: if bytes.byte() % 4 == 0 {
                0.0
            } else {
                bytes.real()
            },
            inv_inertia: if bytes.byte() % 4 == 0 {
                0.0
            } else {
                bytes.real()
            },
        });
    }
    let n = u32::from(bodies);
    let ops = bytes.byte() % 20;
    for k in 0..ops {
        match bytes.byte() % 10 {
            0 | 1 => p.begin_manifold(),
            2..=7 => {
                // Indices in range; `add_point` refuses a == b and other inadmissible points.
                let (a, b) = (u32::from(bytes.byte()) % n, u32::from(bytes.byte()) % n);
                let normal = if bytes.byte() % 4 == 0 {
                    Vector::new(bytes.real(), bytes.real())
                } else {
                    let angle = bytes.small();
                    Vector::new(angle.cos(), angle.sin())
                };
                let point = Vector::new(bytes.real(), bytes.real());
                let id = ContactId {
                    body_a: a.min(b),
                    body_b: a.max(b),
                    feature_a: u64::from(k),
                    feature_b: 0,
                };
                // Inadmissible points are refused here, with a typed error (the contract of
                // `add_point`); the solvers then meet what passed.
                let _ = p.add_point(&PointDesc {
                    id,
                    body_a: a,
                    body_b: b,
                    point,
                    normal,
                    separation: bytes.real(),
                    friction: bytes.real(),
                    restitution: bytes.real(),
                    restitution_threshold: bytes.real(),
                });
            }
            8 => {
                let (s, e) = (u32::from(bytes.byte() % 24), u32::from(bytes.byte() % 24));
                p.manifolds.push((s, e));
            }
            _ => {
                if !p.points.is_empty() {
                    let i = usize::from(bytes.byte()) % p.points.len();
                    p.points[i].body_b = u32::from(bytes.byte());
                }
            }
        }
    }
    p
}

fn solvers(bytes: &mut Bytes<'_>) -> Vec<Box<dyn VelocitySolver>> {
    vec![
        Box::new(PgsSolver::new()),
        Box::new(PgsSolver::with_settings(PgsSettings {
            ordering: Ordering::Sequential,
            ..Default::default()
        })),
        Box::new(PgsSolver::with_settings(PgsSettings {
            block_solver: false,
            ..Default::default()
        })),
        Box::new(PsorSolver::with_settings(PsorSettings {
            omega: if bytes.byte() % 4 == 0 {
                bytes.real()
            } else {
                1.0
            },
            ..Default::default()
        })),
        Box::new(NewtonSolver::new()),
    ]
}

/// What one [`solve_problem`] input reached.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct SolveOutcome {
    /// The problem passed [`ContactProblem::validate`] and has contact points.
    pub valid_problem: bool,
    /// Solves of a valid, non-empty problem under valid settings, with buffers of the right
    /// length and a finite start: the inputs whose results the contract speaks of.
    pub admissible_solves: usize,
    /// Of those, the solves that returned `Ok` (their impulses, velocities and report checked).
    pub checked_solves: usize,
}

/// Bytes → a contact problem, stop rule, warm start and buffers → every solver. Each solve
/// must return `Ok` or a typed error; an `Ok` on a valid problem with buffers of the right
/// length must leave finite, admissible impulses and finite velocities; an invalid problem
/// must never be solved. Returns what the input reached, so that a caller can tell inputs
/// that were refused early from inputs whose solved results were checked.
pub fn solve_problem(data: &[u8]) -> SolveOutcome {
    let mut bytes = Bytes::new(data);
    let problem = problem_from(&mut bytes);
    let valid = problem.validate();
    let settings = SolverSettings {
        max_iterations: u32::from(bytes.byte() % 40),
        tolerance: if bytes.byte() % 2 == 0 {
            1e-4
        } else {
            bytes.real()
        },
        norm: if bytes.byte() % 2 == 0 {
            ResidualNorm::Infinity
        } else {
            ResidualNorm::L2
        },
        min_iterations: u32::from(bytes.byte() % 3),
    };
    let settings_ok = settings.validate().is_ok();
    let len_delta = [0usize, 0, 0, 1][usize::from(bytes.byte() % 4)];
    let body_delta = [0usize, 0, 0, 1][usize::from(bytes.byte() % 4)];
    let start: Vec<Impulse> = (0..problem.len() + len_delta)
        .map(|_| match bytes.byte() % 4 {
            0 => Impulse::ZERO,
            _ => Impulse::new(bytes.real(), bytes.real()),
        })
        .collect();
    let start_finite = start.iter().all(Impulse::is_finite);
    let mut outcome = SolveOutcome {
        valid_problem: valid.is_ok() && !problem.points.is_empty(),
        ..SolveOutcome::default()
    };
    let admissible =
        outcome.valid_problem && settings_ok && len_delta == 0 && body_delta == 0 && start_finite;
    for mut solver in solvers(&mut bytes) {
        let mut impulses = start.clone();
        let mut velocities = vec![Velocity::default(); problem.bodies.len() + body_delta];
        let mut report = SolveReport::default();
        let result = solver.solve(
            &problem,
            &settings,
            &mut impulses,
            &mut velocities,
            &mut report,
        );
        let name = solver.name().to_string();
        if valid.is_err() {
            assert!(
                result.is_err(),
                "{name} solved an invalid problem ({valid:?})"
            );
        }
        if !settings_ok {
            assert!(
                result.is_err(),
                "{name} accepted invalid settings {settings:?}"
            );
        }
        if admissible {
            outcome.admissible_solves += 1;
        }
        if result.is_err() || len_delta != 0 || body_delta != 0 || !start_finite {
            continue;
        }
        if admissible {
            outcome.checked_solves += 1;
        }
        for (i, (imp, p)) in impulses.iter().zip(&problem.points).enumerate() {
            assert!(
                imp.is_finite(),
                "{name}: Ok with a non-finite impulse {imp:?} at point {i}"
            );
            assert!(
                imp.normal >= 0.0,
                "{name}: Ok with λn = {} at point {i}",
                imp.normal
            );
            assert!(
                imp.tangent.abs() <= p.friction * imp.normal * (1.0 + 1e-9) + Real::MIN_POSITIVE,
                "{name}: Ok with |λt| = {} > μ λn = {} at point {i}",
                imp.tangent.abs(),
                p.friction * imp.normal
            );
        }
        for (b, v) in velocities.iter().enumerate() {
            assert!(
                v.linear.x.is_finite() && v.linear.y.is_finite() && v.angular.is_finite(),
                "{name}: Ok with a non-finite velocity {v:?} of body {b}"
            );
        }
        assert!(
            report.iterations >= 1 && report.iterations <= settings.max_iterations,
            "{name}: {report:?}"
        );
    }
    outcome
}

/// A fixed small valid problem: one box corner pair on the ground, one circle on the box.
pub fn small_problem() -> ContactProblem {
    let mut p = ContactProblem::new();
    let body = |y: Real, v: Real, inv_mass: Real| ProblemBody {
        world_index: u32::MAX,
        position: Vector::new(0.0, y),
        angle: 0.0,
        linear_velocity: Vector::new(0.1, v),
        angular_velocity: 0.0,
        inv_mass,
        inv_inertia: 6.0 * inv_mass,
    };
    let ground = p.add_body(body(-0.5, 0.0, 0.0));
    let a = p.add_body(body(0.5, -0.1, 1.0));
    let c = p.add_body(body(1.5, -0.2, 2.0));
    let up = Vector::new(0.0, 1.0);
    let id = |a, b, f| ContactId {
        body_a: a,
        body_b: b,
        feature_a: f,
        feature_b: 0,
    };
    p.begin_manifold();
    p.add_point(&PointDesc {
        id: id(ground, a, 0),
        body_a: ground,
        body_b: a,
        point: Vector::new(-0.5, 0.0),
        normal: up,
        separation: -0.01,
        friction: 0.5,
        restitution: 0.0,
        restitution_threshold: 1.0,
    })
    .expect("a valid point");
    p.add_point(&PointDesc {
        id: id(ground, a, 1),
        body_a: ground,
        body_b: a,
        point: Vector::new(0.5, 0.0),
        normal: up,
        separation: -0.01,
        friction: 0.5,
        restitution: 0.0,
        restitution_threshold: 1.0,
    })
    .expect("a valid point");
    p.begin_manifold();
    p.add_point(&PointDesc {
        id: id(a, c, 2),
        body_a: a,
        body_b: c,
        point: Vector::new(0.0, 1.0),
        normal: up,
        separation: -0.005,
        friction: 0.3,
        restitution: 0.0,
        restitution_threshold: 1.0,
    })
    .expect("a valid point");
    p
}

/// Whether a spec asks for more work than a fuzz iteration should do (a huge iteration cap
/// with a zero tolerance is a legitimate request, just a slow one).
/// The full registry of the project ([`deepcontact_experiments::full_registry`]) as this
/// harness builds it: without the `onnx` feature of deepcontact-experiments here, so the CNN
/// providers (which load model files, too slow once per fuzz input) are absent; every solver,
/// the baselines and `grid` are in.
pub fn registry() -> Registry {
    deepcontact_experiments::full_registry()
}

fn too_slow(spec: &Spec) -> bool {
    spec.params.iter().any(|(k, v)| {
        k.contains("iter") && !matches!(v.trim().parse::<u64>(), Ok(n) if n <= 10_000)
            || k.contains("tolerance") && !matches!(v.trim().parse::<f64>(), Ok(t) if t >= 1e-12)
    })
}

/// Bytes → text → spec parsing, spec lists, the default registry's providers and solvers
/// (each one built is also run once on [`small_problem`]), and the ONNX model-card parser.
/// Each must return `Ok` or a typed error, never panic.
pub fn parse_specs(data: &[u8]) {
    let text = String::from_utf8_lossy(data);
    let text = text.as_ref();
    if let Ok(spec) = text.parse::<Spec>() {
        // Display and FromStr round-trip.
        let shown = spec.to_string();
        assert_eq!(
            shown.parse::<Spec>().as_ref(),
            Ok(&spec),
            "round trip of {text:?} via {shown:?}"
        );
    }
    let _ = split_spec_list(text);
    let _ = deepcontact_onnx::ModelCard::from_json(text, Path::new("fuzz.json"));
    let slow = text.parse::<Spec>().is_ok_and(|s| too_slow(&s));
    let registry = registry();
    let problem = small_problem();
    if let Ok(mut provider) = registry.build_provider(text) {
        if !slow {
            let carried = vec![Some(Impulse::new(1.0, 0.1)); problem.len()];
            let ctx = WarmStartContext::new(&problem, &carried, 1, 0.01);
            let mut out = vec![Impulse::ZERO; problem.len()];
            if provider.warm_start(&ctx, &mut out).is_ok() {
                let report = SolveReport::default();
                provider.observe(&ctx, &Observation::new(&out, &out, false, &report));
            }
        }
    }
    if let Ok(mut solver) = registry.build_solver(text) {
        if !slow {
            let mut impulses = vec![Impulse::ZERO; problem.len()];
            let mut velocities = vec![Velocity::default(); problem.bodies.len()];
            let mut report = SolveReport::default();
            let settings = SolverSettings::default();
            if solver
                .solve(
                    &problem,
                    &settings,
                    &mut impulses,
                    &mut velocities,
                    &mut report,
                )
                .is_ok()
            {
                assert!(
                    impulses.iter().all(Impulse::is_finite),
                    "{text:?}: {impulses:?}"
                );
            }
        }
    }
}

/// Bytes → scene-file text → [`deepcontact_core::scene_file::parse`], then
/// [`deepcontact_core::scene_file::pile_from_circles`] for the first seed in the file (box
/// side from the first byte: 0.5–128 m), then a world built from the scene and stepped three
/// times with `builtin` and PGS. Parsing and checking give the circles or a typed
/// `SceneFile` error; a scene that passes the checks builds and steps to finite bodies, or
/// fails with a typed error; never a panic. Returns the steps made (0 for a refused scene).
pub fn scene_file(data: &[u8]) -> usize {
    use deepcontact_core::scene_file::{parse, pile_from_circles};
    use deepcontact_core::{CarriedWarmStart, CoreError, World, WorldSettings};

    let side = 0.5 * Real::from(data.first().copied().unwrap_or(30).max(1));
    let text = String::from_utf8_lossy(data.get(1..).unwrap_or_default());
    let circles = match parse(&text, "fuzz.csv") {
        Ok(c) => c,
        Err(e) => {
            assert!(matches!(e, CoreError::SceneFile { .. }), "{e:?}");
            return 0;
        }
    };
    assert!(!circles.is_empty(), "parse gave an empty scene");
    let scene = match pile_from_circles(&circles, circles[0].seed, side, "fuzz.csv") {
        Ok(s) => s,
        Err(e) => {
            assert!(matches!(e, CoreError::SceneFile { .. }), "{e:?}");
            return 0;
        }
    };
    let Ok(mut world) = World::with_bodies(WorldSettings::default(), &scene.bodies) else {
        return 0;
    };
    let (mut solver, mut position) = (PgsSolver::new(), deepcontact_pgs::PgsPositionSolver::new());
    for steps in 0..3 {
        if world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .is_err()
        {
            return steps;
        }
        for b in world.bodies() {
            assert!(
                b.position.x.is_finite() && b.position.y.is_finite(),
                "non-finite body after a step: {b:?}"
            );
        }
    }
    3
}
