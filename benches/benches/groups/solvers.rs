//! PGS, PSOR and Newton on settled piles of 100, 1 000 and 10 000 bodies, each island started
//! from its recorded (builtin) warm start:
//!
//! * `solvers/iteration` — a fixed number of iterations (tolerance 0); the throughput is
//!   point-iterations, so criterion's element time is the cost per contact point per iteration;
//! * `solvers/solve` — the thesis stop rule (∞-norm < 1e-4, cap 1000); throughput in points.

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use deepcontact_benches::{SOLVERS, SolveScratch, fixed_iterations, registry};
use deepcontact_core::SolverSettings;

use super::{settled, sizes};

/// Fixed iteration counts per solver: Newton's iterations each factorise a matrix.
fn iterations(solver: &str) -> u32 {
    if solver == "newton" { 3 } else { 10 }
}

/// The `solvers/iteration` and `solvers/solve` groups.
pub fn bench(c: &mut Criterion) {
    let registry = registry();
    let sizes = sizes();
    for (name, stop) in [
        ("solvers/iteration", None),
        ("solvers/solve", Some(SolverSettings::default())),
    ] {
        let mut group = c.benchmark_group(name);
        group.sampling_mode(SamplingMode::Flat);
        for &n in &sizes {
            let snap = settled(n);
            for &solver_name in &SOLVERS {
                let mut solver = registry
                    .build_solver(solver_name)
                    .expect("registered solver");
                let settings = stop.unwrap_or_else(|| fixed_iterations(iterations(solver_name)));
                let mut scratch = SolveScratch::default();
                let counts = match scratch.solve_islands(solver.as_mut(), &snap.islands, &settings)
                {
                    Ok(c) => c,
                    Err(e) => {
                        eprintln!("{name}: skipping {solver_name} at {n} bodies: {e}");
                        continue;
                    }
                };
                let elements = if stop.is_some() {
                    snap.contacts() as u64
                } else {
                    counts.point_iterations
                };
                if stop.is_some() {
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
