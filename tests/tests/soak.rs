//! Soak: the thesis pile for a long time with every baseline warm start
//! (`deepcontact_experiments::soak`; every step: bodies finite and inside the box, no fallback; after
//! settling: kinetic energy under 1 % of the potential-energy scale, penetration under 5 cm).
//!
//! The full soak (20 000 steps per provider, 2 000 for the oracle) is the CLI check that CI
//! runs in release: `cargo run --release -- soak`. Here, in the debug build, a short soak of
//! two providers checks the same code path, and the full one is kept as an ignored test:
//!
//! ```text
//! cargo test --release -p deepcontact-tests --test soak -- --ignored --nocapture
//! ```

use deepcontact_experiments::soak::{KE_FRACTION, soak_one};
use deepcontact_experiments::{ExperimentError, full_registry as registry};

fn soak(spec: &str, steps: u64, settle: u64) {
    let run = soak_one(&registry(), spec, steps, settle, 12345, 100).unwrap();
    println!("{run:?}");
    assert_eq!(run.steps, steps);
    assert!(run.max_kinetic_energy < KE_FRACTION * run.potential_energy);
    assert!(run.mean_iterations > 0.0);
}

#[test]
fn short_soak_of_builtin_and_bad() {
    soak("builtin", 400, 300);
    soak("bad", 400, 300);
}

#[test]
fn soak_reports_the_first_violation_with_its_step() {
    // Checking the energy from step 0, while the circles still fall, must fail at once.
    let err = soak_one(&registry(), "none", 50, 0, 12345, 100).unwrap_err();
    match err {
        ExperimentError::Soak {
            warm_start,
            step,
            what,
        } => {
            assert_eq!(warm_start, "none");
            assert!(step < 50);
            assert!(what.contains("kinetic energy"), "{what}");
        }
        other => panic!("{other}"),
    }
}

#[test]
#[ignore = "minutes in release: cargo test --release -p deepcontact-tests --test soak -- --ignored"]
fn full_soak() {
    for spec in ["none", "builtin", "random", "bad"] {
        soak(spec, 20_000, 1_000);
    }
    soak("copy", 2_000, 1_000);
}
