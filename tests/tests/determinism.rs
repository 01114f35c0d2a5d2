//! Every registered provider, run twice on the same world, gives the same bits, and so do one
//! and two island and collide threads (providers are called in island order on the stepping
//! thread, whatever the threads).

use deepcontact_core::{WarmStart, World, WorldSettings, scene};
use deepcontact_experiments::full_registry;
use deepcontact_pgs::PgsPositionSolver;

/// The bits of every body's pose and velocity and every contact's impulse after `steps`
/// steps of a 100-circle pile with `provider`, under `budget`, on `threads` threads (no more
/// than the cores); the contact points solved in all, and the most islands of a step (from
/// two, a step's islands are solved side by side on two threads).
fn run(
    provider: &str,
    budget: Option<u32>,
    threads: usize,
    steps: usize,
) -> (Vec<u64>, usize, usize) {
    let mut provider = full_registry().build_provider(provider).unwrap();
    run_with(provider.as_mut(), 11, budget, threads, steps)
}

/// [`run`] with a built provider, on the pile of `seed`.
fn run_with(
    provider: &mut dyn WarmStart,
    seed: u64,
    budget: Option<u32>,
    threads: usize,
    steps: usize,
) -> (Vec<u64>, usize, usize) {
    let registry = full_registry();
    let settings = WorldSettings {
        budget,
        island_threads: threads,
        collide_threads: threads,
        ..WorldSettings::default()
    };
    let mut world: World = scene::pile(seed, 100).unwrap().build(settings).unwrap();
    let mut solver = registry.build_solver("pgs").unwrap();
    let mut position = PgsPositionSolver::new();
    let (mut points, mut islands) = (0, 0);
    for _ in 0..steps {
        world
            .step(provider, solver.as_mut(), &mut position)
            .unwrap();
        points += world.last_problems().iter().map(|p| p.len()).sum::<usize>();
        islands = islands.max(world.last_problems().len());
    }
    let mut bits = Vec::new();
    for b in world.bodies() {
        let (p, v) = (b.position, b.linear_velocity);
        bits.extend([p.x, p.y, b.angle, v.x, v.y, b.angular_velocity].map(f64::to_bits));
    }
    for (_, i) in world.contacts() {
        bits.extend([i.normal.to_bits(), i.tangent.to_bits()]);
    }
    (bits, points, islands)
}

#[test]
fn every_provider_gives_the_same_bits_twice_and_on_one_or_two_threads() {
    let registry = full_registry();
    let mut ran = 0;
    for (name, _) in registry.providers() {
        if registry.build_provider(name).is_err() {
            // `onnx` and `graph-file` need a model file named on the command line.
            assert!(
                name == "onnx" || name == "graph-file",
                "{name} does not build"
            );
            continue;
        }
        for budget in [None, Some(8)] {
            let (first, points, islands) = run(name, budget, 1, 70);
            assert!(points > 300, "{name}: {points} contact points solved");
            assert!(islands >= 4, "{name}: at most {islands} islands a step");
            assert_eq!(
                first,
                run(name, budget, 1, 70).0,
                "{name}, {budget:?}: run twice"
            );
            assert_eq!(
                first,
                run(name, budget, 2, 70).0,
                "{name}, {budget:?}: two threads"
            );
            ran += 1;
        }
    }
    assert!(ran >= 40, "{ran} runs");
}

/// A world calls `reset` before its first step: a provider that stepped another world first
/// gives the bits of a fresh one.
#[test]
fn every_provider_reused_on_a_new_world_gives_the_bits_of_a_fresh_one() {
    let registry = full_registry();
    let (mut ran, mut differ) = (0, Vec::new());
    for (name, _) in registry.providers() {
        let Ok(mut used) = registry.build_provider(name) else {
            continue;
        };
        for budget in [None, Some(8)] {
            let (fresh, _, _) = run(name, budget, 1, 70);
            let (_, points, _) = run_with(used.as_mut(), 5, budget, 1, 70);
            assert!(
                points > 300,
                "{name}: {points} contact points on the first world"
            );
            let (again, _, _) = run_with(used.as_mut(), 11, budget, 1, 70);
            if fresh != again {
                differ.push(format!("{name} ({budget:?})"));
            }
            ran += 1;
        }
    }
    assert!(ran >= 40, "{ran} runs");
    assert!(differ.is_empty(), "reused, other bits: {differ:?}");
}

/// `random` seeded its generator at construction only, so a provider that had stepped one
/// world gave a second world other values than a fresh provider with the same seed.
#[test]
fn regression_random_kept_its_stream_across_worlds() {
    let (fresh, _, _) = run("random", None, 1, 70);
    let mut used = full_registry().build_provider("random").unwrap();
    let (first, _, _) = run_with(used.as_mut(), 5, None, 1, 70);
    assert_ne!(first, fresh, "two worlds");
    assert_eq!(run_with(used.as_mut(), 11, None, 1, 70).0, fresh);
}
