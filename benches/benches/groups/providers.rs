//! Every registered provider: `warm_start` on recorded thesis-pile steps (all islands of the
//! step, with the world attached as `World::step` does), and one full `World::step`.
//!
//! `providers/step` times single steps of the thesis pile (seed 12345, thesis settings) in the
//! window of steps 150..250 (the second half of the thesis's 250-step episode): the world is
//! run with builtin to step 150 (untimed), stepped with the provider, and rebuilt (untimed)
//! whenever it reaches step 250, so every provider is timed on the same stretch of the
//! episode, never on a pile that has come to rest.

use std::time::{Duration, Instant};

use criterion::{BenchmarkId, Criterion, Throughput};
use deepcontact_benches::{SEED, provider_cases, registry};
use deepcontact_core::{CarriedWarmStart, Impulse, World, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

use super::thesis_snapshots;

/// Window of steps of the 100-body thesis pile in which a provider's `World::step` is timed.
const STEP_FROM: u64 = 150;
/// End (exclusive) of the timed window.
const STEP_TO: u64 = 250;

/// The thesis pile after `STEP_FROM` builtin steps.
fn world_at_window_start() -> World {
    let mut world = scene::pile(SEED, 100)
        .and_then(|s| s.build(WorldSettings::default()))
        .expect("thesis pile");
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
    for _ in 0..STEP_FROM {
        world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .expect("warm-up step");
    }
    world
}

/// The `providers/warm_start` and `providers/step` groups.
pub fn bench(c: &mut Criterion) {
    if !super::wanted("providers") {
        return;
    }
    let registry = registry();
    let cases = provider_cases(&registry);
    let snapshots = thesis_snapshots();

    let mut group = c.benchmark_group("providers/warm_start");
    for case in &cases {
        let mut provider = match registry.build_provider(&case.spec) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("providers/warm_start: skipping {}: {e}", case.name);
                continue;
            }
        };
        for snap in snapshots {
            group.throughput(Throughput::Elements(snap.contacts() as u64));
            let id = BenchmarkId::new(&case.name, format!("step{}", snap.step));
            let mut out: Vec<Impulse> = Vec::new();
            group.bench_function(id, |b| {
                b.iter(|| snap.warm_start_all(provider.as_mut(), &mut out))
            });
        }
    }
    group.finish();

    let mut group = c.benchmark_group("providers/step");
    for case in &cases {
        let mut provider = match registry.build_provider(&case.spec) {
            Ok(p) => p,
            Err(e) => {
                eprintln!("providers/step: skipping {}: {e}", case.name);
                continue;
            }
        };
        let mut world = world_at_window_start();
        let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
        group.bench_function(
            BenchmarkId::new(&case.name, format!("steps{STEP_FROM}-{STEP_TO}")),
            |b| {
                b.iter_custom(|iters| {
                    let mut timed = Duration::ZERO;
                    for _ in 0..iters {
                        if world.step_index() >= STEP_TO {
                            world = world_at_window_start();
                        }
                        let t = Instant::now();
                        world
                            .step(provider.as_mut(), &mut solver, &mut position)
                            .expect("step");
                        timed += t.elapsed();
                    }
                    timed
                })
            },
        );
    }
    group.finish();
}
