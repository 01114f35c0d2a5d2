//! Soak test: the thesis pile for a long time with every baseline warm start. Ignored by
//! default (minutes); run it in release:
//!
//! ```text
//! cargo test --release -p deepcontact-tests --test soak -- --ignored --nocapture
//! ```
//!
//! `none`, `builtin`, `random` and `bad` run 20 000 steps (200 s of simulated time). `copy`
//! (the oracle: it solves every step's problem to 1e-6 before the real solve, so each step
//! costs about two cold solves) runs 2 000 steps.
//!
//! Per step: every dynamic body finite and inside the box, no fallback. After settling
//! (step 1 000 on): the kinetic energy stays far below the potential-energy scale of the
//! pile (`Σ m g h` at the start), and the deepest penetration stays under 5 cm.

use std::time::Instant;

use deepcontact_core::math::Real;
use deepcontact_core::{BodyKind, World, scene};
use deepcontact_tests::{build, run};
use deepcontact_warmstart::Registry;

const SETTLED: u64 = 1_000;

fn potential_energy(world: &World) -> Real {
    let g = world.settings().gravity.norm();
    world
        .bodies()
        .iter()
        .filter(|b| b.kind == BodyKind::Dynamic)
        .map(|b| b.mass * g * b.position.y)
        .sum()
}

fn soak(spec: &str, steps: u64) {
    let scene = scene::pile(12345, 100).unwrap();
    let (lo, hi) = (scene.min, scene.max);
    let mut world = build(&scene);
    let pe0 = potential_energy(&world);
    let mut warm = Registry::with_defaults().build_provider(spec).unwrap();
    let (mut max_ke, mut min_sep): (Real, Real) = (0.0, 0.0);
    let (mut fallbacks, mut iterations) = (0usize, 0u64);
    let start = Instant::now();
    run(&mut world, warm.as_mut(), steps, |w, r| {
        for (i, b) in w
            .bodies()
            .iter()
            .enumerate()
            .filter(|(_, b)| b.kind == BodyKind::Dynamic)
        {
            let finite = [
                b.position.x,
                b.position.y,
                b.angle,
                b.linear_velocity.x,
                b.linear_velocity.y,
                b.angular_velocity,
            ]
            .iter()
            .all(|v| v.is_finite());
            assert!(
                finite,
                "{spec} step {}: body {i} is not finite: {:?}",
                r.step, b.position
            );
            assert!(
                (lo.x..=hi.x).contains(&b.position.x) && (lo.y..=hi.y).contains(&b.position.y),
                "{spec} step {}: body {i} escaped to {:?}",
                r.step,
                b.position
            );
        }
        fallbacks += r.fallbacks;
        iterations += u64::from(r.velocity_iterations);
        if r.step >= SETTLED {
            max_ke = max_ke.max(w.kinetic_energy());
            min_sep = min_sep.min(r.min_separation);
        }
    })
    .unwrap();
    let secs = start.elapsed().as_secs_f64();
    println!(
        "soak {spec:>8}: {steps} steps in {secs:.1} s ({:.0} steps/s), mean iterations {:.1}, \
         max KE after step {SETTLED} {max_ke:.3e} J (PE scale {pe0:.3e} J), min separation {min_sep:.4} m, \
         fallbacks {fallbacks}",
        steps as Real / secs,
        iterations as Real / steps as Real,
    );
    assert_eq!(fallbacks, 0, "{spec}: fallbacks");
    assert!(
        max_ke < 1e-2 * pe0,
        "{spec}: kinetic energy {max_ke} after settling (PE scale {pe0})"
    );
    assert!(
        min_sep > -0.05,
        "{spec}: penetration {min_sep} after settling"
    );
}

#[test]
#[ignore = "minutes in release: cargo test --release -p deepcontact-tests --test soak -- --ignored"]
fn soak_none() {
    soak("none", 20_000);
}

#[test]
#[ignore = "minutes in release: cargo test --release -p deepcontact-tests --test soak -- --ignored"]
fn soak_builtin() {
    soak("builtin", 20_000);
}

#[test]
#[ignore = "minutes in release: cargo test --release -p deepcontact-tests --test soak -- --ignored"]
fn soak_random() {
    soak("random", 20_000);
}

#[test]
#[ignore = "minutes in release: cargo test --release -p deepcontact-tests --test soak -- --ignored"]
fn soak_bad() {
    soak("bad", 20_000);
}

/// The oracle solves every step twice: 2 000 steps only.
#[test]
#[ignore = "minutes in release: cargo test --release -p deepcontact-tests --test soak -- --ignored"]
fn soak_copy() {
    soak("copy", 2_000);
}
