//! Shared fixtures of the integration tests: seeded random small problems and recorded
//! pile problems.
#![allow(dead_code)]

use std::collections::HashMap;
use std::sync::OnceLock;

use deepcontact_core::Velocity;

use deepcontact_core::math::{Real, Vector};
use deepcontact_core::rng::PortableRng;
use deepcontact_core::{
    CarriedWarmStart, ContactId, ContactProblem, Impulse, PointDesc, ProblemBody, SolveReport,
    SolverSettings, VelocitySolver, WorldSettings, scene,
};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// Conditioning of a random problem.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// Moderate masses, well-spread points and normals.
    Well,
    /// Mass ratios up to 1e4, nearly coincident points with nearly parallel normals.
    Bad,
    /// Like `Bad` but with up to 5 points on the same bodies: the frictional problem may
    /// be non-monotone; solvers must fail gracefully, not necessarily converge.
    Hostile,
    /// More rows than degrees of freedom: a body resting on several points (singular W).
    Redundant,
}

fn body(rng: &mut PortableRng, dynamic: bool, mass_range: (Real, Real)) -> ProblemBody {
    let (im, ii) = if dynamic {
        let lm = rng.uniform_range(mass_range.0.ln(), mass_range.1.ln());
        let li = rng.uniform_range(mass_range.0.ln(), mass_range.1.ln());
        (lm.exp(), li.exp())
    } else {
        (0.0, 0.0)
    };
    ProblemBody {
        world_index: u32::MAX,
        position: Vector::new(rng.uniform_range(-1.0, 1.0), rng.uniform_range(-1.0, 1.0)),
        angle: 0.0,
        linear_velocity: if dynamic {
            Vector::new(rng.normal(), rng.normal() - 1.0)
        } else {
            Vector::zeros()
        },
        angular_velocity: if dynamic { rng.normal() } else { 0.0 },
        inv_mass: im,
        inv_inertia: ii,
    }
}

fn unit(angle: Real) -> Vector {
    Vector::new(angle.cos(), angle.sin())
}

/// A random small problem (at most 5 points) for `seed`.
pub fn random_problem(seed: u64, kind: Kind) -> ContactProblem {
    let mut rng = PortableRng::new(seed);
    let mut p = ContactProblem::new();
    let mass_range = if matches!(kind, Kind::Bad | Kind::Hostile) {
        (1e-3, 1e1)
    } else {
        (0.5, 2.0)
    };
    let ground = p.add_body(body(&mut rng, false, mass_range));
    let nd = 1
        + (rng.next_u64()
            % if matches!(kind, Kind::Well | Kind::Bad) {
                4
            } else {
                3
            }) as u32;
    let dynamic: Vec<u32> = (0..nd)
        .map(|_| p.add_body(body(&mut rng, true, mass_range)))
        .collect();
    let mut feature = 0u64;
    let mut pair_friction: HashMap<(u32, u32), Real> = HashMap::new();
    let mut add =
        |p: &mut ContactProblem, rng: &mut PortableRng, a: u32, b: u32, at: Vector, n: Vector| {
            feature += 1;
            let id = ContactId {
                body_a: a,
                body_b: b,
                feature_a: feature,
                feature_b: 0,
            };
            // All points of one body pair share its friction, as in a world.
            let friction = *pair_friction
                .entry((a.min(b), a.max(b)))
                .or_insert_with(|| rng.uniform_range(0.0, 1.0));
            // Restitution (a velocity bias) except on the nearly coincident points of `Bad`,
            // where one point above the restitution threshold and one below would ask for two
            // different velocities along (almost) the same direction.
            let restitution = if matches!(kind, Kind::Well | Kind::Redundant) && rng.uniform() < 0.3
            {
                rng.uniform()
            } else {
                0.0
            };
            p.add_point(&PointDesc {
                id,
                body_a: a,
                body_b: b,
                point: at,
                normal: n,
                separation: -0.01,
                friction,
                restitution,
                restitution_threshold: 0.5,
            })
            .unwrap();
        };
    match kind {
        Kind::Well => {
            // One point per dynamic body (2 rows for its 3 degrees of freedom): W is regular.
            for &b in &dynamic {
                let others: Vec<u32> = dynamic.iter().copied().filter(|&o| o < b).collect();
                let a = if others.is_empty() || rng.uniform() < 0.5 {
                    ground
                } else {
                    others[(rng.next_u64() % others.len() as u64) as usize]
                };
                let normal = unit(rng.uniform_range(0.0, std::f64::consts::TAU));
                let at =
                    p.bodies[b as usize].position + Vector::new(rng.normal(), rng.normal()) * 0.5;
                p.begin_manifold();
                add(&mut p, &mut rng, a, b, at, normal);
            }
        }
        Kind::Bad => {
            // One manifold per dynamic body, often two nearly coincident points with nearly
            // parallel normals (W nearly singular), masses spread over 1e4.
            for &b in &dynamic {
                let others: Vec<u32> = dynamic.iter().copied().filter(|&o| o < b).collect();
                let a = if others.is_empty() || rng.uniform() < 0.5 {
                    ground
                } else {
                    others[(rng.next_u64() % others.len() as u64) as usize]
                };
                let normal = unit(rng.uniform_range(0.0, std::f64::consts::TAU));
                let at =
                    p.bodies[b as usize].position + Vector::new(rng.normal(), rng.normal()) * 0.5;
                p.begin_manifold();
                add(&mut p, &mut rng, a, b, at, normal);
                if rng.uniform() < 0.7 {
                    let n2 = unit(normal.y.atan2(normal.x) + 1e-4 * rng.normal());
                    add(&mut p, &mut rng, a, b, at + Vector::new(1e-4, -1e-4), n2);
                }
            }
        }
        Kind::Hostile => {
            // Up to 5 points at random places on few bodies, nearly coincident pairs, masses
            // spread over 1e4: many rows per body, sliding friction that may make the
            // problem non-monotone (Painlevé-like).
            let n_points = 1 + (rng.next_u64() % 5) as usize;
            let mut made = 0;
            while made < n_points {
                let b = dynamic[(rng.next_u64() % nd as u64) as usize];
                let a = if rng.uniform() < 0.5 || nd == 1 {
                    ground
                } else {
                    let o = dynamic[(rng.next_u64() % nd as u64) as usize];
                    if o == b { ground } else { o }
                };
                let normal = unit(rng.uniform_range(0.0, std::f64::consts::TAU));
                let at =
                    p.bodies[b as usize].position + Vector::new(rng.normal(), rng.normal()) * 0.5;
                p.begin_manifold();
                add(&mut p, &mut rng, a, b, at, normal);
                made += 1;
                if made < n_points && rng.uniform() < 0.7 {
                    let n2 = unit(normal.y.atan2(normal.x) + 1e-4 * rng.normal());
                    add(&mut p, &mut rng, a, b, at + Vector::new(1e-4, -1e-4), n2);
                    made += 1;
                }
            }
        }
        Kind::Redundant => {
            // The first dynamic body rests on the ground on 3-4 points with the same normal,
            // the others (if any) on it.
            let b = dynamic[0];
            let k = 3 + (rng.next_u64() % 2) as usize;
            let up = Vector::new(0.0, 1.0);
            let c = p.bodies[b as usize].position;
            for m in 0..k {
                if m % 2 == 0 {
                    p.begin_manifold();
                }
                let at = c + Vector::new(-0.5 + m as Real / (k - 1) as Real, -0.5);
                add(&mut p, &mut rng, ground, b, at, up);
            }
            for &o in &dynamic[1..] {
                p.begin_manifold();
                let at = c + Vector::new(rng.uniform_range(-0.3, 0.3), 0.5);
                add(&mut p, &mut rng, b, o, at, up);
            }
        }
    }
    p
}

