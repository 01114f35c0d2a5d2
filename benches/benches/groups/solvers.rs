//! PGS, PSOR and Newton on settled piles of 100, 1 000 and 10 000 bodies, each island started
//! from its recorded (builtin) warm start:
//!
//! * `solvers/iteration` — a fixed number of iterations (tolerance 0; PGS and PSOR 10, Newton 3
//!   and at most 1 000 bodies); the throughput is
//!   point-iterations, so criterion's element time is the cost per contact point per iteration;
//! * `solvers/solve` — the thesis stop rule (∞-norm < 1e-4, cap 1000; Newton: cap 50, at most
//!   1 000 bodies); throughput in contact points;
//! * `solvers/assembly` — the LCP solvers' set-up: `J`, `M⁻¹` and `W = J M⁻¹ Jᵀ` with `q` for
//!   every island of the step (dense up to 128 rows, sparse above, as the solvers choose),
//!   buffers reused across iterations; throughput in contact points;
//! * `solvers/position` — the position pass (`ngs`, one thread) over every island of the step,
//!   10 iterations from the recorded poses with the movable bodies 2 cm lower (every point
//!   corrects, none stops early); throughput in point-iterations.

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use deepcontact_benches::{SOLVERS, SolveScratch, fixed_iterations, registry};
use deepcontact_core::math::{Pose, Vector};
use deepcontact_core::{PositionSettings, PositionSolver, ProblemBody, SolverSettings};
use deepcontact_lcp::{AssemblyMode, DEFAULT_DENSE_THRESHOLD, Delassus};
use deepcontact_pgs::PgsPositionSolver;

use super::{settled, sizes};

/// Fixed iteration counts per solver: Newton's iterations each factorise a matrix, and are
/// not run beyond 1 000 bodies (seconds per iteration at 10 000).
fn iterations(solver: &str, bodies: usize) -> Option<u32> {
    match solver {
        "newton" if bodies > 1_000 => None,
        "newton" => Some(3),
        _ => Some(10),
    }
}

/// Stop rule of the `solvers/solve` group: the thesis rule; for Newton with the cap lowered
/// to 50 (it rarely meets the Δλ rule on piles, and each iteration is a factorisation), and
/// not run beyond 1 000 bodies (one solve would take minutes).
fn solve_settings(solver: &str, bodies: usize) -> Option<SolverSettings> {
    match solver {
        "newton" if bodies > 1_000 => None,
        "newton" => Some(SolverSettings {
            max_iterations: 50,
            ..SolverSettings::default()
        }),
        _ => Some(SolverSettings::default()),
    }
}

/// The `solvers/iteration` and `solvers/solve` groups.
pub fn bench(c: &mut Criterion) {
    if !super::wanted("solvers") {
        return;
    }
    let registry = registry();
    let sizes = sizes();
    assembly(c, &sizes);
    position(c, &sizes);
    for (name, thesis) in [("solvers/iteration", false), ("solvers/solve", true)] {
        let mut group = c.benchmark_group(name);
        group.sampling_mode(SamplingMode::Flat);
        for &n in &sizes {
            let snap = settled(n);
            for &solver_name in &SOLVERS {
                let mut solver = registry
                    .build_solver(solver_name)
                    .expect("registered solver");
                let settings = if thesis {
                    solve_settings(solver_name, n)
                } else {
                    iterations(solver_name, n).map(fixed_iterations)
                };
                let Some(settings) = settings else {
                    eprintln!(
                        "{name}: skipping {solver_name} at {n} bodies (seconds per iteration)"
                    );
                    continue;
                };
                let mut scratch = SolveScratch::default();
                let counts = match scratch.solve_islands(solver.as_mut(), &snap.islands, &settings)
                {
                    Ok(c) => c,
                    Err(e) => {
                        eprintln!("{name}: skipping {solver_name} at {n} bodies: {e}");
                        continue;
                    }
                };
                let elements = if thesis {
                    snap.contacts() as u64
                } else {
                    counts.point_iterations
                };
                if thesis {
                    eprintln!(
                        "{name}: {solver_name} at {n} bodies: {} contacts, {} iterations (max over islands)",
                        snap.contacts(),
                        counts.iterations_max
                    );
                }
                group.throughput(Throughput::Elements(elements));
                group.bench_function(BenchmarkId::new(solver_name, n), |b| {
                    b.iter(|| {
                        scratch
                            .solve_islands(solver.as_mut(), &snap.islands, &settings)
                            .expect("solve")
                    })
                });
            }
        }
        group.finish();
    }
}

/// The `solvers/assembly` group: the Delassus assembly of every island of a settled pile.
fn assembly(c: &mut Criterion, sizes: &[usize]) {
    let mut group = c.benchmark_group("solvers/assembly");
    group.sampling_mode(SamplingMode::Flat);
    for &n in sizes {
        let snap = settled(n);
        let mut delassus = Delassus::new();
        let assemble_all = |delassus: &mut Delassus| {
            for island in &snap.islands {
                delassus
                    .assemble(&island.problem, AssemblyMode::Auto, DEFAULT_DENSE_THRESHOLD)
                    .expect("assembly of a recorded pile problem");
            }
        };
        assemble_all(&mut delassus);
        group.throughput(Throughput::Elements(snap.contacts() as u64));
        group.bench_function(BenchmarkId::new("delassus", n), |b| {
            b.iter(|| assemble_all(&mut delassus))
        });
    }
    group.finish();
}

/// The `solvers/position` group: 10 iterations of the position pass on every island of a
/// settled pile, its movable bodies pushed 2 cm down.
fn position(c: &mut Criterion, sizes: &[usize]) {
    let settings = PositionSettings {
        max_iterations: 10,
        tolerance: 0.0,
        ..PositionSettings::default()
    };
    let mut group = c.benchmark_group("solvers/position");
    group.sampling_mode(SamplingMode::Flat);
    for &n in sizes {
        let snap = settled(n);
        let starts: Vec<Vec<Pose>> = snap
            .islands
            .iter()
            .map(|island| {
                let drop = Vector::new(0.0, 0.02);
                let pushed = |b: &ProblemBody| {
                    let down = if b.inv_mass > 0.0 {
                        drop
                    } else {
                        Vector::zeros()
                    };
                    Pose::new(b.position - down, b.angle)
                };
                island.problem.bodies.iter().map(pushed).collect()
            })
            .collect();
        let mut pass = PgsPositionSolver::new();
        let mut poses = starts.clone();
        let run = |pass: &mut PgsPositionSolver, poses: &mut Vec<Vec<Pose>>| {
            let mut point_iterations = 0;
            for ((island, start), poses) in snap.islands.iter().zip(&starts).zip(poses) {
                poses.clone_from(start);
                let report = pass
                    .solve_positions(&island.problem, &settings, poses)
                    .expect("position pass");
                point_iterations += island.problem.points.len() as u64 * report.iterations as u64;
            }
            point_iterations
        };
        let elements = run(&mut pass, &mut poses);
        assert_eq!(
            elements,
            10 * snap.contacts() as u64,
            "every island ran its 10 iterations"
        );
        group.throughput(Throughput::Elements(elements));
        group.bench_function(BenchmarkId::new("ngs", n), |b| {
            b.iter(|| run(&mut pass, &mut poses))
        });
    }
    group.finish();
}
