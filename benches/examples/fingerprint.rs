//! Fingerprint of a simulation: a hash of every body's state bits after each step, and the
//! velocity iterations of every step. Two builds that print the same lines simulate
//! bit-identically; used to check that performance changes do not change results.
//!
//! ```sh
//! cargo run --release -p deepcontact-benches --example fingerprint -- 100 250 > before.txt
//! # ... change the code ...
//! cargo run --release -p deepcontact-benches --example fingerprint -- 100 250 | diff before.txt -
//! ```
//!
//! Arguments: bodies (default 100), steps (default 250), seed (default 12345). Thesis settings,
//! builtin warm start, PGS.

use deepcontact_benches::{FNV_OFFSET, fnv1a};
use deepcontact_core::{CarriedWarmStart, WorldSettings, scene};
use deepcontact_pgs::{PgsPositionSolver, PgsSolver};

/// FNV-1a over a 64-bit word's bytes.
fn fnv(hash: u64, word: u64) -> u64 {
    fnv1a(hash, &word.to_le_bytes())
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let arg = |i: usize, default: u64| -> Result<u64, Box<dyn std::error::Error>> {
        Ok(std::env::args()
            .nth(i)
            .map(|s| s.parse())
            .transpose()?
            .unwrap_or(default))
    };
    let (bodies, steps, seed) = (
        arg(1, 100)? as usize,
        arg(2, 250)?,
        arg(3, deepcontact_benches::SEED)?,
    );
    let mut world = scene::pile(seed, bodies)?.build(WorldSettings::default())?;
    let (mut solver, mut position) = (PgsSolver::default(), PgsPositionSolver::default());
    let mut total = FNV_OFFSET;
    for _ in 0..steps {
        let r = world.step(&mut CarriedWarmStart, &mut solver, &mut position)?;
        let mut h = FNV_OFFSET;
        for b in world.bodies() {
            for v in b.state() {
                h = fnv(h, v.to_bits());
            }
        }
        for &(id, imp) in world.contacts() {
            h = fnv(h, (u64::from(id.body_a) << 32) | u64::from(id.body_b));
            h = fnv(fnv(h, imp.normal.to_bits()), imp.tangent.to_bits());
        }
        total = fnv(total, h);
        println!(
            "step {:4} contacts {:5} islands {:3} vel_it {:4} vel_it_sum {:6} pos_it {:3} state {h:016x}",
            r.step,
            r.contacts,
            r.islands,
            r.velocity_iterations,
            r.velocity_iterations_sum,
            r.position_iterations
        );
    }
    println!("total {total:016x}");
    Ok(())
}
