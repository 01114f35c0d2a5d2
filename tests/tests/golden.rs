//! Golden hash of the thesis pile: a bit-exact fingerprint of a whole run.
//!
//! Thread-count independence of `deepcontact compare` (1 vs 2 threads, bit for bit) is
//! already covered by `compare_writes_every_file_and_ignores_the_thread_count` in
//! `tests/tests/compare.rs`, so it is not repeated here.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use deepcontact_core::math::Pose;
use deepcontact_core::{
    ContactProblem, CoreError, PositionReport, PositionSettings, PositionSolver, WorldSettings,
    scene,
};
use deepcontact_experiments::simulate::{SimulateConfig, run_scene};
use deepcontact_pgs::{PgsPositionSettings, PgsPositionSolver, PgsSettings, PgsSolver};
use deepcontact_tests::{build, run_with};

/// FNV-1a 64 over the little-endian bytes of `words` (stable by definition, unlike
/// `std::collections::hash_map::DefaultHasher`, whose algorithm may change between releases).
fn fnv1a64(words: impl IntoIterator<Item = u64>) -> u64 {
    fnv1a64_bytes(words.into_iter().flat_map(u64::to_le_bytes))
}

/// FNV-1a 64 over `bytes`.
fn fnv1a64_bytes(bytes: impl IntoIterator<Item = u8>) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for byte in bytes {
        h ^= u64::from(byte);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Hash of the pile (seed 12345, 100 circles) after 250 steps with the `builtin` warm start
/// and the default PGS solver (coloured order, block solver), over every body's
/// position x, y, angle, linear velocity x, y and angular velocity (`f64::to_bits`), in body order.
///
/// **When it may legitimately change:** any change to the step pipeline (integration,
/// broad/narrow phase, contact ids and impulse carry-over, islands, position pass), to the
/// PGS solver (row or manifold order, colouring, block solver, clamping), to the default
/// world settings, to the scene generator or its RNG, to the parry2d (or nalgebra) version,
/// or to the floating-point evaluation order anywhere on that path (including compiler
/// flags such as FMA contraction or target features). A change that is not meant to touch
/// the physics must keep it.
///
/// **How to update it:** run `cargo test -p deepcontact-tests --test golden -- --nocapture`;
/// the test prints the new value (`golden hash: 0x…`). Check that the physics change was
/// intended (e.g. `tests/tests/physics.rs` still passes), then paste the value here and say
/// why in the commit message.
const PILE_12345_250_BUILTIN_PGS: u64 = 0xe32d_4759_00b5_0c98;

fn pile_hash() -> (u64, usize) {
    pile_hash_with(PgsSolver::new(), PgsPositionSolver::new())
}

/// [`pile_hash`] with the given solvers.
fn pile_hash_with(solver: PgsSolver, position: PgsPositionSolver) -> (u64, usize) {
    pile_hash_on(solver, position, 1)
}

/// [`pile_hash_with`] with islands solved on `island_threads` threads.
fn pile_hash_on(
    solver: PgsSolver,
    position: PgsPositionSolver,
    island_threads: usize,
) -> (u64, usize) {
    let (hash, bodies, _) = pile_run(solver, position, island_threads);
    (hash, bodies)
}

/// [`pile_hash_on`], and the most threads that one island's velocity sweep ran on
/// ([`PgsSolver::threads_used`]).
fn pile_run(
    solver: PgsSolver,
    position: PgsPositionSolver,
    island_threads: usize,
) -> (u64, usize, usize) {
    let mut world = build(&scene::pile(12345, 100).unwrap());
    world
        .set_settings(WorldSettings {
            island_threads,
            ..WorldSettings::default()
        })
        .unwrap();
    let mut warm = deepcontact_experiments::full_registry()
        .build_provider("builtin")
        .unwrap();
    let mut solvers = (solver, position);
    let reports = run_with(&mut world, warm.as_mut(), &mut solvers, 250, |_, _| {}).unwrap();
    assert_eq!(reports.len(), 250);
    assert!(reports.iter().all(|r| r.fallbacks == 0));
    let words = world
        .bodies()
        .iter()
        .flat_map(|b| b.state().map(f64::to_bits));
    (
        fnv1a64(words),
        world.bodies().len(),
        solvers.0.threads_used(),
    )
}

#[test]
fn fnv1a64_matches_the_reference_vectors() {
    // The published FNV-1a 64 values (Fowler, Noll, Vo test suite).
    assert_eq!(fnv1a64_bytes(*b""), 0xcbf2_9ce4_8422_2325);
    assert_eq!(fnv1a64_bytes(*b"a"), 0xaf63_dc4c_8601_ec8c);
    assert_eq!(fnv1a64_bytes(*b"foobar"), 0x8594_4171_f739_67e8);
    // A word is its 8 bytes, least significant first: "foobar" and two zero bytes.
    let word = u64::from_le_bytes(*b"foobar\0\0");
    assert_eq!(fnv1a64([word]), fnv1a64_bytes(*b"foobar\0\0"));
    assert_eq!(fnv1a64([]), 0xcbf2_9ce4_8422_2325);
}

#[test]
fn pile_golden_hash() {
    let (hash, bodies) = pile_hash();
    println!("golden hash: {hash:#018x} ({bodies} bodies)");
    assert_eq!(bodies, 104, "100 circles and 4 walls");
    assert_eq!(
        hash, PILE_12345_250_BUILTIN_PGS,
        "the pile's golden hash changed: {hash:#018x} (see the doc comment of \
         PILE_12345_250_BUILTIN_PGS for when this is legitimate and how to update it)"
    );
}

/// The chunked sweeps on every island (`parallel_from` 0) on `threads` threads: the
/// velocity sweep in the chunked plan (`domains` 0, one batch a chunk so that the pile's
/// colours have chunks for several threads), or in the domain plan of `domains`.
fn chunked(threads: usize, position: bool) -> (PgsSolver, PgsPositionSolver) {
    planned(threads, position, 0)
}

/// [`chunked`] with the velocity sweep's and the position pass's `domains` (0: the chunked
/// and coloured plans), that many whatever the islands' sizes.
fn planned(threads: usize, position: bool, domains: usize) -> (PgsSolver, PgsPositionSolver) {
    let solver = PgsSolver::with_settings(PgsSettings {
        threads,
        parallel_min_points: 0,
        domains,
        domain_points: 0,
        chunk: 1,
        ..PgsSettings::default()
    });
    let position = if position {
        PgsPositionSolver::with_settings(PgsPositionSettings {
            threads,
            parallel_min_points: 0,
            domains,
            domain_points: 0,
        })
    } else {
        PgsPositionSolver::new()
    };
    (solver, position)
}

#[test]
fn pile_golden_hash_is_the_same_on_one_two_and_more_threads_than_cores() {
    // Islands side by side, and the chunked velocity sweep, give the golden bits on any
    // thread count (the ∞-norm stop rule sees the same maxima). The counts asked for are 1,
    // 2 and one more than the cores; the sweep runs on as many as the cores allow.
    let cores = deepcontact_tests::cores();
    let counts = [1, 2, cores + 1];
    for threads in counts {
        let (solver, position) = chunked(threads, false);
        let (hash, _, used) = pile_run(solver, position, threads);
        assert_eq!(
            hash, PILE_12345_250_BUILTIN_PGS,
            "islands and chunked velocity sweep on {threads} threads: {hash:#018x}"
        );
        assert_eq!(used, threads.min(cores), "{threads} threads asked for");
    }
    // The coloured position pass visits the points in another order (another, equally valid
    // result), the same for every thread count.
    let hashes = counts.map(|threads| {
        let (solver, position) = chunked(threads, true);
        pile_hash_on(solver, position, threads).0
    });
    assert_eq!(
        hashes[0], hashes[1],
        "coloured position pass, 1 and 2 threads"
    );
    assert_eq!(
        hashes[0],
        hashes[2],
        "coloured position pass, 1 and {} threads",
        cores + 1
    );
    assert_ne!(
        hashes[0], PILE_12345_250_BUILTIN_PGS,
        "the coloured order did not run"
    );
}

#[test]
fn pile_in_the_domain_plan_ends_in_the_same_bits_on_one_two_and_more_threads_than_cores() {
    // Eight domains on every island, in the velocity sweep and the position pass: another
    // Gauss-Seidel order than the golden run's (so another hash), the same for every thread
    // count (1, 2 and one more than the cores).
    let cores = deepcontact_tests::cores();
    let runs = [1, 2, cores + 1].map(|threads| {
        let (solver, position) = planned(threads, true, 8);
        let (hash, _, used) = pile_run(solver, position, threads);
        // No more threads than the cores, nor than the 4 domains of a phase.
        assert_eq!(
            used,
            threads.min(cores).min(4),
            "{threads} threads asked for"
        );
        hash
    });
    assert_eq!(runs[0], runs[1], "domain plan, 1 and 2 threads");
    assert_eq!(runs[0], runs[2], "domain plan, 1 and {} threads", cores + 1);
    assert_ne!(
        runs[0], PILE_12345_250_BUILTIN_PGS,
        "the domain plan did not run"
    );
}

/// [`PgsPositionSolver`]'s pass, counting the forks the world asked for (forks share the
/// count): the world forks the pass only to correct islands side by side.
struct CountingPass {
    pass: Box<dyn PositionSolver>,
    forks: Arc<AtomicUsize>,
}

impl PositionSolver for CountingPass {
    fn name(&self) -> &str {
        "counting"
    }

    fn solve_positions(
        &mut self,
        problem: &ContactProblem,
        settings: &PositionSettings,
        poses: &mut [Pose],
    ) -> Result<PositionReport, CoreError> {
        self.pass.solve_positions(problem, settings, poses)
    }

    fn fork(&self) -> Option<Box<dyn PositionSolver>> {
        self.forks.fetch_add(1, Ordering::Relaxed);
        Some(Box::new(CountingPass {
            pass: self.pass.fork()?,
            forks: Arc::clone(&self.forks),
        }))
    }
}

#[test]
fn position_pass_of_islands_side_by_side_keeps_the_golden_bits() {
    // Two island threads: the falling pile's many small islands are corrected side by side
    // (two forks a step), and the settled pile's large island (corrected on one thread) on a
    // fork beside the others; the run ends in the golden bits.
    let mut world = build(&scene::pile(12345, 100).unwrap());
    world
        .set_settings(WorldSettings {
            island_threads: 2,
            ..WorldSettings::default()
        })
        .unwrap();
    let mut warm = deepcontact_experiments::full_registry()
        .build_provider("builtin")
        .unwrap();
    let forks = Arc::new(AtomicUsize::new(0));
    let mut pass = CountingPass {
        pass: Box::new(PgsPositionSolver::new()),
        forks: Arc::clone(&forks),
    };
    let mut solver = PgsSolver::new();
    for _ in 0..250 {
        world.step(warm.as_mut(), &mut solver, &mut pass).unwrap();
    }
    let words = world
        .bodies()
        .iter()
        .flat_map(|b| b.state().map(f64::to_bits));
    let hash = fnv1a64(words);
    let forks = forks.load(Ordering::Relaxed);
    assert!(
        forks >= 2,
        "{forks} forks: no step corrected islands side by side"
    );
    assert_eq!(
        hash, PILE_12345_250_BUILTIN_PGS,
        "islands corrected side by side ({forks} forks): {hash:#018x}"
    );
}

#[test]
fn simulate_with_a_lower_position_plan_threshold_is_the_same_on_one_and_two_threads() {
    // From 64 points the pile's settled island is corrected in the domain plan (other bits
    // than the default's problem order), shared by the threads: the same bits on 1 and 2.
    let registry = deepcontact_experiments::full_registry();
    let run = |threads: usize, position_parallel_from: usize| {
        let config = SimulateConfig {
            threads,
            position_parallel_from,
            steps: 200,
            ..SimulateConfig::default()
        };
        let (world, totals) = run_scene(&config, &registry, |_| {}).unwrap();
        assert!(
            totals.mean_contacts > 30.0,
            "{} contacts",
            totals.mean_contacts
        );
        let words = world
            .bodies()
            .iter()
            .flat_map(|b| b.state().map(f64::to_bits));
        fnv1a64(words)
    };
    let default = run(1, SimulateConfig::default().position_parallel_from);
    let (one, two) = (run(1, 64), run(2, 64));
    assert_eq!(one, two, "1 and 2 threads from 64 points");
    assert_ne!(one, default, "the domain plan did not run");
}

#[test]
fn simulate_totals_split_the_step_into_its_stages() {
    let registry = deepcontact_experiments::full_registry();
    let config = SimulateConfig {
        steps: 160,
        ..SimulateConfig::default()
    };
    let (_, totals) = run_scene(&config, &registry, |_| {}).unwrap();
    let st = totals.stages;
    assert!(
        totals.mean_contacts > 30.0,
        "{} contacts",
        totals.mean_contacts
    );
    for (stage, ms) in [
        ("collide", st.collide),
        ("islands", st.islands),
        ("solve", st.solve),
        ("position", st.position),
    ] {
        assert!(ms > 0.0, "{stage}: {ms} ms");
    }
    let sum = st.collide + st.islands + st.warm_start + st.solve + st.position + st.rest;
    assert!((sum - st.step).abs() <= 1e-9 * st.step.max(1.0), "{st:?}");
    // The steps are the loop's time but for its bookkeeping.
    assert!(
        (0.5 * totals.ms_per_step..=totals.ms_per_step).contains(&st.step),
        "{st:?} in {} ms",
        totals.ms_per_step
    );
}