/// Recorded problems of the pile `scene::pile(12345, 100)` after [`PILE_STEPS`] steps of
/// PGS with the carried ("builtin") warm start.
#[derive(Debug)]
pub struct PileFixture {
    /// The last step's island problems.
    pub problems: Vec<ContactProblem>,
    /// Per problem, the impulses carried from the step before (the builtin start).
    pub carried: Vec<Vec<Impulse>>,
    /// Per problem, PGS's solution of the last step.
    pub solved: Vec<Vec<Impulse>>,
}

/// Steps of the pile fixture.
pub const PILE_STEPS: u64 = 150;

/// The pile fixture, built once per test binary.
pub fn pile() -> &'static PileFixture {
    static FIXTURE: OnceLock<PileFixture> = OnceLock::new();
    FIXTURE.get_or_init(|| {
        let mut world = scene::pile(12345, 100)
            .unwrap()
            .build(WorldSettings::default())
            .unwrap();
        let (mut solver, mut position, mut warm) =
            (PgsSolver::new(), PgsPositionSolver::new(), CarriedWarmStart);
        for _ in 0..PILE_STEPS - 1 {
            world.step(&mut warm, &mut solver, &mut position).unwrap();
        }
        let before: HashMap<ContactId, Impulse> = world.contacts().iter().copied().collect();
        world.step(&mut warm, &mut solver, &mut position).unwrap();
        let after: HashMap<ContactId, Impulse> = world.contacts().iter().copied().collect();
        let problems = world.last_problems().to_vec();
        let lookup = |m: &HashMap<ContactId, Impulse>, p: &ContactProblem| -> Vec<Impulse> {
            p.points
                .iter()
                .map(|pt| m.get(&pt.id).copied().unwrap_or(Impulse::ZERO))
                .collect()
        };
        let carried = problems.iter().map(|p| lookup(&before, p)).collect();
        let solved = problems.iter().map(|p| lookup(&after, p)).collect();
        PileFixture {
            problems,
            carried,
            solved,
        }
    })
}

/// Runs `solver` on `problem` from `start`; returns the impulses, velocities and report.
pub fn run(
    solver: &mut dyn VelocitySolver,
    problem: &ContactProblem,
    settings: &SolverSettings,
    start: &[Impulse],
) -> (Vec<Impulse>, Vec<Velocity>, SolveReport) {
    let mut imp = start.to_vec();
    let mut vel = vec![Velocity::default(); problem.bodies.len()];
    let mut report = SolveReport::default();
    solver
        .solve(problem, settings, &mut imp, &mut vel, &mut report)
        .unwrap();
    (imp, vel, report)
}

/// Largest component difference between two impulse lists.
pub fn max_diff(a: &[Impulse], b: &[Impulse]) -> Real {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0, |m: Real, (x, y)| {
        m.max((x.normal - y.normal).abs())
            .max((x.tangent - y.tangent).abs())
    })
}

/// Largest impulse magnitude (at least 1), to scale tolerances.
pub fn scale(a: &[Impulse]) -> Real {
    a.iter()
        .fold(1.0, |m: Real, x| m.max(x.normal.abs()).max(x.tangent.abs()))
}

/// Row layout `[n0, t0, ...]` of impulses.
pub fn rows(a: &[Impulse]) -> Vec<Real> {
    a.iter().flat_map(|i| [i.normal, i.tangent]).collect()
}
