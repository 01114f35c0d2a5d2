//! The broad phase's time on the falling and settling 10 000-circle pile: the pile (seed
//! 12345) stepped with carried impulses and the one-thread solvers, the bodies kept every 60
//! steps and at step 249, then `BroadPhase::find_pairs` timed on each snapshot (mean of 200
//! calls, three rounds), with the pair count and a hash of the pairs (equal hashes: the same
//! pairs).
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example broad_phase
//! ```
//!
//! Timings are wall-clock; compare rows of one run only.

use deepcontact_core::broad_phase::BroadPhase;
use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};

fn main() {
    let mut world = scene::pile(12345, 10_000)
        .and_then(|s| s.build(WorldSettings::default()))
        .expect("the 10 000-body pile builds");
    let (mut solver, mut pass) = (
        deepcontact_pgs::PgsSolver::new(),
        deepcontact_pgs::PgsPositionSolver::new(),
    );
    let mut snapshots = Vec::new();
    for step in 0..250 {
        if step % 60 == 0 || step == 249 {
            snapshots.push((step, world.bodies().to_vec()));
        }
        world
            .step(&mut CarriedWarmStart, &mut solver, &mut pass)
            .expect("the pile steps");
    }
    let mut broad = BroadPhase::new();
    for round in 0..3 {
        for (step, bodies) in &snapshots {
            let t = std::time::Instant::now();
            for _ in 0..200 {
                std::hint::black_box(broad.find_pairs(bodies, 0.0).len());
            }
            let ms = t.elapsed().as_secs_f64() / 200.0 * 1e3;
            let pairs = broad.find_pairs(bodies, 0.0);
            let hash = pairs.iter().fold(0_u64, |h, &(a, b)| {
                h.wrapping_mul(1_000_003)
                    .wrapping_add((u64::from(a) << 32) | u64::from(b))
            });
            println!(
                "round {round} step {step:3}: {ms:.3} ms, {} pairs, hash {hash:016x}",
                pairs.len()
            );
        }
    }
}
