//! Criterion benchmarks of deepcontact, one group per module:
//!
//! * `providers` — every registered provider's `warm_start` on recorded thesis-pile steps, and
//!   a full `World::step` per provider;
//! * `solvers` — PGS, PSOR and Newton per iteration (fixed iteration count) and per solve (thesis
//!   stop rule) at 100, 1 000 and 10 000 bodies;
//! * `grid` — particles → grid, grid → particles, the round trip and the world encoder;
//! * `onnx` — one CNN inference on each backend of this build;
//! * `peer` — deepcontact and rapier2d stepping the same pile, side by side.
//!
//! ```sh
//! cargo bench -p deepcontact-benches                      # everything (a few minutes)
//! cargo bench -p deepcontact-benches -- peer              # one group (criterion filter)
//! DEEPCONTACT_BENCH_SIZES=100,1000 cargo bench -p deepcontact-benches -- solvers
//! ```
//!
//! Environment: `DEEPCONTACT_BENCH_SIZES` (pile sizes of `solvers` and `peer`, default
//! `100,1000,10000`), `DEEPCONTACT_BENCH_QUICK=1` (shorter measurement, for smoke runs).

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};

mod groups;

fn config() -> Criterion {
    let quick = std::env::var_os("DEEPCONTACT_BENCH_QUICK").is_some_and(|v| v != "0");
    let (warm_up, measure) = if quick { (100, 300) } else { (500, 2000) };
    Criterion::default()
        .sample_size(10)
        .warm_up_time(Duration::from_millis(warm_up))
        .measurement_time(Duration::from_millis(measure))
        .without_plots()
}

criterion_group! {
    name = benches;
    config = config();
    targets = groups::providers::bench, groups::solvers::bench, groups::grid::bench, groups::onnx::bench,
        groups::peer::bench
}
criterion_main!(benches);
