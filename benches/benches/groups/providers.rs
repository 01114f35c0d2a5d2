//! Every registered provider: `warm_start` on recorded thesis-pile steps (all islands of the
//! step, with the world attached as `World::step` does), and one full `World::step`.

use criterion::{BenchmarkId, Criterion, Throughput};
use deepcontact_benches::{SEED, provider_cases, registry};
use deepcontact_core::{CarriedWarmStart, Impulse, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

use super::thesis_snapshots;

/// Steps of the 100-body pile run with builtin before a provider's `World::step` is timed.
const STEP_FROM: u64 = 150;

/// The `providers/warm_start` and `providers/step` groups.
pub fn bench(c: &mut Criterion) {
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
        let mut world = scene::pile(SEED, 100)
            .and_then(|s| s.build(WorldSettings::default()))
            .expect("thesis pile");
        let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
        for _ in 0..STEP_FROM {
            world
                .step(&mut CarriedWarmStart, &mut solver, &mut position)
                .expect("warm-up step");
        }
        group.bench_function(
            BenchmarkId::new(&case.name, format!("from{STEP_FROM}")),
            |b| {
                b.iter(|| {
                    world
                        .step(provider.as_mut(), &mut solver, &mut position)
                        .expect("step")
                })
            },
        );
    }
    group.finish();
}
