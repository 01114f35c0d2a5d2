//! deepcontact and rapier2d stepping the same pile side by side (one criterion group, so the
//! figures of one run compare directly):
//!
//! * `deepcontact-fixed{N}` — builtin warm start, PGS, exactly N velocity iterations, position
//!   pass capped at N;
//! * `rapier2d-{N}` — rapier2d with `num_solver_iterations = N` (see `rapier_pile.rs` for the
//!   matched settings);
//! * `deepcontact-thesis` — the thesis stop rule (∞-norm < 1e-4, cap 1000; position cap 250).
//!
//! Both engines are first settled for the same number of steps from the same bodies; each
//! benchmark then keeps stepping its own world.

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use deepcontact_benches::{SEED, fixed_world};
use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

use super::rapier_pile::RapierPile;
use super::{settle_steps, sizes};

/// Velocity iterations of the fixed-count comparison.
pub const ITERATIONS: u32 = 10;

/// The `peer` group.
pub fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("peer");
    group.sampling_mode(SamplingMode::Flat);
    for n in sizes() {
        let pile = scene::pile(SEED, n).expect("pile");
        let settle = settle_steps(n);
        group.throughput(Throughput::Elements(n as u64));

        // One world, settled once: the fixed-count benchmark runs first, the thesis stop rule
        // then continues from where it left off.
        let mut world = pile.build(fixed_world(ITERATIONS)).expect("world");
        let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
        let mut contacts = 0;
        for _ in 0..settle {
            contacts = world
                .step(&mut CarriedWarmStart, &mut solver, &mut position)
                .expect("settle")
                .contacts;
        }
        eprintln!(
            "peer: deepcontact at {n} bodies: {contacts} contacts after {settle} steps, KE {:.3} J",
            world.kinetic_energy()
        );
        for (label, settings) in [
            (
                format!("deepcontact-fixed{ITERATIONS}"),
                fixed_world(ITERATIONS),
            ),
            ("deepcontact-thesis".into(), WorldSettings::default()),
        ] {
            world.set_settings(settings).expect("settings");
            group.bench_function(BenchmarkId::new(label, n), |b| {
                b.iter(|| {
                    world
                        .step(&mut CarriedWarmStart, &mut solver, &mut position)
                        .expect("step")
                })
            });
        }

        let mut peer = RapierPile::new(&pile, ITERATIONS as usize);
        for _ in 0..settle {
            peer.step();
        }
        eprintln!(
            "peer: rapier2d-{ITERATIONS} at {n} bodies: {} contacts after {settle} steps, KE {:.3} J",
            peer.contacts(),
            peer.kinetic_energy()
        );
        group.bench_function(BenchmarkId::new(format!("rapier2d-{ITERATIONS}"), n), |b| {
            b.iter(|| peer.step())
        });
    }
    group.finish();
}
