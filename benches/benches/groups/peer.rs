//! deepcontact and rapier2d stepping the same pile side by side (one criterion group, so the
//! figures of one run compare directly):
//!
//! * `deepcontact-fixed{N}` — builtin warm start, PGS, exactly N velocity iterations (N passes
//!   over the contacts, normal and friction rows), position pass capped at N;
//! * `rapier2d-passes{N}` — rapier2d with one substep of N internal PGS passes (friction in
//!   every pass) plus its stabilisation pass: the like-with-like configuration;
//! * `rapier2d-passes{N}-normal-only` — the same with rapier's default friction rule (friction
//!   only in the final unbiased pass, the N passes solve normal rows alone);
//! * `rapier2d-substeps{N}` — rapier2d with N substeps, each an integration, a constraint
//!   update, a PGS pass and a stabilisation pass (see `rapier_pile.rs` for both and for the
//!   matched settings);
//! * `deepcontact-thesis` — the thesis stop rule (∞-norm < 1e-4, cap 1000; position cap 250).
//!
//! Both engines are first settled for the same number of steps from the same bodies; each
//! benchmark then keeps stepping its own world. Before the benchmarks, the solver-only cost
//! (ns per solver contact point per pass, velocity solve of each engine) is printed for
//! every configuration, measured in turn over the same number of steps, and then the slope
//! (`slope.rs`): what one more pass costs each engine (ours in `f64` and in `f32`), from whole
//! steps at 100 and 1 000 passes in turns, with the ratios ours / rapier2d.

use criterion::{BenchmarkId, Criterion, SamplingMode, Throughput};
use deepcontact_benches::{SEED, fixed_world};
use deepcontact_core::{CarriedWarmStart, World, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSettings, PgsSolver, Precision};

use super::rapier_pile::{RapierConfig, RapierPile};
use super::slope;
use super::{peer_sizes, settle_steps};

/// Velocity iterations (passes) of the fixed-count comparison.
pub const ITERATIONS: u32 = 10;

/// Rounds of the slope printed before the benchmarks.
const SLOPE_ROUNDS: u32 = 9;

/// Steps timed for the solver-only figures printed before the benchmarks.
const SOLVER_STEPS: u32 = 20;

/// The rapier2d configurations benchmarked beside ours.
fn rapier_configs() -> [RapierConfig; 3] {
    let n = ITERATIONS as usize;
    [
        RapierConfig::Passes(n),
        RapierConfig::PassesNormalOnly(n),
        RapierConfig::Substeps(n),
    ]
}

/// The `peer` group.
pub fn bench(c: &mut Criterion) {
    if !super::wanted("peer") {
        return;
    }
    let mut group = c.benchmark_group("peer");
    group.sampling_mode(SamplingMode::Flat);
    for n in peer_sizes() {
        let pile = scene::pile(SEED, n).expect("pile");
        group.throughput(Throughput::Elements(n as u64));
        let mut world = settled_world(&pile, n);
        let mut peer = settled_peer(&pile, n);
        print_solver_only(n, &mut world, &mut peer);
        print_slope(n, &mut world, &mut peer);
        bench_ours(&mut group, n, &mut world);
        for config in rapier_configs() {
            peer.set_config(config);
            group.bench_function(BenchmarkId::new(config.label(), n), |b| {
                b.iter(|| peer.step())
            });
        }
    }
    group.finish();
}

/// Our pile settled at the fixed iteration count.
fn settled_world(pile: &scene::Scene, n: usize) -> World {
    let settle = settle_steps(n);
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
    world
}

/// rapier2d's pile settled in its substep configuration.
fn settled_peer(pile: &scene::Scene, n: usize) -> RapierPile {
    let settle = settle_steps(n);
    let mut peer = RapierPile::new(pile, RapierConfig::Substeps(ITERATIONS as usize));
    for _ in 0..settle {
        peer.step();
    }
    eprintln!(
        "peer: rapier2d at {n} bodies: {} contacts after {settle} steps, KE {:.3} J",
        peer.contacts(),
        peer.kinetic_energy()
    );
    peer
}

/// Ours, fixed iterations then the thesis stop rule, continuing from the settled world.
fn bench_ours(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    n: usize,
    world: &mut World,
) {
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
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
}

/// Ns per solver contact point per pass of each engine's velocity solve over
/// [`SOLVER_STEPS`] steps of the settled piles, printed with the ratios (outside criterion;
/// the scaling example reports the same over whole runs).
fn print_solver_only(n: usize, world: &mut World, peer: &mut RapierPile) {
    world
        .set_settings(fixed_world(ITERATIONS))
        .expect("settings");
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
    let (mut solve, mut points) = (0.0, 0);
    for _ in 0..SOLVER_STEPS {
        let r = world
            .step(&mut CarriedWarmStart, &mut solver, &mut position)
            .expect("step");
        solve += r.solve_seconds;
        points += r.contacts;
    }
    let ours = solve / (points.max(1) as f64 * f64::from(ITERATIONS)) * 1e9;
    eprintln!("peer: {n} bodies, ns per solver contact point per pass: deepcontact PGS {ours:.1}");
    for config in rapier_configs() {
        peer.set_config(config);
        let (mut solve, mut points) = (0.0, 0);
        for _ in 0..SOLVER_STEPS {
            peer.step();
            solve += peer.solver_seconds();
            points += peer.contacts();
        }
        let ns = solve / (points.max(1) as f64 * peer.passes() as f64) * 1e9;
        eprintln!(
            "peer: {n} bodies, {} ({} passes per step): {ns:.1} ns per point per pass, ours / it {:.2}",
            config.label(),
            peer.passes(),
            ours / ns
        );
    }
}

/// The slope of both engines on the settled piles ([`slope::measure`], [`SLOPE_ROUNDS`]
/// rounds), printed as its table.
fn print_slope(n: usize, world: &mut World, peer: &mut RapierPile) {
    let mut position = PgsPositionSolver::default();
    let (mut f64_solver, mut f32_solver) = (
        PgsSolver::default(),
        PgsSolver::with_settings(PgsSettings {
            precision: Precision::F32,
            ..PgsSettings::default()
        }),
    );
    let row = slope::measure(
        n,
        world,
        &mut [
            ("pgs (f64)", &mut f64_solver),
            ("pgs:precision=f32", &mut f32_solver),
        ],
        &mut position,
        peer,
        SLOPE_ROUNDS,
        slope::block_steps(n),
    )
    .expect("slope");
    slope::print(&[row]);
}
