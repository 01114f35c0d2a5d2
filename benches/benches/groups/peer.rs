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
use super::{peer_sizes, settle_steps};

/// Velocity iterations of the fixed-count comparison.
pub const ITERATIONS: u32 = 10;

/// Steps timed for the solver-only figures printed before the benchmarks.
const SOLVER_STEPS: u32 = 20;

/// The `peer` group.
pub fn bench(c: &mut Criterion) {
    if !super::wanted("peer") {
        return;
    }
    let mut group = c.benchmark_group("peer");
    group.sampling_mode(SamplingMode::Flat);
    for n in peer_sizes() {
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
        // Solver-only cost over a few steps (outside criterion; see the scaling example too).
        let (mut solve, mut points) = (0.0, 0);
        for _ in 0..SOLVER_STEPS {
            let r = world
                .step(&mut CarriedWarmStart, &mut solver, &mut position)
                .expect("step");
            solve += r.solve_seconds;
            points += r.contacts;
        }
        let ours_ns = solve / (points.max(1) as f64 * f64::from(ITERATIONS)) * 1e9;
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
        let (mut solve, mut collision, mut points) = (0.0, 0.0, 0);
        for _ in 0..SOLVER_STEPS {
            peer.step();
            solve += peer.solver_seconds();
            collision += peer.collision_seconds();
            points += peer.contacts();
        }
        let rapier_ns = solve / (points.max(1) as f64 * f64::from(ITERATIONS)) * 1e9;
        eprintln!(
            "peer: solver only at {n} bodies, ns per contact per iteration: deepcontact PGS {ours_ns:.1}, \
             rapier2d velocity resolution {rapier_ns:.1} (ratio {:.2}); rapier2d collision detection {:.3} ms/step",
            ours_ns / rapier_ns,
            collision / f64::from(SOLVER_STEPS) * 1e3
        );
        group.bench_function(BenchmarkId::new(format!("rapier2d-{ITERATIONS}"), n), |b| {
            b.iter(|| peer.step())
        });
    }
    group.finish();
}
